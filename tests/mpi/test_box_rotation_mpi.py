"""A tilting rigid box on a settling bed: the same bits on 1, 2 or 3 ranks and after a restart.

Run: ``.venv/bin/mpiexec -n 2 .venv/bin/python -m mpi4py -m pytest -q --capture=sys tests/mpi``.
~700 spheres fall in a long box of 5 walls (slabs along x); a rigid box spanning every slab, free
in z and in the tilts about x and y, lands on them under a haversine load applied off its centre.
Its torque, like its force, is an exact sum over all ranks (`pdem.contact.kinds.OrientedBoxContacts`),
so its centre, velocity, orientation, angular momentum and contact force and torque must equal
those of a serial run of the same scene at every sample, and a checkpoint taken mid-run and
restored onto the same ranks and onto one rank must continue to the same bits.
"""
import numpy as np
from factories import box_on_lattice

from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm, configure_threads
from pdem.parallel.slab_domain import SlabDomain

N_STEPS, EVERY, K_STEP = 3000, 50, 1650


def make_scene():
    return box_on_lattice("xyZ", load_point=(0.2, 0.1))


def box_state(sim):
    b = sim.boxes
    return np.concatenate([b.center[0], b.velocity[0], b.ori[0], b.angmom[0], b.angvel[0], b.contact_force[0],
                           b.contact_torque[0]])


def trajectory(sim, n_steps):
    rows = []
    for _ in range(n_steps // EVERY):
        sim.run(EVERY)
        rows.append(box_state(sim))
    return np.array(rows)


def build(comm):
    domain = SlabDomain(comm, axis=0) if comm.size > 1 else None
    return make_scene().build(comm=comm, domain=domain)


def assert_same(comm, a, b, what):
    same = a.shape == b.shape and bool(np.array_equal(a.view(np.uint8), b.view(np.uint8)))
    first = -1 if same or a.shape != b.shape else int(np.flatnonzero(np.any(a != b, axis=-1).ravel())[0])
    assert not comm.any_flag(not same), f"rank {comm.rank}: {what} differs from serial (from sample {first})"


def test_tilting_box_rank_invariant_and_restarts(comm, mpi_tmp_path):
    configure_threads(comm)
    ref_sim = make_scene().build(comm=SerialComm())
    ref = trajectory(ref_sim, N_STEPS)
    sim = build(comm)
    par = trajectory(sim, K_STEP)
    assert_same(comm, par, ref[: len(par)], "box trajectory")
    path = write_checkpoint(mpi_tmp_path, K_STEP, *sim.checkpoint_tables(), comm)
    rest = trajectory(sim, N_STEPS - K_STEP)
    assert_same(comm, rest, ref[len(par):], "box trajectory")
    for target in (comm, SerialComm()):
        again = build(target)
        again.restore_checkpoint(*read_checkpoint(path))
        assert_same(comm, trajectory(again, N_STEPS - K_STEP), ref[len(par):], "restarted box trajectory")
    assert np.max(np.abs(ref[:, 13:16])) > 0.0, "the box never turned"
    assert np.max(np.abs(ref[:, 19:22])) > 0.0, "no contact torque"
    if comm.size > 1:
        kind = sim.kind("sphere_oriented_box")
        assert comm.allreduce_sum_int(int(len(kind.contacts.real_rows()) > 0)) > 1, "box contacts on one rank only"
