"""Hertz–Mindlin (`pdem.contact.hertz_mindlin`) against contact mechanics; no pdem output is truth.

- Elastic impact (e = 1) of a sphere on a plane: maximum overlap δ_max = (15 m* v²/(16 E* √R*))^(2/5)
  and contact time t_c = 2 (δ_max/v) ∫₀¹ (1 − x^(5/2))^(−1/2) dx = (4/5) B(2/5, 1/2) δ_max/v
  (Hertz 1882; Johnson, Contact Mechanics, §11.4).
- Damped impact: the restitution of m* δ'' = −(4/3 E* √R* δ^(3/2) + γ_n(δ) δ'), γ_n = 2 sqrt(5/6) |β|
  sqrt(2 E* sqrt(R* δ) m*), β = ln e/sqrt(ln² e + π²) (Tsuji et al. 1992), integrated here by
  classical Runge–Kutta with 40000 steps per contact (no scipy in the engine's venv); it does not depend on the
  impact velocity, and is close to the e asked for.
- Mindlin: a sphere held at a fixed overlap and dragged along the plane (no slip, e = 1 so no
  tangential dashpot) carries F_t = 8 G* sqrt(R* δ) ξ, ξ the tangential displacement.
- Bad input: e outside (0, 1], ν outside (−1, 0.5]: one line naming the field.
"""
import math

import numpy as np
import pytest
from factories import sphere_mass

from pdem import InputError, Scene

R, RHO, E, NU = 0.005, 2500.0, 1e8, 0.3
E_W, NU_W = 2e8, 0.25
M = sphere_mass(R, RHO)
E_STAR = 1.0 / ((1 - NU ** 2) / E + (1 - NU_W ** 2) / E_W)
G_STAR = 1.0 / (2 * (2 - NU) * (1 + NU) / E + 2 * (2 - NU_W) * (1 + NU_W) / E_W)


def drop(v0, e, dt, gap=1e-7):
    sc = Scene(dt=dt, law="hertz_mindlin")
    ball = sc.material(density=RHO, young=E, poisson=NU, restitution=e, friction=0.5, rolling_friction=0.0)
    wall = sc.material(density=RHO, young=E_W, poisson=NU_W, restitution=e, friction=0.5, rolling_friction=0.0)
    sc.add_spheres([(0.0, 0.0, R + gap)], R, ball, vel=[(0.0, 0.0, -v0)])
    sc.add_wall(2, 0.0, wall)
    return sc.build()


def impact(v0, e, dt):
    """(largest overlap, contact time, rebound velocity) of pdem."""
    sim = drop(v0, e, dt)
    pen, touching = [], []

    def watch(s):
        c = s.kind("sphere_wall").contacts
        pen.append(c.overlap[0] if c.n else 0.0)
        touching.append(c.n > 0 and c.state[0] == 1)

    t_guess = 3.5 * (M ** 2 / (R * E_STAR ** 2 * v0)) ** 0.2
    sim.run(int(t_guess / dt), watch, every=1)
    assert any(touching) and not touching[-1]
    return max(pen), sum(touching) * dt, sim.particles.vel[0, 2]


def test_elastic_impact_matches_hertz():
    v0 = 0.5
    d_max = (15 * M * v0 ** 2 / (16 * E_STAR * math.sqrt(R))) ** 0.4
    integral = 0.4 * math.gamma(0.4) * math.gamma(0.5) / math.gamma(0.9)
    t_c = 2 * integral * d_max / v0
    dt = t_c / 4000
    pen, tc, v1 = impact(v0, 1.0, dt)
    assert pen == pytest.approx(d_max, rel=1e-4)
    assert tc == pytest.approx(t_c, rel=1e-3)
    assert v1 == pytest.approx(v0, rel=1e-5)


def restitution_ode(e, v0, n=40000):
    """e_eff of the Hertz spring with the LIGGGHTS/EDEM dashpot (tension allowed): RK4."""
    le = math.log(e)
    beta = le / math.sqrt(le * le + math.pi ** 2)
    c = -2 * math.sqrt(5 / 6) * beta * math.sqrt(2 * E_STAR * math.sqrt(R) * M)

    def acc(d, v):  # overlap d, its rate v (> 0 approaching)
        dd = max(d, 0.0)
        return -(4 / 3 * E_STAR * math.sqrt(R) * dd ** 1.5 + c * dd ** 0.25 * v) / M

    d_max = (15 * M * v0 ** 2 / (16 * E_STAR * math.sqrt(R))) ** 0.4
    h = 3.5 * d_max / v0 / n
    d, v = 0.0, v0
    while True:
        k1 = (v, acc(d, v))
        k2 = (v + 0.5 * h * k1[1], acc(d + 0.5 * h * k1[0], v + 0.5 * h * k1[1]))
        k3 = (v + 0.5 * h * k2[1], acc(d + 0.5 * h * k2[0], v + 0.5 * h * k2[1]))
        k4 = (v + h * k3[1], acc(d + h * k3[0], v + h * k3[1]))
        d1 = d + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v1 = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        if d1 < 0.0:  # out of contact within this step: the velocity there (no force outside)
            return -(v + (v1 - v) * d / (d - d1)) / v0
        d, v = d1, v1


