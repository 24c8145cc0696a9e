"""Rigid boxes (sleeper, platen) against closed-form mechanics; loads and the cycle record.

Truth is independent of pdem's output: Yade's Ip2 formula for kn, statics (m g/kn, load + weight
shared by symmetric contacts), the closest-point geometry of a cuboid, Newton's third law
(math.fsum of the per-contact forces), the haversine formula of SPEC.md 1.6.
"""
import math

import numpy as np
import pytest
from factories import BALL, STEEL, ball_and_steel

from pdem import InputError
from pdem.scenes.cycles import CycleRecorder
from pdem.boundaries.loads import Constant, Haversine
from pdem.driver.observables import box_forces, box_positions

G = 9.81
R = 0.01
E_S, E_B = BALL["young"], STEEL["young"]
RHO = BALL["density"]
M_S = RHO * (4.0 / 3.0) * math.pi * R ** 3
KN_BOX = 2.0 * (E_B * R) * (E_S * R) / (E_B * R + E_S * R)  # YADE_MODEL §4 with radius1 = radius2 = r
HALF = (0.1, 0.1, 0.05)


def test_static_overlap_on_fixed_box():
    """A sphere resting on the top face of a fixed box (damped) reaches overlap m g/kn."""
    sc, ball, steel = ball_and_steel(dt=2e-6, damping=0.3, gravity=G)
    sc.add_spheres([(0.03, -0.04, HALF[2] + R)], R, ball)
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=34.0, fixed=True)
    sim = sc.build()
    sim.run(40000)
    rows = sim.kind("sphere_box").contacts.real_rows()
    assert len(rows) == 1
    assert sim.kind("sphere_box").contacts.params[rows[0], 0] == pytest.approx(KN_BOX, rel=1e-14)
    assert sim.kind("sphere_box").contacts.overlap[rows[0]] == pytest.approx(M_S * G / KN_BOX, rel=1e-6)
    assert box_forces(sim)[0] == pytest.approx([0.0, 0.0, -M_S * G], rel=1e-6, abs=1e-12)
    assert box_positions(sim)[0].tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("where", ["face", "edge", "corner", "inside"])
def test_contact_normal_is_closest_point_direction(where):
    """One step of a sphere overlapping a fixed box: force on the sphere = kn·pen·n with n from the
    closest point of the box to the centre (face/edge/corner) or, centre inside, along the
    nearest face (pen = r + distance to that face)."""
    hx, hy, hz = HALF
    a, b, c = 0.004, 0.006, 0.003  # offsets beyond the faces (|(a, b, c)| < r)
    centre = {"face": (0.02, 0.03, hz + 0.007), "edge": (hx + a, 0.02, hz + b),
              "corner": (hx + a, -hy - c, hz + b), "inside": (0.05, 0.02, hz - 0.002)}[where]
    x = np.array(centre)
    q = np.clip(x, -np.array(HALF), np.array(HALF))
    if where == "inside":
        n, pen = np.array([0.0, 0.0, 1.0]), R + 0.002
    else:
        n = (x - q) / np.linalg.norm(x - q)
        pen = R - np.linalg.norm(x - q)
    sc, ball, steel = ball_and_steel()
    sc.add_spheres([centre], R, ball)
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=34.0, fixed=True)
    sim = sc.build()
    sim.run(1)
    assert sim.kind("sphere_box").contacts.state[0] == 1
    np.testing.assert_allclose(sim.kind("sphere_box").contacts.history[0, 3:6], n, rtol=0, atol=1e-15)
    assert sim.kind("sphere_box").contacts.overlap[0] == pytest.approx(pen, rel=1e-12)
    np.testing.assert_allclose(sim.kind("sphere_box").contacts.force[0], KN_BOX * pen * n, rtol=1e-12, atol=1e-18)
    if where in ("edge", "corner"):
        assert np.count_nonzero(n) == (2 if where == "edge" else 3)


