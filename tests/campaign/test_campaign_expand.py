"""Campaign files: expansion (crossed and zipped grids, seeds, cases, dotted keys into nested
TOML), the manifest, idempotence, and the one-line errors of bad input. Nothing is run."""
import json
import tomllib
from pathlib import Path

import pytest

from campaign_helpers import ROOT, write_campaign
from pdem.campaign.cli import main as campaign_main
from pdem.campaign.layout import read_manifest, write_campaign as expand_into
from pdem.format.campaign import MANIFEST
from pdem.campaign.spec import load_campaign, set_path, short_names, value_label
from pdem.campaign.tomlw import dumps
from pdem.errors import InputError


def expand(path, **kw):
    camp = load_campaign(path, **kw)
    return camp, expand_into(camp, log=lambda m: None)


def scene(out, name):
    return tomllib.loads((Path(out) / name / "scene.toml").read_text())


def snapshot(root):
    """{relative path: (mtime_ns, bytes)} of every file under root."""
    return {str(p.relative_to(root)): (p.stat().st_mtime_ns, p.read_bytes()) for p in sorted(Path(root).rglob("*"))
            if p.is_file()}


# ---------------------------------------------------------------------------- expansion
def test_crossed_grid_and_seeds(tmp_path, tiny):
    p = write_campaign(tmp_path, """
[seeds]
values = [1, 2]
[[grid]]
"simulation.damping" = [0.2, 0.3, 0.4]
materials.ballast.young = [1e7, 2.8e7]
""")
    camp, man = expand(p)
    names = [m.name for m in camp.members]
    assert len(names) == 12 and len(set(names)) == 12
    # keys in file order, seeds fastest
    assert names[:3] == ["damping-0.2_young-1e7_seed-1", "damping-0.2_young-1e7_seed-2",
                         "damping-0.2_young-2.8e7_seed-1"]
    assert camp.seed_key == "deposition.seed"  # the default for a [deposition] scene
    assert camp.varied == ["simulation.damping", "materials.ballast.young", "deposition.seed"]
    m = camp.members[7]
    assert m.params == {"simulation.damping": 0.3, "materials.ballast.young": 2.8e7, "deposition.seed": 2}
    doc = scene(camp.out, m.name)  # dotted keys land in the nested tables of the scene file
    assert doc["simulation"]["damping"] == 0.3 and doc["materials"]["ballast"]["young"] == 2.8e7
    assert doc["deposition"]["seed"] == 2
    assert doc["deposition"]["count"] == 50 and doc["run"]["steps"] == 400  # the rest is the base
    assert [e["name"] for e in man["members"]] == names
    assert man["seed_key"] == "deposition.seed" and man["format"] == "pdem-campaign"


def test_zipped_grid_and_seed_count(tmp_path, tiny):
    p = write_campaign(tmp_path, """
[seeds]
count = 3
first = 8
[[grid]]
zip = true
"simulation.damping" = [0.2, 0.3]
"materials.ballast.young" = [1e7, 2e7]
""")
    camp, _ = expand(p)
    assert [m.name for m in camp.members] == [
        "damping-0.2_young-1e7_seed-08", "damping-0.2_young-1e7_seed-09", "damping-0.2_young-1e7_seed-10",
        "damping-0.3_young-2e7_seed-08", "damping-0.3_young-2e7_seed-09", "damping-0.3_young-2e7_seed-10"]
    assert {(m.params["simulation.damping"], m.params["materials.ballast.young"]) for m in camp.members} == {
        (0.2, 1e7), (0.3, 2e7)}


def test_cases_crossed_with_seeds_and_common_settings(tmp_path, tiny):
    p = write_campaign(tmp_path, """
[set]
run.steps = 123
[seeds]
values = [4, 5]
[[case]]
name = "reference"
[[case]]
name = "soft"
ranks = 2
[case.materials.ballast]
young = 1e6
""", head="threads = 1")
    camp, man = expand(p)
    assert [m.name for m in camp.members] == ["reference_seed-4", "reference_seed-5", "soft_seed-4", "soft_seed-5"]
    soft = camp.members[2]
    assert soft.params == {"case": "soft", "deposition.seed": 4} and soft.ranks == 2
    assert camp.members[0].ranks == 1
    assert scene(camp.out, "soft_seed-4")["materials"]["ballast"]["young"] == 1e6
    assert scene(camp.out, "reference_seed-5")["materials"]["ballast"]["young"] == 1e7
    assert all(scene(camp.out, m.name)["run"]["steps"] == 123 for m in camp.members)
    assert man["cases"] is True and man["members"][2]["ranks"] == 2


