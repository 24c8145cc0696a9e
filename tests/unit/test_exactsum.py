"""pdem.exactsum: exact, order-independent sums (serial; no MPI)."""

import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pdem.exactsum import (
    NLIMBS,
    NVAL,
    acc_add,
    acc_merge,
    acc_new,
    acc_normalize,
    acc_value,
    acc_values,
    exact_sum,
    exact_sum_acc,
    exact_sum_groups_acc,
    exact_sum_rows,
    exact_sum_rows_acc,
)


def bits(x):
    return np.float64(x).view(np.int64)


def wide_data(rng, n):
    """Random doubles spanning 1e-300 .. 1e300, both signs."""
    return rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-300, 300, n)


def test_accumulator_layout():
    acc = acc_new()
    assert acc.dtype == np.int64 and acc.shape == (NLIMBS,) and NVAL == NLIMBS - 1
    assert not acc.any()
    assert acc_value(acc) == 0.0


@pytest.mark.parametrize("seed", range(5))
def test_matches_fsum_wide_range(seed):
    rng = np.random.default_rng(seed)
    v = wide_data(rng, 2000)
    v = np.concatenate([v, -v[:700], rng.standard_normal(300)])  # partial cancellation
    assert bits(exact_sum(v)) == bits(math.fsum(v))


@pytest.mark.parametrize(
    "values",
    [
        [1e20, 1.0, -1e20],
        [1e300, 1e-300, -1e300],
        [1.0, 2.0**-53],  # exact tie: rounds to even (1.0)
        [1.0, 2.0**-53, 2.0**-200],  # just above the tie: rounds up
        [1.0 + 2.0**-52, 2.0**-53],  # tie, odd mantissa: rounds up
        [-1.0, -(2.0**-53)],
        [0.1] * 10,
        [1e308, -1e308, 1e308],
        [5e-324, 5e-324, -1.5e-323],  # subnormals to zero
        [5e-324, 2.2250738585072014e-308, -1e-320],  # subnormal and smallest normal
        [-0.0, 3.0, -3.0],
        [12345.678, -0.001, 1e-17, -12345.678],
    ],
)
def test_cancellation_and_rounding_cases(values):
    v = np.array(values, dtype=np.float64)
    assert bits(exact_sum(v)) == bits(math.fsum(values) + 0.0)  # +0.0: a zero sum is +0.0


def test_overflow_and_nonfinite():
    # An intermediate beyond DBL_MAX is fine (math.fsum raises here).
    assert exact_sum(np.array([2.0**1023, 2.0**1023, -(2.0**1023)])) == 2.0**1023
    assert exact_sum(np.array([1.7e308, 1.7e308])) == np.inf
    assert exact_sum(np.array([1.7976931348623157e308, 2.0**970])) == np.inf  # rounds up to 2**1024
    assert exact_sum(np.array([1.7976931348623157e308, 2.0**969])) == 1.7976931348623157e308
    assert exact_sum(np.array([-1.7e308, -1.7e308])) == -np.inf
    assert math.isnan(exact_sum(np.array([1.0, np.nan])))
    assert math.isnan(exact_sum(np.array([np.inf, 1.0])))
    assert math.isnan(exact_sum(np.array([np.inf, -np.inf])))


def test_permutation_independent_bitwise():
    rng = np.random.default_rng(11)
    v = np.concatenate([wide_data(rng, 500), rng.standard_normal(500) * 1e-3])
    ref = exact_sum(v)
    ref_acc = exact_sum_acc(v)
    for _ in range(10):
        p = rng.permutation(v)
        assert bits(exact_sum(p)) == bits(ref)
        np.testing.assert_array_equal(exact_sum_acc(p), ref_acc)  # canonical form is unique


def test_chunks_merged_in_any_order_bitwise():
    rng = np.random.default_rng(12)
    v = wide_data(rng, 3000)
    ref = exact_sum(v)
    for _ in range(10):
        cuts = np.sort(rng.integers(0, v.size, rng.integers(1, 8)))
        chunks = np.split(rng.permutation(v), cuts)
        accs = [exact_sum_acc(c) for c in chunks]
        total = acc_new()
        for j in rng.permutation(len(accs)):
            acc_merge(total, accs[j])
        assert bits(acc_value(total)) == bits(ref)
        # A plain element-wise int64 sum (what MPI_Allreduce(SUM) does) gives the same.
        assert bits(acc_value(np.sum(accs, axis=0))) == bits(ref)


