"""Plain scene files with rigid bodies ([[bodies]]), load programs ([[loads]]) and custom clump
shapes (`pdem.build.config`): what they build, and one-line errors naming the field for bad
input. The programs' values against their formulas (`pdem.boundaries.loads`)."""
import copy
import math
import tomllib

import numpy as np
import pytest
from factories import ROOT

from pdem.bodies.boxes import DOF_LETTERS
from pdem.boundaries.loads import HalfSine, Haversine, Motion, Ramp
from pdem.build.config import scene_from_dict
from pdem.errors import InputError

JOB = ROOT / "jobs" / "plate_load.toml"


def job():
    return tomllib.loads(JOB.read_text())


def test_plate_load_builds_a_box_with_its_program():
    scene = scene_from_dict(job())
    (plate,) = scene.boxes.spec()
    assert plate["name"] == "plate"
    assert plate["half_extents"] == [0.075, 0.075, 0.01]
    assert plate["mass"] == pytest.approx(7850.0 * 0.15 * 0.15 * 0.02, rel=1e-15)
    assert plate["blocked"] == sum(1 << DOF_LETTERS.index(c) for c in "xyXYZ")
    assert plate["load"] == {"type": "haversine", "f_min": 50.0, "f_max": 500.0, "frequency": 10.0, "cycles": 3,
                             "start": 0.25}
    assert len(scene.spheres()["gid"]) == 80 * 4
    assert scene.walls.names == ["floor", "x_min", "x_max", "y_min", "y_max"]


def test_load_programs_follow_their_formulas():
    h = Haversine(50.0, 500.0, 10.0, 3, start=0.25)
    assert h.value(0.1) == 50.0 and h.value(0.30) == pytest.approx(500.0) and h.value(0.6) == 50.0
    assert HalfSine(0.0, 2.0, 10.0, 1).value(0.05) == pytest.approx(2.0)
    r = Ramp(1.0, 3.0, 2.0, start=1.0)
    assert (r.value(0.5), r.value(2.0), r.value(9.0)) == (1.0, 2.0, 3.0)
    m = Motion(0.1, 0.02, start=0.5)
    assert (m.value(0.4), m.value(0.6), m.value(5.0)) == (0.0, pytest.approx(0.01), 0.02)
    assert m.step_velocity(0.6, 1e-3) == pytest.approx(0.1) and m.step_velocity(0.75, 1e-3) == 0.0
    assert m.step_velocity(0.699, 0.01) * 0.01 == pytest.approx(0.02 - m.value(0.699))  # lands on u_max


@pytest.mark.parametrize("kind, keys, want", [
    ("constant", {"force": 7.0}, {"type": "constant", "force": 7.0}),
    ("ramp", {"f_to": 3.0, "duration": 0.5}, {"type": "ramp", "f_from": 0.0, "f_to": 3.0, "duration": 0.5,
                                              "start": 0.0}),
    ("half_sine", {"f_max": 3.0, "frequency": 2.0, "cycles": 2}, {"type": "half_sine", "f_min": 0.0, "f_max": 3.0,
                                                                "frequency": 2.0, "cycles": 2, "start": 0.0}),
    ("impulse", {"f0": 9.0, "duration": 0.1}, {"type": "impulse", "f0": 9.0, "duration": 0.1, "start": 0.0}),
])
def test_every_force_program_reaches_the_box(kind, keys, want):
    doc = job()
    doc["loads"] = [{"body": "plate", "type": kind, **keys}]
    assert scene_from_dict(doc).boxes.spec()[0]["load"] == want


def test_displacement_and_velocity_control_of_a_box_and_a_wall():
    doc = job()
    doc["bodies"][0]["blocked"] = "xyzXYZ"
    doc["loads"] = [{"body": "plate", "type": "displacement", "speed": 0.1, "displacement": 0.01},
                    {"wall": "x_max", "type": "velocity", "speed": 0.05, "duration": 0.2, "direction": [-1, 0, 0]}]
    scene = scene_from_dict(doc)
    assert scene.boxes.spec()[0]["load"] is None
    (t0, b0, m0, d0), (t1, b1, m1, d1) = scene.motions
    assert (t0, b0, m0.displacement, d0.tolist()) == ("box", 0, 0.01, [0.0, 0.0, -1.0])
    assert (t1, b1, m1.displacement, d1.tolist()) == ("wall", 2, pytest.approx(0.01), [-1.0, 0.0, 0.0])
    assert [m["type"] for m in scene.spec()["motions"]] == ["motion", "motion"]


