"""What a run holds or wrote, for the tests that compare runs bit for bit: the bodies of a running
simulation gathered from every rank in gid order, its checkpoint tables by key, the comparison of
both with a reference, every dataset of an HDF5 file, and what differs between two runs' HDF5
outputs and final checkpoints."""
from pathlib import Path

import h5py
import numpy as np

from pdem.io.checkpoint import list_checkpoints, read_checkpoint


def bodies_by_gid(comm, sim):
    """[gid, pos, vel, angvel, force, torque] of every owned body on every rank, by gid."""
    p = sim.particles
    n = p.n_local
    cols = [comm.allgather_rows(getattr(p, k)[:n].copy()) for k in ("gid", "pos", "vel", "angvel", "force", "torque")]
    o = np.argsort(cols[0])
    return [c[o] for c in cols]


def tables_by_key(comm, sim):
    """{table: {column: array}} of the simulation's checkpoint tables gathered from every rank in
    key order (gid, key or index); a pair straddling a slab edge is held twice and kept once."""
    tables, _ = sim.checkpoint_tables()
    out = {}
    for t, cols in tables.items():
        cols = {c: comm.allgather_rows(np.ascontiguousarray(a)) for c, a in cols.items()}
        key = cols.get("gid", cols.get("key", cols.get("index")))
        _, first = np.unique(key, return_index=True)  # straddling pairs: two identical copies
        out[t] = {c: a[first] for c, a in cols.items()}
    return out


def state(sim, comm):
    """What `state_differences` compares: bodies by gid, tables by key, step, time, Δt and the
    energy check's reference."""
    return {"bodies": bodies_by_gid(comm, sim), "tables": tables_by_key(comm, sim),
            "scalars": (sim.step, sim.time, sim.dt, sim.energy_reference)}


def _same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def state_differences(ref, comm, sim):
    """The names of what differs, bit for bit, between the `state` ``ref`` and ``sim`` gathered
    over ``comm`` (collective; the same list on every rank): body columns, table/column, scalars."""
    bad = [name for name, a, b in zip(("gid", "pos", "vel", "angvel", "force", "torque"), ref["bodies"],
                                      bodies_by_gid(comm, sim)) if not _same_bits(a, b)]
    got = tables_by_key(comm, sim)
    if sorted(got) != sorted(ref["tables"]):
        bad.append(f"tables {sorted(set(got) ^ set(ref['tables']))}")
    else:
        bad += [f"{t}/{c}" for t, cols in ref["tables"].items() for c, a in cols.items()
                if not _same_bits(a, got[t][c])]
    if (sim.step, sim.time, sim.dt, sim.energy_reference) != ref["scalars"]:
        bad.append("step, time, dt or energy reference")
    return bad


def datasets(path):
    """{"/group/.../name": array} of every dataset in an HDF5 file."""
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def run_differences(ref, got, files=("results.h5", "preparation.h5")):
    """What differs between two run directories (HDF5 datasets bit for bit, last checkpoint's
    particles and platen); [] if nothing."""
    bad = []
    for name in files:
        a, b = datasets(Path(ref) / name), datasets(Path(got) / name)
        if sorted(a) != sorted(b):
            bad.append(f"{name}: datasets {sorted(set(a) ^ set(b))}")
            continue
        bad += [f"{name}:/{k}" for k in a if not (a[k].shape == b[k].shape and
                                                 np.array_equal(np.asarray(a[k]).view(np.uint8),
                                                                np.asarray(b[k]).view(np.uint8)))]
    last = lambda d: read_checkpoint(list_checkpoints(Path(d) / "checkpoints")[-1][1])[0]  # noqa: E731
    ta, tb = last(ref), last(got)
    order = lambda t: np.argsort(t["particles"]["gid"])  # noqa: E731
    oa, ob = order(ta), order(tb)
    for c in ta["particles"]:
        if not np.array_equal(ta["particles"][c][oa], tb["particles"][c][ob]):
            bad.append(f"checkpoint particles/{c}")
    if not np.array_equal(ta["boxes"]["center"], tb["boxes"]["center"]):
        bad.append("checkpoint boxes/center")
    return bad
