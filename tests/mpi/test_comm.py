"""pdem.parallel.comm on 1, 2 or 3 ranks.

Run: ``.venv/bin/mpiexec -n 2 .venv/bin/python -m mpi4py -m pytest -q --capture=sys tests/mpi``.
Every rank runs every test and the assertions are rank-agnostic: a result is first made global
(every rank checks the same gathered/reduced value, or the check is reduced with ``all_ranks``).
"""

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from pdem import exactsum
from pdem.parallel.comm import MpiComm, SerialComm, get_comm, threads_per_rank


def all_ranks(comm, ok):
    """True on every rank iff ``ok`` is true on every rank."""
    return not comm.any_flag(not ok)


def wide_data(seed, n):
    rng = np.random.default_rng(seed)
    v = rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-300, 300, n)
    return np.concatenate([v, -v[: n // 3], rng.standard_normal(n), [1e20, 1.0, -1e20, 5e-324]])


def my_chunk(comm, a, seed=0):
    """This rank's share of ``a``: uneven, shuffled, possibly empty pieces."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(a))
    cuts = np.sort(rng.integers(0, len(a), comm.size - 1))
    return a[np.split(perm, cuts)[comm.rank]]


def test_get_comm_matches_world(comm):
    assert get_comm() is not None
    assert isinstance(comm, (SerialComm, MpiComm))
    assert 0 <= comm.rank < comm.size
    ranks = comm.allgather_rows(np.array([comm.rank]))
    assert ranks.tolist() == list(range(comm.size))
    assert comm.bcast({"size": comm.size, "from": comm.rank}) == {"size": comm.size, "from": 0}


def test_reductions(comm):
    assert comm.allreduce_max(float(comm.rank)) == float(comm.size - 1)
    assert comm.allreduce_min(comm.rank + 5) == 5
    assert isinstance(comm.allreduce_min(comm.rank + 5), int)
    assert comm.allreduce_sum_int(comm.rank + 1) == comm.size * (comm.size + 1) // 2
    s = comm.allreduce_sum_int(np.array([[1, comm.rank]]))
    assert s.shape == (1, 2) and s.tolist() == [[comm.size, comm.size * (comm.size - 1) // 2]]
    m = comm.allreduce_max(np.array([comm.rank, -comm.rank], dtype=np.float64))
    assert m.tolist() == [comm.size - 1.0, 0.0]


def test_any_flag(comm):
    assert comm.any_flag(comm.rank == comm.size - 1) is True
    assert comm.any_flag(False) is False
    assert comm.any_flag(True) is True


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_sum_equals_serial_bitwise(comm, seed):
    data = wide_data(seed, 3000)
    serial = exactsum.exact_sum(data)
    assert serial == math.fsum(data)
    total = comm.exact_sum(my_chunk(comm, data, seed))
    # Same bits as the serial sum, on every rank.
    assert np.float64(total).tobytes() == np.float64(serial).tobytes()
    got = comm.allgather_rows(np.array([total]))
    assert np.all(got.view(np.int64) == np.float64(serial).view(np.int64))


def test_exact_sum_rows_equals_serial_bitwise(comm):
    rng = np.random.default_rng(5)
    col = wide_data(6, 1000)
    data = np.column_stack([col, rng.standard_normal(col.size) * 1e-5, np.zeros(col.size)])
    serial = exactsum.exact_sum_rows(data)
    total = comm.exact_sum_rows(my_chunk(comm, data, 7))
    assert total.tobytes() == serial.tobytes()
    # A rank with no rows still takes part (shape (0, k)).
    part = data if comm.rank == 0 else data[:0]
    assert comm.exact_sum_rows(part).tobytes() == serial.tobytes()


def test_exact_sum_groups_equals_serial_bitwise(comm):
    rng = np.random.default_rng(8)
    col = wide_data(9, 1200)
    data = np.column_stack([col, rng.standard_normal(col.size) * 1e-5, np.zeros(col.size)])
    group = rng.integers(0, 7, col.size)
    serial = exactsum.acc_values(exactsum.exact_sum_groups_acc(data, group, 7)).reshape(7, 3)
    rows = my_chunk(comm, np.column_stack([data, group]), 10)
    total = comm.exact_sum_groups(rows[:, :3], rows[:, 3].astype(np.int64), 7)
    assert total.shape == (7, 3) and total.tobytes() == serial.tobytes()
    # the dense per-column layout gives the same bits
    dense = np.zeros((col.size, 21))
    dense[np.arange(col.size)[:, None], 3 * group[:, None] + np.arange(3)] = data
    assert exactsum.exact_sum_rows(dense).tobytes() == serial.tobytes()


def test_exact_sum_nonfinite(comm):
    v = np.array([np.nan]) if comm.rank == comm.size - 1 else np.array([1.0])
    assert math.isnan(comm.exact_sum(v))


def test_gather_rows_order(comm):
    r = comm.rank
    rows = np.column_stack([np.full(r + 1, r), np.arange(r + 1)]).astype(np.int64)
    g = comm.gather_rows(rows)
    expect = [[q, i] for q in range(comm.size) for i in range(q + 1)]
    if comm.rank == 0:
        ok = g.dtype == np.int64 and g.tolist() == expect
    else:
        ok = g is None
    assert all_ranks(comm, ok)
    a = comm.allgather_rows(rows)
    assert a.tolist() == expect
    # Rows with a trailing shape (e.g. inertia tensors [n, 3, 3]).
    def tensors(q):
        return np.arange(9.0).reshape(1, 3, 3) + np.arange(q + 1)[:, None, None] + 100 * q

    all_t = comm.allgather_rows(tensors(r))
    expect_t = np.concatenate([tensors(q) for q in range(comm.size)])
    assert all_t.shape == expect_t.shape and np.array_equal(all_t, expect_t)


@pytest.mark.parametrize("dtype", [np.float64, np.int32, np.uint8, np.bool_, np.float32])
def test_gather_rows_1d_dtypes_and_empty(comm, dtype):
    n = 0 if comm.rank == 0 else 2 * comm.rank
    v = (np.arange(n) + 10 * comm.rank).astype(dtype)
    expect = np.concatenate([(np.arange(2 * q) + 10 * q).astype(dtype) for q in range(comm.size)])
    a = comm.allgather_rows(v)
    assert a.dtype == np.dtype(dtype) and a.shape == expect.shape and np.array_equal(a, expect)
    g = comm.gather_rows(v)
    assert all_ranks(comm, (g is None) if comm.rank else np.array_equal(g, expect))


def test_gather_rows_layout_mismatch_raises_everywhere(comm):
    if comm.size == 1:
        return  # one rank cannot disagree with itself
    cols = 2 if comm.rank == 0 else 3
    with pytest.raises(ValueError, match="differ"):
        comm.allgather_rows(np.zeros((1, cols)))


def payload(src, dst, n, k=3):
    """Rows that rank ``src`` sends to rank ``dst``: encode both and the row number."""
    i = np.arange(n, dtype=np.float64)
    return np.column_stack([np.full(n, src), np.full(n, dst), i] + [i * 0.5] * (k - 3))


def test_neighbor_exchange(comm):
    r, size = comm.rank, comm.size
    n_lo, n_hi = r + 1, 2 * r + 3  # different sizes in each direction
    send_lo, send_hi = payload(r, r - 1, n_lo, 4), payload(r, r + 1, n_hi, 4)
    recv_lo, recv_hi = comm.neighbor_exchange(send_lo, send_hi)
    if r > 0:  # rank r-1 sent us its send_hi: 2*(r-1)+3 rows
        ok_lo = np.array_equal(recv_lo, payload(r - 1, r, 2 * (r - 1) + 3, 4))
    else:
        ok_lo = recv_lo.shape == (0, 4) and recv_lo.dtype == np.float64
    if r < size - 1:  # rank r+1 sent us its send_lo: r+2 rows
        ok_hi = np.array_equal(recv_hi, payload(r + 1, r, r + 2, 4))
    else:
        ok_hi = recv_hi.shape == (0, 4)
    assert all_ranks(comm, ok_lo and ok_hi)


def test_neighbor_exchange_into_buffers(comm):
    """With receive buffers (the ghost update's form): the same rows as the allocating form,
    received into the given arrays; a buffer of the wrong size raises on its rank only, after
    both messages (no rank is left waiting)."""
    r, size = comm.rank, comm.size
    n_lo, n_hi = r + 1, 2 * r + 3
    send_lo, send_hi = payload(r, r - 1, n_lo, 9), payload(r, r + 1, n_hi, 9)
    want_lo, want_hi = comm.neighbor_exchange(send_lo, send_hi)
    buf = np.full((want_lo.shape[0] + want_hi.shape[0] + 2, 9), -1.0)
    recv_lo, recv_hi = buf[: want_lo.shape[0]], buf[want_lo.shape[0] : want_lo.shape[0] + want_hi.shape[0]]
    got_lo, got_hi = comm.neighbor_exchange(send_lo, send_hi, recv_lo, recv_hi)
    ok = got_lo is recv_lo and got_hi is recv_hi
    ok &= np.array_equal(recv_lo, want_lo) and np.array_equal(recv_hi, want_hi) and np.all(buf[-2:] == -1.0)
    assert all_ranks(comm, ok)
    too_many = np.zeros((want_lo.shape[0] + 1, 9))  # expects a row more than rank - 1 sends
    if r > 0:
        with pytest.raises(RuntimeError, match="disagree"):
            comm.neighbor_exchange(send_lo, send_hi, too_many, np.zeros_like(want_hi))
    else:
        comm.neighbor_exchange(send_lo, send_hi, np.zeros((0, 9)), np.zeros_like(want_hi))
    assert all_ranks(comm, size >= 1)


def test_neighbor_exchange_round_trip_int64(comm):
    r = comm.rank
    rng = np.random.default_rng(100 + r)
    mine_lo = rng.integers(-(2**62), 2**62, (r + 2, 5))  # int64, full range
    mine_hi = rng.integers(-(2**62), 2**62, (3, 5))
    got_lo, got_hi = comm.neighbor_exchange(mine_lo, mine_hi)
    # Send back what we received: each rank gets its own arrays again.
    back_lo, back_hi = comm.neighbor_exchange(got_lo, got_hi)
    ok = True
    if r > 0:
        ok &= back_lo.dtype == np.int64 and np.array_equal(back_lo, mine_lo)
    if r < comm.size - 1:
        ok &= np.array_equal(back_hi, mine_hi)
    # Empty sends and 1-D arrays work too.
    e_lo, e_hi = comm.neighbor_exchange(np.empty((0, 2)), np.array([1.5, 2.5]))
    ok &= e_hi.shape == (0,) or e_hi.shape == (0, 2)
    if r > 0:
        ok &= e_lo.tolist() == [1.5, 2.5]
    else:
        ok &= e_lo.size == 0
    assert all_ranks(comm, ok)


def test_threads_per_rank(comm):
    n = threads_per_rank(comm)
    assert n >= 1
    assert n <= len(os.sched_getaffinity(0))
    # Ranks sharing the cores of one node do not oversubscribe them (more ranks than cores:
    # one thread each).
    total = comm.allreduce_sum_int(n)
    if len(comm.node_allgather(0)) == comm.size:
        assert total <= max(comm.size, len(os.sched_getaffinity(0)))


def test_mpi_tmp_path_is_shared(comm, mpi_tmp_path):
    paths = comm.bcast(str(mpi_tmp_path))
    assert paths == str(mpi_tmp_path)
    (mpi_tmp_path / f"rank{comm.rank}.txt").write_text(str(comm.rank))
    comm.barrier()
    names = sorted(p.name for p in mpi_tmp_path.iterdir())
    assert names == sorted(f"rank{q}.txt" for q in range(comm.size))
    comm.barrier()  # nobody leaves before every rank has listed the directory


def test_only_comm_imports_mpi4py():
    """STYLE §7: pdem/parallel/comm.py is the only module of pdem that imports mpi4py."""
    root = Path(__file__).resolve().parents[2] / "pdem"
    pattern = re.compile(r"^\s*(import\s+mpi4py|from\s+mpi4py\b)", re.M)
    offenders = [
        str(p.relative_to(root.parent))
        for p in sorted(root.rglob("*.py"))
        if pattern.search(p.read_text()) and p != root / "parallel" / "comm.py"
    ]
    assert offenders == []


def test_agree_on_failure_when_every_rank_fails(comm, capsys):
    """Every rank fails (at slightly different times, within the grace time): each learns every
    rank's (status, line) in rank order, and the failure report prints once (rank 0) and returns
    the highest status on every rank, without aborting."""
    import time

    from pdem.driver.failures import report_failure
    from pdem.errors import InputError, InstabilityError

    time.sleep(0.05 * comm.rank)
    got = comm.agree_on_failure(2 + comm.rank % 2, f"line {comm.rank}", 30.0)
    assert got == [(2 + r % 2, f"line {r}") for r in range(comm.size)]
    status = report_failure(comm, InputError("x = 1: must be 2"), grace=30.0)
    err = capsys.readouterr().err
    assert status == 2
    assert err == ("pdem: error: x = 1: must be 2\n" if comm.rank == 0 else "")
    exc = InstabilityError("step 7: blew up") if comm.rank == comm.size - 1 else InputError("bad")
    status = report_failure(comm, exc, grace=30.0)
    err = capsys.readouterr().err
    assert status == (4 if comm.size > 1 else 4)
    if comm.rank == 0 and comm.size > 1:
        assert err.splitlines() == [
            "pdem: error: bad (rank 0)",
            f"pdem: unstable: step 7: blew up (rank {comm.size - 1})",
        ]