def test_custom_clumps_centred_and_named_shapes_still_work():
    doc = job()
    doc["clumps"][0]["count"] = 1
    pos = scene_from_dict(doc).spheres()["pos"]
    members = np.array(doc["clumps"][0]["members"])
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)  # a rigid copy: the same distances
    assert np.allclose(d, np.linalg.norm(members[:, None, :3] - members[None, :, :3], axis=2), atol=1e-12)
    named = copy.deepcopy(doc)
    named["clumps"][0] = {k: v for k, v in named["clumps"][0].items() if k != "members"}
    named["clumps"][0].update(shape="ballast8", member_radius=0.005)
    assert len(scene_from_dict(named).spheres()["gid"]) == 8


def _edit(path, value):
    doc = job()
    node = doc
    for p in path[:-1]:
        node = node[p]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return doc


@pytest.mark.parametrize("path, value, field", [
    (("bodies", 0, "sise"), 1.0, "bodies[0].sise"),
    (("bodies", 0, "size"), [0.1, -0.1, 0.02], "bodies.plate.size"),
    (("bodies", 0, "mass"), 3.0, "bodies.plate: give mass"),
    (("bodies", 0, "density"), KeyError, "bodies.plate: give mass"),
    (("bodies", 0, "blocked"), "xyQ", "bodies.plate.blocked"),
    (("bodies", 0, "material"), "glass", "bodies.plate.material"),
    (("bodies", 0, "shape"), "sphere", "bodies.plate.shape"),
    (("bodies", 0, "name"), "", "bodies[0].name"),
    (("bodies", 0, "name"), "my plate", "bodies[0].name"),
    (("walls", 0, "name"), "a/b", "walls[0].name"),
    (("loads", 0, "type"), "square", "loads[0].type"),
    (("loads", 0, "body"), "sleeper", "loads[0].body"),
    (("loads", 0, "f_max"), 10.0, "loads[0].f_max"),
    (("loads", 0, "cycles"), 0, "loads[0].cycles"),
    (("loads", 0, "frequency"), 5.0, "loads[0]: give frequency"),
    (("loads", 0, "period"), -0.1, "loads[0].period"),
    (("loads", 0, "amplitude"), 1.0, "loads[0].amplitude"),
    (("loads", 0, "wall"), "floor", "loads[0]: give body"),
    (("clumps", 0, "members"), [[0, 0, 0, 0.01], [0.05, 0, 0, 0.01]], "clumps[0].members[1]"),
    (("clumps", 0, "members"), [[0, 0, 0, -0.01]], "clumps[0].members[0] radius"),
    (("clumps", 0, "members"), [[0, 0, 0]], "clumps[0].members"),
    (("clumps", 0, "members"), [[0, 0, 0, 0.01], [0, 0, 0, 0.02]], "clumps[0].members[0] and [1]"),
    (("clumps", 0, "member_radius"), 0.01, "clumps[0].member_radius"),
    (("clumps", 0, "members"), KeyError, "clumps[0].members"),
])
def test_bad_bodies_loads_and_members_are_one_line_naming_the_field(path, value, field):
    with pytest.raises(InputError) as e:
        scene_from_dict(_edit(path, value))
    assert str(e.value).startswith(field) and "\n" not in str(e.value), str(e.value)


@pytest.mark.parametrize("load, field", [
    ({"wall": "floor", "type": "constant", "force": 1.0}, "loads[1].type"),
    ({"body": "plate", "type": "constant", "force": 1.0}, "loads[1].body"),
    ({"wall": "floor", "type": "displacement", "speed": 0.1, "displacement": 0.01, "direction": [1, 0, 0]},
     "loads[1].direction"),
    ({"wall": "floor", "type": "displacement", "speed": 0.1}, "loads[1].displacement"),
    ({"wall": "floor", "type": "velocity", "speed": -0.1}, "loads[1].speed"),
])
def test_bad_second_load_is_one_line(load, field):
    doc = job()
    doc["loads"].append(load)
    with pytest.raises(InputError) as e:
        scene_from_dict(doc)
    assert str(e.value).startswith(field) and "\n" not in str(e.value), str(e.value)


def test_displacement_control_of_a_free_direction_is_refused():
    doc = job()
    doc["loads"] = [{"body": "plate", "type": "displacement", "speed": 0.1, "displacement": 0.01}]
    with pytest.raises(InputError, match=r"^loads\[0\]\.direction.*free along z"):
        scene_from_dict(doc)


def test_mass_from_density_is_the_cuboid_volume():
    doc = job()
    doc["bodies"][0].update(density=1000.0, size=[0.1, 0.2, 0.3])
    assert scene_from_dict(doc).boxes.mass[0] == pytest.approx(1000.0 * 0.1 * 0.2 * 0.3, rel=1e-15)
    assert math.isclose(scene_from_dict(job()).boxes.mass[0], 3.5325, rel_tol=1e-12)
