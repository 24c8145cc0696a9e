"""The new surfaces refuse bad input at load time in one line naming the field, the value and
what is allowed (docs/reliability.md, "Input hardening"): one strictness for every key (list
elements as their scalar siblings), clump shapes and generators, bonds, the plausible ranges of
the [track], [traffic], [blast] and [oedometer] keys with the likely unit slip, campaign files,
and ``pdem run --check`` / ``pdem campaign check``. The truth each test asserts is the input's
own: a value outside what the field allows, or the geometry of the members (distances against
radii), never an output of pdem.
"""
import contextlib
import copy
import io
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

import pdem
from factories import TINY_DEPOSITION, toml_text
from pdem.build.config import scene_from_dict
from pdem.build.validate import number, numbers, vectors
from pdem.scenes import check as check_scene
from pdem.scenes.common.bounds import BOUNDS, PREPARATION_BOUNDS, plausible
from pdem_cli import needs_mpiexec, run_pdem

ROOT = Path(__file__).resolve().parents[2]
MAT = {"density": 2600.0, "young": 1e7, "poisson": 0.3, "friction_angle": 0.5}
COHESIVE = {**MAT, "normal_cohesion": 1e6, "shear_cohesion": 1e6}


def _job(name):
    return tomllib.loads((ROOT / "jobs" / name).read_text())


def _cli(*argv):
    """(status, output lines) of ``pdem ARGV`` run in this process."""
    from pdem.cli import main

    text = io.StringIO()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
        status = main(list(argv))
    return status, [x for x in text.getvalue().splitlines() if x.strip()]


# ---------------------------------------------------------------------------- one strictness
@pytest.mark.parametrize("bad", ["1.5", True, math.nan, math.inf, None, [1.0]])
def test_a_list_element_is_refused_exactly_like_its_scalar(bad):
    """`numbers` and `vectors` refuse, element by element, what `number` refuses for a scalar."""
    with pytest.raises(pdem.InputError) as scalar:
        number("k", bad)
    with pytest.raises(pdem.InputError) as element:
        numbers("k", [0.5, bad])
    assert "must be a finite number" in str(scalar.value)
    assert str(element.value) == str(scalar.value).replace("k = ", "k[1] = ", 1)
    if not isinstance(bad, list):
        with pytest.raises(pdem.InputError, match="not finite" if isinstance(bad, float) else "must be a list of"):
            vectors("k", [[0.0, 0.0, 0.0], [0.0, bad, 0.0]])


@pytest.mark.parametrize("changes, words", [
    ({"simulation": {"gravity": ["0", "0", "-9.81"]}}, ["gravity", "'0'"]),
    ({"spheres": [{"pos": [[0, 0, 0], ["0.1", 0, 0]], "radius": 0.01, "material": "m"}]}, ["spheres.pos", "'0.1'"]),
    ({"spheres": [{"pos": [[0, 0, 0], [0.1, 0, 0]], "radius": ["0.01", 0.01], "material": "m"}]},
     ["spheres.radius[0] = '0.01'"]),
    ({"spheres": [{"pos": [[0, 0, 0], [0.1, 0, 0]], "radius": [0.01, True], "material": "m"}]},
     ["spheres.radius[1] = True"]),
    ({"deposition": {"box_lo": ["0", 0, 0], "box_hi": [1, 1, 1], "count": 2, "radius": 0.01, "material": "m"}},
     ["deposition.box_lo", "'0'"]),
    ({"clumps": [{"shape": "ellipsoid", "radii": [0.02, "0.02", 0.02], "member_radius": 0.005, "material": "m",
                  "box_lo": [0, 0, 0], "box_hi": [1, 1, 1], "count": 1}]}, ["clumps.radii", "'0.02'"]),
])
def test_numeric_strings_in_lists_refused_in_scene_files(one_line_error, changes, words):
    doc = {"materials": {"m": MAT}, **changes}
    one_line_error(pdem.InputError, lambda: scene_from_dict(doc).build(), *words)


def test_clump_member_radius_list_as_strict_as_the_scalar(one_line_error):
    """The list-valued clump key of issue #33 accepted numeric strings its scalar sibling refused."""
    sc = pdem.Scene()
    sc.material(**MAT)
    pos = [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]]
    scalar = one_line_error(pdem.InputError, lambda: sc.add_clump(pos, "0.005", 0), "member_radius", "'0.005'")
    listed = one_line_error(pdem.InputError, lambda: sc.add_clump(pos, ["0.005", "0.005"], 0),
                            "member_radius[0]", "'0.005'")
    assert scalar.split(": ", 1)[1] == listed.split(": ", 1)[1]


