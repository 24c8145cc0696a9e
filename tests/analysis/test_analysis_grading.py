"""Fragment records, grading curves and breakage indices, checked against values worked by hand.

The synthetic sample: clumps of 8 member spheres of radius r (mass 8 m1 each; sieve diameter
d = 2r * 8^(1/3) = 4r) breaking into single spheres (d = 2r = d_min) and pairs
(d = 2r * 2^(1/3)). With f the mass fractions, Hardin's potential of a grading is
sum f log10(d / 2r): 1/3 log10 2 per pair, log10 2 per intact clump, 0 per single sphere.
"""

import math
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from pdem.format.schema import write_results
from analysis.__main__ import build_parser, main
from analysis.grading import (analyse_grading, ballast_breakage_index, grading_curve,
                              grading_lines, hardin, marsal, passing, sieve_diameter,
                              sieve_series)
from pdem.format.groups import read_fragments
from pdem.format.schema import fragment_label, write_fragments

R, RHO = 3.6e-3, 2600.0
M1 = RHO * 4.0 / 3.0 * math.pi * R**3   # one member sphere [kg]
LOG2 = math.log10(2.0)
REPO = Path(__file__).resolve().parents[2]


def base_file(path, kind="oedometer"):
    return write_results(path, {"time": np.arange(4.0), "step": np.arange(4.0) * 100}, None,
                         {"scene": {"name": kind}, "pdem_version": "0.1.0", "kind": kind})


def add(path, label, n, clump=None, step=0, time=0.0, **kw):
    n = np.asarray(n, dtype=np.int64)
    write_fragments(path, label, n, n * M1, step=step, time=time, density=RHO,
                    member_radius_min=R, clump=clump, **kw)


def clumps_intact(n_clumps=10):
    return np.full(n_clumps, 8), np.arange(n_clumps)


def quarter_broken():
    """Clumps 0-4 intact; clumps 5-9 each in 4 single spheres and 2 pairs: 25 % of the mass in
    single spheres, 25 % in pairs, 50 % intact."""
    n = [8] * 5 + [1, 1, 1, 1, 2, 2] * 5
    clump = list(range(5)) + [c for c in range(5, 10) for _ in range(6)]
    return np.array(n), np.array(clump)


@pytest.fixture
def staged(tmp_path):
    """Four stages, written out of order: initial, vibrated (unchanged), peak, unloaded."""
    path = base_file(tmp_path / "results.h5")
    n, c = quarter_broken()
    add(path, "unloaded", n, c, step=300, time=3.0)
    add(path, "initial", *clumps_intact(), step=0, time=0.0)
    half = np.array([8] * 5 + [1] * 40)
    add(path, "peak", half, np.array(list(range(5)) + [c for c in range(5, 10) for _ in range(8)]),
        step=200, time=2.0)
    add(path, "vibrated", *clumps_intact(), step=100, time=1.0)
    return path


def test_sieve_diameter_of_one_sphere_is_its_diameter():
    assert sieve_diameter(M1, RHO) == pytest.approx(2 * R, rel=1e-15)
    assert sieve_diameter(8 * M1, RHO) == pytest.approx(4 * R, rel=1e-15)


def test_records_round_trip_in_step_order(staged):
    fr = read_fragments(staged)
    assert [r.label for r in fr.records] == ["initial", "vibrated", "peak", "unloaded"]
    assert [r.step for r in fr.records] == [0, 100, 200, 300]
    assert fr.density == RHO and fr.member_radius_min == R
    peak = fr.record("peak")
    assert peak.n_members.dtype == np.int64 and peak.mass.sum() == pytest.approx(80 * M1)
    assert peak.clump is not None and peak.time == 2.0


def test_run_directory_is_accepted(staged):
    assert read_fragments(staged.parent).records[0].label == "initial"


