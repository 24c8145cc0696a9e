"""The viscous and Hertz–Mindlin laws on 1, 2 and 3 ranks (run under mpiexec -n 2 and -n 3 by
`make test`): the same bits as the serial run, and a restart from a checkpoint written on this
rank count continues bit for bit on this rank count and on one rank.

A gravity deposition of 900 spheres with sideways velocities in a long box of 5 walls (slab axis
x), so that bodies migrate and contacts straddle slab edges: their law history (the viscous law's
shear force, rolling and twisting moments; Hertz–Mindlin's tangential displacement) must travel
with them. Rolling resistance and rolling friction are on.
"""
import numpy as np
import pytest
from factories import lattice_scene
from run_files import bodies_by_gid

from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm, configure_threads

N_STEPS, K_STEP = 2500, 1630
MATERIALS = {
    "viscous": dict(kn=5e4, ks=2e4, damping_ratio=0.2, friction=0.5, rolling_stiffness=0.125, rolling_coefficient=0.2),
    "hertz_mindlin": dict(young=1e7, poisson=0.3, restitution=0.5, friction=0.5, rolling_friction=0.05),
}
_REFERENCE = {}


def make_scene(law):
    # 900 spheres spinning, a box long along x (the slab axis); bodies cross slab edges
    return lattice_scene(11, (18, 5, 10), vx=0.6, vz=0.5, angvel=20.0, one_sided=True, material=MATERIALS[law],
                         damping=0.0, slab_axis=0, law=law, dt_interval=50, check_interval=40)[0]


def history_by_key(comm, sim):
    out = {}
    for kind in sim.kinds:
        c = kind.contacts
        rows = c.real_rows()
        key = comm.allgather_rows(c.key[rows].copy())
        hist = comm.allgather_rows(c.history[rows].copy())
        _, first = np.unique(key, return_index=True)  # straddling pairs: two identical copies
        out[kind.name] = (key[first], hist[first])
    return out


def reference(law):
    if law not in _REFERENCE:
        ref = make_scene(law).build(comm=SerialComm())
        ref.run(N_STEPS)
        serial = SerialComm()
        _REFERENCE[law] = (bodies_by_gid(serial, ref), history_by_key(serial, ref), (ref.step, ref.time, ref.dt))
    return _REFERENCE[law]


def same(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def assert_matches(comm, sim, law, what):
    state, hist, scalars = reference(law)
    ok = all(same(a, b) for a, b in zip(state, bodies_by_gid(comm, sim)))
    got = history_by_key(comm, sim)
    ok = ok and sorted(got) == sorted(hist) and all(same(got[k][0], hist[k][0]) and same(got[k][1], hist[k][1])
                                                     for k in hist)
    ok = ok and (sim.step, sim.time, sim.dt) == scalars
    assert not comm.any_flag(not ok), f"{law}: {what}: differs from the serial run"


@pytest.mark.parametrize("law", ["viscous", "hertz_mindlin"])
def test_law_rank_invariance_and_restart(comm, mpi_tmp_path, law):
    configure_threads(comm)
    state, hist, _ = reference(law)
    # the scene exercises what it must: moments (rolling) and contacts with history
    assert np.abs(state[5]).max() > 0 and len(hist["sphere_sphere"][0]) > 50
    if law == "viscous":
        assert np.abs(hist["sphere_sphere"][1][:, 3:7]).max() > 0  # rolling and twisting moments

    sim = make_scene(law).build(comm=comm)
    sim.run(K_STEP)
    tables, meta = sim.checkpoint_tables()
    path = write_checkpoint(mpi_tmp_path / law, K_STEP, tables, meta, comm)
    migrated = getattr(sim.domain, "n_migrated", 0)
    sim.run(N_STEPS - K_STEP)
    assert_matches(comm, sim, law, f"{comm.size} rank(s)")
    if comm.size > 1:
        assert comm.allreduce_sum_int(migrated) > 0, "no body migrated: the test does not test migration"

    again = make_scene(law).build(comm=comm)
    again.restore_checkpoint(*read_checkpoint(path))
    again.run(N_STEPS - K_STEP)
    assert_matches(comm, again, law, f"restored onto {comm.size} rank(s)")

    alone = make_scene(law).build(comm=SerialComm())
    alone.restore_checkpoint(*read_checkpoint(path))
    alone.run(N_STEPS - K_STEP)
    assert_matches(SerialComm(), alone, law, f"written on {comm.size}, restored onto 1 rank")