# ---------------------------------------------------------------------------- clumps
def _line(n, r=0.005):
    """n members of radius r on a line, 2r apart (touching): [n, 3] positions."""
    return [[2.0 * r * k, 0.0, 0.0] for k in range(n)]


@pytest.mark.parametrize("pos, radius, words", [
    (_line(1), 0.005, ["at least 2 member spheres, got 1"]),
    (_line(2), [0.005, 0.005, 0.005], ["member_radius", "2 of them, got 3"]),
    (_line(2), 0.0, ["member_radius = 0.0", "> 0"]),
    (_line(2), -0.005, ["member_radius = -0.005", "> 0"]),
    (_line(2), [0.005, math.nan], ["member_radius[1] = nan"]),
    (_line(2), [math.inf, 0.005], ["member_radius[0] = inf"]),
    ([[0, 0, 0], [0.05, 0, 0]], 0.005, ["member 1", "neither overlaps nor touches"]),
    ([[0, 0, 0], [0.01, 0, 0], [0.0, 0, 0]], 0.005, ["member 0", "wholly inside member 2"]),
    ([[0, 0, 0], [0.001, 0, 0]], [0.005, 0.002], ["member 1", "wholly inside member 0"]),
    (_line(3001), 0.005, ["3001 member spheres", "at most 3000"]),
])
@pytest.mark.parametrize("breakable", [False, True])
def test_clump_shapes_refused_at_declaration(one_line_error, pos, radius, words, breakable):
    sc = pdem.Scene(law="cohesive")
    sc.material(**COHESIVE)
    one_line_error(pdem.InputError, lambda: sc.add_clump(pos, radius, 0, breakable=breakable), *words)


def test_a_clump_of_3000_members_is_accepted():
    sc = pdem.Scene()
    sc.material(**MAT)
    assert sc.add_clump(_line(3000), 0.005, 0) == 0


def test_shape_generator_refuses_absurd_member_counts_before_making_them(one_line_error):
    """A member radius in µm (1e-6 for 1 mm) would ask for ~1e13 grid points: refused before
    the grid is allocated, naming the count and the limit."""
    from pdem.bodies.clump_generators import shape_members

    one_line_error(pdem.InputError, lambda: shape_members("ellipsoid", 1e-6, (0.024, 0.024, 0.024)),
                   "clumps.member_radius = 1e-06", "at most 3000", "wrong unit")
    one_line_error(pdem.InputError, lambda: shape_members("cake", 0.001, (0.010, 0.037, 0.037)), "at most 3000")
    assert len(shape_members("cake", 0.0015, (0.010, 0.037, 0.037))[0]) <= 3000


@pytest.mark.parametrize("spacing, ratio, refused", [(0.0095, 0.5, False), (0.007, 0.5, True), (0.007, 0.9, False)])
def test_breakable_members_closer_than_the_overlap_limit_refused_naming_the_cause(one_line_error, spacing, ratio,
                                                                                 refused):
    """Members of r = 5 mm, ``spacing`` apart, overlap by (2r − spacing)/r of a radius: above
    max_overlap_ratio the run would stop at step 1 blaming the time step (exit 4); refused at
    declaration naming the spacing and max_overlap_ratio instead."""
    r = 0.005
    sc = pdem.Scene(law="cohesive", max_overlap_ratio=ratio)
    sc.material(**COHESIVE)
    pos = [[0.0, 0.0, 0.0], [spacing, 0.0, 0.0]]
    overlap = (2 * r - spacing) / r
    assert (overlap > ratio) == refused
    if refused:
        one_line_error(pdem.InputError, lambda: sc.add_breakable_clump(pos, r, 0), "breakable members 0 and 1",
                       f"{overlap:.3g} of the smaller radius", f"max_overlap_ratio = {ratio:g}", "member_spacing")
    else:
        sc.add_breakable_clump(pos, r, 0)
        sc.add_clump(pos, r, 0)  # rigid: the members' overlap is no contact


def test_breakable_oedometer_grain_too_dense_refused_by_check_not_at_step_1():
    """The issue's case in a scene file: a breakable grain whose members overlap past the limit
    (member_spacing 4 mm for r = 3.55 mm: 0.87 r) is refused by the scene's check (exit 2)."""
    doc = _job("oedometer_breakable_small.toml")
    doc["oedometer"]["clumps"]["member_spacing"] = 0.004
    with pytest.raises(pdem.InputError, match=r"oedometer.clumps.*breakable members.*max_overlap_ratio = 0.5"):
        check_scene(doc)
    doc["oedometer"]["clumps"]["member_spacing"] = 0.0071  # the thesis's 7.1 mm for Ø 7.1 mm: accepted
    check_scene(doc)


