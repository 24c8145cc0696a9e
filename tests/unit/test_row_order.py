"""Rows are storage only: the spatial reordering at rebuilds and the fast neighbour/contact
builders give the same lists and the same bits as the plain algorithms (no MPI)."""
import numpy as np
import pytest
from factories import shuffled_lattice, shuffled_lattice_scene

from pdem.contact import neighbors
from pdem.contact.store import ContactList, carry_history, carry_history_by_first, sphere_pair_keys
from pdem.parallel.comm import SerialComm
from pdem.parallel.slab_domain import SlabDomain
from pdem.bodies.state import FIELDS, SCRATCH, Particles


def by_gid(sim):
    p = sim.particles
    o = np.argsort(p.gid[: p.n_local])
    return {k: getattr(p, k)[: p.n_local][o] for k in ("gid", "pos", "vel", "angvel", "force", "torque")}


def brute_pairs(pos, radius, gid, n_local, skin):
    out = []
    for i in range(len(pos)):
        for j in range(len(pos)):
            if gid[j] <= gid[i] or (i >= n_local and j >= n_local):
                continue
            d = pos[j] - pos[i]
            cut = radius[i] + radius[j] + skin
            if d @ d <= cut * cut:
                out.append((i, j))
    return sorted(out, key=lambda ij: (ij[0], gid[ij[1]]))


def test_permute_local_moves_every_column_and_keeps_ghosts():
    p = Particles(4)
    rng = np.random.default_rng(0)
    cols = {k: (rng.standard_normal((7,) + s) if np.dtype(d).kind == "f" else rng.integers(0, 99, (7,) + s)).astype(d)
            for k, (d, s) in FIELDS.items()}
    p.append_local(cols)
    p.force[:7] = rng.standard_normal((7, 3))
    ghost = {k: v[:2].copy() for k, v in cols.items()}
    p.set_ghosts(ghost)
    before = {k: getattr(p, k)[:9].copy() for k in {**FIELDS, **SCRATCH}}
    order = np.array([3, 0, 6, 1, 5, 2, 4])
    p.permute_local(order)
    for k, v in before.items():
        assert np.array_equal(getattr(p, k)[:7], v[order]), k
        assert np.array_equal(getattr(p, k)[7:9], v[7:9]), k


def test_rows_in_cell_order_after_a_rebuild():
    sim = shuffled_lattice_scene().build()
    p = sim.particles
    cell = 2.0 * p.radius[: p.n_local].max() + sim.skin
    lo, dims, cs, _, _ = neighbors.bin_cells(p.pos, p.n_local, cell, 8 * p.n_local + 1000)
    idx = np.minimum(((p.pos[: p.n_local] - lo) / cs).astype(np.int64), dims - 1)
    linear = (idx[:, 0] * dims[1] + idx[:, 1]) * dims[2] + idx[:, 2]
    assert np.all(np.diff(linear) >= 0)
    assert not np.array_equal(p.gid[: p.n_local], np.arange(p.n_local))  # the packing was reordered


@pytest.mark.jit
@pytest.mark.parametrize("domain", [None, "slab"])
@pytest.mark.slow  # runs the scene twice per domain
def test_scrambled_rows_give_the_same_bits(domain):
    """Scramble the owned rows (and rebuild) mid-run: the trajectory by gid is bit-identical."""
    dom = (lambda: SlabDomain(SerialComm(), axis=0)) if domain else (lambda: None)
    a = shuffled_lattice_scene().build(comm=SerialComm(), domain=dom())
    b = shuffled_lattice_scene().build(comm=SerialComm(), domain=dom())
    a.run(2000)
    b.run(2000)
    rng = np.random.default_rng(1)
    b.particles.permute_local(rng.permutation(b.particles.n_local))
    b.domain.renumber_owned(np.arange(b.particles.n_local))  # no ghosts on one rank
    b.rebuild()
    b.n_rebuilds = a.n_rebuilds
    real = len(b.kind("sphere_sphere").contacts.real_rows())
    a.run(1000)
    b.run(1000)
    ra, rb = by_gid(a), by_gid(b)
    for k in ra:
        assert np.array_equal(ra[k], rb[k]), k
    assert real > 20 and a.n_rebuilds > 100  # contacts carried through the scramble, many rebuilds


