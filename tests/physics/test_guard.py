"""The runaway guard (`pdem.checks.guard`): tunnelling, runaway bodies and bodies that leave the domain
stop the run with `InstabilityError` naming the body and the cause, however short the contact;
initial overlaps with walls, facets and boxes are refused like sphere–sphere ones; and the guard
changes no trajectory (it only reads).

Independent truths: a sphere at speed v moves v·Δt per step (leapfrog); a linear contact of
stiffness k stops a mass m within v·sqrt(m/k) (so a soft wall lets a fast sphere through: the
overlap would pass the radius); a 75 % overlap is r − |d| with d the centre's distance.
"""
import dataclasses
import math

import numpy as np
import pytest

from pdem import InputError
from pdem.build.config import scene_from_dict
from pdem.errors import InstabilityError
from pdem.checks.guard import STEP_FRACTION
from pdem.build.scene import Scene

R, RHO, E = 0.01, 2600.0, 2.8e7
M = RHO * 4.0 / 3.0 * math.pi * R ** 3


def shot(v, dt="auto", young=E, **kw):
    """One sphere at v [m/s] along −x towards a two-sided wall at x = 0, no gravity, no damping."""
    sc = Scene(dt=dt, damping=0.0, gravity=(0.0, 0.0, 0.0), **kw)
    m = sc.material(density=RHO, young=young, poisson=0.3, friction_angle=0.5)
    sc.add_spheres([(0.05, 0.0, 0.0)], R, m, vel=[(-v, 0.0, 0.0)])
    sc.add_wall(0, 0.0, m)
    return sc.build()


def test_fast_shot_into_soft_wall_stops_before_it_tunnels():
    """100 m/s into E 2.8e7: v·sqrt(m/k) = 100·sqrt(M/(E r)) ≈ 1.9 r, the sphere would pass the
    plane; the contact lasts fewer steps than the every-100-step check. Stopped at once."""
    sim = shot(100.0)
    assert 100.0 * math.sqrt(M / (E * R)) > R  # it would go through
    with pytest.raises(InstabilityError) as err:
        sim.run(2000)
    msg = str(err.value)
    assert "body gid 0" in msg and "tunnelling" in msg and "\n" not in msg, msg
    assert sim.step < 5


def test_moderate_shot_bounces_with_energy_kept():
    """At 10 m/s (0.05 r per step, overlap peak v·sqrt(m/k) ≈ 0.19 r) nothing trips: the sphere
    bounces back with its speed (no damping: the linear law is elastic in the normal direction;
    leapfrog over the ~20 steps of the contact keeps it to within 1 %)."""
    sim = shot(10.0)
    step_ratio = 10.0 * sim.dt / R
    assert step_ratio < STEP_FRACTION
    sim.run(3000)
    v = sim.particles.vel[0]
    assert v[0] > 0 and abs(v[0] - 10.0) < 0.01 * 10.0, v


def test_soft_wall_overlap_beyond_limit_caught_within_the_contact():
    """A speed under the step limit but a contact too soft to stop it before half a radius: the
    overlap guard (every step) stops it inside the contact, which lasts far fewer steps than
    the check interval; with check_interval 1000 the old periodic check would never see it."""
    young = 2.8e5  # v sqrt(m/k) = 10 sqrt(M/(young R)) ≈ 1.9 r
    sim = shot(10.0, young=young, dt=2e-5, check_interval=1000)
    assert 10.0 * sim.dt / R < STEP_FRACTION
    with pytest.raises(InstabilityError) as err:
        sim.run(2000)
    msg = str(err.value)
    assert "overlap" in msg and "body gid 0" in msg and "wall 0" in msg and "max_overlap_ratio" in msg, msg
    assert sim.step < 1000


def deposition(**sim_changes):
    doc = {"simulation": {"dt": "auto", "damping": 0.3, "gravity": [0.0, 0.0, -9.81], **sim_changes},
           "materials": {"ballast": {"density": RHO, "young": E, "poisson": 0.3, "friction_angle": 0.5}},
           "deposition": {"box_lo": [0, 0, 0], "box_hi": [0.2, 0.1, 0.2], "count": 20, "radius": R, "seed": 1,
                          "material": "ballast", "walls_material": "ballast"}}
    return scene_from_dict(doc).build()


@pytest.mark.parametrize("changes", [{"dt": 1.0}, {"gravity": [0.0, 0.0, -1e9]}])
def test_nonsense_deposition_stops_at_once(changes):
    """dt = 1 s or gravity −1e9: every sphere would fall through the floor (bed top −310 km)."""
    sim = deposition(**changes)
    with pytest.raises(InstabilityError) as err:
        sim.run(300)
    assert "of its radius per step" in str(err.value)
    assert sim.step <= 2


