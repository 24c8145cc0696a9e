"""pdem.io.timeseries: results file layout, buffered appends, truncation on resume, tables."""

import h5py
import numpy as np
import pytest
from io_fakecomm import run_ranks

from functools import partial

from pdem.io import timeseries
from pdem.io.timeseries import ResultsFileError

SCHEMA = ("pdem-results", 1)
TimeSeriesWriter = partial(timeseries.TimeSeriesWriter, schema=SCHEMA)
write_table = partial(timeseries.write_table, schema=SCHEMA)

COLUMNS = {"step": "1", "time": "s", "f_platen": "N", "settlement": "m"}


def row(step):
    return {"step": step, "time": step * 1e-5, "f_platen": 10.0 * step, "settlement": -step * 1e-7}


def read_series(path):
    with h5py.File(path, "r") as f:
        return {c: f["series"][c][()] for c in COLUMNS}


def test_layout_units_and_buffering(tmp_path):
    path = tmp_path / "results.h5"
    w = TimeSeriesWriter(path, COLUMNS, attrs={"scene": "oedometer", "seed": 3, "box": [0.3, 0.3]}, every=7)
    for s in range(10):
        w.append(row(s))
    assert w.rows == 10
    with h5py.File(path, "r") as f:
        assert f["series/step"].shape == (7,)  # 3 rows still buffered
    w.close()
    with h5py.File(path, "r") as f:
        assert f.attrs["schema"] == "pdem-results" and f.attrs["schema_version"] == 1
        g = f["series"]
        assert {c: g[c].attrs["units"] for c in COLUMNS} == COLUMNS
        assert g["step"].dtype == np.int64 and g["time"].dtype == np.float64
        assert g.attrs["scene"] == "oedometer" and g.attrs["seed"] == 3 and g.attrs["box"] == "[0.3, 0.3]"
    data = read_series(path)
    np.testing.assert_array_equal(data["step"], np.arange(10))
    np.testing.assert_array_equal(data["f_platen"], 10.0 * np.arange(10))
    with pytest.raises(ResultsFileError, match="writer is closed"):
        w.append(row(10))
    with pytest.raises(ValueError, match=r"missing columns \['time'\]"):
        TimeSeriesWriter(tmp_path / "other.h5", COLUMNS).append(step=1, f_platen=0.0, settlement=0.0)


def test_resume_truncates_rows_after_restart_step(tmp_path):
    path = tmp_path / "results.h5"
    with TimeSeriesWriter(path, COLUMNS, every=4) as w:  # first run, checkpoint at step 50
        for s in range(0, 100, 5):
            w.append(row(s))
    with TimeSeriesWriter(path, COLUMNS, every=4, append=True, restart_step=50) as w:
        assert w.rows == 11  # steps 0..50
        for s in range(55, 80, 5):
            w.append(**row(s))
    data = read_series(path)
    np.testing.assert_array_equal(data["step"], np.arange(0, 80, 5))
    np.testing.assert_array_equal(data["settlement"], [row(s)["settlement"] for s in range(0, 80, 5)])
    # append=False starts over
    with TimeSeriesWriter(path, COLUMNS) as w:
        w.append(row(0))
    assert read_series(path)["step"].tolist() == [0]


def test_resume_after_crash_inside_a_write_cuts_to_shortest_column(tmp_path):
    path = tmp_path / "results.h5"
    with TimeSeriesWriter(path, COLUMNS) as w:
        for s in range(6):
            w.append(row(s))
    with h5py.File(path, "r+") as f:  # as if killed after resizing only some columns
        f["series/time"].resize((4,))
    with TimeSeriesWriter(path, COLUMNS, append=True, restart_step=10) as w:
        w.append(row(4))
    assert read_series(path)["step"].tolist() == [0, 1, 2, 3, 4]


def test_append_refuses_other_columns_and_schema(tmp_path):
    path = tmp_path / "results.h5"
    TimeSeriesWriter(path, COLUMNS).close()
    with pytest.raises(ResultsFileError, match="results.h5: group series has columns"):
        TimeSeriesWriter(path, {"step": "1", "energy": "J"}, append=True)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["schema"] = "pdem-checkpoint"
    with pytest.raises(ResultsFileError, match="other.h5: schema is 'pdem-checkpoint'"):
        TimeSeriesWriter(other, COLUMNS)


def test_only_rank0_writes(tmp_path):
    path = tmp_path / "results.h5"

    def body(comm):
        with TimeSeriesWriter(path, COLUMNS, comm=comm) as w:
            w.append(row(comm.rank + 1))  # every rank passes the same reduced values in practice
        return w.active

    results, errors = run_ranks(2, body)
    assert errors == [None, None] and results == [True, False]
    assert read_series(path)["step"].tolist() == [1]


def test_write_table_cycles_next_to_series(tmp_path):
    path = tmp_path / "results.h5"
    with TimeSeriesWriter(path, COLUMNS) as w:
        w.append(row(0))
    cycles = {"cycle": np.arange(1, 4), "settlement": np.array([1e-3, 1.5e-3, 1.7e-3]),
              "k_unload": np.array([5e7, 6e7, 6.5e7])}
    units = {"cycle": "1", "settlement": "m", "k_unload": "N/m"}
    write_table(path, "cycles", cycles, units, attrs={"f_max": 30e3})
    write_table(path, "cycles", cycles, units)  # rewriting replaces the group
    with h5py.File(path, "r") as f:
        g = f["cycles"]
        assert g.attrs["n_rows"] == 3 and g["k_unload"].attrs["units"] == "N/m"
        np.testing.assert_array_equal(g["settlement"][()], cycles["settlement"])
        assert f["series/step"].shape == (1,)
    with pytest.raises(ValueError, match=r"no units for columns \['k_unload'\]"):
        write_table(path, "cycles", cycles, {"cycle": "1", "settlement": "m"})
