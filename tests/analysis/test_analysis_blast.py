"""Blast layer: impulse of a triangular ceiling-stress pulse (closed form), input impulse,
amplification, plate motion, the comparison of runs, bad files and the command line.

The synthetic record (samples every 10 us over 9 ms): the paper's load F0 (1 - t/tau) with
F0 = 9 MN, tau = 0.1 ms on a 0.09 m^2 ceiling (input impulse 5000 Pa s); on the ceiling a static
stress S0 plus a triangle rising from 1 ms to its peak S at 2 ms and back to 0 at 4 ms, so that
I_s = S (4 - 1) ms / 2 + S0 * 9 ms exactly (the trapezoidal rule is exact on a polyline sampled
at its corners). The plate sinks by A = 2 mm along a half sine over 4 ms, then rises at 1 m/s.
"""

import json
import math

import h5py
import numpy as np
import pytest

from pdem.format.schema import write_results
from analysis.__main__ import main
from analysis.blast import (PAPER, PAPER_INPUT_IMPULSE, analyse_blast, compare_blast,
                            cumulative_trapezoid)
from pdem.format.groups import read_blast
from pdem.format.schema import write_blast_parameters

F0, TAU, AREA = 9.0e6, 1.0e-4, 0.09
S0, S, A = 2.0e3, 4.0e6, 2.0e-3
T1, TP, T2, T_PLATE = 1e-3, 2e-3, 4e-3, 4e-3


def blast_series(scale=1.0):
    i = np.arange(901)
    t = i * 1e-5
    tri = np.interp(i, [0, 100, 200, 400, 900], [0.0, 0.0, S, 0.0, 0.0]) * scale
    sink = t <= T_PLATE
    z = np.where(sink, 0.3 - A * np.sin(np.pi * t / T_PLATE), 0.3 + 1.0 * (t - T_PLATE))
    v = np.where(sink, -A * np.pi / T_PLATE * np.cos(np.pi * t / T_PLATE), 1.0)
    force = np.where(i <= 10, F0 * (1.0 - i / 10), 0.0)
    return dict(time=t, step=i * 10.0, plate_position=z, plate_velocity=v,
                ceiling_stress=S0 + tri, input_force=force)


def blast_file(path, areal_mass=2700.0, scale=1.0, params=True):
    write_results(path, blast_series(scale), None,
                  {"scene": {"name": "blast"}, "pdem_version": "0.1.0", "kind": "blast"})
    if params:
        write_blast_parameters(path, plate_areal_mass=areal_mass, ceiling_area=AREA, F0=F0,
                               tau=TAU)
    return path


@pytest.fixture
def run(tmp_path):
    return blast_file(tmp_path / "results.h5")


def test_triangular_pulse_impulse_in_closed_form(run):
    r = analyse_blast(*read_blast(run))
    dynamic = S * (T2 - T1) / 2.0                     # 6000 Pa s
    assert r.impulse_dynamic == pytest.approx(dynamic, rel=1e-9)
    assert r.impulse == pytest.approx(dynamic + S0 * 9e-3, rel=1e-9)
    assert r.static_stress == S0
    assert r.input_impulse == pytest.approx(5000.0, rel=1e-15)
    assert r.input_impulse_series == pytest.approx(5000.0, rel=1e-12)
    assert r.amplification == pytest.approx((dynamic + S0 * 9e-3) / 5000.0, rel=1e-9)
    assert r.amplification_dynamic == pytest.approx(1.2, rel=1e-9)
    assert (r.peak_stress, r.peak_time) == pytest.approx((S0 + S, TP))
    assert r.arrival_time == pytest.approx(T1 + 0.05 * (TP - T1), abs=1.01e-5)
    assert (r.plate_drop, r.plate_drop_time) == pytest.approx((A, T_PLATE / 2), rel=1e-9)
    assert r.plate_velocity_end == 1.0
    assert r.paper == (2700.0, 7960.0, 1.59)
    assert r.cumulative_impulse[100] == pytest.approx(S0 * 1e-3, rel=1e-9)


def test_until_limits_the_integral(run):
    r = analyse_blast(*read_blast(run), until=TP)
    assert r.impulse_dynamic == pytest.approx(S * (TP - T1) / 2.0, rel=1e-9)
    assert r.until == pytest.approx(TP)
    with pytest.raises(ValueError, match="fewer than 2 samples"):
        analyse_blast(*read_blast(run), until=-1.0)


def test_cumulative_trapezoid_of_a_line():
    t = np.linspace(0.0, 2.0, 5)
    np.testing.assert_allclose(cumulative_trapezoid(3.0 * t, t), 1.5 * t**2, rtol=1e-15)


def test_paper_values_are_consistent():
    """I_in = F0 tau / 2 / area = 5e-3 MPa s; amplification = I_s / I_in to the paper's digits,
    1.59 for both heavy plates and 1.78 for the light one."""
    assert F0 * TAU / 2 / AREA == pytest.approx(PAPER_INPUT_IMPULSE, rel=1e-12)
    for impulse, amplification in PAPER.values():
        assert round(impulse / PAPER_INPUT_IMPULSE, 2) == amplification
    assert PAPER[10780.0][1] == PAPER[2700.0][1] == 1.59 and PAPER[244.0][1] == 1.78


