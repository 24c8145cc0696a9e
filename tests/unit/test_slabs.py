"""pdem.parallel.slabs (pure functions, no MPI) and the serial communicator."""

import os
import subprocess
import sys

import numpy as np
import pytest

from pdem.parallel import slabs
from pdem.parallel.comm import SerialComm, get_comm, threads_per_rank
from pdem.parallel.slabs import balanced_edges, ghost_destinations, imbalance, owner, uniform_edges


# --------------------------------------------------------------------------- uniform_edges
def test_uniform_edges():
    e = uniform_edges(-1.0, 2.0, 3)
    np.testing.assert_allclose(e, [-1.0, 0.0, 1.0, 2.0])
    assert e[0] == -1.0 and e[-1] == 2.0
    assert uniform_edges(0.0, 1.0, 1).tolist() == [0.0, 1.0]
    e7 = uniform_edges(0.1, 0.7, 7)
    assert e7.size == 8 and e7[-1] == 0.7 and np.all(np.diff(e7) > 0)
    with pytest.raises(ValueError):
        uniform_edges(1.0, 1.0, 2)
    with pytest.raises(ValueError):
        uniform_edges(0.0, 1.0, 0)


# --------------------------------------------------------------------------- owner
def test_owner_interior_edges_belong_to_upper_slab():
    e = np.array([0.0, 1.0, 2.0, 3.0])
    x = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.999, 3.0, -5.0, 7.0])
    assert owner(x, e).tolist() == [0, 0, 1, 1, 2, 2, 2, 0, 2]
    assert owner(1.0, e) == 1 and isinstance(owner(1.0, e), int)
    assert owner(np.nextafter(1.0, 0.0), e) == 0
    assert owner(np.empty(0), e).shape == (0,)
    assert owner(np.array([0.3, 5.0]), [0.0, 1.0]).tolist() == [0, 0]  # one slab


def test_owner_every_coordinate_has_one_owner():
    rng = np.random.default_rng(0)
    e = np.sort(rng.uniform(0, 10, 6))
    x = rng.uniform(-2, 12, 1000)
    r = owner(x, e)
    size = e.size - 1
    inside = (x >= e[0]) & (x < e[-1])
    assert np.all((e[r[inside]] <= x[inside]) & (x[inside] < e[r[inside] + 1]))
    assert np.all(r[x < e[0]] == 0) and np.all(r[x >= e[-1]] == size - 1)


def test_owner_rejects_bad_edges():
    with pytest.raises(ValueError):
        owner(0.5, [0.0, 1.0, 1.0])
    with pytest.raises(ValueError):
        owner(0.5, [0.0])


# --------------------------------------------------------------------------- ghosts
def test_ghost_destinations():
    e = np.array([0.0, 1.0, 2.0, 3.0])
    w = 0.25
    x = np.array([0.1, 0.8, 0.75, 1.0, 1.1, 1.5, 1.8, 2.0, 2.9, -1.0, 4.0, 0.7499])
    d = ghost_destinations(x, e, w)
    expect = [
        [-1, -1],  # 0.1: rank 0, far from edge 1
        [-1, 1],  # 0.8: within 0.25 of edge 1
        [-1, 1],  # 0.75: exactly width away -> included
        [0, -1],  # 1.0: on the edge, owned by rank 1, ghost on rank 0
        [0, -1],
        [-1, -1],
        [-1, 2],
        [1, -1],  # 2.0: owned by rank 2
        [-1, -1],  # last rank has no upper neighbour
        [-1, -1],  # below the first edge: rank 0
        [-1, -1],  # above the last edge: rank 2, no upper neighbour
        [-1, -1],
    ]
    assert d.dtype == np.int64 and d.tolist() == expect


def test_ghost_destinations_single_slab_and_empty():
    assert ghost_destinations([0.5], [0.0, 1.0], 10.0).tolist() == [[-1, -1]]
    assert ghost_destinations(np.empty(0), [0.0, 1.0, 2.0], 0.1).shape == (0, 2)


def test_ghost_destinations_thin_slab_raises():
    e = np.array([0.0, 1.0, 1.1, 3.0])
    with pytest.raises(ValueError, match="thinner than the halo width"):
        ghost_destinations([0.5], e, 0.2)
    # End slabs may be thinner than the halo; an interior slab exactly as thick is fine.
    ghost_destinations([0.5], [0.0, 0.05, 1.0, 1.05], 0.2)
    ghost_destinations([0.5], [0.0, 1.0, 1.2, 3.0], 0.2)
    with pytest.raises(ValueError):
        ghost_destinations([0.5], e, -1.0)


def test_ghost_destinations_are_complete():
    # Brute force: every rank whose slab is within width of x (except the owner).
    rng = np.random.default_rng(1)
    e = np.array([0.0, 1.0, 1.5, 2.7, 3.0, 4.2])
    w = 0.3
    x = rng.uniform(-0.5, 4.7, 2000)
    d = ghost_destinations(x, e, w)
    own = owner(x, e)
    for i in range(x.size):
        want = set()
        for r in range(e.size - 1):
            dist = max(e[r] - x[i], x[i] - e[r + 1], 0.0)
            if r != own[i] and dist <= w:
                want.add(r)
        got = {int(v) for v in d[i] if v >= 0}
        assert got == want, (x[i], got, want)