def test_box_test_keys_and_array_index(tmp_path):
    """A [box_test] base: the seed key defaults to box_test.seed; a key missing from the base but
    known to its table (vibration_time) is added; an integer picks an element of an array of tables
    (a plain scene's [[walls]]; a box test has none and refuses a [[walls]] table)."""
    (tmp_path / "box.toml").write_text((ROOT / "jobs" / "box_test.toml").read_text())
    p = write_campaign(tmp_path, """
[seeds]
values = [1, 2]
[[grid]]
"box_test.vibration_time" = [0.0, 0.5]
""", base="box.toml")
    camp, _ = expand(p)
    assert camp.seed_key == "box_test.seed"
    doc = scene(camp.out, camp.members[0].name)
    assert doc["box_test"]["vibration_time"] == 0.0 and doc["box_test"]["seed"] == 1
    assert doc["box_test"]["cycles"] == 3  # from jobs/box_test.toml
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "dep.toml").write_text((ROOT / "jobs" / "deposition.toml").read_text()
                                                 + '\n[[walls]]\naxis = "z"\nposition = 0.0\nmaterial = "steel"\n')
    p = write_campaign(tmp_path / "plain", """
[[grid]]
"walls.0.position" = [-0.01]
""", base="dep.toml")
    camp, _ = expand(p)
    assert scene(camp.out, camp.members[0].name)["walls"][0] == {"axis": "z", "position": -0.01, "material": "steel"}


def test_names_and_labels():
    assert [value_label(v) for v in (0.2, 1e7, 2.8e-4, 3.0, True, "a b/c", [0.7, 0.3])] == [
        "0.2", "1e7", "2.8e-4", "3", "true", "a-b-c", "0.7x0.3"]
    assert short_names(["materials.ballast.young", "materials.steel.young", "box_test.seed"]) == {
        "materials.ballast.young": "ballast.young", "materials.steel.young": "steel.young", "box_test.seed": "seed"}
    doc = {"a": {"b": 1}, "w": [{"x": 1}, {"x": 2}]}
    assert set_path(doc, "a.c.d", 5) == ["a.c"] and doc["a"]["c"] == {"d": 5}
    set_path(doc, "w.1.x", 7)
    assert doc["w"][1]["x"] == 7
    with pytest.raises(InputError, match="w.5.x: w is an array of 2"):
        set_path(doc, "w.5.x", 1)
    with pytest.raises(InputError, match="a.b is a value"):
        set_path(doc, "a.b.c", 1)


def test_toml_writer_round_trip():
    doc = {"top": 1, "s": 'quote " back \\ tab\t nl\n é 😀 del\x7f', "f": [1.5, -0.0, float("inf")], "b": True,
           "simulation": {"dt": "auto", "gravity": [0.0, 0.0, -9.81]},
           "materials": {"ballast": {"young": 2.8e7}, "with space": {"k": 1}},
           "walls": [{"axis": "z", "position": 0.0, "v": {"a": 1}}, {"axis": "x", "position": 0.7}],
           "empty": {}, "nested": [[1, 2], [3]], "inline": [{"a": 1}, 2]}
    text = dumps(doc, header="line one\nline two")
    assert text.startswith("# line one\n# line two\n")
    back = tomllib.loads(text)
    assert back == doc


# ---------------------------------------------------------------------------- idempotence
def test_expanding_twice_changes_nothing_and_new_seeds_are_added(tmp_path, tiny):
    body = '[seeds]\nvalues = [1, 2]\n[[grid]]\n"simulation.damping" = [0.2, 0.3]\n'
    p = write_campaign(tmp_path, body)
    camp, _ = expand(p)
    out = Path(camp.out)
    # a finished member: its run record and results must survive any later expansion
    done = out / camp.members[0].name
    (done / "run.json").write_text('{"attempts": [{"end": "x", "exit": 0, "wall_s": 1, "core_s": 1}]}')
    (done / "results.h5").write_bytes(b"results")
    before = snapshot(out)
    expand(p)
    assert snapshot(out) == before
    p.write_text(p.read_text().replace("values = [1, 2]", "values = [1, 2, 3]"))
    camp3, man = expand(p)
    after = snapshot(out)
    assert len(man["members"]) == 6
    for k, v in before.items():  # every old file untouched, except the manifest (two members more)
        if k != MANIFEST:
            assert after[k] == v, k
    assert (out / "damping-0.3_seed-3" / "scene.toml").exists()


