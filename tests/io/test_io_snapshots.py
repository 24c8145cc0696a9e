"""pdem.io.snapshots: gid-ordered particle snapshots whose XDMF index matches the HDF5 file."""

import errno
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from io_fakecomm import run_ranks

from pdem.io.snapshots import SnapshotError, SnapshotWriteError, SnapshotWriter

NUMPY_TYPE = {("Float", "8"): "float64", ("Float", "4"): "float32", ("Int", "8"): "int64",
              ("Int", "4"): "int32", ("UInt", "1"): "uint8"}


def particles(step, gids):
    gids = np.asarray(gids, dtype=np.int64)
    pos = np.stack([gids * 0.01, np.full(gids.size, step * 1e-3), -gids * 0.02], axis=1)
    return {"gid": gids, "position": pos, "radius": 0.005 + gids * 1e-4,
            "velocity": pos * 2.0, "fields": {"angvel": -pos, "material": gids % 3, "broken": gids % 2 == 1}}


def write_two_ranks(directory, steps, append=False, restart_step=None):
    def body(comm):
        w = SnapshotWriter(directory, comm=comm, append=append, restart_step=restart_step)
        gids = [5, 1, 3] if comm.rank == 0 else [4, 0, 2, 6]
        for s in steps:
            w.write(s, s * 1e-4, **particles(s, gids))

    _, errors = run_ranks(2, body)
    assert errors == [None, None]


def check_xdmf(xmf_path):
    """Every HDF reference exists with the declared shape and type; returns the grids found."""
    root = ET.parse(xmf_path).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0"
    (collection,) = root.find("Domain")
    assert collection.get("GridType") == "Collection" and collection.get("CollectionType") == "Temporal"
    grids = []
    with h5py.File(xmf_path.parent / "snapshots.h5", "r") as f:
        for grid in collection:
            n = int(grid.find("Topology").get("NumberOfElements"))
            assert grid.find("Topology").get("TopologyType") == "Polyvertex"
            for item in grid.iter("DataItem"):
                assert item.get("Format") == "HDF"
                file_name, dataset = item.text.strip().split(":")
                assert file_name == "snapshots.h5" and dataset in f, item.text
                ds = f[dataset]
                dims = tuple(int(d) for d in item.get("Dimensions").split())
                assert ds.shape == dims and dims[0] == n, item.text
                assert ds.dtype == NUMPY_TYPE[(item.get("NumberType"), item.get("Precision"))]
            names = {a.get("Name"): a.get("AttributeType") for a in grid.findall("Attribute")}
            assert names == {"radius": "Scalar", "velocity": "Vector", "gid": "Scalar",
                             "angvel": "Vector", "material": "Scalar", "broken": "Scalar"}
            g = f[grid.get("Name")]
            assert float(grid.find("Time").get("Value")) == g.attrs["time"]
            grids.append((grid.get("Name"), float(grid.find("Time").get("Value")), n))
    return grids


def test_snapshots_ordered_by_gid_and_xdmf_consistent(tmp_path):
    write_two_ranks(tmp_path, [0, 100, 200])
    with h5py.File(tmp_path / "snapshots.h5", "r") as f:
        assert f.attrs["schema"] == "pdem-snapshots"
        g = f["step_000000000100"]
        expected = particles(100, np.arange(7))
        np.testing.assert_array_equal(g["gid"][()], np.arange(7))
        for key in ("position", "radius", "velocity"):
            np.testing.assert_array_equal(g[key][()], expected[key])
        np.testing.assert_array_equal(g["angvel"][()], expected["fields"]["angvel"])
        assert g["broken"].dtype == np.uint8
        np.testing.assert_array_equal(g["broken"][()], expected["fields"]["broken"])
        np.testing.assert_array_equal(g["connectivity"][()].ravel(), np.arange(7))
    grids = check_xdmf(tmp_path / "snapshots.xmf")
    assert grids == [("step_000000000000", 0.0, 7), ("step_000000000100", 0.01, 7),
                     ("step_000000000200", 0.02, 7)]


def test_meshio_reads_the_xdmf(tmp_path):
    meshio = pytest.importorskip("meshio", reason="meshio is an optional test dependency")
    write_two_ranks(tmp_path, [0, 100])
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "snapshots.xmf")) as reader:
        points, cells = reader.read_points_cells()
        np.testing.assert_array_equal(points, particles(0, np.arange(7))["position"])
        assert cells[0].type == "vertex" and len(cells[0].data) == 7
        for k, step in enumerate([0, 100]):
            t, point_data, _ = reader.read_data(k)
            assert t == step * 1e-4
            np.testing.assert_array_equal(point_data["radius"], particles(step, np.arange(7))["radius"])
            np.testing.assert_array_equal(point_data["velocity"], particles(step, np.arange(7))["velocity"])


def test_append_after_restart_drops_later_snapshots(tmp_path):
    write_two_ranks(tmp_path, [0, 100, 200, 300])
    write_two_ranks(tmp_path, [200, 250], append=True, restart_step=150)
    names = [g[0] for g in check_xdmf(tmp_path / "snapshots.xmf")]
    assert names == ["step_000000000000", "step_000000000100", "step_000000000200", "step_000000000250"]
    with h5py.File(tmp_path / "snapshots.h5", "r") as f:
        assert "step_000000000300" not in f


def test_damaged_file_is_moved_aside_on_append(tmp_path):
    write_two_ranks(tmp_path, [0, 100])
    h5 = tmp_path / "snapshots.h5"
    h5.write_bytes(h5.read_bytes()[:1000])  # as if killed while writing a snapshot
    lines = []
    w = SnapshotWriter(tmp_path, append=True, restart_step=100, log=lines.append)
    assert len(lines) == 1 and "snapshots.h5 is damaged" in lines[0] and "snapshots.h5.damaged" in lines[0]
    w.write(150, 0.015, **particles(150, [2, 0, 1]))
    assert [g[0] for g in check_xdmf(tmp_path / "snapshots.xmf")] == ["step_000000000150"]


def test_duplicate_gid_raises_on_every_rank(tmp_path):
    def body(comm):
        w = SnapshotWriter(tmp_path, comm=comm)
        w.write(1, 0.0, **particles(1, [0, 1] if comm.rank == 0 else [1, 2]))

    _, errors = run_ranks(2, body)
    for exc in errors:
        assert isinstance(exc, SnapshotError) and "gid 1 passed twice" in str(exc)
        assert not isinstance(exc, SnapshotWriteError)  # a bug upstream, not the system's failure


def test_a_failed_write_raises_snapshot_write_error_on_every_rank(tmp_path, monkeypatch):
    """Rank 0's write failing with an OSError (disk full) or MemoryError: `SnapshotWriteError`
    (exit status 5) on every rank, naming the step and the cause."""
    def full(self, *args):
        raise OSError(errno.ENOSPC, "No space left on device", str(self.h5_path))

    monkeypatch.setattr(SnapshotWriter, "_write_rank0", full)

    def body(comm):
        SnapshotWriter(tmp_path, comm=comm).write(7, 0.0, **particles(7, [0, 1] if comm.rank == 0 else [2]))

    _, errors = run_ranks(2, body)
    for exc in errors:
        assert isinstance(exc, SnapshotWriteError), exc
        assert "snapshots.h5: step 7:" in str(exc) and "No space left on device" in str(exc)
