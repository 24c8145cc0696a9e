"""pdem.parallel.packing: the numba packing kernels give exactly the numpy expressions they replace."""
import numpy as np
import pytest

from pdem.parallel.comm import SerialComm
from pdem.parallel.packing import (GHOST_WIDTH, GhostBuffers, field_views, pack_fields, pack_ghost_rows,
                                   unpack_ghost_rows)
from pdem.parallel.slab_domain import pack_rows, unpack_rows
from pdem.bodies.state import FIELDS, Particles


def arrays(n, seed=0):
    """FIELDS columns of n rows with every bit pattern a float can have (NaN payloads, -0.0,
    subnormals, infinities) and full-range ints."""
    rng = np.random.default_rng(seed)
    out = {}
    for k, (dt, shape) in FIELDS.items():
        if np.dtype(dt).kind == "f":
            bits = rng.integers(0, 2**63, (n,) + shape, dtype=np.int64) * rng.choice([1, -1], (n,) + shape)
            a = bits.view(np.float64).copy()
            a.reshape(-1)[: min(4, a.size)] = [-0.0, 5e-324, np.inf, -np.inf][: min(4, a.size)]
        else:
            a = rng.integers(-(2**62), 2**62, (n,) + shape, dtype=np.int64)
        out[k] = a.astype(dt)
    return out


def same_bits(a, b):
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    return np.array_equal(np.ascontiguousarray(a).view(np.uint8), np.ascontiguousarray(b).view(np.uint8))


@pytest.mark.parametrize("m", [0, 1, 17])
def test_pack_ghost_rows_is_the_numpy_concatenation(m):
    a = arrays(40)
    rows = np.random.default_rng(m).choice(40, m, replace=False).astype(np.int64)  # any order
    out = np.full((m + 3, GHOST_WIDTH), 7.0)
    pack_ghost_rows(a["pos"], a["vel"], a["angvel"], rows, out)
    want = np.concatenate([a["pos"][rows], a["vel"][rows], a["angvel"][rows]], axis=1)
    assert same_bits(out[:m], want)
    assert np.all(out[m:] == 7.0)  # the rest of the buffer untouched


def test_unpack_ghost_rows_is_the_slice_assignment():
    a, b = arrays(30, 1), arrays(30, 2)
    block = np.concatenate([b["pos"], b["vel"], b["angvel"]], axis=1)[:12]
    got = {k: a[k].copy() for k in ("pos", "vel", "angvel")}
    unpack_ghost_rows(np.vstack([block, np.zeros((5, 9))]), 12, 10, got["pos"], got["vel"], got["angvel"])
    for k, c in (("pos", 0), ("vel", 3), ("angvel", 6)):
        want = a[k].copy()
        want[10:22] = block[:, c : c + 3]
        assert same_bits(got[k], want)


def test_ghost_kernels_refuse_rows_outside():
    a = arrays(5)
    with pytest.raises(IndexError):
        pack_ghost_rows(a["pos"], a["vel"], a["angvel"], np.array([0, 5]), np.zeros((2, 9)))
    with pytest.raises(IndexError):
        pack_ghost_rows(a["pos"], a["vel"], a["angvel"], np.array([0, 1, 2]), np.zeros((2, 9)))
    with pytest.raises(IndexError):
        unpack_ghost_rows(np.zeros((3, 9)), 3, 3, a["pos"], a["vel"], a["angvel"])


@pytest.mark.parametrize("m", [0, 1, 13])
def test_pack_fields_is_pack_rows_of_the_columns(m):
    a = arrays(25, 3)
    rows = np.random.default_rng(m).choice(25, m, replace=False).astype(np.int64)
    ints, flts = pack_fields(a, rows)
    wi, wf = pack_rows({k: v[rows] for k, v in a.items()}, m)
    assert same_bits(ints, wi) and same_bits(flts, wf)
    dest = np.arange(m, dtype=np.int64) - 3
    li, lf = pack_fields(a, rows, lead=dest)
    assert same_bits(li, np.concatenate([dest[:, None], wi], axis=1)) and same_bits(lf, wf)
    with pytest.raises(IndexError, match="outside"):
        pack_fields(a, np.array([25]))


def test_pack_fields_from_particles_arrays_and_field_views_round_trip():
    a = arrays(9, 4)
    p = Particles(4)
    p.append_local(a)  # capacity > 9: arrays with spare rows
    rows = np.array([8, 0, 3], np.int64)
    ints, flts = pack_fields(vars(p), rows)
    views, copies = field_views(ints, flts), unpack_rows(ints, flts)
    assert set(views) == set(FIELDS)
    for k in FIELDS:
        assert same_bits(views[k], a[k][rows]) and same_bits(copies[k], a[k][rows])
    q = Particles(2)
    q.append_local(field_views(ints[1:], flts[1:]))  # what migration does: append copies the views
    for k in FIELDS:
        assert same_bits(getattr(q, k)[: q.n_local], a[k][rows[1:]])


def test_ghost_buffers_update_like_numpy_and_reuse_buffers():
    """The per-step update with the buffers (SerialComm: nothing received) and the recv views
    filled by hand: send views hold the numpy concatenation, unpack writes the ghost rows; the
    buffers are reallocated only when a list grows."""
    a = arrays(50, 5)
    gb = GhostBuffers()
    lo, hi = np.array([4, 1, 9], np.int64), np.array([30, 2], np.int64)
    gb.set_lists(lo, hi, 4, 2)
    assert gb.reallocations == 2
    gb.pack(a["pos"], a["vel"], a["angvel"])
    for rows, view in ((lo, gb.send_lo), (hi, gb.send_hi)):
        assert view.flags.c_contiguous
        assert same_bits(view, np.concatenate([a["pos"][rows], a["vel"][rows], a["angvel"][rows]], axis=1))
    b = arrays(6, 6)
    block = np.concatenate([b["pos"], b["vel"], b["angvel"]], axis=1)
    assert gb.recv_lo.shape == (4, 9) and gb.recv_hi.shape == (2, 9) and gb.recv_hi.flags.c_contiguous
    gb.recv_lo[:], gb.recv_hi[:] = block[:4], block[4:]
    pos, vel, w = a["pos"].copy(), a["vel"].copy(), a["angvel"].copy()
    gb.unpack(pos, vel, w, 40)
    assert same_bits(pos[40:46], b["pos"]) and same_bits(vel[40:46], b["vel"]) and same_bits(w[40:46], b["angvel"])
    assert same_bits(pos[:40], a["pos"][:40]) and same_bits(pos[46:], a["pos"][46:])
    send_buf = gb.send_lo.base
    gb.set_lists(hi, lo[:1], 1, 3)  # smaller lists: the same buffers
    assert gb.reallocations == 2 and gb.send_lo.base is send_buf
    gb.set_lists(np.arange(40), lo, 0, 60)
    assert gb.reallocations == 4
    lo_r, hi_r = SerialComm().neighbor_exchange(gb.send_lo, gb.send_hi, gb.recv_lo[:0], gb.recv_hi[:0])
    assert lo_r.shape == (0, 9) and hi_r.shape == (0, 9)
    with pytest.raises(RuntimeError, match="single"):
        SerialComm().neighbor_exchange(gb.send_lo, gb.send_hi, gb.recv_lo, gb.recv_hi)
    with pytest.raises(TypeError, match="recv_hi"):
        SerialComm().neighbor_exchange(gb.send_lo, gb.send_hi, gb.recv_lo, None)
