"""Periodic ends along the slab axis: the slabs closed into a ring (``[simulation] periodic``).

Owns: the period ``[lo, hi)`` [m] along the slab axis (L = hi − lo), the wrap of the owned
bodies (a body at x ≥ hi moves to x − L, at x < lo to x + L: per body, after the integration,
before the ghost update: the same operation whatever rank holds it), the ring of slabs (rank 0's
lower neighbour is rank size − 1: halos and migration cross the ends; a ring of one rank is its
own neighbour) and the *image shift* of every ghost row (``image`` [n_total, 3] [m]: −L along
the axis for a copy of a body near hi that sits below lo, +L for a copy of a body near lo above
hi, 0 otherwise).

Minimum image and bit identity: a ghost keeps the true (wrapped) position of its body, and the
sphere-pair geometry of the periodic scenes (`pdem.contact.geometry.PeriodicSphereSphere`)
computes the branch vector as (x_j − x_i) + (s_j − s_i), s the rows' image shifts. The shifts
are 0 or ±L, so s_j − s_i is exact, and x_i, x_j are the same bits on every rank: the pair gives
the same bits whichever rank computes it and whichever of its two bodies is the image there.
The neighbour search sees the shifted positions x + s (a period of more than two halos,
2 (2 r_max + skin), leaves at most one image of a body within reach of another).

One rank: its ring gives it an image of each of its own bodies near an end; a pair across the
ends is then found twice, (i, j') and (i', j); the row whose first body is owned is kept and its
image end is summed into its owned body (`self_image_home`), so every pair is one row as on
several ranks.

Not supported (refused at build, `pdem.build.scene`): rigid or breakable clumps, laws whose
torque lever is the contact point (the cohesive law), walls perpendicular to the periodic axis,
facets and boxes that cross an end without covering the whole period.
"""
import time as _time

import numpy as np
from numba import njit

from pdem.bodies.state import FIELDS
from pdem.errors import InputError
from pdem.parallel import slabs
from pdem.parallel.packing import field_views, pack_fields
from pdem.parallel.slab_domain import SlabDomain

__all__ = ["PeriodicSlabDomain", "wrap_positions"]


@njit(cache=True)
def wrap_positions(pos, n, axis, lo, hi, period):
    """Rows [0, n): x ≥ hi → x − period, x < lo → x + period along ``axis`` [m]; returns how
    many moved."""
    moved = 0
    for k in range(n):
        x = pos[k, axis]
        if x >= hi:
            pos[k, axis] = x - period
            moved += 1
        elif x < lo:
            pos[k, axis] = x + period
            moved += 1
    return moved