def test_body_behind_a_wall_stops_the_run():
    """A body found behind the floor it started above (moved there, as a tunnelling body would
    be): the domain check names it and the wall at the next check."""
    sim = deposition(check_interval=10)
    sim.run(5)
    sim.particles.pos[3, 2] = -0.5
    gid = int(sim.particles.gid[3])
    with pytest.raises(InstabilityError) as err:
        sim.run(10)
    msg = str(err.value)
    assert f"body gid {gid} " in msg and "went through wall 'floor'" in msg, msg


def test_declared_domain():
    sim = shot(1.0, domain=[[0.0, -1.0, -1.0], [0.06, 1.0, 1.0]], check_interval=10)
    sim.particles.vel[0] = (5.0, 0.0, 0.0)  # flies off towards +x, out of the box at x = 0.06
    with pytest.raises(InstabilityError) as err:
        sim.run(1000)
    assert "body gid 0" in str(err.value) and "left the domain" in str(err.value)
    with pytest.raises(InputError, match="domain"):
        Scene(domain=[[0, 0, 0], [1, -1, 1]])
    with pytest.raises(InputError, match="domain"):
        Scene(domain=[[0, 0, True], [1, 1, 1]])


def _one_sphere_and(boundary, z):
    sc = Scene(dt="auto", gravity=(0.0, 0.0, 0.0))
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=0.5)
    sc.add_spheres([(0.0, 0.0, z)], R, m)
    if boundary == "wall":
        sc.add_wall(2, 0.0, m, sense=1, name="floor")
    elif boundary == "facet":
        sc.add_facet([(-0.1, -0.1, 0.0), (0.1, -0.1, 0.0), (0.0, 0.1, 0.0)], m, name="plate")
    else:
        sc.add_box((0.0, 0.0, -0.05), (0.1, 0.1, 0.05), m, mass=1.0, fixed=True, name="block")
    return sc


@pytest.mark.parametrize("boundary, name", [("wall", "'floor'"), ("facet", "'plate'"), ("box", "'block'")])
def test_initial_overlap_with_boundaries_refused(boundary, name):
    """A sphere 75 % inside a wall, a facet or a box is refused like an overlapping sphere pair
    (it would be launched away); touching (overlap 0) and allow_initial_overlap are fine."""
    with pytest.raises(InputError) as err:
        _one_sphere_and(boundary, 0.25 * R).build()
    msg = str(err.value)
    assert f"overlaps {boundary} {name} by 7.500e-03 m (75 % of its radius)" in msg and "allow_initial_overlap" in msg
    _one_sphere_and(boundary, R).build()
    sc = _one_sphere_and(boundary, 0.25 * R)
    sc.settings = dataclasses.replace(sc.settings, allow_initial_overlap=True)
    sc.build()


def test_start_behind_one_sided_wall_refused():
    with pytest.raises(InputError, match="starts behind the one-sided wall 'floor'"):
        _one_sphere_and("wall", -3 * R).build()


def test_guard_changes_no_trajectory():
    """The guard only reads: a run with the limits out of reach (STEP_FRACTION, max_overlap_ratio
    and the domain never met) gives the same bits as the same run with the guard's per-step
    check replaced by nothing."""
    a, b = deposition(), deposition()
    b.guard.check_step = lambda *args: None
    b.guard.check_domain = lambda *args: None
    a.run(400)
    b.run(400)
    for k in ("pos", "vel", "angvel", "force"):
        assert np.array_equal(getattr(a.particles, k)[:20], getattr(b.particles, k)[:20]), k


@pytest.mark.parametrize("threads", [1, 2])
def test_loop_overlap_equals_the_overlap_table(threads):
    """The max reduction of the force loops (serial twin and, above PARALLEL_MIN rows with two
    threads, the parallel one) is the largest overlap / smaller radius of the contact table."""
    import numba

    from pdem.checks import diagnostics

    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"numba allows {numba.config.NUMBA_NUM_THREADS} thread(s) here (NUMBA_NUM_THREADS)")
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        n = 6000  # > PARALLEL_MIN candidate rows
        g = np.stack(np.meshgrid(np.arange(30), np.arange(20), np.arange(10), indexing="ij"), -1).reshape(-1, 3)
        rng = np.random.default_rng(4)
        sc = Scene(dt="auto", damping=0.3, gravity=(0.0, 0.0, -9.81), allow_initial_overlap=True)
        m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=0.5)
        sc.add_spheres((g + 0.5) * 0.0198 + rng.uniform(-1e-4, 1e-4, (n, 3)), R * rng.uniform(0.9, 1.1, n), m)
        sc.add_wall(2, 0.0, m, sense=1)
        sim = sc.build()
        sim.run(3)
        assert sim.kind("sphere_sphere").contacts.n > 4096
        worst = max(k.worst_overlap for k in sim.kinds)
        assert worst > 0 and worst == diagnostics.max_overlap_ratio(sim)
    finally:
        numba.set_num_threads(before)
