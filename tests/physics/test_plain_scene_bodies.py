"""Rigid bodies and load programs of a plain scene file against analytic answers: a box under
gravity and a constant force falls as z0 − (g + F/m) t²/2; a box pressed onto a fixed sphere (a
linear spring) comes to rest where the sphere pushes back m g + F (Newton's third law, statics);
displacement control moves a box or a wall at its speed to its displacement and holds it there."""
import numpy as np
import pytest

from pdem.build.config import scene_from_dict

G = 9.81


def doc(load, *, blocked="xyXYZ", damping=0.0, z0=0.2, extra_loads=()):
    """A steel box of 2 kg, 0.1 m wide, centred at z0 above a fixed steel sphere r = 0.02 m at the
    origin (its top at z = 0.02), with ``load`` on it; fixed Δt."""
    return {
        "simulation": {"dt": 1e-5, "gravity": [0.0, 0.0, -G]},
        "run": {"steps": 10},
        "materials": {"steel": {"density": 7850.0, "young": 2e8, "poisson": 0.3, "friction_angle": 0.5}},
        "walls": [{"name": "lid", "axis": "z", "position": 1.0, "sense": -1, "material": "steel"}],
        "spheres": [{"pos": [[0.0, 0.0, 0.0]], "radius": 0.02, "material": "steel", "fixed": True}],
        "bodies": [{"name": "block", "center": [0.0, 0.0, z0], "size": [0.1, 0.1, 0.1], "material": "steel",
                    "mass": 2.0, "blocked": blocked, "damping": damping}],
        "loads": [{"body": "block", **load}, *extra_loads],
    }


def test_free_fall_under_a_constant_force():
    sim = scene_from_dict(doc({"type": "constant", "force": 10.0})).build()
    z0, n, dt = 0.2, 2000, 1e-5
    sim.run(n)
    a = G + 10.0 / 2.0
    t = n * dt
    assert sim.time == pytest.approx(t, rel=1e-12)
    z = sim.boxes.center[0, 2]
    # leapfrog with a constant acceleration: v_k = k a Δt, z_n = z0 − a Δt² n(n + 1)/2; the
    # continuous answer z0 − a t²/2 differs from it by a Δt t/2
    assert z == pytest.approx(z0 - a * dt * dt * n * (n + 1) / 2, abs=1e-12)
    assert abs(z - (z0 - a * t * t / 2)) <= a * dt * t / 2 * (1 + 1e-9)
    assert sim.boxes.velocity[0, 2] == pytest.approx(-a * t, rel=1e-9)
    assert np.all(sim.boxes.center[0, :2] == 0.0)  # x, y blocked


@pytest.mark.parametrize("force", [0.0, 30.0])
def test_box_on_a_spring_like_support_balances_its_weight_and_load(force):
    # the box's bottom starts on the sphere's top (z0 = 0.02 + 0.05); damped, it settles
    sim = scene_from_dict(doc({"type": "constant", "force": force}, damping=0.7, z0=0.07)).build()
    sim.run(20000)
    fz = sim.boxes.contact_force[0, 2]
    assert fz == pytest.approx(2.0 * G + force, rel=1e-6)  # statics: the support carries m g + F
    assert abs(sim.boxes.velocity[0, 2]) < 1e-6
    assert sim.boxes.center[0, 2] < 0.07  # pressed into the sphere


def test_displacement_control_of_a_box_and_a_wall():
    lid = {"wall": "lid", "type": "velocity", "speed": 0.2, "duration": 0.02, "direction": [0.0, 0.0, -1.0]}
    d = doc({"type": "displacement", "speed": 0.5, "displacement": 0.01, "start": 0.005}, blocked="xyzXYZ",
            extra_loads=[lid])
    sim = scene_from_dict(d).build()
    sim.run(1000)  # t = 0.01: 5 ms of motion at 0.5 m/s
    assert sim.boxes.center[0, 2] == pytest.approx(0.2 - 0.5 * 0.005, abs=1e-12)
    assert sim.walls.position[0] == pytest.approx(1.0 - 0.2 * 0.01, abs=1e-12)
    sim.run(4000)  # t = 0.05: both reached their displacement and hold
    assert sim.boxes.center[0, 2] == pytest.approx(0.2 - 0.01, abs=1e-12)
    assert sim.walls.position[0] == pytest.approx(1.0 - 0.2 * 0.02, abs=1e-12)
    assert sim.boxes.velocity[0, 2] == 0.0 and sim.walls.velocity[0, 2] == 0.0
    assert sim.moving_boundaries