class PeriodicSlabDomain(SlabDomain):
    """`SlabDomain` over the period ``[lo, hi)`` along ``axis``, the slabs closed into a ring
    (any rank count, one included)."""

    def __init__(self, comm, axis, lo, hi, balance_threshold=1.1):
        super().__init__(comm, axis=axis, balance_threshold=balance_threshold)
        self.lo, self.hi = float(lo), float(hi)
        self.period = self.hi - self.lo
        self.image = np.zeros((0, 3))  # per particle row: the image shift of a ghost [m]
        self.n_wrapped = 0  # wraps of owned bodies on this rank, cumulative

    # ------------------------------------------------------------------ set-up
    def distribute(self, particles, cols, owner_pos=None):
        """Keep this rank's bodies; the edges cut the period into equal slabs."""
        x = np.asarray(cols["pos"] if owner_pos is None else owner_pos)[:, self.axis]
        self.r_max = float(np.max(cols["radius"])) if len(x) else 0.0
        self.edges = slabs.uniform_edges(self.lo, self.hi, self.comm.size)
        mine = slabs.owner(x, self.edges) == self.comm.rank
        particles.append_local({k: np.asarray(v)[mine] for k, v in cols.items() if k in FIELDS})

    def check_rank_count(self, cols, skin):
        """One-line InputError if the ring cannot have this many slabs at least one halo thick."""
        if not len(cols["radius"]):
            return
        halo = 2.0 * float(np.max(cols["radius"])) + float(skin)
        most = max(1, int(np.floor(self.period / (halo * (1.0 + 1e-9)))))
        if self.comm.size > most:
            raise InputError(
                f"{self.comm.size} ranks: too many for simulation.periodic = [{self.lo:g}, {self.hi:g}]: each of "
                f"the ring's slabs must be at least one halo (2 r_max + skin = {halo:.4g} m) thick; "
                f"use at most {most} ranks")

    # ------------------------------------------------------------------ the ring
    def _directions(self, dest):
        """Rows go the shorter way round the ring (ties: towards rank + 1)."""
        size = self.comm.size
        fwd = (np.asarray(dest, np.int64) - self.comm.rank) % size
        return fwd > size // 2, (fwd > 0) & (fwd <= size // 2)

    def _exchange(self, send_lo, send_hi):
        return self.comm.neighbor_exchange(send_lo, send_hi, ring=True)

    def _far(self, dest):
        size = self.comm.size
        fwd = (np.asarray(dest, np.int64) - self.comm.rank) % size
        return np.minimum(fwd, size - fwd) > 1

    def _build_ghosts(self, p):
        nl = p.n_local
        x = p.pos[:nl, self.axis]
        rank, size = self.comm.rank, self.comm.size
        thin = np.diff(self.edges) < self.halo * (1.0 - 1e-9)
        if thin.any():
            raise InputError(
                f"simulation.periodic: slab(s) {np.flatnonzero(thin).tolist()} of the ring are thinner than the halo "
                f"{self.halo:.4g} m (edges {self.edges.tolist()}); use fewer ranks")
        self.send_lo = np.flatnonzero(x - self.edges[rank] <= self.halo).astype(np.int64)
        self.send_hi = np.flatnonzero(self.edges[rank + 1] - x <= self.halo).astype(np.int64)
        lo_i, lo_f = pack_fields(vars(p), self.send_lo)
        hi_i, hi_f = pack_fields(vars(p), self.send_hi)
        ri_lo, ri_hi = self._exchange(lo_i, hi_i)
        rf_lo, rf_hi = self._exchange(lo_f, hi_f)
        self.n_from_lo, self.n_from_hi = ri_lo.shape[0], ri_hi.shape[0]
        p.set_ghosts(field_views(np.concatenate([ri_lo, ri_hi]), np.concatenate([rf_lo, rf_hi])))
        self._ghost_buffers.set_lists(self.send_lo, self.send_hi, self.n_from_lo, self.n_from_hi)
        image = np.zeros((p.n_total, 3))
        if rank == 0:  # rank size - 1's bodies near hi, below lo
            image[nl: nl + self.n_from_lo, self.axis] = -self.period
        if rank == size - 1:  # rank 0's bodies near lo, above hi
            image[nl + self.n_from_lo: p.n_total, self.axis] = self.period
        self.image = image

    def self_image_home(self, n_local, n_total):
        """int64 [n_total]: for each row the owned row it is an image of (a ring of one rank:
        its ghosts are images of its own bodies), else the row itself; None on several ranks."""
        if self.comm.size > 1:
            return None
        home = np.arange(n_total, dtype=np.int64)
        home[n_local:] = np.concatenate([self.send_hi, self.send_lo])  # received from lo, then from hi
        return home

    # ------------------------------------------------------------------ every step
    def update_ghosts(self, particles):
        """Wrap the owned bodies that left the period (a wrapped body has moved by L since the
        last rebuild: the next step rebuilds neighbours and ghosts), then the ghost update round
        the ring."""
        t0 = _time.perf_counter()
        p = particles
        self.n_wrapped += wrap_positions(p.pos, p.n_local, self.axis, self.lo, self.hi, self.period)
        gb = self._ghost_buffers
        gb.pack(p.pos, p.vel, p.angvel)
        self.comm.neighbor_exchange(gb.send_lo, gb.send_hi, gb.recv_lo, gb.recv_hi, ring=True)
        gb.unpack(p.pos, p.vel, p.angvel, p.n_local)
        self.comm_seconds += _time.perf_counter() - t0