@pytest.mark.parametrize("e", [0.3, 0.7])
def test_restitution_from_the_damping_formula(e):
    v0 = 0.5
    ref = restitution_ode(e, v0)
    assert restitution_ode(e, 2.0) == pytest.approx(ref, rel=1e-5)  # independent of the velocity
    assert ref == pytest.approx(e, abs=0.02)
    d_max = (15 * M * v0 ** 2 / (16 * E_STAR * math.sqrt(R))) ** 0.4
    _, _, v1 = impact(v0, e, d_max / v0 / 2000)
    assert v1 / v0 == pytest.approx(ref, rel=2e-3)


def test_mindlin_tangential_stiffness():
    delta, v, dt, n = 2e-5, 1e-3, 1e-7, 200
    sc = Scene(dt=dt, law="hertz_mindlin", allow_initial_overlap=True)
    ball = sc.material(density=RHO, young=E, poisson=NU, restitution=1.0, friction=10.0, rolling_friction=0.0)
    wall = sc.material(density=RHO, young=E_W, poisson=NU_W, restitution=1.0, friction=10.0, rolling_friction=0.0)
    sc.add_spheres([(0.0, 0.0, R - delta)], R, ball, vel=[(v, 0.0, 0.0)], fixed=True)
    sc.add_wall(2, 0.0, wall)
    sim = sc.build()
    sim.run(n)
    c = sim.contacts("sphere_wall")
    # n force computations, each after adding v dt: ξ = n v dt at the positions of the last one
    xi = n * v * dt
    kt = 8 * G_STAR * math.sqrt(R * c["overlap"][0])
    assert c["overlap"][0] == pytest.approx(delta, rel=1e-9)
    assert -c["force"][0][0] == pytest.approx(kt * xi, rel=1e-9)
    assert c["shear_force"][0][0] == pytest.approx(-kt * xi, rel=1e-9)
    assert c["force"][0][2] == pytest.approx(4 / 3 * E_STAR * math.sqrt(R) * c["overlap"][0] ** 1.5, rel=1e-12)


def test_automatic_dt_covers_the_hertz_stiffness():
    """A fast impact at the automatic Δt: the step stays below 2 sqrt(m/S_n) at the largest
    overlap (S_n = 2E* sqrt(R* δ_max)), and the sphere rebounds elastically."""
    v0 = 5.0
    d_max = (15 * M * v0 ** 2 / (16 * E_STAR * math.sqrt(R))) ** 0.4
    sc = Scene(law="hertz_mindlin")
    ball = sc.material(density=RHO, young=E, poisson=NU, restitution=1.0, friction=0.5, rolling_friction=0.0)
    wall = sc.material(density=RHO, young=E_W, poisson=NU_W, restitution=1.0, friction=0.5, rolling_friction=0.0)
    sc.add_spheres([(0.0, 0.0, R + 1e-6)], R, ball, vel=[(0.0, 0.0, -v0)])
    sc.add_wall(2, 0.0, wall)
    sim = sc.build()
    dts = []
    sim.run(3000, lambda s: dts.append(s.dt), every=1)
    assert max(dts) < 2 * math.sqrt(M / (2 * E_STAR * math.sqrt(R * d_max)))
    assert sim.particles.vel[0, 2] == pytest.approx(v0, rel=1e-3)


@pytest.mark.parametrize("key, value", [("restitution", 0.0), ("restitution", 1.2), ("poisson", 0.6),
                                        ("poisson", -1.0), ("young", -1.0), ("rolling_friction", -0.1)])
def test_bad_material_one_line(key, value):
    sc = Scene(law="hertz_mindlin")
    props = dict(young=E, poisson=NU, restitution=0.5, friction=0.5, rolling_friction=0.0)
    props[key] = value
    with pytest.raises(InputError) as exc:
        sc.material(density=RHO, name="ballast", **props)
    msg = str(exc.value)
    assert "\n" not in msg and f"materials.ballast.{key}" in msg


def test_bad_pair_one_line():
    sc = Scene(law="hertz_mindlin")
    for name in ("a", "b"):
        sc.material(density=RHO, name=name, young=E, poisson=NU, restitution=0.5, friction=0.5, rolling_friction=0.0)
    with pytest.raises(InputError, match=r"material_pairs\.a-b\.restitution"):
        sc.material_pair("a", "b", restitution=1.5)
    with pytest.raises(InputError, match="young: not a per-pair key"):
        sc.material_pair("a", "b", young=1e9)
    assert np.isfinite(sc.materials.props()).all()
