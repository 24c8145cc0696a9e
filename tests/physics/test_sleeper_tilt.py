"""Turning sleepers of the track (`[track] sleeper_rotation = true`) against rigid-body mechanics
and the beam on elastic supports.

Truth is independent of pdem's output: Newton–Euler for a sleeper body of the track (the
homogeneous box plus the rails as point masses at their seats, I computed here from the
dimensions) under an eccentric point load at its rail seat (dv/dt = F/m, dL/dt = r × F, ω = L/I
while the tilt is tiny); the statics of a rigid sleeper on a bed of equal springs under an
eccentric load (force balance: u = −P/(n k); moment balance: θ = −P e/(k Σ y_i²)); and the beam
on discrete supports: a sleeper hanging in the rail without support (its pad force zero) is the
same beam with that support missing, so what it sheds its neighbours carry; the pads of a turning
sleeper act at its seats (the moment is r × F of each pad, Newton's third law on the rail).
"""
import math

import numpy as np
import pytest

from pdem.bodies.boxes import Boxes
from pdem.boundaries.loads import AxleTrain, Constant
from pdem.boundaries.rail_beam import RailBeam, RailSection, SleeperRails
from pdem.scenes.track import seat_offsets, sleeper_boxes, sleeper_inertia, track_settings

MATERIALS = {"concrete": {"density": 2600.0, "young": 4e6, "poisson": 0.3, "friction_angle": 0.5},
             "ballast": {"density": 2600.0, "young": 2.8e6, "poisson": 0.3, "friction_angle": 0.5},
             "steel": {"density": 7850.0, "young": 2.8e7, "poisson": 0.25, "friction_angle": 0.5},
             "rubber": {"density": 1000.0, "young": 2.8e5, "poisson": 0.5, "friction_angle": 0.7}}


def whole_track(**track):
    """The default B91 track (2600 x 300 x 200 mm, two UIC 60 rails at ±0.7535 m) with turning sleepers."""
    return track_settings({"materials": MATERIALS, "track": {"sleeper_rotation": True, **track}})


def test_the_sleeper_body_has_the_inertia_of_the_box_and_its_rails():
    c = whole_track()
    a, b, h = 0.3, 2.6, 0.2
    m = 2600.0 * a * b * h
    mr, dy = 60.21 * 0.6, (1.435 + 0.072) / 2
    expected = [m * (b * b + h * h) / 12 + 2 * mr * dy * dy, m * (a * a + h * h) / 12,
                m * (a * a + b * b) / 12 + 2 * mr * dy * dy]
    assert sleeper_inertia(c, rails=True) == pytest.approx(expected, rel=1e-12)
    assert sleeper_inertia(c, rails=False) == pytest.approx([m * (b * b + h * h) / 12, m * (a * a + h * h) / 12,
                                                            m * (a * a + b * b) / 12], rel=1e-12)
    assert sleeper_inertia(whole_track(sleeper_inertia=[1.0, 2.0, 3.0]), rails=True) == [1.0, 2.0, 3.0]
    assert c["sleeper_blocked"] == "xyZ"  # z and the two tilts; the vertical axis blocked
    half = whole_track(half=True)
    assert half["sleeper_blocked"] == "yXZ"  # the symmetry plane y = 0 allows only the tilt about y
    assert seat_offsets(c) == pytest.approx(np.array([[0.0, -dy, h / 2], [0.0, dy, h / 2]]))
    assert seat_offsets(half) == pytest.approx(np.array([[0.0, dy - b / 4, h / 2]]))


