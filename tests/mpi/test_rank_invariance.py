"""The same scene on 1, 2 or 3 ranks gives the same bits (SPEC §3), compared by gid.

Run: ``.venv/bin/mpiexec -n 3 .venv/bin/python -m mpi4py -m pytest -q --capture=sys tests/mpi``.
A gravity deposition of ~2000 spheres in a long box of 5 walls, decomposed along x, runs long
enough that bodies migrate across slab edges and contacts straddle them. Every rank also runs the
same scene serially (``SerialComm``) and compares, bit for bit, positions, velocities, spins and
contact forces of every body with the gathered parallel result. Verdicts are reduced over ranks.
Serially (one rank) the test compares two serial runs, i.e. only determinism.
"""
import numpy as np
import pytest
from factories import lattice_scene

from pdem.parallel.comm import SerialComm, configure_threads
from pdem.parallel.slab_domain import SlabDomain

_REFERENCE = {}  # n_steps -> serial state by gid (computed once per process)


def make_scene():
    # 2016 bodies on a jittered lattice; sideways motion: bodies cross slab edges
    return lattice_scene(20261122, (24, 6, 14), vx=0.6, vz=0.5, slab_axis=0)[0]


def state_by_gid(gid, *cols):
    order = np.argsort(gid)
    return [gid[order]] + [c[order] for c in cols]


def owned_columns(sim):
    p = sim.particles
    n = p.n_local
    return [p.gid[:n].copy(), p.pos[:n].copy(), p.vel[:n].copy(), p.angvel[:n].copy(), p.force[:n].copy(),
            p.torque[:n].copy()]


def straddling_contacts(sim):
    ss, n = sim.kind("sphere_sphere").contacts, sim.particles.n_local
    rows = ss.real_rows()
    return int(np.count_nonzero((ss.i[rows] >= n) | (ss.j[rows] >= n)))


def serial_reference(n_steps):
    if n_steps not in _REFERENCE:
        ref_sim = make_scene().build(comm=SerialComm())
        ref_sim.run(n_steps)
        _REFERENCE[n_steps] = (state_by_gid(*owned_columns(ref_sim)), ref_sim.dt, ref_sim.contacts_per_particle())
    return _REFERENCE[n_steps]


@pytest.mark.parametrize("balance, n_steps", [(None, 5000), (1.02, 2000)], ids=["fixed-edges", "balanced"])
def test_rank_invariance(comm, balance, n_steps):
    """Fixed uniform edges, and edges moved at (almost) every rebuild by the load balancer."""
    configure_threads(comm)
    domain = SlabDomain(comm, axis=0, balance_threshold=balance) if comm.size > 1 else None
    sim = make_scene().build(comm=comm, domain=domain)
    migrated, straddle, max_ghost_frac = 0, 0, 0.0
    for _ in range(n_steps // 100):
        sim.run(100)
        straddle += straddling_contacts(sim)
        max_ghost_frac = max(max_ghost_frac, sim.domain.halo_fraction(sim.particles))
    migrated = getattr(sim.domain, "n_migrated", 0)
    par = [comm.allgather_rows(c) for c in owned_columns(sim)]
    par = state_by_gid(*par)

    ref, ref_dt, ref_cpp = serial_reference(n_steps)

    names = ("gid", "pos", "vel", "angvel", "force", "torque")
    same = {k: bool(a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8)))
            for k, a, b in zip(names, par, ref)}
    ok = all(same.values())
    assert not comm.any_flag(not ok), f"rank {comm.rank}: differs from serial: {same}; " \
        f"max |dpos| = {np.abs(par[1] - ref[1]).max() if same['gid'] else 'gid sets differ'}"
    assert sim.step == n_steps and sim.dt == ref_dt
    assert len(ref[0]) == 2016 and np.array_equal(ref[0], np.arange(2016))
    assert ref_cpp > (1.0 if n_steps >= 5000 else 0.1)  # contacts formed (a packing forming, at 5000 steps)
    if comm.size > 1:
        assert comm.allreduce_sum_int(migrated) > 0, "no body migrated: the test does not test migration"
        assert comm.allreduce_sum_int(straddle) > 0, "no real contact straddled a slab edge"
        assert comm.allreduce_max(max_ghost_frac) > 0.0
        if balance is not None:
            assert sim.domain.n_rebalanced > 0, "the load balancer never moved an edge"
