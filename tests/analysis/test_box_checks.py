"""``python -m analysis box-checks`` on synthetic calibration and checks campaigns with known
answers: the calibration picks the option set nearest the thesis's 63.5 mm, the checks must use
it (else a one-line error naming the key), and each row of the table is the number or finding
built into the records."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from analysis.__main__ import main
from analysis.box_checks import DAMPING_CASES, FREQUENCY_CASES, STIFFNESS_CASES, box_checks_report, build_checks
from analysis.campaign import CampaignError, read_campaign
from pdem.format.schema import write_results

_spec = importlib.util.spec_from_file_location("analysis_records", Path(__file__).with_name("conftest.py"))
records = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(records)

OPTION = {"box_test.vibration_time": 0.0}


def member(root, name, case, seed, overrides, peak, n_cycles=1, scale=None, max_over=1.2, kept=0.8, at_force=None):
    """A member whose cycle k has settlement_peak = peak[k] (start 0 for the first, then the previous
    peak), settlement_max = max_over × peak, settlement_end = kept × settlement_max and the
    synthetic record's series with its settlement × scale (unloading stiffness ÷ scale; default
    1 + seed / 100, so that seeds differ)."""
    scale = 1.0 + 0.01 * seed if scale is None else scale
    d = root / name
    d.mkdir(parents=True)
    rec = records.make_box_record(n_cycles=n_cycles)
    series = dict(rec.series, sleeper_settlement=rec.series["sleeper_settlement"] * scale)
    peak = np.atleast_1d(np.asarray(peak, float))
    start = np.concatenate(([0.0], peak[:-1]))
    s_max = max_over * peak
    cycles = dict(rec.cycles, settlement_start=start, settlement_peak=peak, settlement_max=(s_max, "m"),
                  settlement_end=kept * s_max,
                  settlement_at_force_max=(peak if at_force is None else at_force * s_max, "m"))
    write_results(d / "results.h5", series, cycles, records.ATTRS)
    a = {"start": "t0", "end": "t1", "wall_s": 1.0, "exit": 0, "ranks": 1, "threads": 1, "core_s": 1.0}
    (d / "run.json").write_text(json.dumps({"member": name, "attempts": [a]}))
    (d / "member.json").write_text(json.dumps({"name": name, "params": {"case": case, "box_test.seed": seed},
                                               "overrides": {**overrides, "box_test.seed": seed}}))
    return (name, {"case": case, "box_test.seed": seed})


def manifest(root, entries):
    (root / "campaign.json").write_text(json.dumps({
        "format": "pdem-campaign", "version": 1, "name": root.name, "seed_key": "box_test.seed",
        "varied": ["box_test.seed"], "cases": True,
        "members": [{"name": n, "dir": n, "params": p, "ranks": 1, "threads": 1} for n, p in entries]}))
    return root


def calibration(tmp_path):
    root = tmp_path / "calibration"
    common = {"run.progress_every": 100}
    e = [member(root, f"pdem_seed-{s}", "pdem", s, common, v) for s, v in ((1, 0.010), (2, 0.011))]
    e += [member(root, f"unvibrated_seed-{s}", "unvibrated", s, {**common, **OPTION}, v)
          for s, v in ((1, 0.040), (2, 0.044))]
    return manifest(root, e)


def checks(tmp_path, option=OPTION, clump_scale=0.5, skip=()):
    root = tmp_path / "checks"
    over = {**option, "run.progress_every": 100000}
    e = []
    for s in (1, 2):
        within = np.array([0.020 / k for k in range(1, 11)])  # within cycle k: 20 mm / k
        e.append(member(root, f"ten-cycles_seed-{s}", "ten-cycles", s, over, np.cumsum(within), n_cycles=10,
                        at_force=0.6))
        for c, young, _ in STIFFNESS_CASES:
            if c not in ("ten-cycles",):
                kept = 0.8 if c != "constant-radius" else 0.7
                e.append(member(root, f"{c}_seed-{s}", c, s, over, 0.05 * (2.8e6 / young) ** 0.3, kept=kept))
        for c, lam in DAMPING_CASES:
            if c != "constant-radius":
                e.append(member(root, f"{c}_seed-{s}", c, s, over, 0.05 * (1 - 0.5 * lam), kept=0.7))
        for c, f in FREQUENCY_CASES[1:]:
            e.append(member(root, f"{c}_seed-{s}", c, s, over, 0.02, at_force=0.6 + 0.3 * (1 - f) ** 2 - 0.1 * s / 10))
        e.append(member(root, f"spheres-3e6_seed-{s}", "spheres-3e6", s, over, 0.05))
        e.append(member(root, f"clumps-3e6_seed-{s}", "clumps-3e6", s, over, 0.05, scale=clump_scale + 0.01 * s))
    e = [x for x in e if x[1]["case"] not in skip]
    return manifest(root, e)


def row(rows, start):
    return next(r for r in rows if r.check.startswith(start))


def test_the_calibration_chooses_the_nearest_mean_and_the_checks_compare_with_the_thesis(tmp_path):
    rows, ctx = build_checks(read_campaign(calibration(tmp_path)), read_campaign(checks(tmp_path)))
    assert ctx["best"] == "unvibrated" and ctx["opts"] == OPTION  # 42 mm is nearer 63.5 than 10.5
    r = rows[0]
    assert r.pdem_mean == pytest.approx(0.042) and r.verdict == f"pdem/thesis = {0.042 / 0.0635:.3g}"
    assert row(rows, "seed scatter").pdem_mean == pytest.approx(0.004 / 0.042)
    assert row(rows, "B (E_k 2.8e7, 10 cycles): settlement within cycle 1").pdem_mean == pytest.approx(0.020)
    assert row(rows, "B: settlement within cycle 10").pdem_mean == pytest.approx(0.002)
    assert row(rows, "B: within cycle 1 / within cycle 10").pdem_mean == pytest.approx(10.0)
    assert row(rows, "A / B").pdem_mean == pytest.approx(0.042 / 0.020)
    assert row(rows, "stiffness study: settlement").verdict == "holds"  # 0.05 (2.8e6/E)^0.3 falls
    # rebound = (1 - kept) max: constant-radius (E 2.8e6) kept 0.7, ten-cycles kept 0.8 ... falls
    assert row(rows, "stiffness study: the rebound").verdict == "holds"
    # the clumps' settlement is scaled by ~0.5: unloading stiffness ~2x that of the spheres
    clumps = row(rows, "unloading stiffness, 8-sphere")
    assert clumps.verdict == "holds" and "Welch p" in clumps.pdem
    # the calibration's two seeds and the constant radius both carry the record's stiffness
    assert row(rows, "unloading stiffness, radii").verdict == "holds"
    # damping: magnitude 0.05 (1 - λ/2) varies 1.64x, the kept fraction not at all
    assert row(rows, "damping").verdict == "holds"
    # frequency: sinking after the peak 1 - at_force: 0.4 at 1 Hz, then 0.157..., 0.1294...: falls
    assert row(rows, "frequency").verdict == "holds"


def test_a_finding_that_fails_says_so(tmp_path):
    rows, _ = build_checks(read_campaign(calibration(tmp_path)), read_campaign(checks(tmp_path, clump_scale=2.0)))
    assert row(rows, "unloading stiffness, 8-sphere").verdict == "does not hold"


def test_a_campaign_in_progress_gives_the_checks_it_can(tmp_path):
    rows, ctx = build_checks(read_campaign(calibration(tmp_path)),
                             read_campaign(checks(tmp_path, skip=("clumps-3e6", "stiffness-2.8e10", "frequency-0.01"))))
    waiting = row(rows, "unloading stiffness, 8-sphere")
    assert waiting.verdict == "—" and waiting.pdem == "not run yet: no finished member of clumps-3e6"
    sweep = row(rows, "stiffness study: settlement")
    assert "E_k 2.8e6, 2.8e7, 2.8e8, 2.8e9)" in sweep.check and sweep.verdict == "holds"
    assert row(rows, "frequency 1/0.1 Hz").verdict == "holds"
    assert row(rows, "B: settlement within cycle 10").pdem_mean == pytest.approx(0.002)


def test_checks_with_another_option_set_are_refused(tmp_path):
    with pytest.raises(CampaignError, match=r"box_test.vibration_time = 0.5, but the calibration chose 0.0"):
        build_checks(read_campaign(calibration(tmp_path)),
                     read_campaign(checks(tmp_path, option={"box_test.vibration_time": 0.5})))


def test_the_command_writes_the_table_and_the_plots(tmp_path, capsys):
    cal, chk = calibration(tmp_path), checks(tmp_path)
    assert main(["box-checks", str(cal), str(chk), "--out", str(tmp_path / "out")]) == 0
    names = {Path(p).name for p in capsys.readouterr().out.split()}
    assert {"checks.md", "checks.json", "checks_calibration.png", "checks_ten_cycles.png", "checks_stiffness.png",
            "checks_loops.png"} <= names
    assert (tmp_path / "out" / "checks_loops.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (tmp_path / "out" / "checks.md").read_text()
    assert "Chosen: **unvibrated**" in text and "| calibration: settlement at the peak" in text
    assert json.loads((tmp_path / "out" / "checks.json").read_text())["option_set"] == OPTION
    assert box_checks_report(cal, chk, tmp_path / "again")  # the function behind it
    assert main(["box-checks", str(cal), str(tmp_path / "nothing")]) == 2
    assert "not a campaign directory" in capsys.readouterr().err