# ---------------------------------------------------------------------------- bonds
@pytest.mark.parametrize("key, value, words", [
    ("normal_cohesion", 0.0, ["normal_cohesion = 0.0", "> 0 [Pa] for bonds"]),
    ("shear_cohesion", 0.0, ["shear_cohesion = 0.0", "> 0 [Pa] for bonds"]),
    ("normal_cohesion", -1e6, ["normal_cohesion = -1000000.0", ">= 0"]),
    ("shear_cohesion", math.inf, ["shear_cohesion = inf", "finite"]),
    ("normal_cohesion", math.nan, ["normal_cohesion = nan", "finite"]),
    ("normal_cohesion", "1e6", ["normal_cohesion = '1e6'"]),
])
def test_bond_strengths_refused(one_line_error, key, value, words):
    def declare():
        sc = pdem.Scene(law="cohesive")
        sc.material(**{**COHESIVE, key: value})
        sc.add_breakable_clump(_line(2), 0.005, 0)
        sc.build()
    one_line_error(pdem.InputError, declare, *words)


def test_bonds_between_bodies_that_do_not_touch_refused(one_line_error):
    sc = pdem.Scene(law="cohesive")
    sc.material(**COHESIVE)
    sc.add_spheres([[0, 0, 0], [0.0101, 0, 0], [0.05, 0, 0]], 0.005, 0)
    sc.add_bonds([[0, 1]])
    one_line_error(pdem.InputError, sc.build, "gid 0 and 1", "apart", "overlap or touch")
    sc2 = pdem.Scene(law="cohesive")
    sc2.material(**COHESIVE)
    sc2.add_spheres([[0, 0, 0], [0.01, 0, 0]], 0.005, 0)
    one_line_error(pdem.InputError, lambda: sc2.add_bonds([[1, 1]]), "bonded to itself")
    sc2.add_bonds([[0, 7]])
    one_line_error(pdem.InputError, sc2.build, "gid 7", "not a sphere")


# ---------------------------------------------------------------------------- plausible ranges
ALL_BOUNDS = [(s, k, b) for s, table in BOUNDS.items() for k, b in table.items()] + \
    [("track", k, b) for k, b in PREPARATION_BOUNDS.items()]


@pytest.mark.parametrize("section, key, bounds", ALL_BOUNDS, ids=[f"{s}.{k}" for s, k, _ in ALL_BOUNDS])
def test_every_key_at_its_bounds_accepted_and_past_them_refused(one_line_error, section, key, bounds):
    lo, hi, unit, _ = bounds
    table = None if section in BOUNDS and key in BOUNDS[section] else PREPARATION_BOUNDS
    for v in (lo, hi):
        plausible(section, {key: v}, table)
    past = [hi * (1 + 1e-9) + 1e-300] + ([lo * (1 - 1e-9)] if lo > 0 else [-1e-12])
    for v in past:
        one_line_error(pdem.InputError, lambda: plausible(section, {key: v}, table), f"{section}.{key} = {v!r}",
                       f"{lo:g} .. {hi:g} {unit}")


@pytest.mark.parametrize("job, section, key, value, words", [
    ("track_beam.toml", "track", "sleeper_size", [0.3, 2600.0, 0.2],
     ["track.sleeper_size[1] = 2600.0", "0.01 .. 10 m", "2.6 m would be plausible", "given in mm"]),
    ("track_beam.toml", "track", "gauge", 1435.0, ["track.gauge = 1435.0", "1.435 m would be plausible", "mm"]),
    ("track_beam.toml", "traffic", "axle_load", 225.0, ["traffic.axle_load = 225.0", "225000 N", "given in kN"]),
    ("track_slice.toml", "traffic", "f_max", 200.0, ["traffic.f_max = 200.0", "200000 N", "given in kN"]),
    ("track_beam.toml", "traffic", "speed", 27780.0, ["traffic.speed = 27780.0", "27.78 m/s", "mm/s"]),
    ("blast.toml", "blast", "plate_thickness", 20.0, ["blast.plate_thickness = 20.0", "0.02 m", "mm"]),
    ("blast.toml", "blast", "tau", 0.1, ["blast.tau = 0.1", "0.0001 s", "ms"]),
    ("oedometer_ci.toml", "oedometer", "diameter", 300.0, ["oedometer.diameter = 300.0", "0.3 m", "mm"]),
    ("oedometer_ci.toml", "oedometer", "platen_mass", 2400.0e3, ["oedometer.platen_mass = 2400000.0", "2400 kg",
                                                                 "given in g"]),
])
def test_units_off_by_1000_refused_naming_the_slip(one_line_error, job, section, key, value, words):
    doc = _job(job)
    doc[section][key] = value
    one_line_error(pdem.InputError, lambda: check_scene(doc), *words)