@pytest.mark.jit
def test_the_skin_changes_the_rebuilds_not_the_bits():
    """A thin skin (0.05 r: many more rebuilds, fewer candidate rows) and the default r/4 give the
    same trajectory by gid (jobs/box_test_full_10.toml runs at a 1 mm skin for speed)."""
    a = shuffled_lattice_scene().build(comm=SerialComm())
    b = shuffled_lattice_scene(skin=0.00025).build(comm=SerialComm())
    a.run(3000)
    b.run(3000)
    ra, rb = by_gid(a), by_gid(b)
    for k in ra:
        assert np.array_equal(ra[k], rb[k]), k
    assert b.n_rebuilds > 2 * a.n_rebuilds and a.n_rebuilds > 10
    assert b.kind("sphere_sphere").contacts.n < a.kind("sphere_sphere").contacts.n
    assert len(a.kind("sphere_sphere").contacts.real_rows()) > 20


@pytest.mark.jit
def test_state0_rows_are_clear():
    """ContactList invariant the force loop relies on: a row with state 0 has zero history and
    zero outputs (rows, or a sphere pair's slots), after steps and right after a rebuild."""
    sim = shuffled_lattice_scene().build()
    for _ in range(4):
        sim.run(60)
        for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts):
            off = np.flatnonzero(cl.state[: cl.n] == 0)
            outputs = (cl.force, cl.torque) if cl.row_outputs else ()
            for arr in (cl.history, cl.overlap, *outputs):
                assert not np.any(arr[off]), arr
        pairs = sim.kind("sphere_sphere")  # the slots of a pair that is not a contact are clear
        off = np.flatnonzero(pairs.contacts.state[: pairs.contacts.n] == 0)
        for side in (0, 1):
            s = pairs.slot[off, side]
            s = s[s >= 0]
            assert len(s) > 0 and not np.any(pairs.slot_f[s]) and not np.any(pairs.slot_t[s])
        sim.rebuild()


@pytest.mark.jit
def test_one_rank_slab_domain_sends_no_ghosts():
    """On the first (and last) rank no body goes to the missing neighbour (-1 in the ghost
    destinations used to select every body on rank 0)."""
    sim = shuffled_lattice_scene().build(comm=SerialComm(), domain=SlabDomain(SerialComm(), axis=0))
    sim.run(30)
    assert sim.domain.send_lo.size == 0 and sim.domain.send_hi.size == 0


@pytest.mark.parametrize("n_local_frac", [1.0, 0.7])
def test_sphere_pairs_match_brute_force(n_local_frac):
    pos, radius, _ = shuffled_lattice((5, 4, 4), seed=2)
    n = len(pos)
    gid = np.random.default_rng(3).permutation(n).astype(np.int64) * 3 + 7
    nl = int(n * n_local_frac)
    skin = 0.002
    pi, pj = neighbors.build_sphere_pairs(pos, radius, gid, nl, n, skin, 2 * radius.max() + skin, 8 * n + 1000)
    assert list(zip(pi.tolist(), pj.tolist())) == brute_pairs(pos, radius, gid, nl, skin)


def test_sphere_pairs_dense_cluster_widens_the_buffer():
    rng = np.random.default_rng(4)
    pos = rng.uniform(0, 0.02, (60, 3))
    radius = np.full(60, 0.01)
    gid = np.arange(60, dtype=np.int64)
    pi, pj = neighbors.build_sphere_pairs(pos, radius, gid, 60, 60, 0.0, 0.02, 8 * 60 + 1000)
    assert np.bincount(pi).max() > 16  # more partners than the first buffer width
    assert list(zip(pi.tolist(), pj.tolist())) == brute_pairs(pos, radius, gid, 60, 0.0)


