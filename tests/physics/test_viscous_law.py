"""The viscous law with rolling resistance (`pdem.contact.viscous`, SPEC 1.3) against closed-form
mechanics; no pdem output is used as truth.

- Normal impact on a wall, no gravity: the linear spring–dashpot without tension (the contact
  force ends when k x + c ẋ = 0, before the overlap does) has, for ζ < 1/√2, contact time
  t_c = (π − arctan(2ζ√(1−ζ²)/(1−2ζ²)))/ω_d and restitution e = −ẋ(t_c)/v0 = exp(−ζ ω0 t_c)·(…)
  (Schwager & Pöschel 2007, Granular Matter 9:465, eq. 18); ω0 = sqrt(k_n/m), ω_d = ω0 √(1−ζ²).
- Rolling on a plane with rolling resistance: the moment is capped at f F_n = β r m g, so a sphere
  rolling without slip decelerates at a = β g/1.4 (I = 0.4 m r²) until it stops, then stays
  (rocks within the elastic rolling angle M_cap/k_θ).
- Twisting: a sphere spinning about the normal decelerates at dω/dt = β r m g/I = β g/(0.4 r).
- Time step: the automatic Δt of a damped scene is below the paper's eq. 10 step.
"""
import math

import numpy as np
import pytest
from factories import sphere_mass

from pdem import InputError, Scene, timestep
from pdem.contact import viscous

R, RHO, KN, KS = 0.005, 2000.0, 5.6e6, 2.0e6
M = sphere_mass(R, RHO)
G = 9.81


def material(sc, zeta=0.2, mu=0.3, beta=0.0, k_theta=0.0):
    return sc.material(density=RHO, kn=KN, ks=KS, damping_ratio=zeta, friction=mu, rolling_stiffness=k_theta,
                       rolling_coefficient=beta)


def damped_impact(zeta):
    """(t_c, e) of the spring–dashpot without tension, closed form."""
    w0 = math.sqrt(KN / M)
    wd = w0 * math.sqrt(1.0 - zeta * zeta)
    tc = (math.pi - math.atan(2 * zeta * math.sqrt(1 - zeta * zeta) / (1 - 2 * zeta * zeta))) / wd
    a = zeta * w0
    e = math.exp(-a * tc) * abs(math.cos(wd * tc) - a / wd * math.sin(wd * tc))
    return tc, e


@pytest.mark.parametrize("zeta", [0.0, 0.2, 0.5])
def test_normal_impact_restitution_and_contact_time(zeta):
    w0 = math.sqrt(KN / M)
    dt = 0.002 / w0
    sc = Scene(dt=dt, law="viscous")
    mat = material(sc, zeta=zeta)
    v0 = 0.5
    sc.add_spheres([(0.0, 0.0, R + 1e-7)], R, mat, vel=[(0.0, 0.0, -v0)])
    sc.add_wall(2, 0.0, mat)
    sim = sc.build()
    pushing = []

    def watch(s):
        c = s.contacts("sphere_wall")
        pushing.append(len(c["normal_force"]) > 0 and np.linalg.norm(c["normal_force"][0]) > 0.0)

    tc, e = damped_impact(zeta)
    sim.run(int(1.5 * tc / dt) + 10, watch, every=1)
    vz = sim.particles.vel[0, 2]
    assert any(pushing) and not pushing[-1]
    assert vz / v0 == pytest.approx(e, rel=2e-3)
    assert sum(pushing) * dt == pytest.approx(tc, rel=3e-3)
    if zeta == 0.0:
        assert tc == pytest.approx(math.pi / w0) and e == pytest.approx(1.0)


def test_damping_coefficient_is_zeta_times_critical():
    """c_n = ζ·2·sqrt(m1 m2 k_n/(m1 + m2)) for two spheres of different size (paper eqs. 3–4)."""
    sc = Scene(dt=1e-7, law="viscous")
    mat = material(sc, zeta=0.3)
    r2 = 0.004
    sc.add_spheres([(0.0, 0.0, 0.0), (0.0, 0.0, R + r2 + 1e-7)], [R, r2], mat, vel=[(0.0, 0.0, 0.1), (0.0, 0.0, -0.1)])
    sim = sc.build()
    sim.run(20)
    c = sim.contacts()
    m1, m2 = M, sphere_mass(r2, RHO)
    assert c["cn"][0] == pytest.approx(0.3 * 2 * math.sqrt(m1 * m2 * KN / (m1 + m2)), rel=1e-12)
    assert c["kn"][0] == KN and c["ks"][0] == KS and c["r_min"][0] == r2


