"""Ghost send lists of the slab domain: only bodies within a halo of an existing neighbour are
sent, and they stay right after the owned rows are reordered at rebuilds.

Run: ``.venv/bin/mpiexec -n 3 .venv/bin/python -m mpi4py -m pytest -q --capture=sys tests/mpi``.
(Rank 0 used to select every owned body for its missing lower neighbour, pack them all and
send them to MPI_PROC_NULL at every step.)
"""
import numpy as np
from factories import shuffled_lattice_scene

from pdem.parallel.slab_domain import SlabDomain


def test_send_lists(comm):
    domain = SlabDomain(comm, axis=0, balance_threshold=None) if comm.size > 1 else None
    sim = shuffled_lattice_scene((18, 5, 6), seed=11, slab_axis=0).build(comm=comm, domain=domain)
    d, p = sim.domain, sim.particles
    for _ in range(5):
        sim.run(200)
        if comm.size == 1:
            continue
        lo, hi = d.edges[comm.rank], d.edges[comm.rank + 1]
        # the lists as the rebuild made them (rows renumbered after the reordering)
        assert np.all(np.abs(p.pos_at_rebuild[d.send_lo, 0] - lo) <= d.halo)
        assert np.all(np.abs(hi - p.pos_at_rebuild[d.send_hi, 0]) <= d.halo)
        if comm.rank == 0:
            assert d.send_lo.size == 0
        if comm.rank == comm.size - 1:
            assert d.send_hi.size == 0
        assert d.send_lo.size + d.send_hi.size < p.n_local
        # every owned body near an inner edge is sent
        near = np.flatnonzero(p.pos_at_rebuild[: p.n_local, 0] - lo <= d.halo) if comm.rank > 0 else []
        assert set(np.asarray(near).tolist()) <= set(d.send_lo.tolist())
