"""Restart bit for bit on the current rank count (run under mpiexec -n 2 and -n 3 by `make test`).

Every rank computes the uninterrupted serial reference (N steps). The parallel run stops at step
k and writes a checkpoint (collective writer: straddling contacts are held by two ranks and
written once); the checkpoint is then restored (a) onto the same communicator and (b) onto one
rank (each process alone, SerialComm), both continued to N. Positions, velocities, spins, forces
and torques of every body (by gid), the contact tables, Δt, time and the energy-check reference
must equal the reference to the last bit. Restores of a 2-rank checkpoint onto 1, 2 and 3 ranks
through the command line: tests/io/test_restart_cli.py.
"""
from factories import lattice_scene
from run_files import state, state_differences

from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm, configure_threads

N_STEPS, K_STEP = 9000, 6345
_REFERENCE = {}


def make_scene():
    # 900 bodies, a box long along x (the slab axis); bodies cross slab edges
    return lattice_scene(5, (18, 5, 10), vx=0.6, vz=0.5, one_sided=True, slab_axis=0, dt_interval=50,
                         check_interval=40)[0]


def reference():
    if not _REFERENCE:
        ref = make_scene().build(comm=SerialComm())
        ref.run(N_STEPS)
        _REFERENCE.update(state(ref, SerialComm()))
    return _REFERENCE


def assert_matches(comm, sim, what):
    bad = state_differences(reference(), comm, sim)
    assert bad == [], f"{what}: {bad}"


def test_restart_on_this_rank_count_and_on_one(comm, mpi_tmp_path):
    configure_threads(comm)
    reference()
    first = make_scene().build(comm=comm)
    first.run(K_STEP)
    tables, meta = first.checkpoint_tables()
    path = write_checkpoint(mpi_tmp_path, K_STEP, tables, meta, comm)
    n_contacts = comm.allreduce_sum_int(len(tables["contacts/sphere_sphere"]["key"]))
    del first
    saved, saved_meta = read_checkpoint(path)
    assert len(saved["particles"]["gid"]) == 900
    # straddling pairs were held twice and written once
    assert len(saved["contacts/sphere_sphere"]["key"]) > 300
    if comm.size > 1:
        assert n_contacts > len(saved["contacts/sphere_sphere"]["key"])

    again = make_scene().build(comm=comm)
    again.restore_checkpoint(saved, saved_meta)
    again.run(N_STEPS - K_STEP)
    assert_matches(comm, again, f"restored onto {comm.size} rank(s)")

    alone = make_scene().build(comm=SerialComm())
    alone.restore_checkpoint(*read_checkpoint(path))
    alone.run(N_STEPS - K_STEP)
    assert_matches(SerialComm(), alone, f"written on {comm.size}, restored onto 1 rank")
