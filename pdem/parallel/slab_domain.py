"""Slab decomposition over MPI: the `pdem.parallel.serial_domain.SerialDomain` interface for several ranks.

Owns: the slab edges along one axis, migration of bodies (with every real contact that involves
them: key, state, params, history) to the rank whose slab holds their centre, the ghost layer
(copies of the neighbours' bodies within ``halo = 2 r_max + skin`` of this slab, refreshed every
step) and optional dynamic load balancing (edges moved to equalise owned bodies plus contacts).
A rigid clump (`pdem.bodies.clumps`) is owned, with all its members, by the rank whose slab holds the
clump's centre: its members may stick out of that slab by up to the clump extent e (the largest
member distance from a clump centre), so the halo is 2 r_max + skin + 2 e and the clump rows
migrate with their members.

Why the trajectory does not depend on the rank count: a sphere pair is computed by every rank
that owns one of its bodies, from exact copies of both bodies, and each rank sums forces only for
its owned bodies in partner-gid order (`pdem.contact.forces`); so no force is ever sent back. Ownership
only decides who computes what, never a number, so moving edges does not change any bit.

Talks to MPI only through a ``pdem.parallel.comm`` communicator (numpy buffers: ``neighbor_
exchange``, ``allgather_rows``, integer reductions); imports no mpi4py. The copies between the
particle arrays and the messages are numba kernels of `pdem.parallel.packing` (the per-step ghost
update packs into and receives into buffers kept between steps). The pure helpers (`pack_rows`,
`unpack_rows`, `contact_gids`, `migrating_contacts`) are unit-tested without MPI.
"""
import time as _time

import numpy as np

from pdem.bodies.clumps import unpack_clumps
from pdem.contact.store import KEY_SHIFT_INDEX, KEY_SHIFT_SPHERE
from pdem.errors import InputError
from pdem.parallel import slabs
from pdem.parallel.packing import FLOAT_FIELDS, INT_FIELDS, GhostBuffers, field_views, pack_fields
from pdem.bodies.state import FIELDS

__all__ = ["SlabDomain", "contact_gids", "migrating_contacts", "pack_rows", "unpack_rows"]


# --------------------------------------------------------------------------- pure helpers
def pack_rows(cols, n=None):
    """FIELDS columns -> (int64[n, ki], float64[n, kf]) blocks, one row per body (the domain packs
    the particle arrays directly with `packing.pack_fields`: the same bits)."""
    if n is None:
        n = len(cols["gid"])
    def width(k):
        return int(np.prod(FIELDS[k][1], dtype=np.int64))

    ints = [np.asarray(cols[k]).reshape(n, width(k)).astype(np.int64) for k in INT_FIELDS]
    flts = [np.asarray(cols[k]).reshape(n, width(k)).astype(np.float64) for k in FLOAT_FIELDS]
    return np.concatenate(ints, axis=1), np.concatenate(flts, axis=1)


def unpack_rows(ints, floats):
    """Inverse of `pack_rows`: a dict of FIELDS columns (copies) with their trailing shapes."""
    return {k: np.array(v) for k, v in field_views(ints, floats).items()}


def contact_gids(key, sphere_pair):
    """Global ids in contact keys: ``(gid_i, gid_j)`` for sphere pairs, ``(gid, -1)`` otherwise."""
    key = np.asarray(key, np.int64)
    if sphere_pair:
        return key >> KEY_SHIFT_SPHERE, key & ((1 << KEY_SHIFT_SPHERE) - 1)
    return key >> KEY_SHIFT_INDEX, np.full(key.shape, -1, np.int64)


