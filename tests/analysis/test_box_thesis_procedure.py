"""``python -m analysis box-thesis-procedure`` on synthetic soft and full-stiffness campaigns with
known answers: each stiffness is calibrated on its own target (the case nearest it), a target is
met when it lies in the case's interval of the mean, the unfitted quantities (end of the cycle,
end − peak) are judged against the lab, and the verdict says when no option set fits both."""
import importlib.util
import json
from pathlib import Path

import pytest

from analysis.__main__ import main
from analysis.box_thesis_procedure import LAB_PEAK, build, covers
from analysis.campaign import CampaignError, read_campaign

_spec = importlib.util.spec_from_file_location("box_checks_test", Path(__file__).with_name("test_box_checks.py"))
fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fixtures)


SEEDS = ((1, 1.0), (2, 1.02), (3, 0.98))


def campaign(root, peaks, kept=0.8, knob=True, seeds=SEEDS):
    """Cases vibrated_T (T = vibration time [s]) with seeds 1..3 whose settlement at the peak is
    peaks[T] × (1, 1.02, 0.98); settlement_max = 1.2 × peak, end = kept × max."""
    e = []
    for t, p in peaks.items():
        for seed, f in seeds:
            over = {"box_test.vibration_time": t} if knob else {}
            e.append(fixtures.member(root, f"vibrated_{t}_seed-{seed}", f"vibrated_{t}", seed, over, p * f, kept=kept))
    return fixtures.manifest(root, e)


def test_each_stiffness_is_calibrated_on_its_own_target_and_no_set_fits_both(tmp_path):
    soft = campaign(tmp_path / "soft", {0.0: 0.040, 0.5: 0.030})   # thesis 55.1-76.0 mm: neither
    # full: unvibrated 17 mm at the peak (max 20.4, end 0.8 x 20.4 = 16.3 mm), vibrated 1 mm
    full = campaign(tmp_path / "full", {0.0: 0.017, 0.5: 0.001})
    d = build(read_campaign(soft), read_campaign(full))
    assert d["cases"] == ["vibrated_0.0", "vibrated_0.5"]
    assert d["chosen_soft"] == "vibrated_0.0" and d["chosen_full"] == "vibrated_0.0"
    assert d["full_values"]["vibrated_0.0"]["peak"]["mean"] == pytest.approx(LAB_PEAK)
    assert d["fits"]["vibrated_0.0"] == {"thesis": False, "lab_peak": True, "lab_end": False, "lab_after_peak": False}
    assert d["fits_both"] == []
    # end - peak = (0.8 x 1.2 - 1) x 17 mm = -0.68 mm (the lab: -2 mm)
    assert d["full_values"]["vibrated_0.0"]["after_peak"]["mean"] == pytest.approx((0.8 * 1.2 - 1) * 0.017)


def test_a_set_inside_both_targets_fits_both(tmp_path):
    soft = campaign(tmp_path / "soft", {0.0: 0.0635, 0.5: 0.030})
    full = campaign(tmp_path / "full", {0.0: 0.017, 0.5: 0.001})
    assert build(read_campaign(soft), read_campaign(full))["fits_both"] == ["vibrated_0.0"]


def test_covers_is_the_interval_meeting_the_target():
    s = {"ci_low": 1.0, "ci_high": 2.0}
    assert covers(s, 1.5, 1.5) and covers(s, 2.0, 3.0) and not covers(s, 2.1, 3.0)
    assert not covers({"ci_low": float("nan"), "ci_high": float("nan")}, 1.0, 1.0)


def test_the_command_writes_table_json_and_plot_and_refuses_a_case_without_the_knob(tmp_path, capsys):
    soft = campaign(tmp_path / "soft", {0.0: 0.040, 0.25: 0.035, 0.5: 0.030})  # 0.25 not run at full stiffness
    full = campaign(tmp_path / "full", {0.0: 0.017, 0.5: 0.001})
    assert main(["box-thesis-procedure", str(soft), str(full), "--out", str(tmp_path / "out")]) == 0
    out = tmp_path / "out"
    assert (out / "thesis_procedure.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "thesis_procedure.md").read_text()
    assert "No option set fits both" in text and "| vibrated_0.0 | 0 |" in text
    assert "| vibrated_0.25 | 0.25 | 35 [" in text and "| not run | not run | not run | not run | 3 / 0 |" in text
    assert json.loads((out / "thesis_procedure.json").read_text())["chosen_full"] == "vibrated_0.0"
    one = campaign(tmp_path / "one", {0.0: 0.017}, seeds=SEEDS[:1])  # one seed: its count is not scaled to mm
    assert main(["box-thesis-procedure", str(soft), str(one), "--out", str(tmp_path / "one_out")]) == 0
    assert "| 17 (n = 1) |" in (tmp_path / "one_out" / "thesis_procedure.md").read_text()
    bare = campaign(tmp_path / "bare", {0.0: 0.017}, knob=False)
    with pytest.raises(CampaignError, match="does not set box_test.vibration_time"):
        build(read_campaign(bare), read_campaign(full))
    capsys.readouterr()
    assert main(["box-thesis-procedure", str(bare), str(full)]) == 2
    assert "does not set box_test.vibration_time" in capsys.readouterr().err