@pytest.mark.parametrize("job", ["track_beam.toml", "track_slice.toml", "blast.toml", "oedometer_ci.toml"])
def test_every_bounded_key_past_its_range_refused_by_the_scene_naming_it(job):
    """Each key of the scene's sections set 1000 times past its upper bound in a shipped job:
    the scene's check refuses it naming that key (or, first, a key it must agree with)."""
    doc0 = _job(job)
    named = 0
    for section in [s for s in ("track", "traffic", "blast", "oedometer") if s in doc0]:
        bounds = {**BOUNDS[section], **(PREPARATION_BOUNDS if section in ("track", "oedometer") else {})}
        for key, (lo, hi, _, _) in bounds.items():
            doc = copy.deepcopy(doc0)
            if section == "traffic" and key in (("f_min", "f_max", "frequency") if doc["traffic"].get(
                    "program", "axles") == "axles" else ("axle_load", "axles", "speed", "rest_time",
                                                          "rail_bending_stiffness", "rail_seat_stiffness",
                                                          "rail_pad_stiffness", "rail_length",
                                                          "characteristic_length")):
                continue  # not a key of this program
            if key == "rail_pad_stiffness" or key == "rail_length":
                doc["traffic"]["rail_model"] = "beam"
            old = doc[section].get(key)
            doc[section][key] = [hi * 1000 + 1] * len(old) if isinstance(old, list) else hi * 1000 + 1
            with pytest.raises(pdem.InputError) as info:
                check_scene(doc)
            message = str(info.value)
            assert "\n" not in message
            named += message.startswith(f"{section}.{key}")
    assert named >= 3


# ---------------------------------------------------------------------------- campaigns
def _campaign(tmp_path, body, name="camp", head=""):
    (tmp_path / "tiny.toml").write_text(TINY_DEPOSITION)
    p = tmp_path / f"{name}.toml"
    p.write_text(f'[campaign]\nname = "{name}"\nbase = "tiny.toml"\n{head}\n{body}')
    return p


@pytest.mark.parametrize("body, head, words", [
    ("[[grid]]\n", "", ["grid[0]: empty grid"]),
    ("[[grid]]\n\"deposition.seed\" = []\n", "", ["deposition.seed = []", "non-empty list"]),
    ("[[grid]]\n\"deposition.seed\" = [1, 2, 1]\n", "", ["value 2 (1) repeats value 0", "same scene"]),
    ("[[grid]]\nzip = true\n\"deposition.seed\" = [1, 2, 1]\n\"deposition.count\" = [10, 20, 10]\n", "",
     ["row 2 ([1, 10]) repeats row 0"]),
    ("[[case]]\nname = \"Soft\"\n[[case]]\nname = \"soft\"\n", "", ["'Soft' and 'soft'", "one folder"]),
    ("[[grid]]\n\"deposition.sed\" = [1, 2]\n", "", ["deposition.sed: unknown key"]),
    ("[[grid]]\n\"walls.0.axis\" = [\"x\"]\n", "", ["walls", "not in the base scene", "a typo?"]),
    ("[seeds]\ncount = 2\n", "base = 5\n", None),
])
def test_campaign_file_problems_one_line_exit_2(tmp_path, body, head, words):
    if head:  # base given twice would be a TOML error: the head replaces the base line
        p = tmp_path / "camp.toml"
        (tmp_path / "tiny.toml").write_text(TINY_DEPOSITION)
        p.write_text(f'[campaign]\nname = "camp"\n{head}\n{body}')
        words = ["campaign.base = 5", "must be a path"]
    else:
        p = _campaign(tmp_path, body)
    status, lines = _cli("campaign", "check", str(p), "--out", str(tmp_path / "runs"))
    assert status == 2 and len(lines) == 1 and lines[0].startswith("pdem: error: "), lines
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not (tmp_path / "runs").exists()