def _free_box_with_spheres(dt=1e-6):
    # spheres start deep in the box's faces, edges and corners (up to 0.6 r): a test of Newton's
    # third law, not of stability, so the overlap limit of the runaway guard is raised
    sc, ball, steel = ball_and_steel(dt=dt, max_overlap_ratio=1.0)
    rng = np.random.default_rng(3)
    hx, hy, hz = HALF
    pos = [(0.03, 0.01, hz + R - 0.0005), (hx + 0.004, -0.02, 0.01), (-hx - 0.003, hy + 0.004, hz + 0.005),
           (0.0, -hy - R + 0.0007, -0.02), (0.05, 0.05, -hz - R + 0.0003)]
    vel = rng.uniform(-0.01, 0.01, (len(pos), 3))
    sc.add_spheres(pos, R, ball, vel=vel)
    sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=2.0, velocity=(0.01, -0.02, 0.03))
    return sc.build()


def test_newton_third_law_and_momentum():
    """The force on a free box is exactly minus the (correctly rounded) sum of its contact forces on
    the spheres, and without gravity the total momentum of spheres + box is conserved."""
    sim = _free_box_with_spheres()
    p = sim.particles
    p0 = (p.mass[: p.n_local, None] * p.vel[: p.n_local]).sum(0) + sim.boxes.mass[0] * sim.boxes.velocity[0]
    most = 0
    for _ in range(200):
        sim.run(1)
        rows = sim.kind("sphere_box").contacts.real_rows()
        most = max(most, len(rows))
        expect = [-math.fsum(sim.kind("sphere_box").contacts.force[rows, c]) for c in range(3)]
        assert sim.boxes.contact_force[0].tolist() == expect
    assert most == 5
    p1 = (p.mass[: p.n_local, None] * p.vel[: p.n_local]).sum(0) + sim.boxes.mass[0] * sim.boxes.velocity[0]
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-12 * (abs(p0).max() + 1.0))


@pytest.mark.slow  # thousands of steps of a packed bed under a box
def test_loaded_box_settles_on_bed_of_fixed_spheres():
    """A free box (z only, own damping) under a constant downward load on 9 fixed spheres settles
    where the contact force equals load + weight, shared equally: pen = (F + M g)/(9 kn)."""
    load, mass = 200.0, 5.0
    sc, ball, steel = ball_and_steel(dt=2e-6, gravity=G)
    xy = [(x, y) for x in (-0.03, 0.0, 0.03) for y in (-0.03, 0.0, 0.03)]
    sc.add_spheres([(x, y, 0.0) for x, y in xy], R, ball, fixed=True)
    half = (0.05, 0.05, 0.02)
    sc.add_box((0.0, 0.0, R + half[2] + 1e-4), half, steel, mass=mass, blocked="xyXYZ", load=Constant(load),
               damping=0.3)
    sim = sc.build()
    sim.run(60000)
    pen = (load + mass * G) / (9 * KN_BOX)
    assert box_forces(sim)[0, 2] == pytest.approx(load + mass * G, rel=1e-6)
    assert sim.boxes.center[0, 2] == pytest.approx(R + half[2] - pen, abs=1e-6 * pen)
    assert abs(sim.boxes.velocity[0, 2]) < 1e-6
    np.testing.assert_allclose(
        sim.kind("sphere_box").contacts.overlap[sim.kind("sphere_box").contacts.real_rows()], pen, rtol=1e-5
    )


def test_blocked_dofs_hold_under_oblique_contacts():
    """A box free in z only, pushed by a sphere at its edge (oblique normal), keeps x and y exactly
    while z moves; the same box with free translations moves sideways."""
    def run(blocked):
        sc, ball, steel = ball_and_steel(dt=1e-6)
        sc.add_spheres([(HALF[0] + 0.004, 0.0, -HALF[2] - 0.006)], R, ball, fixed=True)
        sc.add_box((0.0, 0.0, 0.0), HALF, steel, mass=1.0, blocked=blocked)
        sim = sc.build()
        sim.run(300)
        return sim
    sim = run("xyXYZ")
    assert sim.boxes.contact_force[0, 0] < 0.0 and sim.boxes.contact_force[0, 2] > 0.0
    assert sim.boxes.center[0, 0] == 0.0 and sim.boxes.center[0, 1] == 0.0
    assert sim.boxes.velocity[0, 0] == 0.0 and sim.boxes.center[0, 2] > 0.0
    free = run("XYZ")
    assert free.boxes.center[0, 0] < 0.0


