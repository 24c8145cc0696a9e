"""The validation table (analysis/validation.py, docs/validation_table.md, issue #32).

Every number in pdem's column must come from a file: the committed table is regenerated from the
committed result files and compared, each numeric token of pdem's column is traced to a number an
extractor returned, and a row whose result file is missing says "not run here" and no number.
The statistics are checked against scipy's own (t interval, one-way ANOVA) and against the
tabulated d₂ constants of control charts.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from analysis import validation as V

ROOT = Path(__file__).resolve().parents[2]
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?")


@pytest.fixture(scope="module")
def built():
    rows, results, _ = V.build(V.ROWS, ROOT, do_refresh=False)
    return rows, results


def _pdem_cells(lines):
    """pdem's column (the 4th) of every row of a generated table, by row id."""
    cells = {}
    for line in lines:
        m = re.match(r"^\| \d+ `([^`]+)` \|", line)
        if m:
            cols = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
            cells[m.group(1)] = cols[3]
    return cells


def test_committed_table_is_regenerated_from_the_files(built):
    rows, results = built
    text = "\n".join(V.table_lines(results, V.ROWS)) + "\n"
    assert (ROOT / V.TABLE).read_text() == text, "docs/validation_table.md is stale: run make validate"


def test_at_least_twenty_rows_and_some_numbers(built):
    rows, results = built
    assert len(rows) >= 20
    assert sum(1 for r in results if r.samples) >= 5


def test_every_number_in_pdems_column_comes_from_an_extractor(built):
    rows, results = built
    cells = _pdem_cells((ROOT / V.TABLE).read_text().splitlines())
    assert set(cells) == {r["id"] for r in rows}
    for res in results:
        cell = cells[res.row["id"]]
        allowed = {V.fmt(x) for x in res.numbers}
        # the labels of a trend's groups are the row file's, not pdem's numbers
        body = re.sub(r"\[[^\]]*\]$", "", cell)
        parts = [p.split("→", 1)[-1] for p in body.split(";")]
        tokens = [t for p in parts for t in NUMBER.findall(p)]
        for t in tokens:
            assert t in allowed, f"{res.row['id']}: {t!r} in {cell!r} is not an extractor's number"
        if res.samples is None:
            assert tokens == [] and cell == V.NOT_RUN


def test_means_and_intervals_are_those_of_the_values(built):
    """Independent of the module's statistics: numpy's mean and scipy's t interval."""
    _, results = built
    checked = 0
    for res in results:
        for s in res.samples or []:
            if len(s.values) >= 2:
                lo, hi = stats.t.interval(0.95, len(s.values) - 1, loc=np.mean(s.values), scale=stats.sem(s.values))
                assert s.mean == pytest.approx(np.mean(s.values), rel=1e-12)
                assert s.half == pytest.approx((hi - lo) / 2, rel=1e-9)
                checked += 1
    assert checked >= 2


def _row(**kw):
    row = {"id": "x", "title": "t", "where": "w", "quote": "q", "english": "e", "comparison": "value",
           "seed": 10.0, "unit": "mm", "campaign": "jobs/campaigns/x.toml", "cost": "1 h", "differences": []}
    row.update(kw)
    return row


@pytest.mark.parametrize("pdem", [
    {"extractor": "campaign", "file": "docs/validation/nowhere/values.json", "quantity": "cycles.settlement_peak@1"},
    {"extractor": "text", "file": "docs/nowhere.txt", "pattern": r"(?P<value>\d+)"},
    {"extractor": "campaign_txt", "file": "docs/nowhere/campaign.txt", "quantity": "q"},
    {"extractor": "blast_compare", "file": "docs/nowhere/compare.txt", "plate": 244, "quantity": "I_s/I_in"},
])
def test_a_missing_run_says_not_run_here_never_a_number(tmp_path, pdem):
    res = V.evaluate(_row(pdem=pdem), tmp_path)
    assert res.cell == V.NOT_RUN
    assert not NUMBER.search(res.cell)
    assert res.verdict.startswith(V.NOT_RUN) and res.numbers == []
    line = V.table_lines([res], "rows.toml")[-1]
    assert _pdem_cells([line])["x"] == V.NOT_RUN


