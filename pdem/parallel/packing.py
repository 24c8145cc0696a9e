"""Packing of the slab domain's messages: numba kernels and reusable buffers.

Owns the copies between the particle arrays (`pdem.bodies.state.Particles`, structure of arrays) and the
contiguous row blocks that `pdem.parallel.comm` sends, for `pdem.parallel.slab_domain`:

- every step, the ghost update: ``GHOST_WIDTH`` = 9 float64 per ghost (pos [m], vel [m/s],
  angvel [rad/s], in that order), one row per body of a send list, in send-list order
  (`GhostBuffers`, kernels `pack_ghost_rows` / `unpack_ghost_rows`). The send list (rank - 1's
  rows, then rank + 1's) and the send and receive buffers are kept between steps and reallocated
  only when a list grows past their capacity (factor 1.5): a step allocates nothing.
- at neighbour rebuilds (migration, ghost-layer rebuild), every FIELDS column of the given rows
  as an int64 block and a float64 block (`pack_fields`, the same bits as
  ``slab_domain.pack_rows(particles.columns(rows))`` in one pass, without the per-column
  temporaries), and views of the FIELDS columns of received blocks (`field_views`) for
  ``Particles.set_ghosts`` / ``append_local`` to copy once.

Copies only: no arithmetic, so the numbers sent are the bits of the arrays, and the messages
are the same as the numpy expressions they replace (``np.concatenate([pos[rows], vel[rows],
angvel[rows]], axis=1)``, ``pack_rows``); `tests/unit/test_packing.py` checks exact equality.
Pure: no MPI, no particles class; plain arrays in.
"""
import numpy as np
from numba import njit

from pdem.bodies.state import FIELDS

__all__ = ["FLOAT_FIELDS", "GHOST_WIDTH", "GhostBuffers", "INT_FIELDS", "field_views", "pack_fields",
           "pack_ghost_rows", "unpack_ghost_rows"]

GHOST_WIDTH = 9  # pos, vel, angvel: float64 per ghost row
INT_FIELDS = [k for k, (dt, _) in FIELDS.items() if np.dtype(dt).kind in "iu"]
FLOAT_FIELDS = [k for k, (dt, _) in FIELDS.items() if np.dtype(dt).kind == "f"]


def _width(name):
    return int(np.prod(FIELDS[name][1], dtype=np.int64))


# --------------------------------------------------------------------------- kernels
@njit(cache=True)
def pack_ghost_rows(pos, vel, angvel, rows, out):
    """``out[i] = (pos[rows[i]], vel[rows[i]], angvel[rows[i]])`` for i < len(rows); ``out`` has
    at least len(rows) rows of 9 float64 (the rest is left as it is). IndexError for a row
    outside the arrays."""
    lim = min(pos.shape[0], vel.shape[0], angvel.shape[0])
    if rows.shape[0] > out.shape[0]:
        raise IndexError("pack_ghost_rows: more rows than the send buffer holds")
    for i in range(rows.shape[0]):
        r = rows[i]
        if r < 0 or r >= lim:
            raise IndexError("pack_ghost_rows: a send-list row outside the particle arrays")
        for j in range(3):
            out[i, j] = pos[r, j]
            out[i, 3 + j] = vel[r, j]
            out[i, 6 + j] = angvel[r, j]


@njit(cache=True)
def unpack_ghost_rows(block, n, start, pos, vel, angvel):
    """The first ``n`` rows of ``block`` [m >= n, 9] into rows ``start .. start + n`` of pos,
    vel, angvel (columns 0-2, 3-5, 6-8)."""
    if n > block.shape[0] or start < 0 or start + n > min(pos.shape[0], vel.shape[0], angvel.shape[0]):
        raise IndexError("unpack_ghost_rows: rows outside the block or the particle arrays")
    for i in range(n):
        r = start + i
        for j in range(3):
            pos[r, j] = block[i, j]
            vel[r, j] = block[i, 3 + j]
            angvel[r, j] = block[i, 6 + j]


@njit(cache=True)
def _gather_columns(src, rows, out, col):
    """``out[i, col + j] = src[rows[i], j]`` for a 2-D ``src`` (cast to ``out``'s dtype)."""
    w = src.shape[1]
    for i in range(rows.shape[0]):
        r = rows[i]
        for j in range(w):
            out[i, col + j] = src[r, j]


