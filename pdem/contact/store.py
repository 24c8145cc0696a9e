"""Contact store: candidate pairs of one kind with their per-contact parameters and history.

One `ContactList` per contact kind (sphere–sphere, sphere–wall, sphere–facet). A row is a
*candidate* pair from the neighbour list; `state[p]` is 1 while the pair is a real contact
(Yade: the interaction exists) and 0 otherwise. Columns:

- ``i`` row of the first body (int32, as ``j``: rows, never gids); for sphere–sphere
  ``gid[i] < gid[j]`` (Yade's id1 < id2), for sphere–wall and sphere–facet ``i`` is the sphere
  and ``j`` the wall or facet index.
- ``key`` int64 that identifies the pair on every rank and across rebuilds:
  ``gid_i << 32 | gid_j`` for spheres, ``gid << 20 | index`` for walls and facets.
- ``params[:, n_params]`` fixed when the contact is created (Yade's Ip2), ``history[:, width]``
  carried from step to step; the widths are set by the contact law.
- per step outputs: ``overlap`` [m] (0 when not in contact); for walls, facets and boxes also
  ``force`` [N] and ``torque`` [N·m] on the sphere (``row_outputs``). Sphere pairs write their
  forces into per-body slots instead (`pdem.contact.kinds.SpherePairs`).
  Invariant: a row with ``state == 0`` has zero history and zero outputs (`replace` clears the
  rows it installs, the force loops clear a contact that opens), so a loop may skip it.

History survives neighbour-list rebuilds and migration because it is looked up by ``key``.
"""
import numpy as np
from numba import njit, prange

from ..kernels import kernel

KEY_SHIFT_SPHERE = 32
KEY_SHIFT_INDEX = 20
MAX_WALLS_OR_FACETS = 1 << KEY_SHIFT_INDEX
ROW = np.int32  # dtype of row indices (i, j): half the bytes of int64 per candidate
SLACK = 1.05  # capacity over the rows in use when the list grows (a row costs ~100 B)


class ContactList:
    """Candidate pairs of one kind, structure of arrays, with growable capacity."""

    def __init__(self, n_params, history_width, capacity=64, row_outputs=True):
        self.n_params = n_params
        self.history_width = history_width
        self.row_outputs = row_outputs
        self.n = 0
        self.capacity = 0
        self._alloc(capacity)

    def _alloc(self, capacity):
        self.capacity = capacity
        self.i = np.zeros(capacity, ROW)
        self.j = np.zeros(capacity, ROW)
        self.key = np.zeros(capacity, np.int64)
        self.state = np.zeros(capacity, np.int8)
        self.params = np.zeros((capacity, self.n_params))
        self.history = np.zeros((capacity, self.history_width))
        rows = capacity if self.row_outputs else 0
        self.force = np.zeros((rows, 3))
        self.torque = np.zeros((rows, 3))
        self.overlap = np.zeros(capacity)

    def replace(self, i, j, key, key_shift=None):
        """Install a new candidate list; state, params and history of pairs whose key existed
        before are carried over, every other row starts empty.

        ``key_shift``: if ``key >> key_shift`` is the gid of the pair's first body (sphere pairs:
        `KEY_SHIFT_SPHERE`), the carry looks contacts up per first body instead of hashing every
        key (`carry_history_by_first`): the same rows, faster on large lists."""
        n = len(i)
        old = (self.n, self.key, self.state, self.params, self.history)
        cap = max(n, 16)
        if cap > self.capacity or cap < self.capacity // 4:
            cap = int(cap * SLACK) + 16
        else:
            cap = self.capacity
        new_state = np.zeros(cap, np.int8)
        new_params = np.zeros((cap, self.n_params))
        new_hist = np.zeros((cap, self.history_width))
        if key_shift is None or not carry_history_by_first(old[0], old[1], old[2], old[3], old[4], n, key, key_shift,
                                                           new_state, new_params, new_hist):
            carry_history(old[0], old[1], old[2], old[3], old[4], n, key, new_state, new_params, new_hist)
        if cap != self.capacity:
            self._alloc(cap)
        self.state, self.params, self.history = new_state, new_params, new_hist
        # a row with state 0 is clear (zero history and outputs): the force loops skip such rows
        # while the pair stays apart instead of clearing them every step
        for out in (self.force, self.torque, self.overlap):
            out[:n] = 0.0
        self.i[:n] = i
        self.j[:n] = j
        self.key[:n] = key
        self.n = n

    def real_rows(self):
        """Indices of the rows that are real contacts."""
        return np.flatnonzero(self.state[: self.n] == 1)

    def add_carried(self, key, state, params, history):
        """Merge rows received from another rank (migration) into the carry table.

        They are stored as extra rows after ``n`` with state kept, so the next `replace`
        finds them by key."""
        m = len(key)
        if m == 0:
            return
        need = self.n + m
        if need > self.capacity:
            keep = (self.i[: self.n].copy(), self.j[: self.n].copy(), self.key[: self.n].copy(),
                    self.state[: self.n].copy(), self.params[: self.n].copy(), self.history[: self.n].copy())
            self._alloc(int(need * SLACK) + 16)
            for arr, val in zip((self.i, self.j, self.key, self.state, self.params, self.history), keep):
                arr[: self.n] = val
        sl = slice(self.n, need)
        self.key[sl], self.state[sl], self.params[sl], self.history[sl] = key, state, params, history
        self.i[sl] = -1
        self.j[sl] = -1
        self.n = need

    def bytes(self):
        return sum(a.nbytes for a in (self.i, self.j, self.key, self.state, self.params, self.history,
                                      self.force, self.torque, self.overlap))


