"""Pure helpers of pdem.parallel.slab_domain and the Particles methods migration uses (no MPI)."""
import numpy as np
import pytest

from pdem.contact.store import KEY_SHIFT_INDEX, KEY_SHIFT_SPHERE
from pdem.parallel.comm import SerialComm
from pdem.parallel.slab_domain import SlabDomain, contact_gids, migrating_contacts, pack_rows, unpack_rows
from pdem.build.scene import Scene
from pdem.bodies.state import FIELDS, SCRATCH, Particles


def random_cols(n, seed=0):
    rng = np.random.default_rng(seed)
    cols = {}
    for k, (dt, shape) in FIELDS.items():
        a = rng.standard_normal((n,) + shape) if np.dtype(dt).kind == "f" else rng.integers(0, 1 << 40, (n,) + shape)
        cols[k] = a.astype(dt)
    cols["gid"] = np.arange(100, 100 + n, dtype=np.int64)
    return cols


@pytest.mark.parametrize("n", [0, 1, 7])
def test_pack_unpack_roundtrip_is_exact(n):
    cols = random_cols(n)
    ints, flts = pack_rows(cols)
    assert ints.dtype == np.int64 and flts.dtype == np.float64 and ints.shape[0] == flts.shape[0] == n
    back = unpack_rows(ints, flts)
    assert set(back) == set(FIELDS)
    for k, (dt, shape) in FIELDS.items():
        assert back[k].dtype == dt and back[k].shape == (n,) + shape
        assert np.array_equal(back[k].view(np.uint8), cols[k].view(np.uint8))


def test_contact_gids():
    gi, gj = np.array([3, 70000, 2**31 - 1]), np.array([9, 70001, 2**31])
    key = (gi << KEY_SHIFT_SPHERE) | gj
    a, b = contact_gids(key, True)
    assert a.tolist() == gi.tolist() and b.tolist() == gj.tolist()
    key = (gi << KEY_SHIFT_INDEX) | np.array([0, 4, 5])
    a, b = contact_gids(key, False)
    assert a.tolist() == gi.tolist() and b.tolist() == [-1, -1, -1]


def test_migrating_contacts():
    pairs = [(1, 2), (2, 5), (3, 4), (5, 6), (7, 8)]
    key = np.array([(i << KEY_SHIFT_SPHERE) | j for i, j in pairs])
    # 2 -> rank 1, 5 -> rank 1, 6 -> rank 3
    rows, dest = migrating_contacts(key, True, np.array([6, 2, 5]), np.array([3, 1, 1]))
    got = sorted(zip(rows.tolist(), dest.tolist()))
    assert got == [(0, 1), (1, 1), (3, 1), (3, 3)]  # (2,5) once to rank 1, (5,6) to both ranks
    rows, dest = migrating_contacts(key, True, np.zeros(0, np.int64), np.zeros(0, np.int64))
    assert rows.size == dest.size == 0
    wkey = np.array([(4 << KEY_SHIFT_INDEX) | 0, (4 << KEY_SHIFT_INDEX) | 2, (9 << KEY_SHIFT_INDEX) | 1])
    rows, dest = migrating_contacts(wkey, False, np.array([4]), np.array([0]))
    assert rows.tolist() == [0, 1] and dest.tolist() == [0, 0]


def test_particles_remove_local_and_set_ghosts():
    p = Particles(4)
    cols = random_cols(6)
    p.append_local(cols)
    p.force[:6] = np.arange(18.0).reshape(6, 3)
    p.set_ghosts(random_cols(3, seed=1))
    assert p.n_local == 6 and p.n_ghost == 3 and p.n_total == 9
    assert np.array_equal(p.pos_at_rebuild[6:9], p.pos[6:9])
    mask = np.array([False, True, False, False, True, False])
    p.remove_local(mask)
    assert p.n_local == 4 and p.n_ghost == 0
    assert p.gid[:4].tolist() == [100, 102, 103, 105]
    assert np.array_equal(p.pos[:4], cols["pos"][~mask])
    assert np.array_equal(p.force[:4], np.arange(18.0).reshape(6, 3)[~mask])
    assert set(SCRATCH) <= set(vars(p))
    p.append_local(random_cols(2, seed=2))  # allowed again: no ghosts
    assert p.n_local == 6


def small_scene():
    rng = np.random.default_rng(3)
    g = np.stack(np.meshgrid(np.arange(6), np.arange(3), np.arange(4), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * 0.016 + rng.uniform(-5e-4, 5e-4, (len(g), 3))
    scene = Scene(dt="auto", damping=0.3, gravity=(0.0, 0.0, -9.81))
    m = scene.material(density=2700.0, young=1e7, poisson=0.3, friction_angle=0.5)
    scene.add_spheres(
        pos, 0.005 * rng.uniform(0.6, 1.4, len(g)), m, vel=np.c_[rng.uniform(-1, 1, len(g)), 0 * g[:, :2]]
    )
    scene.add_wall(2, 0.0, m)
    scene.add_wall(0, 0.0, m)
    scene.add_wall(0, 0.096, m)
    return scene


@pytest.mark.jit
def test_slab_domain_on_one_rank_matches_serial_domain():
    a = small_scene().build(comm=SerialComm())
    b = small_scene().build(comm=SerialComm(), domain=SlabDomain(SerialComm(), axis=0))
    a.run(300)
    b.run(300)
    pa, pb = a.particles, b.particles
    assert pb.n_ghost == 0 and b.domain.halo_width() > 0 and b.domain.halo_fraction(pb) == 0.0
    oa, ob = np.argsort(pa.gid[: pa.n_local]), np.argsort(pb.gid[: pb.n_local])
    for name in ("gid", "pos", "vel", "angvel", "force"):
        assert np.array_equal(getattr(pa, name)[oa], getattr(pb, name)[ob]), name


def test_slab_domain_rejects_bad_axis():
    with pytest.raises(ValueError, match="slab axis"):
        SlabDomain(SerialComm(), axis=3)
