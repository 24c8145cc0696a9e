"""The box-test campaign files of the calibration and the thesis's studies (docs/box_test.md
"Calibration and studies") expand: every member's scene passes `pdem run`'s checks, with the
options and values each file promises. Nothing is run."""
import pytest

from campaign_helpers import ROOT
from pdem.campaign.spec import load_campaign


def members(name, tmp_path):
    camp = load_campaign(ROOT / "jobs" / "campaigns" / f"{name}.toml", out=str(tmp_path / name))
    return {m.name: m.doc for m in camp.members}


def test_calibration_crosses_the_compaction_options_with_ten_seeds(tmp_path):
    got = members("box_calibration", tmp_path)
    assert len(got) == 80
    seeds = sorted({d["box_test"]["seed"] for d in got.values()})
    assert seeds == list(range(1, 11))
    for d in got.values():  # thesis (b)
        assert d["materials"]["ballast"]["young"] == 2.8e6 and d["box_test"]["radius_spread"] == 0.4
        assert (d["box_test"]["f_min"], d["box_test"]["f_max"]) == (0.0, 3000.0)
    yade = next(d for n, d in got.items() if n.startswith("yade_"))["box_test"]
    assert (yade["cut"], yade["sleeper_placement"], yade["base"], yade["vibration_friction_contacts"]) == (
        "center", "cut", "two_sided", "new")
    assert next(d for n, d in got.items() if n.startswith("unvibrated"))["box_test"]["vibration_time"] == 0.0
    sleeper = next(d for n, d in got.items() if n.startswith("yade-sleeper_"))["box_test"]
    assert (sleeper["sleeper_surface"], sleeper["sleeper_mass"], sleeper["vibration_friction_contacts"]) == (
        "spheres", "members", "new")


@pytest.mark.parametrize("name, key, values", [
    ("box_stiffness", ("materials", "ballast", "young"), [2.8e6, 2.8e7, 2.8e8, 2.8e9, 2.8e10]),
    ("box_frequency", ("box_test", "frequency"), [1.0, 0.1, 0.01]),
    ("box_damping", ("simulation", "damping"), [0.2, 0.3, 0.6, 0.9]),
])
def test_study_files_expand(tmp_path, name, key, values):
    got = members(name, tmp_path)
    seen = []
    for d in got.values():
        v = d
        for k in key:
            v = v[k]
        seen.append(v)
    assert sorted(seen) == sorted(values)
    if name == "box_stiffness":  # steel 10x and rubber 0.1x the ballast in every member
        for d in got.values():
            m = d["materials"]
            assert m["steel"]["young"] == pytest.approx(10 * m["ballast"]["young"])
            assert m["rubber"]["young"] == pytest.approx(0.1 * m["ballast"]["young"])


def test_clump_study_sets_the_8_sphere_grain_on_one_case(tmp_path):
    got = members("box_clumps", tmp_path)
    assert len(got) == 6
    shapes = sorted(d["box_test"].get("clumps", {}).get("shape", "spheres") for d in got.values())
    assert shapes == ["ballast8"] * 3 + ["spheres"] * 3
    for d in got.values():
        assert d["materials"]["ballast"]["young"] == 3.0e6 and d["materials"]["rubber"]["young"] == 3.0e5


def test_checks_use_the_calibrated_option_set_on_the_thesis_studies(tmp_path):
    """box_checks runs the thesis's other studies with the option set of the calibration's case
    `unvibrated-sleeper` (the nearest mean, docs/box_test.md); `analysis box-checks` verifies the
    same against the measured calibration."""
    calib = members("box_calibration", tmp_path)
    chosen = next(d for n, d in calib.items() if n.startswith("unvibrated-sleeper_"))["box_test"]
    got = members("box_checks", tmp_path)
    assert len(got) == 12 * 2
    cases = {}
    for name, d in got.items():
        b = d["box_test"]
        for k in ("vibration_time", "sleeper_surface", "sleeper_mass"):
            assert b[k] == chosen[k], (name, k)
        assert b["radius_spread"] == 0.0 and (b["f_min"], b["f_max"]) == (0.0, 3000.0)
        m = d["materials"]
        assert m["steel"]["young"] == pytest.approx(10 * m["ballast"]["young"])
        assert m["rubber"]["young"] == pytest.approx(0.1 * m["ballast"]["young"])
        cases[name.rsplit("_seed-", 1)[0]] = d
    assert cases["ten-cycles"]["box_test"]["cycles"] == 10
    for e in ("2.8e8", "2.8e9", "2.8e10"):  # prepared at 2.8e7, stiffened before the load
        d = cases[f"stiffness-{e}"]
        assert d["materials"]["ballast"]["young"] * d["box_test"]["prep_stiffness_factor"] == pytest.approx(2.8e7)
    assert [cases[f"frequency-{f}"]["box_test"]["frequency"] for f in ("0.1", "0.01")] == [0.1, 0.01]
    assert [cases[f"damping-{x}"]["simulation"]["damping"] for x in ("0.2", "0.6", "0.9")] == [0.2, 0.6, 0.9]
    assert cases["clumps-3e6"]["box_test"]["clumps"]["shape"] == "ballast8"
    assert cases["clumps-3e6"]["box_test"]["base"] == cases["spheres-3e6"]["box_test"]["base"] == "two_sided"
