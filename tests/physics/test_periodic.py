"""Periodic ends (#30) against mechanics: no pdem output is used as truth.

A body leaving at hi re-enters at lo with its velocity (free flight); two spheres touching
across the ends feel equal and opposite forces equal to the analytic elastic contact
k_n·δ (k_n = E r for two equal spheres of one material, YADE_MODEL §4) and to the same pair in
the interior; a periodic gas conserves its momentum (no external force); an elastic head-on
collision across the ends exchanges the velocities of two equal spheres and keeps the kinetic
energy. All on one rank (a ring of one: the images are its own bodies); the rank-count and
restart identity is tests/mpi/test_periodic_mpi.py. Bad input: one line, exit 2.
"""
import math

import numpy as np
import pytest

from factories import sphere_mass
from pdem import Scene
from pdem.errors import InputError
from pdem_cli import run_pdem

R, RHO, E = 0.01, 2600.0, 1e8
L = 0.2  # period [m] along x
KN = E * R  # two equal spheres of one material: kn = 2(E r)(E r)/(E r + E r) = E r
M = sphere_mass(R, RHO)


def scene(pos, vel=None, *, dt=1e-6, friction_angle=0.5, **kw):
    kw.setdefault("allow_initial_overlap", True)
    sc = Scene(dt=dt, damping=0.0, gravity=(0.0, 0.0, 0.0), skin=0.0025, slab_axis=0, periodic=[0.0, L], **kw)
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=friction_angle)
    sc.add_spheres(pos, R, m, vel=vel)
    return sc


def test_leaving_at_hi_reenters_at_lo_with_its_velocity():
    v = np.array([[1.5, 0.25, -0.5], [-2.0, 0.0, 0.125]])
    x0 = np.array([[L - 0.002, 0.05, 0.05], [0.003, 0.15, 0.05]])  # leaves at hi / at lo
    sim = scene(x0, v, dt=1e-5).build()
    sim.run(1000)
    t = sim.time
    b = sim.bodies()
    free = x0 + v * t  # free flight, then one period back or forth along x
    expect = free.copy()
    expect[0, 0] -= L
    expect[1, 0] += L
    assert 0.0 <= b["pos"][0, 0] < 0.02 and L - 0.02 < b["pos"][1, 0] < L
    np.testing.assert_allclose(b["pos"], expect, rtol=0, atol=1e-12)
    assert np.array_equal(b["vel"], v)  # nothing touched them: the velocity is the initial one, bit for bit
    assert sim.domain.n_wrapped == 2


def test_contact_across_the_ends_equals_the_interior_pair():
    """Pair 0-1 overlaps by δ across x = 0 = L, pair 2-3 by the same δ in the interior."""
    d = 2 * R - 5e-4  # centre distance: overlap δ = 5e-4 m
    pos = [(0.004, 0.05, 0.05), (0.004 - d + L, 0.05, 0.05), (0.1, 0.15, 0.05), (0.1 - d, 0.15, 0.05)]
    sim = scene(pos).build()
    sim.run(1)
    f = sim.bodies()["force"]
    assert np.array_equal(f[0], -f[1])  # Newton's third law, bit for bit
    assert f[0, 0] == pytest.approx(KN * 5e-4, rel=1e-9)  # analytic: kn δ along the line of centres
    assert f[0, 1] == 0.0 and f[0, 2] == 0.0
    np.testing.assert_allclose(f[0], f[2], rtol=1e-9, atol=0)  # the same pair in the interior
    np.testing.assert_allclose(f[1], f[3], rtol=1e-9, atol=0)
    assert len(sim.contacts()["gid1"]) == 2  # one contact across the ends (not one per image)