# --------------------------------------------------------------------------- rebuild blocks
def pack_fields(arrays, rows, lead=None):
    """Every FIELDS column of ``rows`` as (int64[n, lead + ki], float64[n, kf]).

    ``arrays``: name -> array with the FIELDS trailing shape (e.g. ``vars(particles)``, of any
    capacity >= max(rows) + 1). ``lead``: optional int64[n] written as column 0 of the int
    block (the destination rank of migration) before the fields. Same bits as
    ``slab_domain.pack_rows({k: arrays[k][rows] for k in FIELDS})`` (with ``lead`` in front)."""
    rows = np.ascontiguousarray(rows, dtype=np.int64).reshape(-1)
    n = rows.size
    off = 0 if lead is None else 1
    ints = np.empty((n, off + sum(_width(k) for k in INT_FIELDS)), np.int64)
    floats = np.empty((n, sum(_width(k) for k in FLOAT_FIELDS)), np.float64)
    if lead is not None:
        ints[:, 0] = lead
    if n == 0:
        return ints, floats
    have = min(np.asarray(arrays[k]).shape[0] for k in FIELDS)
    if rows.min() < 0 or rows.max() >= have:
        raise IndexError(f"pack_fields: rows {rows.min()}..{rows.max()} outside the {have} rows of the arrays")
    for block, names, c in ((ints, INT_FIELDS, off), (floats, FLOAT_FIELDS, 0)):
        for k in names:
            a, w = np.asarray(arrays[k]), _width(k)
            _gather_columns(a.reshape(a.shape[0], w), rows, block, c)
            c += w
    return ints, floats


def field_views(ints, floats):
    """The FIELDS columns of (int block, float block) as views with their trailing shapes (a copy
    only for a column whose dtype differs from its block's): for a consumer that copies them
    anyway (``Particles.set_ghosts``, ``append_local``). `slab_domain.unpack_rows` returns copies."""
    n = ints.shape[0]
    out = {}
    for block, names in ((ints, INT_FIELDS), (floats, FLOAT_FIELDS)):
        c = 0
        for k in names:
            dtype, shape = FIELDS[k]
            w = _width(k)
            out[k] = block[:, c : c + w].reshape((n,) + shape).astype(dtype, copy=False)
            c += w
    return out


# --------------------------------------------------------------------------- ghost update
class GhostBuffers:
    """Send list and preallocated buffers of the per-step ghost update of one rank.

    ``set_lists(send_lo, send_hi, n_from_lo, n_from_hi)`` at every ghost-layer rebuild (and
    after the owned rows are permuted); then every step ``pack(pos, vel, angvel)`` fills the
    send buffer (``send_lo``/``send_hi`` are its views, C-contiguous), the communicator receives
    into ``recv_lo``/``recv_hi`` (views of the receive buffer: rank - 1's rows first), and
    ``unpack(pos, vel, angvel, start)`` writes them to the ghost rows from ``start``."""

    def __init__(self):
        self.rows = np.zeros(0, np.int64)  # send_lo then send_hi
        self.n_recv = 0
        self._send = np.zeros((0, GHOST_WIDTH))
        self._recv = np.zeros((0, GHOST_WIDTH))
        self.reallocations = 0  # buffer growths, cumulative (for tests and benchmarks)
        self._views(0, 0, 0)

    @staticmethod
    def _grown(buf, n):
        if n <= buf.shape[0]:
            return buf, False
        return np.empty((max(n, int(1.5 * buf.shape[0]) + 16), GHOST_WIDTH)), True

    def _views(self, n_lo, n_from_lo, n_from_hi):
        m = self.rows.size
        self.send_lo, self.send_hi = self._send[:n_lo], self._send[n_lo:m]
        self.recv_lo, self.recv_hi = self._recv[:n_from_lo], self._recv[n_from_lo : n_from_lo + n_from_hi]

    def set_lists(self, send_lo, send_hi, n_from_lo, n_from_hi):
        """Rows sent to rank - 1 and rank + 1 (this order in the send buffer) and the rows
        received from each (ghost rows ``start .. start + n_from_lo`` then ``n_from_hi``)."""
        self.rows = np.concatenate([np.asarray(send_lo, np.int64), np.asarray(send_hi, np.int64)])
        self.n_recv = int(n_from_lo) + int(n_from_hi)
        self._send, grew_s = self._grown(self._send, self.rows.size)
        self._recv, grew_r = self._grown(self._recv, self.n_recv)
        self.reallocations += int(grew_s) + int(grew_r)
        self._views(len(send_lo), int(n_from_lo), int(n_from_hi))

    def pack(self, pos, vel, angvel):
        """Fill the send buffer from the owned rows of the send list (``send_lo``/``send_hi``)."""
        pack_ghost_rows(pos, vel, angvel, self.rows, self._send)

    def unpack(self, pos, vel, angvel, start):
        """Received rows (``recv_lo`` then ``recv_hi``) into rows ``start ..`` of pos, vel, angvel."""
        unpack_ghost_rows(self._recv, self.n_recv, int(start), pos, vel, angvel)