def test_changed_base_refuses_and_writes_nothing(tmp_path, tiny):
    p = write_campaign(tmp_path, '[seeds]\nvalues = [1, 2]\n')
    camp, _ = expand(p)
    before = snapshot(camp.out)
    tiny.write_text(tiny.read_text().replace("count = 50", "count = 60"))
    with pytest.raises(InputError, match="its scene .* differ .* members are never overwritten"):
        expand(p)
    assert snapshot(camp.out) == before


def test_another_campaigns_directory_is_refused(tmp_path, tiny):
    out = tmp_path / "shared"
    a = write_campaign(tmp_path, '[seeds]\nvalues = [1]\n', name="alpha", out=out)
    b = write_campaign(tmp_path, '[seeds]\nvalues = [1]\n', name="beta", out=out)
    expand(a)
    before = snapshot(out)
    with pytest.raises(InputError, match="holds the members of campaign 'alpha'.*not of 'beta'"):
        expand(b)
    assert snapshot(out) == before
    other = tmp_path / "other"
    other.mkdir()
    (other / "results.h5").write_text("x")
    with pytest.raises(InputError, match="not a campaign directory"):
        expand(b, out=other)


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("body, message", [
    ('[[grid]]\n"simulation.dampin" = [0.1]', r"member dampin-0.1: simulation.dampin: unknown key; allowed:"),
    ('[[grid]]\n"deposition.cont" = [1]', r"deposition.cont: unknown key"),
    ('[[grid]]\n"run.stepz" = [1]', r"run.stepz: unknown key"),
    ('[[grid]]\n"foo.bar" = [1]', r"foo: unknown key"),
    ('[[grid]]\n"materials.balast.young" = [1e7]',
     r"materials.balast.\w+: required key is missing \(\[materials.balast\] is not in the base scene"),
    ('[[grid]]\n"simulation.damping" = []', r"grid\[0\].simulation.damping = \[\]: must be a non-empty list"),
    ("[[grid]]\nzip = true", r"grid\[0\]: empty grid"),
    ('[[grid]]\nzip = true\n"simulation.damping" = [0.1, 0.2]\n"run.steps" = [1]',
     r"zip = true needs lists of equal length"),
    ('[seeds]\nvalues = []', r"seeds.values = \[\]"),
    ("[seeds]\ncount = 0", r"seeds.count = 0: must be an integer >= 1"),
    ('[seeds]\nvalues = [1, 1]', r"a seed is repeated"),
    ("", r"nothing varies"),
    ('[seeds]\nvalues = [1]\n[slurm]\nwalltime = "1:00:00"', r"slurm.walltime: unknown key"),
    ('[seeds]\nvalues = [1]\n[sets]\na = 1', r"sets: unknown key"),
    ('[seeds]\nvalues = [1]\n[set]\n"deposition.seed" = 4', r"set.deposition.seed: also varied"),
    ('[seeds]\nvalues = [1]\n[[case]]\nname = "x"\ndeposition.seed = 4', r"case\[0\].deposition.seed: also varied"),
    ('[[grid]]\n"simulation.damping" = [-1.0]', r"damping"),
    ("[seeds]\nkey = 7.5\ncount = 2", r"seeds.key = 7.5: must be a dotted scene key as text"),
    ('[[grid]]\n"simulation.damping" = [0.1, 0.2, 0.3]\n[seeds]\ncount = 3334',
     r"expands to 10002 members \(the product of its cases, grids and seeds\): at most 10000"),
])
def test_bad_campaigns_give_one_line(tmp_path, tiny, body, message):
    p = write_campaign(tmp_path, body)
    with pytest.raises(InputError, match=message) as exc:
        expand(p)
    assert "\n" not in str(exc.value) and str(exc.value).startswith(str(p))
    assert not (tmp_path / "runs").exists()


def test_cli_exit_status_2_and_one_line(tmp_path, tiny, capsys):
    p = write_campaign(tmp_path, '[[grid]]\n"box_test.seed" = [1]')
    assert campaign_main(["expand", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pdem: error: ") and "box_test" in err
    assert campaign_main(["expand", str(tmp_path / "missing.toml")]) == 2
    assert "campaign file not found" in capsys.readouterr().err
    ok = write_campaign(tmp_path, '[seeds]\nvalues = [1, 2]', name="ok")
    assert campaign_main(["expand", str(ok)]) == 0
    assert "2 members" in capsys.readouterr().out
    man = read_manifest(tmp_path / "runs" / "ok")
    assert json.loads((tmp_path / "runs" / "ok" / "seed-1" / "member.json").read_text())["campaign"] == "ok"
    assert [e["params"] for e in man["members"]] == [{"deposition.seed": 1}, {"deposition.seed": 2}]