# --------------------------------------------------------------------------- balance
def test_balanced_edges_uniform_weights():
    rng = np.random.default_rng(2)
    x = rng.uniform(0.0, 10.0, 10000)
    e = balanced_edges(x, 1.0, 4, 0.0, 10.0)
    assert e[0] == 0.0 and e[-1] == 10.0 and np.all(np.diff(e) > 0)
    counts = np.bincount(owner(x, e), minlength=4)
    assert imbalance(counts) < 1.001


def test_balanced_edges_skewed_weights():
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(0, 1, 3000), rng.uniform(1, 10, 1000)])
    w = rng.uniform(0.5, 2.0, x.size)
    for size in (2, 3, 5):
        e = balanced_edges(x, w, size, 0.0, 10.0)
        loads = np.bincount(owner(x, e), weights=w, minlength=size)
        assert imbalance(loads) < 1.01, (size, loads)
        assert imbalance(loads) < imbalance(
            np.bincount(owner(x, uniform_edges(0, 10, size)), weights=w, minlength=size)
        )


def test_balanced_edges_order_independent_and_deterministic():
    rng = np.random.default_rng(4)
    x = np.round(rng.uniform(0, 5, 3000), 2)  # many ties in x
    w = rng.integers(1, 4, x.size) * 0.1
    e = balanced_edges(x, w, 3, 0.0, 5.0)
    p = rng.permutation(x.size)
    assert balanced_edges(x[p], w[p], 3, 0.0, 5.0).tobytes() == e.tobytes()


def test_balanced_edges_min_thickness():
    x = np.full(100, 0.5)  # all bodies at one point
    e = balanced_edges(x, 1.0, 4, 0.0, 1.0, min_thickness=0.2)
    assert e[0] == 0.0 and e[-1] == 1.0
    assert np.all(np.diff(e) >= 0.2 - 1e-15)
    ghost_destinations(x, e, 0.2)  # the result is usable with that halo
    e = balanced_edges(x, 1.0, 4, 0.0, 1.0)  # default: only strictly increasing
    assert np.all(np.diff(e) > 0)
    with pytest.raises(ValueError, match="do not fit"):
        balanced_edges(x, 1.0, 4, 0.0, 1.0, min_thickness=0.3)


def test_balanced_edges_degenerate_inputs():
    np.testing.assert_array_equal(balanced_edges([], [], 3, 0.0, 3.0), uniform_edges(0, 3, 3))
    np.testing.assert_array_equal(balanced_edges([1.0], 0.0, 3, 0.0, 3.0), uniform_edges(0, 3, 3))
    assert balanced_edges([0.2, 0.7], 1.0, 1, 0.0, 1.0).tolist() == [0.0, 1.0]
    e = balanced_edges([-5.0, 0.25, 0.75, 9.0], 1.0, 2, 0.0, 1.0)  # outside: clipped
    assert e.size == 3 and 0.0 < e[1] < 1.0
    with pytest.raises(ValueError):
        balanced_edges([0.5], [-1.0], 2, 0.0, 1.0)
    with pytest.raises(ValueError):
        balanced_edges([0.5], [np.nan], 2, 0.0, 1.0)


def test_imbalance():
    assert imbalance([1, 1, 1]) == 1.0
    assert imbalance([3.0, 1.0]) == 1.5
    assert imbalance([0, 0]) == 1.0
    with pytest.raises(ValueError):
        imbalance([])


# --------------------------------------------------------------------------- serial comm
def test_import_parallel_does_not_import_mpi4py():
    code = (
        "import sys, pdem.parallel as p; c = p.get_comm(); "
        "print(type(c).__name__, 'mpi4py' in sys.modules)"
    )
    launcher = ("PMI_SIZE", "PMI_RANK", "OMPI_COMM_WORLD_SIZE", "SLURM_STEP_NUM_TASKS")
    env = {k: v for k, v in os.environ.items() if k not in launcher}
    res = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["SerialComm", "False"]


def test_serial_comm_interface():
    c = SerialComm()
    assert get_comm(c) is c and (c.rank, c.size) == (0, 1)
    c.barrier()
    assert c.bcast({"a": 1}) == {"a": 1}
    assert c.allreduce_max(2.5) == 2.5 and isinstance(c.allreduce_max(2.5), float)
    assert c.allreduce_min(3) == 3 and isinstance(c.allreduce_min(3), int)
    assert c.allreduce_sum_int(np.array([1, 2])).tolist() == [1, 2]
    with pytest.raises(TypeError):
        c.allreduce_sum_int(1.5)
    assert c.any_flag(True) is True and c.any_flag(0) is False
    assert c.exact_sum(np.array([1e20, 1.0, -1e20])) == 1.0
    rows = np.array([[1e20, 1.0], [1.0, 2.0], [-1e20, 3.0]])
    assert c.exact_sum_rows(rows).tolist() == [1.0, 6.0]
    a = np.arange(6, dtype=np.int32).reshape(3, 2)
    g = c.gather_rows(a)
    assert g.dtype == np.int32 and g.tolist() == a.tolist() and g is not a
    assert c.allgather_rows(np.arange(3.0)).tolist() == [0.0, 1.0, 2.0]
    lo, hi = c.neighbor_exchange(np.ones((2, 3)), np.ones((1, 3), dtype=np.int64))
    assert lo.shape == (0, 3) and lo.dtype == np.float64
    assert hi.shape == (0, 3) and hi.dtype == np.int64
    assert c.node_allgather("x") == ["x"]
    assert threads_per_rank(c) >= 1


def test_module_layout():
    public = {"uniform_edges", "owner", "ghost_destinations", "balanced_edges", "imbalance"}
    assert set(slabs.__all__) == public