def test_compare_groups_plates_mean_and_scatter(tmp_path):
    runs = [blast_file(tmp_path / f"r{i}.h5", m, s)
            for i, (m, s) in enumerate([(244.0, 1.0), (244.0, 1.2), (10780.0, 1.0)])]
    groups = compare_blast([analyse_blast(*read_blast(p)) for p in runs])
    assert [g.plate_areal_mass for g in groups] == [10780.0, 244.0]
    light = groups[1]
    i1, i2 = 6000.0 + S0 * 9e-3, 7200.0 + S0 * 9e-3
    e = light.stats["impulse"]
    assert light.n == 2 and e["mean"] == pytest.approx((i1 + i2) / 2)
    assert e["std"] == pytest.approx(abs(i2 - i1) / math.sqrt(2))
    assert (e["min"], e["max"]) == pytest.approx((i1, i2))
    assert e["ci_low"] < e["mean"] < e["ci_high"]
    assert math.isnan(groups[0].stats["impulse"]["std"]) and groups[0].paper[1] == 7970.0


def test_cli_one_run(run, capsys):
    assert main(["blast", str(run.parent)]) == 0
    out = run.parent / "results-analysis"
    assert (out / "blast.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    js = json.loads((out / "blast.json").read_text())
    assert js["impulse_dynamic"] == pytest.approx(6000.0, rel=1e-9)
    assert js["paper"]["impulse"] == 7960.0
    text = (out / "blast.txt").read_text()
    assert "I_s/I_in" in text and "paper (plate 2700 kg/m^2)" in text


def test_cli_several_runs(tmp_path, capsys):
    runs = []
    for name, mass in (("heavy", 10780.0), ("light", 244.0)):
        (tmp_path / name).mkdir()
        runs.append(str(blast_file(tmp_path / name / "results.h5", mass).parent))
    assert main(["blast", *runs]) == 2
    assert "need --out" in capsys.readouterr().err
    out = tmp_path / "cmp"
    assert main(["blast", *runs, "--out", str(out)]) == 0
    for name in ("heavy", "light"):
        assert (out / name / "blast.png").is_file()
    assert (out / "blast_compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "blast_compare.txt").read_text()
    assert "plate 244 kg/m^2: 1 run(s)" in text and "plate 10780 kg/m^2: 1 run(s)" in text
    js = json.loads((out / "blast_compare.json").read_text())
    assert [p["plate_areal_mass"] for p in js["plates"]] == [10780.0, 244.0]


# --- bad files ---

def test_missing_parameters_group(expect_error, tmp_path, capsys):
    path = blast_file(tmp_path / "b.h5", params=False)
    expect_error(read_blast, path, "group /blast missing")
    assert main(["blast", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/blast missing" in err


def test_missing_or_wrong_series(expect_error, tmp_path):
    series = {k: v for k, v in blast_series().items() if k != "ceiling_stress"}
    path = write_results(tmp_path / "b.h5", series, None,
                         {"scene": {}, "pdem_version": "0", "kind": "blast"})
    expect_error(read_blast, path, "/series/ceiling_stress", "missing")
    path = blast_file(tmp_path / "c.h5")
    with h5py.File(path, "r+") as f:
        f["series/ceiling_stress"].attrs["units"] = "MPa"
    expect_error(read_blast, path, "/series/ceiling_stress", "'MPa'")


def test_bad_parameter_and_non_finite_series(expect_error, tmp_path):
    path = blast_file(tmp_path / "b.h5")
    with h5py.File(path, "r+") as f:
        f["blast"].attrs["tau"] = -1.0
    expect_error(read_blast, path, "tau", "> 0")
    path = blast_file(tmp_path / "c.h5")
    with h5py.File(path, "r+") as f:
        f["series/plate_velocity"][5] = np.inf
    expect_error(read_blast, path, "/series/plate_velocity", "non-finite")
    with pytest.raises(ValueError, match="finite and > 0"):
        write_blast_parameters(path, plate_areal_mass=0.0, ceiling_area=AREA, F0=F0, tau=TAU)


def test_layer_stiffness_and_the_one_degree_of_freedom_model(tmp_path):
    """A heavy plate (mu = 10 780 kg/m^2) on a massless linear layer (k_A = 2e8 Pa/m), hit by the
    input impulse I_in: d(t) = I_in sin(wt)/(mu w), sigma_0 = S0 + k_A d, w = sqrt(k_A/mu). The
    analysis finds k_A from the record, and the impulse it integrates is I_in (1 - cos wT)."""
    mu, k_a = 10780.0, 2.0e8
    w = math.sqrt(k_a / mu)
    t = np.arange(9001) * 1e-6
    d = 5000.0 * np.sin(w * t) / (mu * w)
    series = dict(time=t, step=np.arange(9001.0), plate_position=0.3 - d,
                  plate_velocity=-5000.0 / mu * np.cos(w * t), ceiling_stress=S0 + k_a * d,
                  input_force=np.where(t <= TAU, F0 * (1.0 - t / TAU), 0.0))
    path = tmp_path / "sdof.h5"
    write_results(path, series, None, {"scene": {"name": "blast"}, "pdem_version": "0.1.0", "kind": "blast"})
    write_blast_parameters(path, plate_areal_mass=mu, ceiling_area=AREA, F0=F0, tau=TAU)
    r = analyse_blast(*read_blast(path))
    assert r.layer_stiffness == pytest.approx(k_a, rel=1e-9)
    assert r.sdof_amplification == pytest.approx(1.0 - math.cos(w * 9e-3), rel=1e-12)
    assert r.amplification_dynamic == pytest.approx(r.sdof_amplification, rel=1e-6)
