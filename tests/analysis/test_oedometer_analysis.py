"""`analysis.oedometer`: stiffness of a synthetic load-unload record, the identification of E_k by
equal unloading stiffness (thesis table 4.14) on synthetic data, and the command line on a
synthetic results file; `analysis.oedometer_overlap`'s breakage split and conclusion on made-up
numbers (its figures on a real run: tests/scenes/test_oedometer.py)."""
import math

import numpy as np
import pytest

from analysis.__main__ import main
from analysis.oedometer import analyse, identify_modulus
from pdem.format.schema import write_results


def record(k_load=2e6, k_unload=8e6, f_min=250.0, f_max=1.5e6, n=401):
    """A load-unload record: force linear in displacement on loading (k_load) and unloading (k_unload)."""
    t = np.linspace(0.0, 0.2, n)
    load = f_min + (f_max - f_min) * (1 - np.cos(2 * np.pi * t / 0.2)) / 2
    peak = n // 2
    u = np.where(np.arange(n) <= peak, (load - f_min) / k_load,
                 (f_max - f_min) / k_load - (f_max - load) / k_unload)
    return {"time": t, "step": np.arange(n, dtype=float), "platen_load": load, "platen_force": load.copy(),
            "platen_displacement": u}


def test_stiffness_of_a_bilinear_record():
    r = analyse(record())
    assert r.loading_stiffness == pytest.approx(2e6, rel=1e-9)
    assert r.unloading_stiffness == pytest.approx(8e6, rel=1e-9)
    assert r.u_max == pytest.approx((1.5e6 - 250) / 2e6, rel=1e-12)
    assert r.u_end == pytest.approx((1.5e6 - 250) * (1 / 2e6 - 1 / 8e6), rel=1e-9)


@pytest.mark.parametrize("b", [1.0, 0.8])
def test_identify_modulus_on_a_power_law(b):
    """Runs at three moduli with k = C E^b: the modulus of the target stiffness comes back."""
    c = 3.0e-4
    e = np.array([1e6, 1e7, 1e8])
    k = c * e**b
    e_true = 5.55e6
    got, slope, coef = identify_modulus(e, k, c * e_true**b)
    assert got == pytest.approx(e_true, rel=1e-10)
    assert slope == pytest.approx(b, rel=1e-12) and coef == pytest.approx(c, rel=1e-10)


def test_identify_modulus_thesis_table_4_14():
    """Thesis table 4.14: moduli giving equal unloading stiffness; a grain type whose runs give
    k = k_ref (E / E_id) recovers E_id (e.g. r = 4.5 mm: 5.0 MPa)."""
    k_ref = 1.0e5
    for e_id in (5.55e6, 5.0e6, 4.5e6, 3.8e6, 2.9e6, 3.0e6, 2.8e6):
        e = np.array([1e6, 1e7])
        got, _, _ = identify_modulus(e, k_ref * e / e_id, k_ref)
        assert got == pytest.approx(e_id, rel=1e-12)


@pytest.mark.parametrize("e, k, target, match", [
    ([1e6], [1.0], 1.0, "two or more"),
    ([1e6, 1e6], [1.0, 2.0], 1.0, "two or more"),
    ([1e6, 1e7], [1.0, -2.0], 1.0, "> 0"),
    ([1e6, 1e7], [2.0, 1.0], 1.0, "does not grow"),
])
def test_identify_modulus_refuses_bad_data(e, k, target, match):
    with pytest.raises(ValueError, match=match):
        identify_modulus(e, k, target)