def test_campaign_check_ok_writes_nothing_and_refuses_another_campaigns_folder(tmp_path):
    a = _campaign(tmp_path, "[seeds]\ncount = 2\n", name="a")
    b = _campaign(tmp_path, "[seeds]\ncount = 2\n", name="b")
    out = tmp_path / "runs"
    status, lines = _cli("campaign", "check", str(a), "--out", str(out))
    assert status == 0 and len(lines) == 1 and lines[0].startswith("ok ") and "2 members" in lines[0]
    assert not out.exists()
    assert _cli("campaign", "expand", str(a), "--out", str(out))[0] == 0
    status, lines = _cli("campaign", "check", str(b), "--out", str(out))
    assert status == 2 and len(lines) == 1 and "holds the members of campaign 'a'" in lines[0], lines


# ---------------------------------------------------------------------------- pdem run --check
def test_run_check_ok_in_one_line_writing_nothing(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_DEPOSITION)
    out = tmp_path / "out"
    status, lines = _cli("run", str(scene), "--check", "--out", str(out))
    assert status == 0 and len(lines) == 1 and lines[0].startswith("ok ") and "50 spheres, 400 steps" in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("problem, words", [
    ("out_file", ["--out", "exists and is not a directory"]),
    ("steps", ["--steps = 1000000000000000", "years"]),
    ("overlap", ["overlap", "allow_initial_overlap"]),
    ("campaign", ["a campaign file, not a scene file", "pdem campaign"]),
])
def test_run_check_refuses_what_a_run_refuses_at_start(tmp_path, problem, words):
    scene = tmp_path / "s.toml"
    text = TINY_DEPOSITION
    extra = []
    out = tmp_path / "out"
    if problem == "out_file":
        out.write_text("a file")
    if problem == "steps":
        extra = ["--steps", str(10 ** 15)]
    if problem == "overlap":
        doc = tomllib.loads(text)
        del doc["deposition"]
        doc["spheres"] = [{"pos": [[0, 0, 0.05], [0.015, 0, 0.05]], "radius": 0.01, "material": "ballast"}]
        text = toml_text(doc)
    if problem == "campaign":
        text = '[campaign]\nbase = "x.toml"\n[seeds]\ncount = 2\n'
    scene.write_text(text)
    status, lines = _cli("run", str(scene), "--check", "--out", str(out), *extra)
    assert status == 2 and len(lines) == 1 and lines[0].startswith("pdem: error: "), lines
    for w in words:
        assert w in lines[0], (w, lines[0])


# ---------------------------------------------------------------------------- 2 ranks
@pytest.mark.slow
@needs_mpiexec
@pytest.mark.parametrize("case", ["ok", "breakable", "plate_slip", "numeric_string"])
def test_checks_on_2_ranks_one_line(tmp_path, case):
    """The same refusals from the real command line on 2 ranks: one line, printed once, exit 2;
    a valid scene checked on 2 ranks: one 'ok' line, exit 0, nothing written."""
    if case == "ok":
        doc = tomllib.loads(TINY_DEPOSITION)
    elif case == "breakable":
        doc = _job("oedometer_breakable_small.toml")
        doc["oedometer"]["clumps"]["member_spacing"] = 0.004
    elif case == "plate_slip":
        doc = _job("blast.toml")
        doc["blast"]["plates"] = [10780.0e3]
    else:
        doc = tomllib.loads(TINY_DEPOSITION)
        doc["deposition"]["box_hi"] = [0.2, "0.1", 0.3]
    scene = tmp_path / "s.toml"
    scene.write_text(toml_text(doc))
    r = run_pdem(2, scene, tmp_path / "out", "--check", expect=0 if case == "ok" else 2)
    lines = [x for x in (r.stdout + r.stderr).splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stdout + r.stderr
    want = {"ok": "ok ", "breakable": "pdem: error: oedometer.clumps", "plate_slip": "pdem: error: blast.plates[0]",
            "numeric_string": "pdem: error: deposition.box_hi"}[case]
    assert lines[0].startswith(want), lines
    assert not (tmp_path / "out").exists()


def test_numbers_fast_path_keeps_arrays_bitwise():
    """`numbers` of a numeric array returns the same float64 values (no change to any valid input)."""
    a = np.random.default_rng(1).uniform(0.001, 0.01, 1000)
    assert np.array_equal(numbers("r", a, 1000, 0.0, lo_open=True), a)
    assert np.array_equal(numbers("r", a.tolist(), 1000, 0.0, lo_open=True), a)
