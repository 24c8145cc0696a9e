"""Bad input gets one line naming the field, the value and what is allowed (API and CLI)."""
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import pdem
from pdem.build.config import scene_from_dict

BASE = {
    "materials": {"ballast": {"density": 2600.0, "young": 1e7, "poisson": 0.3, "friction_angle": 0.5}},
    "spheres": [{"pos": [[0, 0, 0], [0.1, 0, 0]], "radius": 0.01, "material": "ballast"}],
}


def _doc(**changes):
    import copy

    d = copy.deepcopy(BASE)
    d.update(changes)
    return d


@pytest.mark.parametrize(
    "doc, words",
    [
        (_doc(simulation={"dampin": 0.3}), ["simulation.dampin", "unknown key", "damping"]),
        (_doc(simulation={"damping": 1.5}), ["damping", "1.5", "[0, 0.99]"]),
        (_doc(simulation={"dt": -1e-6}), ["dt", "-1e-06", "> 0"]),
        (
            _doc(materials={"ballast": {"density": 2600.0, "young": -5.0, "poisson": 0.3, "friction_angle": 0.5}}),
            ["young", "-5.0", "> 0"],
        ),
        (_doc(materials={"ballast": {"density": 2600.0, "young": 1e7, "poisson": 0.3}}), ["friction_angle", "missing"]),
        (
            _doc(spheres=[{"pos": [[0, 0, 0]], "radius": 0.01, "material": "granite"}]),
            ["granite", "unknown material", "ballast"],
        ),
        (_doc(spheres=[{"pos": [[0, 0, 0]], "radius": -0.01, "material": "ballast"}]), ["radius", "-0.01", "> 0"]),
        (_doc(walls=[{"axis": "w", "position": 0.0, "material": "ballast"}]), ["axis", "'w'", "x, y, z"]),
        (
            _doc(spheres=[{"pos": [[0, 0, 0], [0.015, 0, 0]], "radius": 0.01, "material": "ballast"}]),
            ["gid 0 and 1", "overlap", "allow_initial_overlap"],
        ),
    ],
)
def test_one_line_error_names_the_field(one_line_error, doc, words):
    one_line_error(pdem.InputError, lambda: scene_from_dict(doc).build(), *words)


def test_overlap_allowed_when_asked():
    doc = _doc(spheres=[{"pos": [[0, 0, 0], [0.015, 0, 0]], "radius": 0.01, "material": "ballast"}],
               simulation={"allow_initial_overlap": True})
    sim = scene_from_dict(doc).build()
    sim.run(1)
    assert sim.kind("sphere_sphere").contacts.state[: sim.kind("sphere_sphere").contacts.n].sum() == 1


def test_cli_exit_status_2_and_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(textwrap.dedent("""
        [simulation]
        damping = 0.3
        gravty = [0.0, 0.0, -9.81]
        [materials.b]
        density = 2600.0
        young = 1e7
        poisson = 0.3
        friction_angle = 0.5
        """))
    out = subprocess.run([sys.executable, "-m", "pdem", "run", str(bad), "--out", str(tmp_path / "o")],
                         capture_output=True, text=True)
    assert out.returncode == 2
    lines = [l for l in out.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and "simulation.gravty" in lines[0] and "unknown key" in lines[0], out.stderr


def test_poisson_zero_on_both_sides_gives_ks_zero_not_a_crash():
    """Yade's Ip2 gives ks = 0/0 = NaN when both materials have ν = 0; numba raised
    ZeroDivisionError inside the kernel. pdem defines ks = 0 (no shear spring, documented in
    pdem.contact.linear): the contact pushes but carries no shear force."""
    sc = pdem.Scene(dt=1e-6, gravity=(0.0, 0.0, -9.81), allow_initial_overlap=True)
    a = sc.material(density=2600.0, young=1e7, poisson=0.0, friction_angle=0.5)
    b = sc.material(density=2600.0, young=1e7, poisson=0.0, friction_angle=0.5)
    sc.add_spheres([(0.0, 0.0, 0.0099), (0.0, 0.0, 0.03)], 0.01, [a, b], vel=[(0.1, 0, 0), (0, 0, 0)])
    sc.add_wall("z", 0.0, b, sense=1)
    sim = sc.build()
    sim.run(200)
    c = sim.contacts("sphere_wall")
    assert len(c["ks"]) == 1 and c["ks"][0] == 0.0 and c["kn"][0] > 0.0
    assert np.all(c["shear_force"] == 0.0) and np.all(np.isfinite(sim.particles.vel))

@pytest.mark.parametrize(
    "changes, words",
    [
        ({"simulation": [1, 2]}, ["simulation", "must be a table"]),
        ({"walls": 5}, ["walls", "array of tables"]),
        ({"walls": [{"axis": "z", "position": 0.0, "material": "ballast", "sense": True}]}, ["sense", "True"]),
        ({"walls": [{"axis": "z", "position": True, "material": "ballast"}]}, ["position", "True"]),
        ({"simulation": {"dt": True}}, ["dt", "True"]),
        ({"simulation": {"energy_check": "no"}}, ["energy_check", "'no'", "true or false"]),
        ({"simulation": {"allow_initial_overlap": "false"}}, ["allow_initial_overlap", "'false'"]),
        ({"simulation": {"domain": [[0, 0, 0], [1, 1]]}}, ["domain"]),
        ({"spheres": [{"pos": [[0.0, 0.0]], "radius": 0.01, "material": "ballast"}]}, ["spheres.pos", "shape (1, 2)"]),
        (
            {"spheres": [{"pos": [[0, 0, 0], [0.1, 0, 0]], "radius": [0.01] * 3, "material": "ballast"}]},
            ["radius", "2 numbers"],
        ),
        ({"spheres": [{"pos": [[0.0, "a", 0.0]], "radius": 0.01, "material": "ballast"}]}, ["spheres.pos", "'a'"]),
        (
            {"spheres": [{"pos": [[0, 0, 0]], "radius": 0.01, "material": "ballast", "fixed": "false"}]},
            ["fixed", "'false'"],
        ),
        (
            {"materials": {"ballast": {"density": 2600.0, "young": True, "poisson": 0.3, "friction_angle": 0.5}}},
            ["young", "True"],
        ),
    ],
)
def test_strict_types_one_line(one_line_error, changes, words):
    """Numbers are numbers (not booleans), booleans are booleans (not strings), shapes are checked."""
    one_line_error(pdem.InputError, lambda: scene_from_dict(_doc(**changes)).build(), *words)


@pytest.mark.parametrize("content", [b"\xff\xfe[\x00r\x00u\x00n\x00]\x00", bytes(range(256))])
def test_binary_or_utf16_scene_file_one_line(tmp_path, content):
    from pdem.build.config import load_toml

    p = tmp_path / "scene.toml"
    p.write_bytes(content)
    with pytest.raises(pdem.InputError, match="not a text file in UTF-8"):
        load_toml(p)
    with pytest.raises(pdem.InputError, match="is a directory"):
        load_toml(tmp_path)