def rolling_sphere(dt, v0=0.0, w=(0.0, 0.0, 0.0), beta=0.2, k_theta=20.0):
    sc = Scene(dt=dt, law="viscous", gravity=(0.0, 0.0, -G), allow_initial_overlap=True)
    mat = material(sc, zeta=0.3, mu=0.5, beta=beta, k_theta=k_theta)
    sc.add_spheres([(0.0, 0.0, R - M * G / KN)], R, mat, vel=[(v0, 0.0, 0.0)], angvel=[w])
    sc.add_wall(2, 0.0, mat)
    return sc.build()


def test_rolling_resistance_decelerates_and_stops():
    """v(t) falls at β g/1.4 while rolling; it stops at v0/(β g/1.4) and stays."""
    beta, v0 = 0.2, 0.05
    dt = 2e-6
    sim = rolling_sphere(dt, v0=v0, w=(0.0, v0 / R, 0.0), beta=beta)
    a = beta * G / 1.4
    t_stop = v0 / a
    t, v, x = [], [], []
    sim.run(int(1.5 * t_stop / dt), lambda s: (t.append(s.time), v.append(s.particles.vel[0, 0]),
                                               x.append(s.particles.pos[0, 0])), every=20)
    t, v, x = map(np.array, (t, v, x))
    rolling = (t > 0.05 * t_stop) & (t < 0.9 * t_stop)
    slope = np.polyfit(t[rolling], v[rolling], 1)[0]
    assert -slope == pytest.approx(a, rel=0.01)
    # stopped: it travelled v0²/(2a) and rocks by no more than the elastic rolling angle
    after = t > 1.1 * t_stop
    m_cap = beta * R * M * G
    assert x[after].mean() == pytest.approx(v0 ** 2 / (2 * a), rel=0.01)
    assert np.ptp(x[after]) < 4 * R * m_cap / 20.0
    assert np.abs(v[after]).max() < 0.02 * v0


def test_twisting_resistance_decelerates_spin():
    beta, w0 = 0.2, 5.0
    dt = 2e-6
    sim = rolling_sphere(dt, w=(0.0, 0.0, w0), beta=beta)
    rate = beta * G / (0.4 * R)
    t, w = [], []
    sim.run(int(0.8 * w0 / rate / dt), lambda s: (t.append(s.time), w.append(s.particles.angvel[0, 2])), every=20)
    t, w = np.array(t), np.array(w)
    keep = t > 0.1 * w0 / rate
    assert -np.polyfit(t[keep], w[keep], 1)[0] == pytest.approx(rate, rel=0.01)
    # no rolling: the spin about the normal moves nothing
    assert np.abs(sim.particles.vel[0, :2]).max() < 1e-6


def test_automatic_dt_is_below_the_damped_critical_step():
    """A sphere between two others: pdem's Δt is below the paper's eq. 10 step for the stiffness
    it carries, and it decreases with ζ as sqrt(1 + ζ²) − ζ."""
    out = []
    for zeta in (0.0, 0.5):
        sc = Scene(law="viscous", allow_initial_overlap=True)
        mat = material(sc, zeta=zeta)
        sc.add_spheres([(0, 0, 0), (0, 0, 2 * R - 1e-6), (0, 0, 4 * R - 2e-6)], R, mat)
        sim = sc.build()
        sim.run(1)
        sim.update_dt(force=True)
        out.append(timestep.contact_dt(sim))
        # middle sphere: two normal springs in parallel; 1 DOF step with eq. 10
        assert sim.dt < viscous.critical_step(2 * KN, M, zeta)
    assert out[1] / out[0] == pytest.approx(math.sqrt(1.25) - 0.5, rel=1e-12)


@pytest.mark.parametrize("key, value", [("damping_ratio", -0.1), ("damping_ratio", 1.0), ("rolling_coefficient", -0.5),
                                        ("kn", 0.0), ("friction", -1.0), ("rolling_stiffness", float("nan"))])
def test_bad_material_one_line(key, value):
    sc = Scene(law="viscous")
    props = dict(kn=KN, ks=KS, damping_ratio=0.2, friction=0.3, rolling_stiffness=1.0, rolling_coefficient=0.1)
    props[key] = value
    with pytest.raises(InputError) as exc:
        sc.material(density=RHO, name="grain", **props)
    msg = str(exc.value)
    assert "\n" not in msg and f"materials.grain.{key}" in msg