def test_a_group_missing_from_a_values_file_is_not_run(tmp_path):
    _values(tmp_path, {"a": [1.0, 2.0]})
    row = _row(comparison="trend", trend="increasing",
               pdem={"extractor": "campaign", "file": "v.json", "quantity": "q",
                     "groups": [{"case": "a"}, {"case": "b"}], "labels": ["a", "b"]})
    assert V.evaluate(row, tmp_path).cell == V.NOT_RUN


def _values(root, groups):
    members = [{"name": f"{c}_{i}", "params": {"case": c, "seed": i}, "results": f"runs/x/{c}_{i}/results.h5",
                "values": {"q": v}} for c, vals in groups.items() for i, v in enumerate(vals)]
    (root / "v.json").write_text(json.dumps({"format": V.VALUES_FORMAT, "members": members}))


def test_value_verdicts_follow_the_numbers(tmp_path):
    _values(tmp_path, {"a": [9.0, 10.0, 11.0, 10.5, 9.5]})
    pdem = {"extractor": "campaign", "file": "v.json", "quantity": "q", "select": {"case": "a"}}
    assert V.evaluate(_row(pdem=pdem, seed=10.2), tmp_path).verdict == "agrees within scatter"
    far = V.evaluate(_row(pdem=pdem, seed=30.0, explanation={"status": "tested", "text": "t"}), tmp_path)
    assert far.verdict == "differs, explanation tested"
    ranged = V.evaluate(_row(pdem=pdem, seed=30.0, seed_range=[5.0, 40.0]), tmp_path)
    assert ranged.verdict == "agrees within scatter"
    assert V.evaluate(_row(pdem=pdem, seed=30.0), tmp_path).verdict == "differs, explanation untested"


def test_trend_verdicts_use_anova(tmp_path):
    _values(tmp_path, {"a": [1.0, 1.1, 0.9, 1.05], "b": [2.0, 2.1, 1.9, 2.05], "c": [1.02, 0.98, 1.1, 0.95]})
    def row(trend, groups):
        return _row(comparison="trend", trend=trend, pdem={"extractor": "campaign", "file": "v.json", "quantity": "q",
                                                           "groups": [{"case": g} for g in groups], "labels": groups})
    assert V.evaluate(row("increasing", ["a", "b"]), tmp_path).verdict == "agrees within scatter"
    assert V.evaluate(row("decreasing", ["a", "b"]), tmp_path).verdict.startswith("differs")
    assert V.evaluate(row("equal", ["a", "c"]), tmp_path).verdict == "agrees within scatter"
    assert V.evaluate(row("differ", ["a", "c"]), tmp_path).verdict.startswith("differs")


def test_anova_from_summaries_is_scipys_one_way_anova():
    rng = np.random.default_rng(3)
    groups = [rng.normal(m, 1.0, n) for m, n in ((0.0, 5), (0.8, 7), (0.3, 4))]
    samples = [V.sample_of(g) for g in groups]
    assert V.anova(samples) == pytest.approx(stats.f_oneway(*groups).pvalue, rel=1e-9)


@pytest.mark.parametrize("n, d2", [(2, 1.128), (5, 2.326), (10, 3.078)])
def test_expected_range_is_the_tabulated_d2(n, d2):
    assert V.expected_range(n) == pytest.approx(d2, abs=6e-4)


def test_summary_samples_recover_the_t_interval():
    s = V.sample_from_summary("x", 5, 1.0, std=0.1)
    assert s.half == pytest.approx(stats.t.ppf(0.975, 4) * 0.1 / np.sqrt(5), rel=1e-12)
    back = V.sample_from_summary("x", 5, 1.0, half=s.half)
    assert back.std == pytest.approx(0.1, rel=1e-12)