def test_incidence_sorted_by_partner_gid():
    pos, radius, _ = shuffled_lattice((5, 4, 4), seed=6)
    n = len(pos)
    gid = np.random.default_rng(7).permutation(n).astype(np.int64)
    nl = n - 10
    pi, pj = neighbors.build_sphere_pairs(pos, radius, gid, nl, n, 0.002, 2 * radius.max() + 0.002, 8 * n + 1000)
    ptr, pair, first = neighbors.build_incidence(nl, len(pi), pi, pj, gid)
    for b in range(nl):
        rows = pair[ptr[b] : ptr[b + 1]]
        f = first[ptr[b] : ptr[b + 1]]
        assert np.all(np.where(f == 1, pi[rows], pj[rows]) == b)
        partner = np.where(f == 1, gid[pj[rows]], gid[pi[rows]])
        assert np.all(np.diff(partner) > 0)
        assert len(rows) == np.count_nonzero(pi == b) + np.count_nonzero(pj == b)


@pytest.mark.jit
@pytest.mark.parametrize("sparse", [False, True])
def test_carry_by_first_gid_equals_hash_carry(sparse):
    rng = np.random.default_rng(8)
    g = rng.integers(0, 400, (3000, 2)) * (10**6 if sparse else 1)
    g.sort(axis=1)
    g = g[g[:, 0] < g[:, 1]]
    old_key = (g[:, 0] << 32) | g[:, 1]
    old_key[5] = old_key[3]  # a key held twice: the first row's data wins
    n_old = len(old_key)
    old_state = rng.integers(0, 2, n_old).astype(np.int8)
    old_params = rng.standard_normal((n_old, 3))
    old_hist = rng.standard_normal((n_old, 6))
    new_key = np.unique(np.concatenate([old_key[::2], old_key[1::3] + 1]))
    rng.shuffle(new_key)
    n = len(new_key)
    out = []
    for f, extra in ((carry_history, ()), (carry_history_by_first, (32,))):
        st, pa, hi = np.zeros(n, np.int8), np.zeros((n, 3)), np.zeros((n, 6))
        ok = f(n_old, old_key, old_state, old_params, old_hist, n, new_key, *extra, st, pa, hi)
        assert ok is None or ok is (not sparse)
        out.append((st, pa, hi))
    if not sparse:
        for x, y in zip(*out):
            assert np.array_equal(x, y)
        assert out[0][0].sum() > 100


@pytest.mark.jit
def test_replace_with_key_shift_equals_plain_replace():
    pos, radius, _ = shuffled_lattice((5, 4, 4), seed=9)
    n = len(pos)
    gid = np.arange(n, dtype=np.int64)
    pi, pj = neighbors.build_sphere_pairs(pos, radius, gid, n, n, 0.002, 2 * radius.max() + 0.002, 8 * n + 1000)
    key = sphere_pair_keys(pi, pj, gid)
    lists = [ContactList(3, 6), ContactList(3, 6)]
    rng = np.random.default_rng(10)
    for cl in lists:
        cl.replace(pi, pj, key)
        cl.state[: cl.n] = (np.arange(cl.n) % 3 != 0)
        cl.params[: cl.n] = np.arange(3 * cl.n).reshape(-1, 3)
        cl.history[: cl.n] = np.arange(6 * cl.n).reshape(-1, 6)
    keep = rng.random(len(pi)) < 0.8
    lists[0].replace(pi[keep], pj[keep], key[keep])
    lists[1].replace(pi[keep], pj[keep], key[keep], key_shift=32)
    a, b = lists
    assert a.n == b.n
    for name in ("i", "j", "key", "state", "params", "history", "force", "overlap"):
        assert np.array_equal(getattr(a, name)[: a.n], getattr(b, name)[: b.n]), name
