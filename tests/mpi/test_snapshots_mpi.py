"""Snapshots on 1, 2 and 3 ranks: the same files, bit for bit (SPEC 3).

Run by `make test` under ``mpiexec -n 2`` and ``-n 3`` (and serially: then it only checks that a
run writes the same files twice). The scene (`factories.snapshot_scene`): rigid and breakable
clumps crossing slab edges, a fixed sphere, walls, a facet and a turning box; snapshots with the
contact network. Rank 0 also runs the scene on one rank and compares every dataset and attribute
of snapshots.h5 and the text of every XDMF index with the parallel run's.
"""
import h5py
import numpy as np
from factories import snapshot_scene

from pdem.driver.snapshots import open_snapshots, write_snapshot
from pdem.parallel.comm import SerialComm, configure_threads

STEPS = (0, 700, 1400)


def write_run(comm, directory):
    """Run the scene, a snapshot at every step of STEPS; returns the simulation."""
    sim = snapshot_scene().build(comm=comm)
    snaps = open_snapshots(directory, comm, {"snapshot_every": 1, "snapshot_contacts": True})
    write_snapshot(snaps, sim)
    for a, b in zip(STEPS[:-1], STEPS[1:]):
        sim.run(b - a)
        write_snapshot(snaps, sim)
    return sim


def content(path):
    """{name: (attributes, bytes of the dataset or None)} of every group and dataset."""
    out = {}

    def visit(name, obj):
        data = None
        if isinstance(obj, h5py.Dataset):
            a = obj[()]
            data = (a.dtype.str, a.shape, a.tobytes())
        out[name] = ({k: np.asarray(v).tobytes() for k, v in obj.attrs.items()}, data)

    with h5py.File(path, "r") as f:
        out["/"] = ({k: np.asarray(v).tobytes() for k, v in f.attrs.items()}, None)
        f.visititems(visit)
    return out


def differences(ref, got):
    a, b = content(ref / "snapshots.h5"), content(got / "snapshots.h5")
    bad = [f"snapshots.h5: only in one file: {sorted(set(a) ^ set(b))}"] if set(a) != set(b) else []
    bad += [f"snapshots.h5:/{k}" for k in sorted(set(a) & set(b)) if a[k] != b[k]]
    indexes = sorted(p.name for p in ref.glob("*.xmf"))
    if indexes != sorted(p.name for p in got.glob("*.xmf")):
        bad.append(f"indexes {indexes} vs {sorted(p.name for p in got.glob('*.xmf'))}")
    bad += [name for name in indexes if (got / name).exists() and (ref / name).read_text() != (got / name).read_text()]
    return bad


def test_snapshot_file_same_on_any_rank_count(comm, mpi_tmp_path):
    configure_threads(comm)
    sim = write_run(comm, mpi_tmp_path / "ranks")
    p = sim.particles
    kind = sim.kind("sphere_sphere")
    rows = kind.contacts.real_rows()
    across = int(np.count_nonzero(kind.contacts.j[rows] >= p.n_local))  # contacts with a ghost sphere
    if comm.size > 1:
        assert comm.allreduce_sum_int(int(p.n_local == 0)) == 0, "a rank owns no sphere"
        assert comm.allreduce_sum_int(across) > 0, "no contact crosses a slab edge"
    bad = None
    if comm.rank == 0:
        write_run(SerialComm(), mpi_tmp_path / "one_rank")
        bad = differences(mpi_tmp_path / "one_rank", mpi_tmp_path / "ranks")
        with h5py.File(mpi_tmp_path / "ranks" / "snapshots.h5", "r") as f:
            g = f[sorted(f)[-1]]
            blocks = sorted(k for k in g if isinstance(g[k], h5py.Group))
            assert blocks == ["boxes", "contacts", "facets", "walls"], blocks
            assert "fragment_id" in g.attrs["fields"] and len(g["contacts/normal_force"]) > 0
    bad = comm.bcast(bad)
    assert not bad, f"{comm.size} ranks differ from one: {bad}"