def test_haversine_program():
    """F = F_min + (F_max − F_min)(1 − cos 2πft)/2: F_min at 0, F_max at 1/(2f), F_min at 1/f."""
    h = Haversine(3000.0, 40000.0, 1.0, 3)
    assert h.value(0.0) == 3000.0
    assert h.value(0.5) == 40000.0
    assert h.value(1.0) == pytest.approx(3000.0, abs=1e-9)
    assert h.value(0.25) == pytest.approx(21500.0, rel=1e-14)
    assert h.value(1.5) == 40000.0
    assert h.value(3.2) == 3000.0  # after the last cycle
    h2 = Haversine(0.0, 3000.0, 0.1, 1, start=2.0)
    assert h2.value(1.0) == 0.0 and h2.value(7.0) == pytest.approx(3000.0, rel=1e-14)
    for bad in (dict(f_min=5, f_max=1, frequency=1, cycles=1), dict(f_min=0, f_max=1, frequency=0, cycles=1),
                dict(f_min=0, f_max=1, frequency=1, cycles=0), dict(f_min=0, f_max=1, frequency=1, cycles=1.5)):
        with pytest.raises(InputError):
            Haversine(**bad)


def test_box_input_errors_and_no_boxes():
    sc, ball, steel = ball_and_steel()
    for kw in (dict(mass=0.0), dict(mass=1.0, blocked="q"),  # free rotations: tests/physics/test_box_rotation.py
               dict(mass=1.0, load=5.0), dict(mass=1.0, damping=2.0)):
        with pytest.raises(InputError) as e:
            sc.add_box((0, 0, 0), HALF, steel, **kw)
        assert "\n" not in str(e.value)
    with pytest.raises(InputError):
        sc.add_box((0, 0, 0), (0.1, -0.1, 0.1), steel, mass=1.0)
    sc.add_spheres([(0.0, 0.0, 0.0)], R, ball)
    sim = sc.build()
    assert sim.kind("sphere_box") is None and sim.boxes is None and "boxes" not in sim.spec


@pytest.mark.slow  # thousands of steps of a packed bed under a box
def test_haversine_on_box_and_cycle_record():
    """A sleeper under a haversine program: the applied load follows the formula, and the cycle
    record has one row per cycle with the load extrema F_max/F_min and the settlement sampled at
    the start, peak and end of each cycle."""
    f = 50.0
    h = Haversine(20.0, 200.0, f, 3)
    sc, ball, steel = ball_and_steel(dt=2e-6, gravity=G)
    xy = [(x, y) for x in (-0.03, 0.0, 0.03) for y in (-0.03, 0.0, 0.03)]
    sc.add_spheres([(x, y, 0.0) for x, y in xy], R, ball, fixed=True)
    half = (0.05, 0.05, 0.02)
    sc.add_box((0.0, 0.0, R + half[2]), half, steel, mass=5.0, blocked="xyXYZ", load=h, damping=0.3)
    sim = sc.build()
    rec = CycleRecorder(h)
    z = []
    for _ in range(int(3.2 / f / 2e-6)):
        t = sim.time
        sim.run(1)
        assert sim.boxes.load_force[0, 2] == -h.value(t)
        rec.sample_box(sim, 0)
        z.append((sim.time, sim.boxes.center[0, 2]))
    tab = rec.table()
    assert tab["cycle"].tolist() == [0, 1, 2]
    np.testing.assert_allclose(tab["load_max"], 200.0, rtol=1e-6)
    np.testing.assert_allclose(tab["load_min"], 20.0, rtol=1e-3)
    z0 = z[0][1]  # reference = centre after the first step
    times = np.array([t for t, _ in z])
    zz = np.array([v for _, v in z])
    for k in range(3):
        for name, tk in (
            ("settlement_start", k / f),
            ("settlement_peak", (k + 0.5) / f),
            ("settlement_end", (k + 1) / f),
        ):
            i = int(np.flatnonzero(times >= tk)[0])  # first sample at or after the instant
            assert tab[name][k] == pytest.approx(z0 - zz[i], abs=1e-15)
    # quasi-static: at the peak the bed carries ≈ F_max + M g (the load changes slowly vs the period)
    assert tab["force_max"][1] == pytest.approx(200.0 + 5.0 * G, rel=0.05)
    assert np.all(tab["settlement_peak"] > tab["settlement_start"])