def test_an_eccentric_point_load_tilts_the_sleeper_as_newton_euler_says():
    """A free sleeper body (zero gravity, no bed) under a constant load P at its hi rail seat:
    v_z = −P t/m; L = r × F t = (−P dy, 0, 0) t about x with r = (0, dy, h/2); ω_x = L_x/I_x
    (I of the box and the rails, from the dimensions), no turn about y; the tilt Σ ω_x Δt is
    atan2(R_zy, R_zz) of the box's rotation."""
    c = whole_track()
    centres, half = sleeper_boxes(c)
    seat = seat_offsets(c)[1]
    ix = c["sleeper_mass"] * (half[1] ** 2 + half[2] ** 2) / 3 + 2 * 60.21 * 0.6 * seat[1] ** 2
    bx = Boxes()
    m, p, dt, n = c["body_mass"], 2.0e4, 1e-5, 400
    bx.add(centres[0], half, 0, m, blocked=c["sleeper_blocked"], load=Constant(p), load_point=seat,
           inertia=sleeper_inertia(c, rails=True))
    tilt = 0.0
    for k in range(n):
        bx.integrate(k * dt, dt, (0.0, 0.0, 0.0))
        tilt += bx.angvel[0, 0] * dt
    t = n * dt
    assert bx.velocity[0] == pytest.approx([0.0, 0.0, -p * t / m], rel=1e-12)
    assert bx.angmom[0, 0] == pytest.approx(-p * seat[1] * t, rel=1e-4)
    assert bx.angvel[0, 0] == pytest.approx(-p * seat[1] * t / ix, rel=1e-4)
    assert bx.angvel[0, 1] == 0.0 and bx.angvel[0, 2] == 0.0
    r = bx.rotation[0]
    assert math.atan2(r[2, 1], r[2, 2]) == pytest.approx(tilt, rel=1e-9)
    assert tilt < 0  # the loaded (hi) end goes down


def test_moment_balance_of_a_sleeper_on_a_spring_bed():
    """A sleeper on n equal springs k under its base (y_i across it), an eccentric load P at
    y = e on its top, damped to rest: the force balance gives the sinking u = −P/(n k), the
    moment balance about x the tilt θ = −P e/(k Σ y_i²) (small tilts; the springs' forces act at
    their base points, turned with the sleeper)."""
    c = whole_track()
    centres, half = sleeper_boxes(c)
    ys = np.linspace(-0.9 * half[1], 0.9 * half[1], 10)
    base = np.stack([np.zeros_like(ys), ys, np.full_like(ys, -half[2])], axis=1)
    k, p, e = 2.0e6, 2.0e4, 0.5
    bx = Boxes()
    bx.add(centres[0], half, 0, c["body_mass"], blocked=c["sleeper_blocked"], load=Constant(p),
           load_point=(0.0, e, half[2]), inertia=sleeper_inertia(c, rails=True), damping=0.5)
    rest = bx.center[0] + base  # spring ends unstressed at the start
    dt = 2e-5
    for step in range(40000):
        points = bx.center[0] + base @ bx.rotation[0].T
        f = np.zeros((len(ys), 3))
        f[:, 2] = -k * (points[:, 2] - rest[:, 2])
        bx.contact_force[0] = f.sum(axis=0)
        bx.contact_torque[0] = np.cross(points - bx.center[0], f).sum(axis=0)
        bx.integrate(step * dt, dt, (0.0, 0.0, 0.0))
    u = bx.center[0, 2] - centres[0, 2]
    r = bx.rotation[0]
    theta = math.atan2(r[2, 1], r[2, 2])
    assert u == pytest.approx(-p / (len(ys) * k), rel=1e-3)
    assert theta == pytest.approx(-p * e / (k * np.sum(ys ** 2)), rel=1e-2)
    assert np.abs(bx.angvel[0]).max() < 1e-6 and abs(bx.velocity[0, 2]) < 1e-7


class Sleepers:
    """What `SleeperRails` reads of turning sleepers: centres and rotations."""

    def __init__(self, centres):
        self.center = np.array(centres, float)
        self.rotation = np.repeat(np.eye(3)[None], len(centres), axis=0)


def turning_rails(k_pads, seats, n=6, spacing=0.6):
    train = AxleTrain(2.0e5, [0.0], 20.0, 1, spacing=spacing, length=0.7, x_from=-1.0, x_to=5.0)
    x = (np.arange(n) + 0.5) * spacing
    section = RailSection(6.38e6, 0.0)  # weightless rails: the pads carry the wheels only
    beams = [RailBeam(x, k_pads, section=section, x_start=0.0, x_end=n * spacing) for _ in seats]
    return SleeperRails(beams, train, seats=seats), x


