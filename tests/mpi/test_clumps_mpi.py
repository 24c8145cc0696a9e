"""Rigid and breakable clumps on 1, 2 and 3 ranks: the same bits, and exact restarts (SPEC 3).

Run by `make test` under ``mpiexec -n 2`` and ``-n 3`` (and serially: then only determinism).
The scene (`factories.clump_scene`): 60 rigid 8-sphere clumps thrown sideways and spinning and 6
breakable grains (bonded spheres) falling onto the floor of a box long along x, the slab axis.
Clumps migrate between slabs with their members, straddle slab edges (members on both sides of
the owner's edge), bonds break. Every rank also runs the scene serially and compares the gathered
parallel state bit for bit: bodies by gid (pos, vel, angvel, force, torque), clumps by id (pos,
vel, angvel, angmom, ori, force, torque) and the contact tables (bond history) by key.
"""
import numpy as np
from factories import clump_scene

from pdem.bodies.fragments import fragments
from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm, configure_threads

N_STEPS, K_STEP = 4000, 2713
_REFERENCE = {}

BODY = ("gid", "pos", "vel", "angvel", "force", "torque")
CLUMP = ("id", "pos", "vel", "angvel", "angmom", "ori", "force", "torque")


def gathered(comm, sim):
    """(bodies by gid, clumps by id, contact tables by key, fragments) of all ranks."""
    p = sim.particles
    n = p.n_local
    b = [comm.allgather_rows(np.ascontiguousarray(getattr(p, k)[:n])) for k in BODY]
    o = np.argsort(b[0])
    bodies = {k: a[o] for k, a in zip(BODY, b)}
    ct = sim.clumps_table()
    c = [comm.allgather_rows(np.ascontiguousarray(ct[k])) for k in CLUMP]
    o = np.argsort(c[0])
    clumps = {k: a[o] for k, a in zip(CLUMP, c)}
    tables, _ = sim.checkpoint_tables()
    contacts = {}
    for t in ("contacts/sphere_sphere", "contacts/sphere_wall"):
        cols = {k: comm.allgather_rows(np.ascontiguousarray(a)) for k, a in tables[t].items()}
        _, first = np.unique(cols["key"], return_index=True)  # straddling pairs are held twice
        contacts[t] = {k: a[first] for k, a in cols.items()}
    f = fragments(sim)
    f = comm.bcast({k: v for k, v in f.items()} if comm.rank == 0 else None)
    return bodies, clumps, contacts, f


def reference(n_steps):
    if n_steps not in _REFERENCE:
        sim = clump_scene().build(comm=SerialComm())
        sim.run(n_steps)
        _REFERENCE[n_steps] = (gathered(SerialComm(), sim), sim.dt, sim.time)
    return _REFERENCE[n_steps]


def same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def differences(got, ref):
    bad = []
    for k in BODY:
        if not same(got[0][k], ref[0][k]):
            bad.append(f"body {k}")
    for k in CLUMP:
        if not same(got[1][k], ref[1][k]):
            bad.append(f"clump {k}")
    for t, cols in ref[2].items():
        for k, a in cols.items():
            if not same(got[2][t][k], a):
                bad.append(f"{t}/{k}")
    for k in ("n_members", "mass", "clump"):
        if not same(got[3][k], ref[3][k]):
            bad.append(f"fragments {k}")
    return bad


def straddling_clumps(sim):
    """Owned clumps with a member outside this rank's slab (0 on one rank)."""
    edges = getattr(sim.domain, "edges", None)
    if edges is None or sim.comm.size == 1:
        return 0
    c, p, r = sim.clumps, sim.particles, sim.comm.rank
    x = p.pos[c.mrow, 0]
    out = (x < edges[r]) | (x >= edges[r + 1])
    return len(np.unique(c.mclump[out]))


def test_clumps_rank_invariance(comm):
    configure_threads(comm)
    sim = clump_scene().build(comm=comm)
    straddle = 0
    counts = []
    for _ in range(N_STEPS // 100):
        sim.run(100)
        straddle += straddling_clumps(sim)
        counts.append(sim.clumps.n)
    got = gathered(comm, sim)
    (ref, ref_dt, ref_time) = reference(N_STEPS)
    bad = differences(got, ref)
    assert not comm.any_flag(bool(bad)), f"rank {comm.rank}: differs from the serial run: {bad}"
    assert (sim.dt, sim.time) == (ref_dt, ref_time)
    assert len(ref[1]["id"]) == 60 and len(ref[0]["gid"]) == 60 * 8 + 6 * 32
    assert len(ref[3]["n_members"]) > 66, "no breakable grain broke: the test does not test bond breakage"
    assert 0 < ref[3]["n_bonds"] < 360, "some bonds must be intact, some broken"
    if comm.size > 1:
        assert comm.allreduce_sum_int(straddle) > 0, "no clump ever straddled a slab edge"
        assert comm.allreduce_sum_int(int(np.ptp(counts) > 0)) > 0, "no clump ever migrated"


def test_clumps_restart(comm, mpi_tmp_path):
    """Checkpoint at step K with partly broken bonds; restored onto this rank count and onto one
    rank, both continue to N with the reference's bits."""
    configure_threads(comm)
    first = clump_scene().build(comm=comm)
    first.run(K_STEP)
    tables, meta = first.checkpoint_tables()
    path = write_checkpoint(mpi_tmp_path, K_STEP, tables, meta, comm)
    del first
    saved, _ = read_checkpoint(path)
    assert len(saved["clumps"]["id"]) == 60 and len(saved["clump_members"]["gid"]) == 480
    bonds = saved["contacts/sphere_sphere"]["history"][:, 4] > 0
    assert 0 < bonds.sum() < 360, "the checkpoint must hold intact and broken bonds"
    (ref, ref_dt, ref_time) = reference(N_STEPS)
    for what, c in ((f"restored onto {comm.size} rank(s)", comm), ("restored onto 1 rank", SerialComm())):
        sim = clump_scene().build(comm=c)
        sim.restore_checkpoint(*read_checkpoint(path))
        sim.run(N_STEPS - K_STEP)
        bad = differences(gathered(c, sim), ref)
        assert not comm.any_flag(bool(bad)), f"{what}, rank {comm.rank}: {bad}"
        assert (sim.dt, sim.time) == (ref_dt, ref_time), what


def test_clump_wider_than_a_slab(comm):
    """A chain clump 0.1 m long in a 0.2 m long scene: its halo (2 r_max + skin + 2 × 0.045 m)
    is wider than the middle of 3 slabs: one-line InputError on every rank; 1 or 2 ranks have no
    interior slab and run."""
    import pytest

    from pdem.errors import InputError
    from pdem.build.scene import Scene

    sc = Scene(dt=1e-5)
    m = sc.material(density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    sc.add_clump([(0.05 + 0.01 * k, 0.0, 0.0) for k in range(10)], 0.005, m)
    sc.add_spheres([(0.0, 0.05, 0.0), (0.1, 0.05, 0.0), (0.2, 0.05, 0.0)], 0.005, m)
    if comm.size < 3:
        sc.build(comm=comm).run(10)
        return
    with pytest.raises(InputError) as exc:
        sc.build(comm=comm)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("clumps: the largest clump reaches 0.045 m") and "fewer ranks" in msg
