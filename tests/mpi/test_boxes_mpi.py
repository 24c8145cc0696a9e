"""A loaded rigid box on a settling bed: the same box trajectory, bit for bit, on 1, 2 or 3 ranks.

Run: ``.venv/bin/mpiexec -n 2 .venv/bin/python -m mpi4py -m pytest -q --capture=sys tests/mpi``.
~700 spheres fall in a long box of 5 walls (slabs along x); a rigid box (z translation only,
haversine load plus its weight) spanning every slab lands on them. The box is replicated and
integrated on every rank from the exact global sum of its contact forces, so its centre,
velocity and contact force must equal those of a serial run of the same scene at every sample.
"""
import numpy as np
from factories import box_on_lattice

from pdem.parallel.comm import SerialComm, configure_threads
from pdem.parallel.slab_domain import SlabDomain

N_STEPS, EVERY = 3000, 50


def make_scene():
    return box_on_lattice("xyXYZ")


def trajectory(sim):
    rows = []
    for _ in range(N_STEPS // EVERY):
        sim.run(EVERY)
        b = sim.boxes
        rows.append(np.concatenate([b.center[0], b.velocity[0], b.contact_force[0]]))
    return np.array(rows)


def test_box_trajectory_rank_invariant(comm):
    configure_threads(comm)
    domain = SlabDomain(comm, axis=0) if comm.size > 1 else None
    sim = make_scene().build(comm=comm, domain=domain)
    par = trajectory(sim)
    ref = trajectory(make_scene().build(comm=SerialComm()))
    same = bool(np.array_equal(par.view(np.uint8), ref.view(np.uint8)))
    first = int(np.flatnonzero(np.any(par != ref, axis=1))[0]) if not same else -1
    assert not comm.any_flag(not same), f"rank {comm.rank}: box trajectory differs from serial from sample {first}"
    assert np.max(ref[:, 8]) > 0.0, "the box never touched the bed"
    if comm.size > 1:
        assert comm.allreduce_sum_int(len(sim.kind("sphere_box").contacts.real_rows())) > 0
        assert comm.allreduce_sum_int(int(len(sim.kind("sphere_box").contacts.real_rows()) > 0)) > 1, (
            "box contacts on one rank only"
        )
