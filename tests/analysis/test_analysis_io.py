"""Reading and validating results files; the writer round trip."""

import h5py
import numpy as np
import pytest

from pdem.format.read import read_box_test, read_results
from pdem.format.schema import SCHEMA, write_results


def test_round_trip(box_file, box_record):
    r = read_box_test(box_file)
    assert r.kind == "box_test"
    assert r.scene["F_max"] == 40e3
    assert r.attrs["schema"] == SCHEMA and r.attrs["schema_version"] == 1
    assert r.units["sleeper_settlement"] == "m"
    for name, values in box_record.series.items():
        np.testing.assert_array_equal(r.series[name], values)
        assert r.series[name].dtype == np.float64
    for name, values in box_record.cycles.items():
        np.testing.assert_array_equal(r.cycles[name], values)


def test_no_cycles_group(box_file_no_cycles):
    assert read_results(box_file_no_cycles).cycles is None


def test_plain_hdf5_without_schema(expect_error, tmp_path):
    path = tmp_path / "plain.h5"
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3.0)
    expect_error(read_box_test, path, "not a pdem result", "'schema'")


def test_text_file(expect_error, tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("time,force\n0,1\n")
    expect_error(read_box_test, path, "not an HDF5 file")


def test_missing_file(expect_error, tmp_path):
    expect_error(read_box_test, tmp_path / "nowhere.h5", "no such file")


def test_wrong_schema(expect_error, tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f.attrs["schema"] = "yade-output"
    expect_error(read_box_test, path, "'yade-output'", SCHEMA)


def test_missing_dataset(expect_error, tmp_path, box_record, box_attrs):
    series = {k: v for k, v in box_record.series.items() if k != "sleeper_force"}
    path = write_results(tmp_path / "dep.h5", series, None, {**box_attrs, "kind": "deposition"})
    read_results(path)  # a valid result, just not a box test
    expect_error(read_box_test, path, "/series/sleeper_force", "deposition")


def with_edit(path, edit):
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


def test_wrong_units(expect_error, box_file):
    with_edit(box_file, lambda f: f["series/sleeper_settlement"].attrs.__setitem__("units", "mm"))
    expect_error(read_box_test, box_file, "/series/sleeper_settlement", "'mm'")


def test_future_version(expect_error, box_file):
    with_edit(box_file, lambda f: f.attrs.__setitem__("schema_version", 2))
    expect_error(read_box_test, box_file, "schema_version 2")


def test_missing_root_attribute(expect_error, box_file):
    with_edit(box_file, lambda f: f.attrs.__delitem__("pdem_version"))
    expect_error(read_box_test, box_file, "pdem_version")


def test_unequal_lengths(expect_error, box_file):
    def edit(f):
        del f["series/step"]
        f["series/step"] = np.arange(5.0)
        f["series/step"].attrs["units"] = "-"
    with_edit(box_file, edit)
    expect_error(read_box_test, box_file, "differ in length")


def test_incomplete_cycles_table(expect_error, box_file):
    with_edit(box_file, lambda f: f.__delitem__("cycles/force_min"))
    expect_error(read_box_test, box_file, "/cycles/force_min")


def test_non_finite_series(expect_error, box_file):
    with_edit(box_file, lambda f: f["series/sleeper_force"].__setitem__(3, np.nan))
    expect_error(read_box_test, box_file, "/series/sleeper_force", "non-finite")


def test_writer_rejects_bad_input(tmp_path, box_attrs):
    good = dict(time=np.arange(3.0), step=np.arange(3.0))
    with pytest.raises(ValueError, match="length"):
        write_results(tmp_path / "a.h5", {**good, "step": np.arange(2.0)}, None, box_attrs)
    with pytest.raises(ValueError, match="units unknown"):
        write_results(tmp_path / "a.h5", {**good, "energy": np.arange(3.0)}, None, box_attrs)
    with pytest.raises(ValueError, match="time"):
        write_results(tmp_path / "a.h5", {"step": np.arange(3.0)}, None, box_attrs)
    path = write_results(tmp_path / "a.h5", {**good, "energy": (np.arange(3.0), "J")}, None, box_attrs)
    assert read_results(path).units["energy"] == "J"
    assert not list(tmp_path.glob("*.tmp"))
