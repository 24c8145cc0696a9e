"""Track section: a hand-made record of 4 sleepers and 3 passages with known per-sleeper numbers.

Passage p (1..3) lasts from t = p - 1 to p s, sampled every 0.1 s. Sleeper k (0..3) settles
permanently by PERM[p, k] = 1 mm * p * (1 + k/2) after passage p; in the middle of the passage it
peaks at PERM[p, k] + 2 mm; between these corners the settlement is linear. Gaps
GAP[p, k] = p * (0, 0.2, 0, 0.05) mm: sleeper 1 is hanging after every passage (> 0.1 mm),
sleeper 3 only after passage 3 (at passage 2 its gap is exactly the 0.1 mm threshold).
"""

import json

import h5py
import numpy as np
import pytest

from pdem.format.schema import write_results
from analysis.__main__ import build_parser, main
from pdem.format.groups import read_track
from pdem.format.schema import append_passages, append_track_rows, write_forces, write_track
from analysis.track import analyse_track, exceedance, force_statistics, passage_table

X = np.array([0.0, 0.6, 1.2, 1.8])
P = np.arange(1, 4)
PERM = 1e-3 * P[:, None] * (1.0 + 0.5 * np.arange(4))[None, :]
PEAK = PERM + 2e-3
GAP = 1e-4 * P[:, None] * np.array([0.0, 2.0, 0.0, 0.5])[None, :]
FORCES = 10.0 * np.arange(1, 101)          # 10 .. 1000 N


def series():
    t = np.round(np.arange(31) * 0.1, 12)
    corners_t = [0.0]
    corners_s = [np.zeros(4)]
    for p in range(3):
        corners_t += [p + 0.5, p + 1.0]
        corners_s += [PEAK[p], PERM[p]]
    corners_s = np.array(corners_s)
    s = np.column_stack([np.interp(t, corners_t, corners_s[:, k]) for k in range(4)])
    force = 1e4 * (1.0 + s / 1e-3)
    return t, s, force


def track_file(path, gap=True, forces=True):
    t, s, force = series()
    write_results(path, {"time": t, "step": np.arange(len(t)) * 1000.0}, None,
                  {"scene": {"name": "track"}, "pdem_version": "0.1.0", "kind": "track"})
    with h5py.File(path, "r+") as f:      # the writers also take an open file
        write_track(f, X)
        append_track_rows(f, s[:10], force[:10])
        append_track_rows(f, s[10:], force[10:])
        for p in range(3):
            append_passages(f, float(p), float(p + 1), PEAK[p], PERM[p],
                            gap=GAP[p] if gap else None)
        if forces:
            write_forces(f, "peak_passage_1", step=5000, time=0.5, sleeper_ballast=FORCES,
                         sleeper_index=np.arange(100) % 4,
                         ballast_ballast=np.random.default_rng(3).exponential(200.0, 500))
            write_forces(f, "end", step=30000, time=3.0, ballast_ballast=FORCES / 10.0)
    return path


@pytest.fixture
def run(tmp_path):
    (tmp_path / "track_run").mkdir()
    return track_file(tmp_path / "track_run" / "results.h5")


def test_round_trip(run):
    rec = read_track(run)
    np.testing.assert_array_equal(rec.sleeper_x, X)
    t, s, force = series()
    np.testing.assert_array_equal(rec.settlement, s)
    np.testing.assert_array_equal(rec.force, force)
    np.testing.assert_array_equal(rec.passages["passage"], [1, 2, 3])
    np.testing.assert_array_equal(rec.passages["gap"], GAP)
    assert list(rec.forces) == ["peak_passage_1", "end"]
    assert rec.forces["end"].sleeper_ballast is None
    np.testing.assert_array_equal(rec.forces["peak_passage_1"].sleeper_index, np.arange(100) % 4)


