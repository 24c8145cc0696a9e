"""``python -m analysis campaign`` and ``error-vs-runtime`` on synthetic campaign directories:
a manifest as pdem campaign writes it, member directories with results.h5 (pdem.format.schema's
write_results) and run.json, and known answers."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sps

from analysis.__main__ import main
from analysis.campaign import CampaignError, Quantity, campaign_report, envelope, read_campaign
from analysis.error_vs_runtime import error_report, select_reference
from pdem.format.schema import write_results

_spec = importlib.util.spec_from_file_location("analysis_records", Path(__file__).with_name("conftest.py"))
records = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(records)
ATTRS = records.ATTRS


def member_dir(root, name, series, cycles, wall_s=10.0, ranks=1, threads=1, exit_status=0):
    d = root / name
    d.mkdir(parents=True)
    write_results(d / "results.h5", series, cycles, ATTRS)
    a = {"start": "t0", "end": "t1", "wall_s": wall_s, "exit": exit_status, "ranks": ranks, "threads": threads,
         "core_s": wall_s * ranks * threads}
    (d / "run.json").write_text(json.dumps({"member": name, "attempts": [a], "wall_s": wall_s,
                                            "core_s": a["core_s"], "exit": exit_status}))
    return d


def manifest(root, members, seed_key="box_test.seed", varied=None, cases=False, analysis=None):
    man = {"format": "pdem-campaign", "version": 1, "name": root.name, "seed_key": seed_key,
           "varied": varied or [seed_key], "cases": cases, "analysis": analysis or {},
           "members": [{"name": n, "dir": n, "params": p, "ranks": r, "threads": 1} for n, p, r in members]}
    (root / "campaign.json").write_text(json.dumps(man))


def flat_record(peaks, n=3):
    """A short record whose /cycles table has the given settlement_peak per cycle [m]."""
    peaks = np.asarray(peaks, float)
    k = len(peaks)
    t = np.linspace(0.0, k, 20 * k + 1)
    load = 1e3 * (1 - np.cos(2 * np.pi * t))
    series = dict(time=t, step=np.arange(len(t)) * 10.0, sleeper_load=load, sleeper_force=load.copy(),
                  sleeper_settlement=np.interp(t, np.arange(1, k + 1), peaks))
    cycles = dict(cycle=np.arange(1.0, k + 1), t_start=np.arange(0.0, k), settlement_start=peaks * 0.5,
                  settlement_peak=peaks, settlement_end=peaks * 0.9, force_peak=np.full(k, 2e3), force_min=np.zeros(k))
    return series, cycles


def seed_campaign(tmp_path, values, extra_stopped=True):
    root = tmp_path / "seeds"
    root.mkdir()
    entries = []
    for s, v in enumerate(values, start=1):
        name = f"seed-{s:02d}"
        series, cycles = flat_record([0.5 * v, 0.8 * v, v])
        member_dir(root, name, series, cycles, wall_s=10.0 + s)
        entries.append((name, {"box_test.seed": s}, 1))
    if extra_stopped:
        series, cycles = flat_record([1.0, 1.0, 1.0])
        member_dir(root, "seed-99", series, cycles, exit_status=3)  # stopped: must not be used
        entries.append(("seed-99", {"box_test.seed": 99}, 1))
    manifest(root, entries)
    return root


def test_seed_variability_with_known_answers(tmp_path):
    v = np.array([0.0102, 0.0111, 0.0097, 0.0120, 0.0105])  # settlement at the peak of the last cycle [m]
    root = seed_campaign(tmp_path, v)
    written = campaign_report(root, ["cycles.settlement_peak@last", "cycles.settlement_peak@1"],
                              ["cycles.settlement_peak", "series.sleeper_settlement"])
    names = {p.name for p in written}
    assert {"campaign.txt", "campaign.json", "variability_cycles_settlement_peak_last.png",
            "envelope_cycles_settlement_peak.png", "envelope_series_sleeper_settlement.png"} <= names
    for p in written:
        assert p.exists() and (p.suffix != ".png" or p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n")
    data = json.loads((root / "analysis" / "campaign.json").read_text())
    assert data["not_done"] == ["seed-99"] and len(data["members"]) == 5
    (g,) = data["groups"]
    s = g["stats"]["cycles.settlement_peak@last"]
    half = sps.t.ppf(0.975, 4) * v.std(ddof=1) / np.sqrt(5)
    assert s["n"] == 5 and s["mean"] == pytest.approx(v.mean(), rel=1e-12)
    assert s["std"] == pytest.approx(v.std(ddof=1), rel=1e-12) and s["cov"] == pytest.approx(v.std(ddof=1) / v.mean())
    assert (s["ci_low"], s["ci_high"]) == pytest.approx((v.mean() - half, v.mean() + half), rel=1e-12)
    assert (s["min"], s["max"]) == (v.min(), v.max())
    assert g["stats"]["cycles.settlement_peak@1"]["mean"] == pytest.approx(0.5 * v.mean())
    text = (root / "analysis" / "campaign.txt").read_text()
    assert "not used (not done): seed-99 (exit 3)" in text and f"{1e3 * v.mean():.6g}" in text


def test_envelope_of_curves():
    x, mean, lo, hi = envelope([([1, 2, 3], [1.0, 2.0, 3.0]), ([1, 2], [3.0, 0.0])], per_cycle=True)
    assert x.tolist() == [1, 2] and mean.tolist() == [2.0, 1.0]
    assert lo.tolist() == [1.0, 0.0] and hi.tolist() == [3.0, 2.0]
    x, mean, lo, hi = envelope([([0.0, 2.0], [0.0, 2.0]), ([0.0, 1.0], [1.0, 1.0])], per_cycle=False, n_grid=3)
    assert x.tolist() == [0.0, 0.5, 1.0] and lo.tolist() == [0.0, 0.5, 1.0] and hi.tolist() == [1.0, 1.0, 1.0]


def test_parameter_study(tmp_path):
    root = tmp_path / "grid"
    root.mkdir()
    entries, expect = [], {}
    for young in (1e6, 1e7):
        for seed in (1, 2, 3):
            name = f"young-{young:g}_seed-{seed}"
            v = 0.01 * (1e7 / young) ** 0.5 + 1e-4 * seed
            series, cycles = flat_record([v, v])
            member_dir(root, name, series, cycles)
            entries.append((name, {"materials.ballast.young": young, "box_test.seed": seed}, 1))
            expect.setdefault(young, []).append(v)
    manifest(root, entries, varied=["materials.ballast.young", "box_test.seed"],
             analysis={"quantities": ["cycles.settlement_peak@last"], "curves": []})
    assert main(["campaign", str(root)]) == 0  # quantities and curves from the manifest
    data = json.loads((root / "analysis" / "campaign.json").read_text())
    assert [g["params"] for g in data["groups"]] == [{"materials.ballast.young": 1e6}, {"materials.ballast.young": 1e7}]
    for g in data["groups"]:
        vals = expect[g["params"]["materials.ballast.young"]]
        assert g["stats"]["cycles.settlement_peak@last"]["mean"] == pytest.approx(np.mean(vals), rel=1e-12)
    assert (root / "analysis" / "param_materials_ballast_young_cycles_settlement_peak_last.png").exists()
    assert not list((root / "analysis").glob("envelope_*"))


def test_quantities_of_a_box_record(tmp_path):
    rec = records.make_box_record(n_cycles=5)
    root = tmp_path / "box"
    root.mkdir()
    member_dir(root, "m", rec.series, rec.cycles)
    manifest(root, [("m", {"box_test.seed": 1}, 1)])
    (m,) = read_campaign(root).members
    assert Quantity.parse("cycles.settlement_peak@2").value(m) == rec.cycles["settlement_peak"][1]
    assert Quantity.parse("cycles.settlement_peak@-2").value(m) == rec.cycles["settlement_peak"][3]
    assert Quantity.parse("cycles.settlement_end").value(m) == rec.cycles["settlement_end"][-1]
    assert np.isnan(Quantity.parse("cycles.settlement_end@9").value(m))
    assert Quantity.parse("series.sleeper_settlement@max").value(m) == rec.series["sleeper_settlement"].max()
    assert Quantity.parse("stiffness.unloading@3").value(m) == pytest.approx(rec.k_unload[2], rel=1e-9)
    assert Quantity.parse("settlement.plastic@4").value(m) == pytest.approx(rec.plastic[3], rel=1e-12)
    assert Quantity.parse("stiffness.unloading@3").units(m) == "N/m"
    for bad in ("cycles.settlement_peak@0", "series.time@3", "stiffness.elastic@1", "foo.bar", "cycles.x@median"):
        with pytest.raises(CampaignError):
            Quantity.parse(bad)
    with pytest.raises(CampaignError, match="no /cycles/nonexistent"):
        Quantity.parse("cycles.nonexistent").value(m)


# ---------------------------------------------------------------------------- error vs run time
def error_campaign(tmp_path):
    """reference: 3 seeds, 10, 11, 12 mm, 100 s on 2 ranks; fast: 12.1 mm twice, 10 s; close: 11.5 mm, 20 s."""
    root = tmp_path / "evr"
    root.mkdir()
    entries = []
    settings = (("reference", [10e-3, 11e-3, 12e-3], 100.0, 2), ("fast", [12.1e-3, 12.1e-3], 10.0, 1),
                ("close", [11.5e-3], 20.0, 1))
    for case, vals, wall, ranks in settings:
        for seed, v in enumerate(vals, start=1):
            name = f"{case}_seed-{seed}"
            series, cycles = flat_record([v / 2, v])
            member_dir(root, name, series, cycles, wall_s=wall, ranks=ranks)
            entries.append((name, {"case": case, "box_test.seed": seed}, ranks))
    manifest(root, entries, cases=True, analysis={"reference": "reference", "quantities": ["cycles.settlement_peak@2"]})
    return root


def test_error_against_run_time_known_answers(tmp_path):
    root = error_campaign(tmp_path)
    written = error_report(root, ["cycles.settlement_peak@last"], "reference")
    assert [p.name for p in written] == ["error_vs_runtime.txt", "error_vs_runtime.json", "error_vs_runtime.png"]
    data = json.loads((root / "analysis" / "error_vs_runtime.json").read_text())
    (t,) = data["quantities"]
    assert t["q_ref"] == pytest.approx(11e-3) and t["s_ref"] == pytest.approx(1e-3) and t["n_ref"] == 3
    assert t["floor"] == pytest.approx(1 / 11)
    rows = {r["group"]: r for r in t["rows"]}
    ref, fast, close = rows["case = reference"], rows["case = fast"], rows["case = close"]
    assert ref["reference"] and ref["abs_error"] == pytest.approx(0, abs=1e-12) and ref["wall_s"] == 100.0
    assert ref["core_h"] == pytest.approx(200 / 3600)
    assert fast["error"] == pytest.approx(0.1) and fast["speedup"] == pytest.approx(10.0)
    assert fast["floor"] == pytest.approx(np.sqrt(1 / 2 + 1 / 3) / 11) and fast["noise"] is False
    assert close["abs_error"] == pytest.approx(0.5 / 11) and close["noise"] is True and close["speedup"] == 5.0
    assert close["core_h"] == pytest.approx(20 / 3600)
    # no CPU time measured in these records: the cost is wall x ranks x threads (reference on 2 ranks)
    assert fast["cost_ratio"] == pytest.approx(20.0) and close["cost_ratio"] == pytest.approx(10.0)
    assert ref["member_errors"] == pytest.approx([1 / 11, 0, 1 / 11])
    text = (root / "analysis" / "error_vs_runtime.txt").read_text()
    assert "q_ref = 11 mm" in text and "10.00" in text


def test_error_vs_runtime_command_line(tmp_path, capsys):
    root = error_campaign(tmp_path)
    assert main(["error-vs-runtime", str(root)]) == 0  # reference and quantity from the manifest
    assert "error_vs_runtime.png" in capsys.readouterr().out
    assert main(["error-vs-runtime", str(root), "-r", "case=fast", "-q", "series.sleeper_settlement@max"]) == 0
    assert main(["error-vs-runtime", str(root), "-r", "slow"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "reference 'slow' matches 0 groups" in err
    assert main(["error-vs-runtime", str(tmp_path / "nothing")]) == 2
    assert "not a campaign directory" in capsys.readouterr().err
    assert main(["campaign", str(root), "-q", "cycles.settlement_peak@zero"]) == 2
    assert "must be a cycle number" in capsys.readouterr().err


def test_reference_selectors(tmp_path):
    from analysis.campaign import Group

    groups = [Group({"case": "a", "simulation.damping": 0.2}, []), Group({"case": "a", "simulation.damping": 0.3}, []),
              Group({"case": "b", "simulation.damping": 0.2}, [])]
    assert select_reference(groups, "a,damping=0.3") is groups[1]
    assert select_reference(groups, {"case": "b"}) is groups[2]
    assert select_reference(groups, "case=a,simulation.damping=0.2") is groups[0]
    with pytest.raises(CampaignError, match="matches 2 groups"):
        select_reference(groups, "damping=0.2")