def test_grading_curve_by_members_and_by_diameter():
    n, c = quarter_broken()
    x, p = grading_curve(n, n * M1)
    np.testing.assert_array_equal(x, [1, 2, 8])
    np.testing.assert_allclose(p, [0.25, 0.5, 1.0], rtol=1e-15)
    d = sieve_diameter(n * M1, RHO)
    np.testing.assert_allclose(passing(d, n * M1, [2 * R, 2 * R * 2 ** (1 / 3), 3.99 * R, 4 * R]),
                               [0.25, 0.5, 0.5, 1.0], rtol=1e-15)


def test_half_single_spheres_gives_one_half_everywhere(staged):
    result = analyse_grading(read_fragments(staged), intact_members=8)
    peak = {b.label: b for b in result.breakage}["peak"]
    assert peak.reference == "initial"
    assert peak.marsal_members == pytest.approx(50.0, rel=1e-12)
    assert peak.hardin_bp0 == pytest.approx(LOG2, rel=1e-12)
    assert peak.hardin_bp == pytest.approx(0.5 * LOG2, rel=1e-12)
    assert peak.hardin_bt == pytest.approx(0.5 * LOG2, rel=1e-12)
    assert peak.hardin_br == pytest.approx(0.5, rel=1e-12)
    assert (peak.bbi_a, peak.bbi_b) == pytest.approx((0.5 * LOG2, 0.5 * LOG2), rel=1e-12)
    assert peak.bbi == pytest.approx(0.5, rel=1e-12)
    s = {s.label: s for s in result.summaries}
    assert s["peak"].fraction_single == pytest.approx(0.5)
    assert s["peak"].fraction_large == pytest.approx(0.5)
    assert s["peak"].fraction_intact == pytest.approx(0.5)
    assert s["initial"].fraction_large == 1.0 and s["initial"].fraction_single == 0.0
    assert s["initial"].d_max == pytest.approx(4 * R) and s["peak"].d50 == pytest.approx(2 * R)


def test_quarter_singles_quarter_pairs(staged):
    result = analyse_grading(read_fragments(staged), intact_members=8)
    b = {b.label: b for b in result.breakage}
    vib, unl = b["vibrated"], b["unloaded"]
    assert (vib.marsal_members, vib.hardin_bt, vib.bbi) == (0.0, 0.0, 0.0)
    assert unl.marsal_members == pytest.approx(50.0)
    assert unl.hardin_bp == pytest.approx(7 / 12 * LOG2, rel=1e-12)
    assert unl.hardin_br == pytest.approx(5 / 12, rel=1e-12)
    assert unl.bbi_a == pytest.approx(5 / 12 * LOG2, rel=1e-12)
    assert unl.bbi_b == pytest.approx(7 / 12 * LOG2, rel=1e-12)
    assert unl.bbi == pytest.approx(5 / 12, rel=1e-12)
    s = {s.label: s for s in result.summaries}["unloaded"]
    assert (s.fraction_single, s.fraction_large, s.fraction_intact) == pytest.approx(
        (0.25, 0.5, 0.5))
    assert s.n_fragments == 35
    # by number of fragments (the thesis's text): 20 single spheres and 5 whole clumps of 35
    assert (s.count_single, s.count_large) == pytest.approx((20 / 35, 5 / 35), rel=1e-15)


def test_reference_and_threshold_options(staged):
    result = analyse_grading(read_fragments(staged), reference="peak")
    assert [b.label for b in result.breakage] == ["unloaded"]
    # peak -> unloaded: singles 50 % -> 25 %, pairs 0 -> 25 %, intact 50 % -> 50 %
    b = result.breakage[0]
    assert b.marsal_members == pytest.approx(25.0)
    assert b.hardin_bt == pytest.approx(0.5 * LOG2 - 7 / 12 * LOG2)  # negative: coarser
    assert {s.label: s.fraction_large for s in result.summaries}["initial"] == 0.0  # n >= 135
    with pytest.raises(ValueError, match="no fragment record 'nope'"):
        analyse_grading(read_fragments(staged), reference="nope")


