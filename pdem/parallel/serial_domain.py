"""The serial domain: the interface the step loop uses to talk to other ranks, for one rank.

`pdem.parallel.slab_domain.SlabDomain` implements the same methods over MPI. The simulation
calls only these; physics code never knows its rank.
"""
import numpy as np


class SerialDomain:
    """One rank owns everything: no ghosts, no migration; global reductions are local."""

    def __init__(self, comm):
        self.comm = comm
        self.comm_seconds = 0.0

    def distribute(self, particles, cols, owner_pos=None):
        """Take every body of the full column dict (``owner_pos``: the positions that decide
        ownership, e.g. a clump member's clump centre; nothing to decide here)."""
        particles.append_local(cols)

    def owns(self, points):
        """bool [n]: which of the points [n, 3] lie in this rank's part of space (all)."""
        return np.ones(len(points), bool)

    def halo_width(self):
        return 0.0

    def rebuild(self, sim):
        """Migrate bodies and rebuild ghosts before a neighbour-list rebuild (nothing to do)."""

    def renumber_owned(self, order):
        """The owned rows were permuted (new row k = old row ``order[k]``): nothing to remap."""

    def update_ghosts(self, particles):
        """Refresh ghost positions/velocities/spins every step (nothing to do)."""

    def halo_fraction(self, particles):
        return 0.0