def test_passage_table_from_the_series():
    t, s, _ = series()
    peak, perm = passage_table(t, s, [0.0, 1.0, 2.0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(peak, PEAK, rtol=1e-12)
    np.testing.assert_allclose(perm, PERM, rtol=1e-12)
    with pytest.raises(ValueError, match="passage 2 .* holds no sample"):
        passage_table(t, s, [0.0, 1.01], [1.0, 1.05])


def test_per_passage_numbers(run):
    r = analyse_track(read_track(run))
    t = r.per_passage
    np.testing.assert_allclose(t["mean_permanent"], 1.75e-3 * P, rtol=1e-12)
    np.testing.assert_allclose(t["increment"], [1.75e-3] * 3, rtol=1e-12)
    np.testing.assert_allclose(t["min_permanent"], 1e-3 * P, rtol=1e-12)
    np.testing.assert_allclose(t["max_permanent"], 2.5e-3 * P, rtol=1e-12)
    np.testing.assert_allclose(t["differential"], 0.5e-3 * P, rtol=1e-12)
    np.testing.assert_allclose(t["max_peak"], 2.5e-3 * P + 2e-3, rtol=1e-12)
    np.testing.assert_allclose(t["mean_gap"], 1e-4 * P * (0 + 2 + 0 + 0.5) / 4, rtol=1e-12)
    np.testing.assert_allclose(t["max_gap"], 0.2e-3 * P, rtol=1e-12)
    np.testing.assert_array_equal(t["hanging"], [1, 1, 2])


def test_force_statistics_by_hand():
    s = force_statistics(np.arange(1.0, 101.0))
    assert (s.n, s.mean, s.median, s.maximum) == (100, 50.5, 50.5, 100.0)
    assert s.std == pytest.approx(np.sqrt((100**2 - 1) / 12.0), rel=1e-14)
    assert (s.q95, s.q99) == pytest.approx((95.05, 99.01), rel=1e-14)
    assert s.max_over_mean == pytest.approx(100 / 50.5)
    f, frac = exceedance([3.0, 1.0, 2.0, 4.0])
    np.testing.assert_array_equal(f, [1, 2, 3, 4])
    np.testing.assert_array_equal(frac, [1.0, 0.75, 0.5, 0.25])
    assert force_statistics([]).n == 0


def test_cli_writes_all_figures_and_tables(run, capsys):
    assert main(["track", str(run.parent)]) == 0
    out = run.parent / "results-analysis"
    for name in ("track_settlement", "track_sleepers", "track_voids", "track_forces"):
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    text = (out / "track.txt").read_text().splitlines()
    row3 = next(line.split() for line in text if line.split()[:2] == ["3", "3"])
    assert [float(v) for v in row3[2:7]] == pytest.approx([5.25, 3.0, 7.5, 1.75, 1.5])
    assert float(row3[-1]) == 2                                   # hanging sleepers
    sleeper1 = next(line.split() for line in text if line.split()[:2] == ["1", "0.6000"])
    assert [float(v) for v in sleeper1[2:]] == pytest.approx([1.5, 4.5, 6.5, 0.6])
    peak1 = next(line.split() for line in text
                 if line.split()[:2] == ["peak_passage_1", "sleeper_ballast"])
    assert [float(v) for v in peak1[2:]] == pytest.approx(
        [100, 0.505, np.sqrt((100**2 - 1) / 12.0) * 1e-2, 0.505, 0.9505, 0.9901, 1.0,
         100 / 50.5], rel=1e-3)
    js = json.loads((out / "track.json").read_text())
    assert js["passages"]["hanging"] == [1, 1, 2]
    assert js["forces"]["end"]["ballast_ballast"]["n"] == 100
    assert js["settlement_permanent"][2] == pytest.approx(PERM[2].tolist())


def test_cli_without_gaps_and_forces(tmp_path, capsys):
    path = track_file(tmp_path / "t.h5", gap=False, forces=False)
    out = tmp_path / "o"
    assert main(["track", str(path), "--out", str(out), "--hanging-gap", "0.05"]) == 0
    assert not (out / "track_voids.png").exists() and not (out / "track_forces.png").exists()
    assert "(no /forces records)" in (out / "track.txt").read_text()


def test_hanging_threshold_option(run):
    args = build_parser().parse_args(["track", str(run), "--hanging-gap", "0.01"])
    assert args.hanging_gap == 0.01
    r = analyse_track(read_track(run), hanging_gap=args.hanging_gap * 1e-3)
    np.testing.assert_array_equal(r.per_passage["hanging"], [2, 2, 2])


# --- bad files and writer misuse ---

def test_rows_must_match_the_series(expect_error, run, capsys):
    with h5py.File(run, "r+") as f:
        f["track/settlement"].resize(20, axis=0)
    expect_error(read_track, run, "/track/settlement", "(20, 4)", "(31, 4)")
    assert main(["track", str(run)]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_missing_groups_and_bad_units(expect_error, tmp_path):
    path = write_results(tmp_path / "a.h5", {"time": np.arange(3.0), "step": np.arange(3.0)},
                         None, {"scene": {}, "pdem_version": "0", "kind": "box_test"})
    expect_error(read_track, path, "group /track missing", "box_test")
    path = track_file(tmp_path / "b.h5")
    with h5py.File(path, "r+") as f:
        f["passages/gap"].attrs["units"] = "mm"
    expect_error(read_track, path, "/passages/gap", "'mm'")


def test_bad_force_records(expect_error, tmp_path):
    path = track_file(tmp_path / "c.h5")
    with h5py.File(path, "r+") as f:
        f["forces/peak_passage_1/sleeper_index"][0] = 7
    expect_error(read_track, path, "/forces/peak_passage_1/sleeper_index", "0..3")
    path = track_file(tmp_path / "d.h5")
    with h5py.File(path, "r+") as f:
        f["passages/settlement_permanent"][1, 2] = np.nan
    expect_error(read_track, path, "/passages/settlement_permanent", "non-finite")


def test_writers_refuse_misuse(tmp_path):
    path = write_results(tmp_path / "w.h5", {"time": np.arange(3.0), "step": np.arange(3.0)},
                         None, {"scene": {}, "pdem_version": "0", "kind": "track"})
    with pytest.raises(ValueError, match="write_track first"):
        append_track_rows(path, np.zeros(4), np.zeros(4))
    write_track(path, X)
    with pytest.raises(ValueError, match="exists already"):
        write_track(path, X)
    with pytest.raises(ValueError, match="4 column"):
        append_track_rows(path, np.zeros((2, 3)), np.zeros((2, 3)))
    assert append_track_rows(path, np.zeros(4), np.ones(4)) == 1
    append_passages(path, 0.0, 1.0, PEAK[0], PERM[0], gap=GAP[0])
    with pytest.raises(ValueError, match="every passage or for none"):
        append_passages(path, 1.0, 2.0, PEAK[1], PERM[1])
    with pytest.raises(ValueError, match="t_end >= t_start"):
        append_passages(path, 2.0, 1.0, PEAK[1], PERM[1], gap=GAP[1])
    with pytest.raises(ValueError, match="sleeper_ballast, ballast_ballast or both"):
        write_forces(path, "x", step=0, time=0.0)
    with pytest.raises(ValueError, match="sleeper_index"):
        write_forces(path, "x", step=0, time=0.0, ballast_ballast=[1.0], sleeper_index=[0])
