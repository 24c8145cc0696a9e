"""Track section with turning sleepers: a hand-made record of 6 sleepers and 8 passages whose
per-sleeper numbers are known in closed form (the analysis of `analysis.track` against them).

Sleeper k (0..5) settles permanently by S_k(N) = A_k + B_k log10 N after passage N (1..8), with
A_k = 0.5 mm (1 + k/5), B_k = 1 mm (1 + k/10): the fit S = a + b log10 N of every sleeper must give
A_k, B_k back (exact data: rms residual ~ 0), and so must the fit of the mean (mean A, mean B).
Tilts: tilt_x = 1 mrad k + 0.2 mrad N, tilt_y = -1 mrad k N, so the drift (last passage less
first) is 1.4 mrad about x for every sleeper and -7 k mrad about y. Voids under the end thirds:
gap_lo = 0.1 mm k, gap_hi = 0.05 mm N; load share 0.4 + 0.05 k.
"""

import json

import h5py
import numpy as np
import pytest

from analysis.__main__ import main
from analysis.track import analyse_track, tilt_drift
from pdem.format.groups import read_track
from pdem.format.schema import append_passages, append_track_rows, write_results, write_track

K = np.arange(6)
N = np.arange(1, 9)
A = 0.5e-3 * (1.0 + K / 5.0)
B = 1e-3 * (1.0 + K / 10.0)
PERM = A[None, :] + B[None, :] * np.log10(N)[:, None]
TILT_X = 1e-3 * K[None, :] + 2e-4 * N[:, None]
TILT_Y = -1e-3 * K[None, :] * N[:, None]
GAP_LO = np.broadcast_to(1e-4 * K[None, :], PERM.shape)
GAP_HI = np.broadcast_to(5e-5 * N[:, None], PERM.shape)
SHARE = np.broadcast_to(0.4 + 0.05 * K[None, :], PERM.shape)


def turning_file(path):
    t = np.arange(len(N) + 1, dtype=float)  # a sample at the start and at the end of every passage
    s = np.vstack([np.zeros(len(K)), PERM])
    write_results(path, {"time": t, "step": 1000.0 * t}, None,
                  {"scene": {"name": "track"}, "pdem_version": "0.2.0", "kind": "track"})
    with h5py.File(path, "r+") as f:
        write_track(f, 0.3 * K + 0.15)
        append_track_rows(f, s, np.full_like(s, 1e3))
        for i in range(len(N)):
            append_passages(f, float(i), float(i + 1), PERM[i] + 1e-3, PERM[i], gap=np.zeros(len(K)),
                            load_peak=np.full(len(K), 500.0), settlement_lo=PERM[i], settlement_hi=PERM[i],
                            tilt_x=TILT_X[i], tilt_y=TILT_Y[i], gap_lo=GAP_LO[i], gap_hi=GAP_HI[i],
                            load_share=SHARE[i])
    return path


@pytest.fixture
def run(tmp_path):
    (tmp_path / "turning").mkdir()
    return turning_file(tmp_path / "turning" / "results.h5")


def test_fits_per_sleeper_give_the_log_law_back(run):
    r = analyse_track(read_track(run))
    assert len(r.fits_per_sleeper) == len(K)
    for k, fits in enumerate(r.fits_per_sleeper):
        f = fits.forms["a + b log10 N"]
        assert f["a"] == pytest.approx(A[k], rel=1e-8) and f["b"] == pytest.approx(B[k], rel=1e-8)
        assert f["rms"] < 1e-12
        assert fits.forms["a N^b"]["rms"] > 1e-6  # a log law is not a power law
    mean = r.fits.forms["a + b log10 N"]
    assert (mean["a"], mean["b"]) == pytest.approx((A.mean(), B.mean()), rel=1e-8)


def test_tilt_drift(run):
    dx, dy = tilt_drift(read_track(run).passages)
    np.testing.assert_allclose(dx, 1.4e-3, rtol=1e-12)
    np.testing.assert_allclose(dy, -7e-3 * K, rtol=1e-12, atol=1e-15)


def test_cli_writes_the_turning_figures_and_tables(run, capsys):
    assert main(["track", str(run.parent)]) == 0
    out = run.parent / "results-analysis"
    for name in ("track_tilt", "track_turning_passages", "track_shares", "track_passages", "track_settlement"):
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    text = (out / "track.txt").read_text().splitlines()
    head = next(i for i, line in enumerate(text) if line.startswith("permanent settlement of each sleeper"))
    rows = [line.split() for line in text[head + 3: head + 3 + len(K)]]
    for k, row in enumerate(rows):  # sleeper, a, b [mm], rms [mm], power law a, b, rms
        assert int(row[0]) == k
        assert [float(v) for v in row[1:3]] == pytest.approx([A[k] * 1e3, B[k] * 1e3], abs=1e-4)
        assert float(row[3]) == pytest.approx(0.0, abs=1e-4)
    turning = next(i for i, line in enumerate(text) if line.startswith("turning sleepers after passage 8"))
    row5 = text[turning + 3 + 5].split()  # sleeper 5: tilt_x, tilt_y, dtilt_x, dtilt_y [mrad], ..., share
    assert [float(v) for v in row5[1:5]] == pytest.approx([5.0 + 1.6, -40.0, 1.4, -35.0], abs=1e-4)
    assert float(row5[-1]) == pytest.approx(0.65)
    js = json.loads((out / "track.json").read_text())
    assert js["fits_per_sleeper"][3]["a + b log10 N"]["b"] == pytest.approx(B[3], rel=1e-8)
    assert js["tilt_drift"]["tilt_y"] == pytest.approx((-7e-3 * K).tolist(), abs=1e-15)