def test_bad_row_file_is_one_line_exit_2(tmp_path):
    bad = tmp_path / "rows.toml"
    bad.write_text('[[row]]\nid = "a"\ntitle = "t"\nwhere = "w"\nquote = "q"\nenglish = "e"\n'
                   'comparison = "maybe"\ncampaign = "c"\ncost = "1"\n[row.pdem]\nextractor = "none"\n')
    p = subprocess.run([sys.executable, "-m", "analysis", "validate", "--rows", str(bad), "--root", str(tmp_path),
                        "--out", str(tmp_path / "t.md")], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "comparison = 'maybe'" in p.stderr and "Traceback" not in p.stderr


def test_cost_projection_is_steps_over_the_measured_rate():
    p = V.project(steps_done=2000, wall_s=4.0, ranks=2, steps_needed=7.0e6)
    assert p.wall_needed_s == pytest.approx(7.0e6 / 500.0)
    assert p.core_hours == pytest.approx(2 * 7.0e6 / 500.0 / 3600.0)
    with pytest.raises(V.ValidationError):
        V.project(0, 1.0, 1, 10)


def _track_file(path):
    """Two passages of a haversine 0 -> 2 kN -> 0 on two sleepers whose settlement follows the load
    with a lag of 0.1 s (so the largest settlement comes after the largest load)."""
    import h5py

    from pdem.format.schema import append_passages, append_track_rows, write_results, write_track

    t = np.round(np.arange(201) * 0.01, 12)
    load = 1e3 * (1.0 - np.cos(2.0 * np.pi * t))
    lagged = 1e3 * (1.0 - np.cos(2.0 * np.pi * np.clip(t - 0.1, 0.0, None)))
    s = np.column_stack([1e-6 * lagged, 2e-6 * lagged]) + 1e-3 * (t >= 1.0)[:, None]
    write_results(path, {"time": t, "step": np.arange(len(t)) * 10.0, "applied_load": (load, "N")}, None,
                  {"scene": {"name": "track"}, "pdem_version": "0.1.0", "kind": "track"})
    with h5py.File(path, "r+") as f:
        write_track(f, np.array([0.0, 0.6]))
        append_track_rows(f, s, 10.0 * s)
        for k in range(2):
            inside = (t >= k) & (t <= k + 1)
            append_passages(f, float(k), float(k + 1), s[inside].max(axis=0), s[inside][-1])
    return t, load, s


def test_track_quantities_are_the_passage_table_and_the_settlement_at_the_largest_load(tmp_path):
    from types import SimpleNamespace

    path = tmp_path / "results.h5"
    t, load, s = _track_file(path)
    member = SimpleNamespace(results_path=path)
    second = (t >= 1.0) & (t <= 2.0)
    assert V.member_quantity(member, "track.settlement_peak@2") == pytest.approx(s[second].max(axis=0).mean())
    assert V.member_quantity(member, "track.settlement_permanent@2") == pytest.approx(s[second][-1].mean())
    at = np.flatnonzero(second)[np.argmax(load[second])]
    assert V.member_quantity(member, "track.settlement_at_max_load@2") == pytest.approx(s[at].mean())
    first = V.member_quantity(member, "track.settlement_at_max_load@1")
    assert first < V.member_quantity(member, "track.settlement_peak@1")  # the settlement lags the load
    assert np.isnan(V.member_quantity(member, "track.settlement_peak@3"))
    with pytest.raises(V.ValidationError):
        V.member_quantity(member, "track.gap@1")


def test_cost_of_a_stopped_run_from_its_log(tmp_path):
    """A run stopped by a signal has no run_info.json: its log's last progress line (lines as a run
    stopped with timeout -s TERM printed them, 2026-12-07) gives the rate of the stage it was in."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "log.txt").write_text(
        "# pdem 0.2.0, 2026-12-07 10:00:00 UTC: pdem run old.toml --out run\n"
        "pdem 0.2.0: oedometer old.toml on 2 rank(s); stages pour, refill, vibrate, settle, load\n"
        "stage pour: 10 spheres, t = 0.0000 s, dt = 1.000e-05 s\n"
        "stage 1/5 pour  step      2000  t = 2.0e-02 s  dt = 1.000e-05 s  contacts/particle = 1.00  "
        "9.99 M particle-steps/s  ETA 1 s\n"
        "# pdem 0.2.0, 2026-12-07 15:52:41 UTC: pdem run scene.toml --out run\n"
        "pdem 0.2.0: oedometer scene.toml on 1 rank(s); stages pour, refill, vibrate, settle, load\n"
        "stage pour: 24344 spheres, t = 0.0000 s, dt = 2.255e-07 s; poured 179 breakable clumps of 136 spheres\n"
        "numba: the first step took 0.1 s (compilation or cache load)\n"
        "stage 1/5 pour  step      2000  t = 4.51058e-04 s  dt = 2.255e-07 s  contacts/particle = 4.59  "
        "1.08 M particle-steps/s  ETA ≥ 49867 s\n"
        "stage pour done at t = 1.5000 s, step 3000: unbalanced force ratio 0.01, bed top 200.0 mm\n"
        "stage refill: 10200 spheres, t = 1.5000 s, dt = 2.255e-07 s; removed\n"
        "stage 2/5 refill  step      4000  t = 9.02115e-04 s  dt = 2.000e-07 s  contacts/particle = 4.59  "
        "1.02 M particle-steps/s  ETA ≥ 50774 s\n"
        "step 4600: stop signal received; writing a checkpoint and stopping (exit status 3)\n")
    steps, wall, ranks, dt, stage = V.stopped_run_rate(run)
    assert (steps, ranks, dt, stage) == (1000, 1, 2.0e-7, "refill")
    assert wall == pytest.approx(1000 * 10200 / 1.02e6)
    steps, wall, _, dt, _ = V.stopped_run_rate(run, "pour")
    assert (steps, dt) == (2000, 2.255e-7) and wall == pytest.approx(2000 * 24344 / 1.08e6)
    p = V.project_run(run, steps=1.0e6)
    assert p.wall_needed_s == pytest.approx(1.0e6 * 10200 / 1.02e6) and p.core_hours == pytest.approx(
        p.wall_needed_s / 3600)
    assert V.project_run(run, simulated_time=0.2).steps_needed == pytest.approx(0.2 / 2.0e-7)
    with pytest.raises(V.ValidationError, match="progress line"):
        V.stopped_run_rate(run, "load")
    with pytest.raises(V.ValidationError, match="log.txt"):
        V.project_run(tmp_path, steps=1.0)


def test_a_refresh_keeps_the_members_finished_elsewhere():
    """A values file gathers a campaign's members across sessions and machines: a refresh from a
    runs/ directory holding only some members keeps the others (same name and parameters), takes
    the fresh values of those run again, and drops members the campaign no longer has or whose
    parameters changed."""
    old = {"members": [{"name": "a_seed-1", "params": {"case": "a", "seed": 1}, "values": {"q": 1.0}},
                       {"name": "b_seed-1", "params": {"case": "b", "seed": 1}, "values": {"q": 2.0}},
                       {"name": "c_seed-1", "params": {"case": "c", "seed": 1}, "values": {"q": 3.0}},
                       {"name": "gone_seed-1", "params": {"case": "gone", "seed": 1}, "values": {"q": 4.0}}]}
    new = [{"name": "b_seed-1", "params": {"case": "b", "seed": 1}, "values": {"q": 20.0}},
           {"name": "d_seed-1", "params": {"case": "d", "seed": 1}, "values": {"q": 5.0}}]
    campaign = [("a_seed-1", {"case": "a", "seed": 1}), ("b_seed-1", {"case": "b", "seed": 1}),
                ("c_seed-1", {"case": "c", "seed": 1, "x": 0.5}), ("d_seed-1", {"case": "d", "seed": 1})]
    got = V.merged_members(old, new, campaign)
    assert [(m["name"], m["values"]["q"]) for m in got] == [("a_seed-1", 1.0), ("b_seed-1", 20.0), ("d_seed-1", 5.0)]
    assert V.merged_members(None, new, campaign) == new