@njit(cache=True)
def _hash_slot(key, mask):
    h = (key * 0x9E3779B97F4A7C15) & 0x7FFFFFFFFFFFFFFF
    return (h >> 17) & mask


@njit(inline="always", cache=True)
def _copy_row(src, p, dst, q):
    """dst[q, :] = src[p, :] element by element (a slice assignment per contact costs array views
    with atomic reference counts and a memcpy call: 3/4 of the carry's time)."""
    for c in range(src.shape[1]):
        dst[q, c] = src[p, c]


@njit(cache=True)
def carry_history(n_old, old_key, old_state, old_params, old_hist, n_new, new_key, new_state, new_params, new_hist):
    """Copy state/params/history of the real contacts among the old rows to the new rows with
    the same key (open-addressing hash on the key; O(n))."""
    n_real = 0
    for p in range(n_old):
        if old_state[p] == 1:
            n_real += 1
    if n_real == 0:
        return
    size = 1
    while size < 2 * n_real:
        size *= 2
    mask = size - 1
    table = np.full(size, -1, np.int64)
    for p in range(n_old):
        if old_state[p] != 1:
            continue
        s = _hash_slot(old_key[p], mask)
        while table[s] >= 0:
            s = (s + 1) & mask
        table[s] = p
    for q in range(n_new):
        k = new_key[q]
        s = _hash_slot(k, mask)
        while table[s] >= 0:
            p = table[s]
            if old_key[p] == k:
                new_state[q] = 1
                _copy_row(old_params, p, new_params, q)
                _copy_row(old_hist, p, new_hist, q)
                break
            s = (s + 1) & mask


@kernel(size_arg=5)
def carry_history_by_first(n_old, old_key, old_state, old_params, old_hist, n_new, new_key, shift, new_state,
                           new_params, new_hist):
    """`carry_history` without a hash table, for keys whose high part ``key >> shift`` is the
    first body's gid: the old real contacts are chained per first gid (a gid-indexed table of
    list heads) and each new row walks the few contacts of its first body. Old and new rows are
    both in spatial order, so the walks stay in cache (the hash probes were cache misses). A
    key held twice keeps the first row's data, as in `carry_history`. Returns False (and does
    nothing) if the gids are negative or too sparse for a table."""
    g_max = -1
    for p in range(n_old):
        if old_state[p] == 1:
            g = old_key[p] >> shift
            if g < 0:
                return False
            g_max = max(g_max, g)
    if g_max < 0:
        return True
    if g_max + 1 > 16 * (n_old + n_new) + 1024:
        return False
    head = np.full(g_max + 1, -1, np.int64)
    nxt = np.empty(n_old, np.int64)
    for p in range(n_old - 1, -1, -1):  # chains in increasing row order: the first row wins
        if old_state[p] == 1:
            g = old_key[p] >> shift
            nxt[p] = head[g]
            head[g] = p
    for q in prange(n_new):  # each new row reads the chains and writes only its own row
        k = new_key[q]
        g = k >> shift
        if g < 0 or g > g_max:
            continue
        p = head[g]
        while p >= 0:
            if old_key[p] == k:
                new_state[q] = 1
                _copy_row(old_params, p, new_params, q)
                _copy_row(old_hist, p, new_hist, q)
                break
            p = nxt[p]
    return True


@njit(cache=True)
def sphere_pair_keys(i, j, gid):
    out = np.empty(i.shape[0], np.int64)
    for p in range(i.shape[0]):
        out[p] = (gid[i[p]] << 32) | gid[j[p]]
    return out


@njit(cache=True)
def index_pair_keys(i, j, gid):
    out = np.empty(i.shape[0], np.int64)
    for p in range(i.shape[0]):
        out[p] = (gid[i[p]] << 20) | j[p]
    return out