def test_acc_add_matches_exact_sum():
    rng = np.random.default_rng(13)
    v = np.concatenate([wide_data(rng, 200), [5e-324, -7e-322, 2.2e-308]])
    acc = acc_new()
    for x in v:
        acc_add(acc, float(x))
    assert bits(acc_value(acc)) == bits(exact_sum(v))
    acc_normalize(acc)
    np.testing.assert_array_equal(acc, exact_sum_acc(v))


def test_carry_headroom():
    # Limbs close to the carry limit, then additions: the value stays exact.
    acc = acc_new()
    acc[3] = (1 << 62) - 5
    acc[4] = -(1 << 62)
    ref = [math.ldexp(float((1 << 62) - 5), 32 * 3 - 1074), -math.ldexp(2.0**62, 32 * 4 - 1074)]
    extra = [math.ldexp(0.75, 32 * 3 - 1074 + 40), -math.ldexp(0.5, 32 * 4 - 1074 + 60)]
    for x in extra:
        acc_add(acc, x)
    assert np.abs(acc[:NVAL]).max() <= 1 << 62
    assert bits(acc_value(acc)) == bits(math.fsum(ref + extra))


def test_value_does_not_modify_accumulator():
    acc = exact_sum_acc(np.array([1.0, -3.0]))
    acc[0] += 5  # denormalise on purpose
    before = acc.copy()
    acc_value(acc)
    np.testing.assert_array_equal(acc, before)


def test_rows():
    rng = np.random.default_rng(14)
    v = np.column_stack([wide_data(rng, 400), rng.standard_normal(400), np.zeros(400)])
    s = exact_sum_rows(v)
    assert s.shape == (3,)
    for j in range(3):
        assert bits(s[j]) == bits(math.fsum(v[:, j]) + 0.0)
    accs = exact_sum_rows_acc(v)
    assert accs.shape == (3, NLIMBS)
    np.testing.assert_array_equal(acc_values(accs), s)
    # order independence of the rows version
    np.testing.assert_array_equal(exact_sum_rows(v[rng.permutation(400)]), s)
    # non-contiguous input (a column view)
    assert bits(exact_sum(v[:, 1])) == bits(s[1])
    assert exact_sum_rows(np.zeros((0, 2))).tolist() == [0.0, 0.0]


def test_groups():
    """Per-group column sums (the force on each of many rigid boxes): each the correctly rounded
    sum of its rows, whatever their order; empty groups sum to +0.0."""
    rng = np.random.default_rng(15)
    v = np.column_stack([wide_data(rng, 500), rng.standard_normal(500)])
    g = rng.integers(0, 4, 500)  # group 4 of 5 stays empty
    s = acc_values(exact_sum_groups_acc(v, g, 5)).reshape(5, 2)
    for k in range(5):
        for j in range(2):
            assert bits(s[k, j]) == bits(math.fsum(v[g == k, j]) + 0.0)
    p = rng.permutation(500)
    np.testing.assert_array_equal(acc_values(exact_sum_groups_acc(v[p], g[p], 5)).reshape(5, 2), s)
    assert bits(s[4, 0]) == bits(0.0)


def test_runs_without_jit():
    code = textwrap.dedent(
        """
        import math
        import numpy as np
        from pdem.exactsum import (
            acc_merge, acc_new, acc_value, exact_sum, exact_sum_acc, exact_sum_rows
        )
        v = np.array([1e20, 1.0, -1e20, 5e-324, -2.5e-310, 3.0e300, -3.0e300, 0.1, 0.2])
        assert exact_sum(v) == math.fsum(v), exact_sum(v)
        acc = acc_new()
        acc_merge(acc, exact_sum_acc(v[:4]))
        acc_merge(acc, exact_sum_acc(v[4:]))
        assert acc_value(acc) == math.fsum(v)
        r = exact_sum_rows(v.reshape(3, 3))
        assert r.tolist() == [math.fsum(v.reshape(3, 3)[:, j]) for j in range(3)]
        print("ok")
        """
    )
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    res = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=root, capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"