def test_command_line_on_a_synthetic_file(tmp_path, capsys):
    path = write_results(tmp_path / "results.h5", record(), None, {"kind": "oedometer", "scene": "{}",
                                                                   "pdem_version": "test"})
    assert main(["oedometer", str(path), "--out", str(tmp_path / "a")]) == 0
    text = (tmp_path / "a" / "oedometer.txt").read_text()
    assert "unloading stiffness 8 kN/mm" in text and (tmp_path / "a" / "oedometer.png").stat().st_size > 1000
    assert not (tmp_path / "a" / "grading.txt").exists()  # no /fragments: no grading
    assert main(["oedometer", str(tmp_path / "missing.h5")]) == 2
    assert math.isfinite(analyse(record(n=9)).unloading_stiffness)  # a sparse record: two samples at least
    assert "largest overlap" not in text  # not recorded


def test_largest_overlap_is_reported_when_recorded(tmp_path):
    rec = record()
    rec["max_overlap_ratio"] = (0.2 * rec["platen_force"] / rec["platen_force"].max(), "-")
    attrs = {"kind": "oedometer", "scene": "{}", "pdem_version": "test"}
    path = write_results(tmp_path / "results.h5", rec, None, attrs)
    assert main(["oedometer", str(path), "--out", str(tmp_path / "a")]) == 0
    assert "largest overlap 0.2 of the smaller radius" in (tmp_path / "a" / "oedometer.txt").read_text()


# ---------------------------------------------------------------------------- analysis.oedometer_overlap
def test_breakage_above_a_threshold_counts_intervals_with_either_end_above():
    from analysis.oedometer_overlap import breakage_above

    bonds = [100, 100, 90, 90, 60, 55, 55]
    largest = [0.01, 0.02, 0.04, 0.06, 0.20, 0.03, 0.01]
    # lost per interval: 0, 10, 0, 30, 5, 0; above 0.05 at the start: (3,4), (4,5); at an end also (2,3)
    assert breakage_above(bonds, largest, 0.05) == (35.0, 35.0, 45.0)
    assert breakage_above(bonds, largest, 0.1) == (5.0, 35.0, 45.0)  # only (4,5) starts above; (3,4) ends there
    assert breakage_above(bonds, largest, 0.03) == (35.0, 45.0, 45.0)  # (1,2) ends above 0.03
    assert breakage_above(bonds, largest, 0.5) == (0.0, 0.0, 45.0)


def test_overlap_conclusion_compares_each_case_with_the_first():
    from analysis.oedometer_overlap import conclusion

    def case(name, broken, single):
        return {"case": name, "n": len(broken), "values": {"broken_fraction": broken, "single_mass": single}}

    thesis = case("thesis", [0.30, 0.32, 0.31, 0.29, 0.33], [0.010, 0.012, 0.011, 0.009, 0.013])
    same = case("identified", [0.31, 0.30, 0.33, 0.29, 0.32], [0.011, 0.010, 0.012, 0.013, 0.009])
    less = case("identified", [0.05, 0.06, 0.04, 0.05, 0.07], [0.001, 0.002, 0.001, 0.002, 0.001])
    assert conclusion([thesis, same]).count("no significant difference, not an overlap artefact") == 2
    assert conclusion([thesis, less]).count("breakage depends on the overlap") == 2
    assert "fewer than two seeds" in conclusion([thesis, case("identified", [0.1], [0.0])])
    for c, start in ((thesis, 1000.0), (same, 995.0), (less, 500.0)):
        c["values"]["bonds_start"] = [start] * c["n"]
    assert "warning" not in conclusion([thesis, same])
    assert "starts the load with 500 intact bonds against 1000, 50 % fewer" in conclusion([thesis, less])
    assert conclusion([thesis]) == "one case only: nothing to compare"


def test_overlap_command_names_missing_columns(tmp_path, capsys):
    """A record without the overlap statistics (pdem < 0.3.0): one line naming the column."""
    path = write_results(tmp_path / "results.h5", record(), None, {"kind": "oedometer", "scene": "{}",
                                                                   "pdem_version": "test"})
    assert main(["oedometer-overlap", str(path), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "intact_bonds" in err and len(err.strip().splitlines()) == 1
    assert main(["oedometer-overlap", str(path), "--threshold", "1.5"]) == 2