def migrating_contacts(key, sphere_pair, mig_gid, mig_dest):
    """Which contact rows travel where: (row[m], dest[m]).

    ``mig_gid``/``mig_dest`` are the migrating bodies and their new owners. A row goes to the new
    owner of each of its migrating bodies (once per destination; a pair whose two bodies move to
    different ranks is sent to both)."""
    key = np.asarray(key, np.int64)
    if key.size == 0 or len(mig_gid) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.argsort(mig_gid, kind="stable")
    g_sorted, d_sorted = np.asarray(mig_gid)[order], np.asarray(mig_dest)[order]
    rows, dests = [], []
    for g in contact_gids(key, sphere_pair):
        pos = np.clip(np.searchsorted(g_sorted, g), 0, g_sorted.size - 1)
        hit = g_sorted[pos] == g
        rows.append(np.flatnonzero(hit))
        dests.append(d_sorted[pos[hit]])
    rows, dests = np.concatenate(rows), np.concatenate(dests)
    # a pair with both bodies going to the same rank: send once
    _, first = np.unique(rows * (1 << 20) + dests, return_index=True)
    first.sort()
    return rows[first], dests[first]


# --------------------------------------------------------------------------- the domain
class SlabDomain:
    """Slabs along ``axis`` over the ranks of ``comm`` (rank r owns ``[edges[r], edges[r+1])``).

    Parameters
    ----------
    comm : MpiComm (or SerialComm: one slab, nothing to exchange)
    axis : int
        Decomposed axis (0, 1, 2).
    balance_threshold : float or None
        At every neighbour rebuild, if ``max/mean`` over ranks of (owned bodies + their real
        contacts) exceeds this, the interior edges are moved (`slabs.balanced_edges`, at least
        one halo thick). ``None`` keeps the initial uniform edges.
    """

    def __init__(self, comm, axis=0, balance_threshold=1.1):
        if axis not in (0, 1, 2):
            raise ValueError(f"slab axis must be 0, 1 or 2, got {axis!r}")
        self.comm = comm
        self.axis = int(axis)
        self.balance_threshold = balance_threshold
        self.comm_seconds = 0.0
        self.edges = None
        self.r_max = 0.0
        self.halo = 0.0
        self.send_lo = np.zeros(0, np.int64)  # owned rows that are ghosts on rank - 1
        self.send_hi = np.zeros(0, np.int64)  # ... on rank + 1
        self.n_from_lo = 0  # ghost rows [n_local, n_local + n_from_lo) came from rank - 1
        self.n_from_hi = 0
        self._ghost_buffers = GhostBuffers()  # the per-step update's send list and buffers
        self.n_migrated = 0  # bodies this rank sent away, cumulative
        self.n_rebalanced = 0  # edge moves, cumulative (same on every rank)

    # ------------------------------------------------------------------ set-up
    def distribute(self, particles, cols, owner_pos=None):
        """Keep the bodies of this rank's slab from the full column dict (identical on every rank).

        ``owner_pos`` [n, 3]: the positions that decide the owner (default the bodies' own; a
        rigid clump's members go with their clump's centre). Edges: uniform over the extent of
        these along the axis (load balancing at the first rebuild may move them)."""
        x = np.asarray(cols["pos"] if owner_pos is None else owner_pos)[:, self.axis]
        self.r_max = float(np.max(cols["radius"])) if len(x) else 0.0
        lo, hi = (float(x.min()), float(x.max())) if len(x) else (0.0, 1.0)
        if not hi > lo:
            hi = lo + max(1e-9, 4.0 * self.r_max)
        self.edges = slabs.uniform_edges(lo, hi, self.comm.size)
        mine = slabs.owner(x, self.edges) == self.comm.rank
        particles.append_local({k: np.asarray(v)[mine] for k, v in cols.items() if k in FIELDS})

    def check_rank_count(self, cols, skin):
        """Raise a one-line InputError (on every rank: ``cols`` are the same everywhere) if the
        scene cannot be cut into this many slabs at least one halo (2 r_max + skin) thick, with
        the largest rank count that works."""
        from pdem.errors import InputError

        x = np.asarray(cols["pos"])[:, self.axis]
        if self.comm.size <= 2 or not len(x):
            return
        halo = 2.0 * float(np.max(cols["radius"])) + float(skin)
        most = slabs.max_slabs(float(x.min()), float(x.max()), halo)
        if self.comm.size > most:
            raise InputError(
                f"{self.comm.size} ranks: too many for this scene: its spheres span {float(np.ptp(x)):.4g} m along "
                f"{'xyz'[self.axis]} and each slab must be at least one halo (2 r_max + skin = {halo:.4g} m) thick; "
                f"use at most {most} ranks (or another simulation.slab_axis)")

    def owns(self, points):
        """bool [n]: which of the points [n, 3] lie in this rank's slab."""
        x = np.asarray(points, np.float64).reshape(-1, 3)[:, self.axis]
        return slabs.owner(x, self.edges) == self.comm.rank if len(x) else np.zeros(0, bool)

    def halo_width(self):
        return self.halo

    def _owner_coordinate(self, sim):
        """[n_local] coordinate of each owned body that decides its owner (a rigid clump's members
        go with the clump's centre)."""
        p = sim.particles
        if sim.clumps is None:
            return p.pos[: p.n_local, self.axis]
        return sim.clumps.centre_coordinate(p, self.axis)

    def halo_fraction(self, particles):
        """Ghost rows per owned row on this rank."""
        return particles.n_ghost / max(particles.n_local, 1)

    # ------------------------------------------------------------------ rebuild
    def rebuild(self, sim):
        """Before a neighbour-list rebuild: (balance edges,) migrate bodies and their contacts,
        then rebuild the ghost layer and the send lists."""
        t0 = _time.perf_counter()
        p = sim.particles
        comm = self.comm
        self.r_max = comm.allreduce_max(float(p.radius[: p.n_local].max()) if p.n_local else 0.0)
        extent = sim.clumps.extent if sim.clumps is not None else 0.0
        # a member may stick out of its owner's slab by the clump extent, and so may its partner
        self.halo = 2.0 * self.r_max + float(sim.skin) + 2.0 * extent
        moved_edges = self._balance(sim)
        self._check_clump_reach(sim, extent)
        self._migrate(sim, moved_edges)
        self._build_ghosts(p)
        self.comm_seconds += _time.perf_counter() - t0

    def _check_clump_reach(self, sim, extent):
        """InputError if an interior slab is thinner than the halo widened for the clumps (a clump
        would reach past the neighbouring slab, whose ghosts are the only ones exchanged)."""
        thick = np.diff(self.edges)[1:-1]
        if extent > 0.0 and len(thick) and thick.min() < self.halo * (1.0 - 1e-9):
            raise InputError(
                f"clumps: the largest clump reaches {extent:.4g} m from its centre, so the slab halo "
                f"(2 r_max + skin + 2 x {extent:.4g} = {self.halo:.4g} m) is wider than the thinnest slab "
                f"({thick.min():.4g} m of {self.comm.size} along {'xyz'[self.axis]}); use fewer ranks")

    def _loads(self, sim):
        """Work per owned body: 1 + its real contacts (of every kind)."""
        p = sim.particles
        nl = p.n_local
        w = np.ones(nl)
        for kind in sim.kinds:
            if kind.contacts.n == 0:
                continue
            for idx in kind.body_rows(kind.contacts.real_rows()):
                idx = idx[(idx >= 0) & (idx < nl)]
                w += np.bincount(idx, minlength=nl)[:nl]
        return w

    def _balance(self, sim):
        """Move the interior edges if the load imbalance exceeds the threshold; True if moved."""
        if self.balance_threshold is None or self.comm.size == 1:
            return False
        w = self._loads(sim)
        x = self._owner_coordinate(sim)
        per_rank = self.comm.allgather_rows(np.array([int(w.sum())], np.int64))
        if slabs.imbalance(per_rank) <= self.balance_threshold:
            return False
        xw = self.comm.allgather_rows(np.stack([x, w], axis=1))
        lo, hi = float(self.edges[0]), float(self.edges[-1])
        try:
            new = slabs.balanced_edges(xw[:, 0], xw[:, 1], self.comm.size, lo, hi,
                                       min_thickness=self.halo * (1.0 + 1e-6))
        except ValueError:
            return False  # the box is too short for balanced slabs this thick: keep the edges
        if np.array_equal(new, self.edges):
            return False
        self.edges = new
        self.n_rebalanced += 1
        return True

    def _route(self, ints, floats):
        """Deliver rows to the rank in ``ints[:, 0]`` hop by hop along the chain of slabs.

        Returns the (ints, floats) rows addressed to this rank, received from other ranks."""
        comm, rank = self.comm, self.comm.rank
        got_i, got_f = [], []
        hops = 0
        while comm.any_flag(ints.shape[0] > 0):
            hops += 1
            if hops > comm.size:
                raise RuntimeError("slab migration did not converge (a destination rank outside 0..size-1?)")
            lo, hi = self._directions(ints[:, 0])
            ri_lo, ri_hi = self._exchange(ints[lo], ints[hi])
            rf_lo, rf_hi = self._exchange(floats[lo], floats[hi])
            ints = np.concatenate([ri_lo, ri_hi])
            floats = np.concatenate([rf_lo, rf_hi])
            here = ints[:, 0] == rank
            got_i.append(ints[here])
            got_f.append(floats[here])
            ints, floats = ints[~here], floats[~here]
        if not got_i:
            return np.zeros((0, ints.shape[1]), np.int64), np.zeros((0, floats.shape[1]))
        return np.concatenate(got_i), np.concatenate(got_f)

    def _directions(self, dest):
        """(towards rank - 1, towards rank + 1): bool masks of rows addressed to ranks ``dest``."""
        rank = self.comm.rank
        return dest < rank, dest > rank

    def _exchange(self, send_lo, send_hi):
        """`neighbor_exchange` with the neighbouring slabs (of the chain; a ring in the periodic
        domain)."""
        return self.comm.neighbor_exchange(send_lo, send_hi)

    def _far(self, dest):
        """bool: owners ``dest`` more than one slab away from this rank."""
        return np.abs(dest - self.comm.rank) > 1

    def _migrate(self, sim, edges_moved):
        p = sim.particles
        comm, rank = self.comm, self.comm.rank
        nl = p.n_local
        p.n_ghost = 0  # ghost rows are rebuilt below; contact rows only use keys from here on
        x = self._owner_coordinate(sim)
        dest = slabs.owner(x, self.edges) if nl else np.zeros(0, np.int64)
        leave = dest != rank
        far = leave & self._far(dest)
        if comm.any_flag(bool(far.any()) and not edges_moved):
            msg = ""
            if far.any():
                k = int(np.flatnonzero(far)[0])
                msg = (f" body gid {int(p.gid[k])} at {p.pos[k].tolist()} moved from slab {rank} to slab "
                       f"{int(dest[k])} ({self.edges.tolist()})")
            raise RuntimeError(
                "slab migration: a body crossed more than one slab since the last neighbour rebuild "
                f"(edges along axis {self.axis}: {self.edges.tolist()});{msg or ' see the other ranks'}. "
                "The state has blown up or the slabs are far too thin: use fewer ranks or a smaller time step")
        mig = np.flatnonzero(leave)
        mig_gid, mig_dest = p.gid[mig], dest[mig]
        self.n_migrated += int(mig.size)
        # bodies
        bi, bf = pack_fields(vars(p), mig, lead=mig_dest)  # [dest, ints...], floats
        # contacts: every real row that involves a migrating body
        parcels = []
        for kind in sim.kinds:
            cl = kind.contacts
            real = cl.real_rows()
            rows, cdest = migrating_contacts(cl.key[real], kind.sphere_pair, mig_gid, mig_dest)
            rows = real[rows]
            ci = np.stack([cdest, cl.key[rows], cl.state[rows].astype(np.int64)], axis=1)
            cf = np.concatenate([cl.params[rows], cl.history[rows]], axis=1)
            parcels.append((cl, ci, cf))
        p.remove_local(leave)
        ri, rf = self._route(bi, bf)
        if ri.shape[0]:
            p.append_local(field_views(ri[:, 1:], rf))
        if sim.clumps is not None:  # the clump bodies go where their members went
            self._migrate_clumps(sim.clumps)
        for cl, ci, cf in parcels:
            ri, rf = self._route(ci, cf)
            if ri.shape[0] == 0:
                continue
            key = ri[:, 1]
            # drop rows this rank already holds (pair with a body it owned) and duplicates
            _, first = np.unique(key, return_index=True)
            first.sort()
            have = cl.key[cl.real_rows()]
            first = first[~np.isin(key[first], have)]
            if first.size:
                cl.add_carried(key[first], ri[first, 2].astype(np.int8), rf[first, : cl.n_params],
                               rf[first, cl.n_params :])

    def _migrate_clumps(self, clumps):
        rank = self.comm.rank
        dest = slabs.owner(clumps.pos[:, self.axis], self.edges) if clumps.n else np.zeros(0, np.int64)
        leave = dest != rank
        ci, cf, mi, mf = clumps.pack(leave, dest)
        clumps.keep(~leave)
        ci, cf = self._route(ci, cf)
        mi, mf = self._route(mi, mf)
        if ci.shape[0]:
            clumps.add(*unpack_clumps(ci, cf, mi, mf))

    def _build_ghosts(self, p):
        nl = p.n_local
        x = p.pos[:nl, self.axis]
        rank = self.comm.rank
        # owner given, not recomputed from x: a clump member may lie outside its owner's slab
        dest = slabs.ghost_destinations(x, self.edges, self.halo, owners=np.full(nl, rank, np.int64))
        # -1 in dest means "no neighbour": on rank 0, `dest[:, 0] == rank - 1` selected every
        # body, and all of them were packed and "sent" to MPI_PROC_NULL at every ghost update
        # (5-7 ms per step at 100k bodies per rank, while rank 1 waited: the 2-rank speedup
        # at 200k was 1.5-1.8 instead of 1.9-2.0)
        self.send_lo = np.flatnonzero((dest[:, 0] == rank - 1) & (dest[:, 0] >= 0)).astype(np.int64)
        self.send_hi = np.flatnonzero((dest[:, 1] == rank + 1) & (dest[:, 1] >= 0)).astype(np.int64)
        lo_i, lo_f = pack_fields(vars(p), self.send_lo)
        hi_i, hi_f = pack_fields(vars(p), self.send_hi)
        ri_lo, ri_hi = self.comm.neighbor_exchange(lo_i, hi_i)
        rf_lo, rf_hi = self.comm.neighbor_exchange(lo_f, hi_f)
        self.n_from_lo, self.n_from_hi = ri_lo.shape[0], ri_hi.shape[0]
        p.set_ghosts(field_views(np.concatenate([ri_lo, ri_hi]), np.concatenate([rf_lo, rf_hi])))
        self._ghost_buffers.set_lists(self.send_lo, self.send_hi, self.n_from_lo, self.n_from_hi)

    def renumber_owned(self, order):
        """The owned rows were permuted after `rebuild` (new row k = old row ``order[k]``,
        `Particles.permute_local`): remap the send lists, keeping their order (the neighbours'
        ghost rows stay in the order they were received)."""
        order = np.asarray(order, np.int64)
        new_of_old = np.empty(order.size, np.int64)
        new_of_old[order] = np.arange(order.size, dtype=np.int64)
        self.send_lo = new_of_old[self.send_lo]
        self.send_hi = new_of_old[self.send_hi]
        self._ghost_buffers.set_lists(self.send_lo, self.send_hi, self.n_from_lo, self.n_from_hi)

    # ------------------------------------------------------------------ every step
    def update_ghosts(self, particles):
        """Send pos/vel/angvel of the send lists to the neighbours; overwrite the ghost rows.

        Messages: 9 float64 per row of ``send_lo`` (to rank - 1) and ``send_hi`` (to rank + 1),
        in list order; packed, received and unpacked in buffers kept since the last ghost-layer
        rebuild (`packing.GhostBuffers`: nothing is allocated here)."""
        t0 = _time.perf_counter()
        p = particles
        gb = self._ghost_buffers
        gb.pack(p.pos, p.vel, p.angvel)
        self.comm.neighbor_exchange(gb.send_lo, gb.send_hi, gb.recv_lo, gb.recv_hi)
        gb.unpack(p.pos, p.vel, p.angvel, p.n_local)
        self.comm_seconds += _time.perf_counter() - t0