def test_a_hanging_sleeper_sheds_its_load_to_its_neighbours_through_the_beam():
    """The wheel over sleeper 2 of a whole track (two rails). Sleeper 2 loses its support and
    hangs in the rails without weight: its seats go down until its pads carry nothing, and then
    the other pads carry what a beam without that support gives them (the same beam, its pad
    made 10⁻⁹ as stiff); the wheel load is carried all the same."""
    seats = [(0.0, -0.7535, 0.1), (0.0, 0.7535, 0.1)]
    k = 1.0e8
    centres = [(xk, 0.0, 0.3) for xk in (np.arange(6) + 0.5) * 0.6]
    rails, x = turning_rails(k, seats)
    box = Sleepers(centres)
    rails.attach(box, rails.seat_heights(box.center, box.rotation))
    t = (x[2] + 1.0) / 20.0  # the wheel over sleeper 2
    assert rails.train.axle_positions(t) == [pytest.approx(x[2])]
    supported = np.array([rails.load(t, xk) for xk in x])
    assert supported.sum() == pytest.approx(2.0e5, rel=1e-12)
    # sleeper 2 sinks by s: its load is linear in s; find where it vanishes
    loads = []
    for s in (0.0, 1e-3):
        box.center[2, 2] = 0.3 - s
        loads.append(np.array([rails.load(t, xk) for xk in x]))
    s0 = 1e-3 * loads[0][2] / (loads[0][2] - loads[1][2])
    box.center[2, 2] = 0.3 - s0
    hanging = np.array([rails.load(t, xk) for xk in x])
    assert abs(hanging[2]) < 1e-6 * supported[2]
    missing = RailBeam(x, [k, k, 1e-9 * k, k, k, k], section=RailSection(6.38e6, 0.0), x_start=0.0, x_end=3.6)
    expected = -2 * missing.seat_forces(np.zeros(6), [x[2]], [1.0e5])
    np.testing.assert_allclose(hanging[[0, 1, 3, 4, 5]], expected[[0, 1, 3, 4, 5]], rtol=1e-6)
    assert hanging.sum() == pytest.approx(2.0e5, rel=1e-9)
    assert np.all(hanging[[1, 3]] > supported[[1, 3]])  # the neighbours carry what it shed


def test_the_pads_of_a_tilted_sleeper_act_at_its_seats():
    """A sleeper tilted by θ about x (its hi end up): the hi seat rises by about dy θ, so the hi
    rail's pad pushes more and the lo rail's less; the load is the sum of the two pads and its
    moment Σ (R s_r) × (0, 0, F_r), which turns the sleeper back (restoring)."""
    seats = [(0.0, -0.7535, 0.1), (0.0, 0.7535, 0.1)]
    centres = [(xk, 0.0, 0.3) for xk in (np.arange(6) + 0.5) * 0.6]
    rails, x = turning_rails(1.0e8, seats)
    box = Sleepers(centres)
    rails.attach(box, rails.seat_heights(box.center, box.rotation))
    theta = 1e-3
    cs, sn = math.cos(theta), math.sin(theta)
    box.rotation[3] = [[1, 0, 0], [0, cs, -sn], [0, sn, cs]]
    t = 0.0  # the wheel not yet on the rails: only the tilt loads the pads
    forces, points = rails.turning_forces(t, box.center, box.rotation)
    assert forces[1, 3] < 0 < forces[0, 3]  # z up: the hi pad pushes the sleeper down, the lo pad pulls it up
    assert points[1, 3, 2] - 0.4 == pytest.approx(0.7535 * sn + 0.1 * (cs - 1), rel=1e-12)
    load = rails.load(t, x[3])
    moment = rails.moment(t, x[3])
    assert load == pytest.approx(-(forces[0, 3] + forces[1, 3]), rel=1e-12)
    arms = points[:, 3] - box.center[3]
    expected = sum(np.cross(arms[r], (0.0, 0.0, forces[r, 3])) for r in range(2))
    np.testing.assert_allclose(moment, expected, rtol=1e-12, atol=1e-9)
    assert moment[0] < 0  # against the tilt θ > 0