def test_periodic_gas_conserves_momentum():
    rng = np.random.default_rng(30)
    g = np.stack(np.meshgrid(np.arange(8), np.arange(3), np.arange(3), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * np.array([L / 8, 0.025, 0.025]) + rng.uniform(-0.002, 0.002, (len(g), 3))
    vel = rng.uniform(-3.0, 3.0, (len(g), 3)) + np.array([2.0, 0.0, 0.0])  # a drift along x: bodies wrap
    sim = scene(pos, vel, dt=5e-6, friction_angle=0.3, allow_initial_overlap=False).build()
    p0 = (M * vel).sum(axis=0)
    across = 0
    for _ in range(40):
        sim.run(100)
        c = sim.kind("sphere_sphere").contacts
        rows = c.real_rows()
        across += int(np.count_nonzero(sim.domain.image[c.j[rows], 0] != sim.domain.image[c.i[rows], 0]))
    b = sim.bodies()
    p1 = (b["mass"][:, None] * b["vel"]).sum(axis=0)
    scale = float(np.sum(M * np.linalg.norm(vel, axis=1)))
    assert np.abs(p1 - p0).max() <= 1e-13 * scale
    assert sim.domain.n_wrapped > 0 and across > 0  # bodies wrapped and touched across the ends
    assert sim.contacts_per_particle() >= 0.0


@pytest.mark.parametrize("where", ["across", "interior"])
def test_elastic_collision_across_the_ends(where):
    """Head-on, friction-free, undamped: the equal spheres exchange velocities, energy is kept."""
    x = (0.006, L - 0.016) if where == "across" else (0.106, 0.084)
    v0 = 1.0
    sim = scene([(x[0], 0.05, 0.05), (x[1], 0.05, 0.05)], [(-v0, 0, 0), (v0, 0, 0)], dt=2e-7,
                friction_angle=0.0).build()
    e0 = sim.energy()["total"]
    assert e0 == pytest.approx(M * v0 * v0, rel=1e-14)
    duration = math.pi * math.sqrt(0.5 * M / KN)  # half a period of the reduced mass on kn
    sim.run(int((0.002 / (2 * v0) + 2 * duration) / 2e-7))
    assert len(sim.contacts()["gid1"]) == 0  # apart again
    b = sim.bodies()
    np.testing.assert_allclose(b["vel"][:, 0], [v0, -v0], rtol=0, atol=1e-5 * v0)
    assert sim.energy()["total"] == pytest.approx(e0, rel=1e-5)


# ---------------------------------------------------------------------------- refusals
def _base(**kw):
    return scene([(0.05, 0.05, 0.05), (0.1, 0.05, 0.05)], **kw)


def _with_end_wall():
    sc = _base()
    sc.add_wall(0, 0.0, 0)
    return sc


def _with_crossing_facet():
    sc = _base()
    sc.add_facet([(L - 0.01, 0.0, 0.0), (L + 0.01, 0.0, 0.0), (L, 0.1, 0.0)], 0)
    return sc


def _short_period():
    sc = Scene(dt=1e-6, skin=0.0025, periodic=[0.0, 0.04])
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=0.5)
    sc.add_spheres([(0.01, 0.05, 0.05)], R, m)
    return sc


def _outside():
    return scene([(L + 0.01, 0.05, 0.05)])


def _cohesive():
    sc = Scene(dt=1e-6, skin=0.0025, periodic=[0.0, L], law="cohesive")
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=0.5, normal_cohesion=1e6, shear_cohesion=1e6)
    sc.add_spheres([(0.05, 0.05, 0.05)], R, m)
    return sc


@pytest.mark.parametrize("make, words", [
    (_with_end_wall, "walls[0]: a wall perpendicular to x"),
    (_with_crossing_facet, "facets[0]: spans"),
    (_short_period, "must be longer than two halos"),
    (_outside, "lies outside simulation.periodic"),
    (_cohesive, "not supported with periodic ends"),
])
def test_refusals(make, words):
    with pytest.raises(InputError) as err:
        make().build()
    assert words in str(err.value) and "\n" not in str(err.value)


def test_bad_periodic_value_exits_2_with_one_line(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('[simulation]\nperiodic = [0.3, 0.1]\n[materials.m]\ndensity = 2600.0\nyoung = 1e8\n'
                 'poisson = 0.3\nfriction_angle = 0.5\n[[spheres]]\npos = [[0.2, 0.0, 0.0]]\nradius = 0.01\n'
                 'material = "m"\n')
    r = run_pdem(1, f, tmp_path / "out", "--fresh", expect=2)
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "periodic" in lines[0], r.stderr


def test_initial_overlap_across_the_ends_is_refused():
    with pytest.raises(InputError, match="overlap by"):
        scene([(0.004, 0.05, 0.05), (L - 0.0155, 0.05, 0.05)], allow_initial_overlap=False).build()


def test_a_contact_across_the_ends_counts_for_both_bodies():
    """Two bodies touching across the ends: 1 contact per body, as for the interior pair."""
    d = 2 * R - 5e-4
    sim = scene([(0.004, 0.05, 0.05), (0.004 - d + L, 0.05, 0.05)]).build()
    sim.run(1)
    assert sim.contacts_per_particle() == 1.0
