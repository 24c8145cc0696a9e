"""Physics of the linear model against closed-form mechanics (no pdem output is used as truth).

(a) undamped elastic bounce conserves energy / speed; (b) sliding → rolling on a wall: deceleration
μg, final speed 5/7 v0; (d) static overlap m g/k_n; (e) explicit stability limit 2·sqrt(m/k_n).
"""
import math

import numpy as np
import pytest

from pdem import InstabilityError, Scene
from factories import sphere_mass

R, RHO, E = 0.01, 2600.0, 1e8
M = sphere_mass(R, RHO)
KN_WALL = E * R  # sphere–wall of equal materials: kn = 2(E r)(E r)/(E r + E r) = E r (YADE_MODEL §4)
G = 9.81


def sphere_on_wall(*, dt, damping=0.0, gravity=0.0, z=R, vel=(0.0, 0.0, 0.0), angvel=(0.0, 0.0, 0.0),
                   friction_angle=0.5, poisson=0.3, **kw):
    # the cases start at the static overlap on purpose
    kw.setdefault("allow_initial_overlap", True)
    sc = Scene(dt=dt, damping=damping, gravity=(0.0, 0.0, -gravity), **kw)
    mat = sc.material(density=RHO, young=E, poisson=poisson, friction_angle=friction_angle)
    sc.add_spheres([(0.0, 0.0, z)], R, mat, vel=[vel], angvel=[angvel])
    sc.add_wall(2, 0.0, mat)
    return sc.build()


@pytest.mark.parametrize("gap", [1.0e-5, 1.77e-5])
def test_elastic_bounce_conserves_energy(gap):
    """(a) No gravity, no damping, normal impact at 1 m/s: after the contact the speed and the total
    energy (kinetic only before and after: no contact, no potential) equal the initial ones to 1e-6."""
    dt = 1e-7  # ω·dt = sqrt(kn/m)·dt ≈ 1e-3
    sim = sphere_on_wall(dt=dt, z=R + gap, vel=(0.0, 0.0, -1.0))
    p = sim.particles
    e0 = sim.energy()
    assert e0["elastic"] == 0.0 and e0["potential"] == 0.0
    assert e0["total"] == pytest.approx(0.5 * M * 1.0, rel=1e-15)
    touched = []
    t_contact = math.pi * math.sqrt(M / KN_WALL)
    sim.run(
        int((gap / 1.0 + 2 * t_contact) / dt),
        lambda s: touched.append(s.kind("sphere_wall").contacts.state[0] == 1),
        every=1,
    )
    assert any(touched) and not touched[-1], "the sphere must hit the wall and leave it again"
    assert p.vel[0, 2] > 0.0
    assert abs(np.linalg.norm(p.vel[0]) / 1.0 - 1.0) < 1e-6
    e1 = sim.energy()
    assert e1["elastic"] == 0.0
    assert abs(e1["total"] / e0["total"] - 1.0) < 1e-6
    # contact duration π·sqrt(m/kn) (half a period of the normal spring)
    assert sum(touched) * dt == pytest.approx(t_contact, rel=2e-3)


def test_slide_then_roll():
    """(b) Sphere launched along a horizontal wall without spin, tan φ = μ, no damping: while sliding
    dv/dt = −μ g and dω/dt = μ m g r/I; it rolls without slip from v = 5/7 v0 on."""
    mu, v0, dt = 0.4, 1.0, 1e-5
    kn = KN_WALL
    sim = sphere_on_wall(dt=dt, gravity=G, z=R - M * G / kn, vel=(v0, 0.0, 0.0), friction_angle=math.atan(mu))
    p = sim.particles
    t, vx, wy = [], [], []

    def rec(s):
        t.append(s.time)
        vx.append(p.vel[0, 0])
        wy.append(p.angvel[0, 1])

    t_roll = 2.0 * v0 / (7.0 * mu * G)  # v0 − μ g t = (5/2) μ g t
    sim.run(int(1.5 * t_roll / dt), rec, every=1)
    t, vx, wy = np.array(t), np.array(vx), np.array(wy)
    slip = vx - wy * R  # contact-point velocity (ω_y > 0 rolls towards +x)
    sliding = np.flatnonzero(slip > 0.05 * v0)
    sl = sliding[20:]  # skip the build-up of the shear spring
    slope = np.polyfit(t[sl], vx[sl], 1)[0]
    assert slope == pytest.approx(-mu * G, rel=1e-6)
    spin = np.polyfit(t[sl], wy[sl], 1)[0]
    assert spin == pytest.approx(mu * M * G * R / (0.4 * M * R * R), rel=1e-4)  # lever r − pen/2 ≈ r
    a, b = np.polyfit(t[sl], slip[sl], 1)  # slip = v0 − 3.5 μ g t while sliding
    assert a == pytest.approx(-3.5 * mu * G, rel=1e-4)
    assert -b / a == pytest.approx(t_roll, rel=1e-4)
    late = t > 1.2 * t_roll
    assert np.mean(vx[late]) == pytest.approx(5.0 / 7.0 * v0, rel=1e-3)
    assert np.mean(wy[late]) * R == pytest.approx(5.0 / 7.0 * v0, rel=1e-3)
    assert np.max(np.abs(slip[late])) < 5e-3 * v0


def test_static_overlap():
    """(d) Sphere resting on a wall under gravity, Cundall damping: overlap → m g / k_n (1e-6 relative)."""
    sim = sphere_on_wall(dt=1e-5, damping=0.3, gravity=G, z=R)
    sim.run(4000)
    rows = sim.kind("sphere_wall").contacts.real_rows()
    assert len(rows) == 1
    assert sim.kind("sphere_wall").contacts.params[rows[0], 0] == pytest.approx(KN_WALL, rel=1e-15)
    assert sim.kind("sphere_wall").contacts.overlap[rows[0]] == pytest.approx(M * G / KN_WALL, rel=1e-6)
    assert abs(sim.particles.vel[0, 2]) < 1e-9


def dt_critical():
    return 2.0 * math.sqrt(M / KN_WALL)


@pytest.mark.parametrize("factor,stable,energy_check", [(1.1, False, True), (0.9, True, False), (0.9, True, True)])
def test_time_step_limit(factor, stable, energy_check):
    """(e) One normal spring (sphere on a wall, gravity, no damping), resting at the static overlap with a
    small vertical velocity (oscillation amplitude ≈ 0.1 of the static overlap, so the contact never
    opens): dt = 1.1·2·sqrt(m/k_n) stops with InstabilityError naming the time step, dt = 0.9·… runs
    (with and without the built-in energy check: the motion is bounded, so the check must not fire)."""
    dt = factor * dt_critical()
    delta = M * G / KN_WALL
    sim = sphere_on_wall(dt=dt, gravity=G, z=R - delta, vel=(0.0, 0.0, 0.1 * delta * math.sqrt(KN_WALL / M)),
                         poisson=0.2, energy_check=energy_check)
    if stable:
        sim.run(20000)
        assert sim.kind("sphere_wall").contacts.state[0] == 1
        assert abs(sim.kind("sphere_wall").contacts.overlap[0] / delta - 1.0) < 0.5
    else:
        with pytest.raises(InstabilityError) as err:
            sim.run(20000)
        msg = str(err.value).lower()
        # a fixed dt above the automatic one is named as the cause, with the factor (docs/stability.md)
        assert "the time step fixed by simulation.dt is" in msg and "too large for the stiffnesses present" in msg, msg