def test_marsal_depends_on_the_size_fractions(tmp_path):
    """Pairs breaking into single spheres: B_g = 50 % by member count, 0 with one sieve at 3r
    (pairs and single spheres both pass it)."""
    path = base_file(tmp_path / "r.h5")
    add(path, "before", [8] * 5 + [2] * 20, step=0)
    add(path, "after", [8] * 5 + [1] * 40, step=1)
    result = analyse_grading(read_fragments(path), sieves=[3 * R])
    b = result.breakage[0]
    assert b.marsal_members == pytest.approx(50.0)
    assert b.marsal_sieves == pytest.approx(0.0, abs=1e-12)
    assert b.hardin_bp0 == pytest.approx(2 / 3 * LOG2)
    assert b.hardin_br == pytest.approx(0.25)
    assert b.bbi == pytest.approx(b.hardin_br, rel=1e-12)
    assert math.isnan(result.summaries[1].fraction_intact)  # no clump ids in this file


def test_bbi_equals_hardin_br_for_random_gradings():
    """With the boundary 'all single spheres' and d_max >= every fragment, A + B = B_p,0 and
    A = B_t (docs/breakage_indices.md): two routes, one number."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        n0 = rng.integers(1, 136, 60)
        n1 = np.concatenate([rng.integers(1, 40, 90), rng.integers(100, 136, 10)])
        m0, m1 = n0 * M1 * rng.uniform(0.9, 1.0, 60), n1 * M1 * rng.uniform(0.9, 1.0, 100)
        d0, d1 = sieve_diameter(m0, RHO), sieve_diameter(m1, RHO)
        *_, br = hardin(d0, m0, d1, m1, 2 * R * 0.9)
        a, b, bbi = ballast_breakage_index(d0, m0, d1, m1, 2 * R * 0.9)
        assert bbi == pytest.approx(br, rel=1e-10)


def test_marsal_and_sieve_series_by_hand():
    assert marsal([1, 2], [3.0, 1.0], [1, 2, 3], [1.0, 1.0, 2.0]) == pytest.approx(50.0)
    s = sieve_series(1.0, 4.0)
    np.testing.assert_allclose(s, [1, 2**0.5, 2, 2**1.5, 4])
    assert len(sieve_series(1.0, 1.0)) == 1


def test_cli_writes_png_table_json(staged, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["grading", str(staged), "--out", str(out), "--intact-members", "8"]) == 0
    assert (out / "grading.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "grading.txt").read_text()
    assert "reference of the indices: 'initial'" in text
    row = next(line.split() for line in text.splitlines()
               if line.split()[:1] == ["unloaded"] and len(line.split()) == 9)
    assert float(row[1]) == pytest.approx(50.0) and float(row[8]) == pytest.approx(5 / 12, abs=1e-4)
    import json
    js = json.loads((out / "grading.json").read_text())
    assert js["records"][3]["fraction_single"] == pytest.approx(0.25)
    assert js["records"][3]["count_single"] == pytest.approx(20 / 35)
    row = next(line.split() for line in text.splitlines()
               if line.split()[:1] == ["unloaded"] and len(line.split()) == 12)
    assert (float(row[10]), float(row[11])) == pytest.approx((100 * 20 / 35, 100 * 5 / 35), abs=0.01)
    assert js["curves"]["peak"]["passing_n"] == pytest.approx([0.5, 1.0])
    assert js["records"][0]["fraction_intact"] == 1.0
    printed = capsys.readouterr().out.split()
    assert str(out / "grading.png") in printed


def test_cli_default_output_beside_the_file_and_sieves(staged):
    assert main(["grading", str(staged.parent), "--sieves", "7.2,10,14.4"]) == 0
    text = (staged.parent / "results-analysis" / "grading.txt").read_text()
    assert "  10.000" in text


# --- bad files and bad input ---

def test_file_without_fragments(expect_error, tmp_path, capsys):
    path = base_file(tmp_path / "box.h5", kind="box_test")
    expect_error(read_fragments, path, "group /fragments missing", "box_test")
    assert main(["grading", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/fragments missing" in err
    assert not (tmp_path / "o").exists()


def edit(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)


def test_malformed_records(expect_error, staged):
    edit(staged, lambda f: f["fragments/peak/mass"].attrs.__setitem__("units", "g"))
    expect_error(read_fragments, staged, "/fragments/peak/mass", "'g'", "'kg'")


def test_non_integer_member_counts(expect_error, staged):
    def fn(f):
        del f["fragments/peak/n_members"]
        f["fragments/peak/n_members"] = np.full(45, 1.5)
        f["fragments/peak/n_members"].attrs["units"] = "-"
    edit(staged, fn)
    expect_error(read_fragments, staged, "/fragments/peak/n_members", "integers")


def test_unequal_lengths_and_missing_attributes(expect_error, staged):
    def fn(f):
        del f["fragments/initial/mass"]
        f["fragments/initial/mass"] = np.ones(3)
        f["fragments/initial/mass"].attrs["units"] = "kg"
    edit(staged, fn)
    expect_error(read_fragments, staged, "/fragments/initial", "differ in length")
    edit(staged, lambda f: f["fragments"].attrs.__delitem__("density"))
    expect_error(read_fragments, staged, "lacks attribute 'density'")


def test_missing_step(expect_error, staged):
    edit(staged, lambda f: f["fragments/vibrated"].attrs.__delitem__("step"))
    expect_error(read_fragments, staged, "/fragments/vibrated", "'step'")


def test_version_is_checked(expect_error, staged):
    edit(staged, lambda f: f.attrs.__setitem__("schema_version", 2))
    expect_error(read_fragments, staged, "schema_version 2 not supported")


def test_density_units_attribute_is_checked(expect_error, staged):
    edit(staged, lambda f: f["fragments"].attrs.__setitem__(
        "units", '{"density": "g/cm^3", "member_radius_min": "m"}'))
    expect_error(read_fragments, staged, "density", "'g/cm^3'", "'kg/m^3'")


def test_writer_refuses_bad_input(tmp_path):
    path = base_file(tmp_path / "w.h5")
    with pytest.raises(ValueError, match=">= 1"):
        add(path, "a", [0, 1])
    with pytest.raises(ValueError, match="'/'"):
        add(path, "a/b", [1])
    with pytest.raises(ValueError, match="mass"):
        write_fragments(path, "a", np.array([1]), [-1.0], step=0, time=0.0, density=RHO,
                        member_radius_min=R)
    add(path, "a", [1, 2])
    with pytest.raises(ValueError, match="exists already"):
        add(path, "a", [1])
    add(path, "a", [1], replace=True)
    assert len(read_fragments(path).record("a").mass) == 1
    with pytest.raises(ValueError, match="density"):
        write_fragments(path, "b", np.array([1]), [M1], step=0, time=0.0, density=2000.0,
                        member_radius_min=R)
    with pytest.raises(ValueError, match="no such results file"):
        add(tmp_path / "none.h5", "a", [1])
    assert fragment_label(120) == "step_000000000120"


def test_single_record_has_no_indices(tmp_path):
    path = base_file(tmp_path / "one.h5")
    add(path, fragment_label(0), *clumps_intact())
    result = analyse_grading(read_fragments(path))
    assert result.breakage == () and result.reference == "step_000000000000"
    assert "(no record after the reference)" in "\n".join(grading_lines(result))


def test_new_commands_are_listed_and_fail_cleanly(tmp_path):
    text = build_parser().format_help()
    assert all(name in text for name in ("grading", "blast", "track"))
    bad = tmp_path / "bad.h5"
    bad.write_text("not hdf5\n")
    proc = subprocess.run([sys.executable, "-m", "analysis", "grading", str(bad)],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "not an HDF5 file" in proc.stderr and "Traceback" not in proc.stderr
