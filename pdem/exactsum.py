"""Exact, order-independent floating-point sums (a superaccumulator).

Owns: the fixed-point accumulator that makes global sums (the force on a platen, energies,
any reduction across bodies, threads or ranks) independent of summation order, so that a run
gives the same bits on 1, 2 or 3 ranks (SPEC §3, STYLE §7).  Must not import mpi4py: the MPI
reduction of an accumulator lives in ``pdem.parallel.comm``.

Representation
--------------
Every finite double is an integer multiple of 2**-1074.  An accumulator is an ``int64`` array
of ``NLIMBS`` entries: limbs ``0 .. NVAL-1`` hold the exact sum as
``sum_i acc[i] * 2**(32*i - 1074)`` and the last entry counts non-finite inputs (NaN, ±inf).
Each limb nominally holds 32 bits and keeps 31 bits of head-room for carries, so

* ``acc_add`` adds a double exactly (integer mantissa and exponent from ``math.frexp``, which
  is exact, then integer shifts; no floating-point rounding anywhere);
* ``acc_merge`` is an element-wise ``int64`` add, exactly what ``MPI_Allreduce(SUM)`` of the
  arrays does; integer addition is associative, so the result does not depend on order;
* ``acc_value`` propagates carries to the canonical form (limbs ``0..NVAL-2`` in
  ``[0, 2**32)``, the top limb signed) and rounds once, to nearest with ties to even.  The
  result is therefore the correctly rounded exact sum (what ``math.fsum`` returns), a
  deterministic function of the exact sum.  A sum of zeros is ``+0.0``; a sum with any NaN or
  infinity is NaN; an exact sum beyond the double range is ±inf.

``acc_normalize`` brings an accumulator to canonical form; a normalised accumulator can be
summed element-wise over up to 2**31 ranks without overflowing a limb.

All functions are ``numba.njit(cache=True)`` and also run with ``NUMBA_DISABLE_JIT=1``.
"""

import math

import numpy as np
from numba import njit

__all__ = [
    "NLIMBS",
    "NVAL",
    "acc_new",
    "acc_add",
    "acc_merge",
    "acc_normalize",
    "acc_value",
    "acc_values",
    "exact_sum",
    "exact_sum_acc",
    "exact_sum_rows",
    "exact_sum_rows_acc",
    "exact_sum_groups_acc",
]

NVAL = 67  # value limbs: 2**-1074 .. 2**1070 and a signed top limb (room for ~2**63 x DBL_MAX)
NLIMBS = NVAL + 1  # + one counter of non-finite inputs
_EMIN = -1074  # exponent of limb 0 bit 0: the smallest subnormal
_MASK = 0xFFFFFFFF
_LIMIT = 1 << 61  # carry a limb upward once it grows past this
_TWO53 = 9007199254740992.0


@njit(cache=True)
def acc_new():
    """Return an empty accumulator: ``int64[NLIMBS]`` of zeros."""
    return np.zeros(NLIMBS, dtype=np.int64)


@njit(cache=True)
def acc_add(acc, x):
    """Add the double ``x`` to the accumulator ``acc`` exactly (in place).

    NaN and ±inf only increment the non-finite counter (the sum then becomes NaN).
    """
    if not math.isfinite(x):
        acc[NVAL] += 1
        return
    if x == 0.0:
        return
    m, e = math.frexp(x)  # x = m * 2**e, 0.5 <= |m| < 1; exact
    mant = np.int64(m * _TWO53)  # |mant| < 2**53, exact (scaling by a power of two)
    neg = mant < 0
    if neg:
        mant = -mant
    p = e - 53 - _EMIN  # bit position of mant's lowest bit above 2**-1074
    if p < 0:  # subnormal: the bits shifted out are zero
        mant = mant >> (-p)
        p = 0
    k = p >> 5
    s = p & 31
    lo = (mant & _MASK) << s  # < 2**63
    hi = (mant >> 32) << s  # < 2**52
    d0 = lo & _MASK
    d1 = (lo >> 32) + (hi & _MASK)
    d2 = hi >> 32
    if neg:
        acc[k] -= d0
        acc[k + 1] -= d1
        acc[k + 2] -= d2
    else:
        acc[k] += d0
        acc[k + 1] += d1
        acc[k + 2] += d2
    # Keep head-room: carry any limb that grew large, as far up as needed.
    for i in range(k, NVAL - 1):
        v = acc[i]
        if v > _LIMIT or v < -_LIMIT:
            acc[i] = v & _MASK
            acc[i + 1] += v >> 32
        elif i >= k + 2:
            break


@njit(cache=True)
def acc_normalize(acc):
    """Propagate carries in place: limbs ``0..NVAL-2`` in ``[0, 2**32)``, top limb signed.

    The represented value is unchanged; the canonical form is unique for each exact sum.
    """
    for i in range(NVAL - 1):
        v = acc[i]
        acc[i] = v & _MASK
        acc[i + 1] += v >> 32


@njit(cache=True)
def acc_merge(acc, other):
    """Add accumulator ``other`` into ``acc`` (in place): element-wise ``int64`` addition.

    ``acc`` is normalised afterwards so that it can take any number of further merges.
    """
    for i in range(NLIMBS):
        acc[i] += other[i]
    acc_normalize(acc)


@njit(cache=True)
def _bit(a, b):
    return (a[b >> 5] >> (b & 31)) & 1


@njit(cache=True)
def acc_value(acc):
    """Return the exact sum held in ``acc`` rounded to the nearest double (ties to even).

    ``acc`` is not modified.
    """
    if acc[NVAL] != 0:
        return np.nan
    a = acc[:NVAL].copy()
    acc_normalize(a)
    neg = a[NVAL - 1] < 0
    if neg:
        for i in range(NVAL):
            a[i] = -a[i]
        acc_normalize(a)  # now all limbs >= 0: the magnitude
    h = NVAL - 1
    while h >= 0 and a[h] == 0:
        h -= 1
    if h < 0:
        return 0.0
    top = a[h]
    nbits = 0
    while top > 0:
        top >>= 1
        nbits += 1
    length = 32 * h + nbits  # bit length of the magnitude in units of 2**-1074
    if length <= 53:
        mag = a[0]
        if h >= 1:
            mag += a[1] << 32
        value = math.ldexp(float(mag), _EMIN)  # exact: on the double grid
    else:
        shift = length - 53
        mant = np.int64(0)
        for j in range(52, -1, -1):
            mant = (mant << 1) | _bit(a, shift + j)
        rnd = _bit(a, shift - 1)
        sticky = False
        pos = shift - 1
        q = pos >> 5
        if (a[q] & ((np.int64(1) << (pos & 31)) - 1)) != 0:
            sticky = True
        else:
            for i in range(q):
                if a[i] != 0:
                    sticky = True
                    break
        if rnd == 1 and (sticky or (mant & 1) == 1):
            mant += 1  # may reach 2**53: still exact
        top_exp = shift + _EMIN + 53  # value < 2**top_exp, or == if mant == 2**53
        if top_exp > 1024 or (top_exp == 1024 and mant == np.int64(1) << 53):
            value = np.inf  # beyond the double range (math.ldexp would raise without JIT)
        else:
            value = math.ldexp(float(mant), shift + _EMIN)
    if neg:
        return -value
    return value


@njit(cache=True)
def acc_values(accs):
    """Round each row of ``accs`` (``int64[k, NLIMBS]``): ``float64[k]``."""
    k = accs.shape[0]
    out = np.empty(k, dtype=np.float64)
    for j in range(k):
        out[j] = acc_value(accs[j])
    return out


@njit(cache=True)
def exact_sum_acc(values):
    """Normalised accumulator of the 1-D array ``values``."""
    acc = acc_new()
    for i in range(values.shape[0]):
        acc_add(acc, values[i])
    acc_normalize(acc)
    return acc


@njit(cache=True)
def exact_sum(values):
    """Correctly rounded, order-independent sum of the 1-D ``float64`` array ``values``."""
    return acc_value(exact_sum_acc(values))


@njit(cache=True)
def exact_sum_rows_acc(values):
    """Normalised accumulators of the column sums of ``values[n, k]``: ``int64[k, NLIMBS]``."""
    n, k = values.shape
    accs = np.zeros((k, NLIMBS), dtype=np.int64)
    for i in range(n):
        for j in range(k):
            acc_add(accs[j], values[i, j])
    for j in range(k):
        acc_normalize(accs[j])
    return accs


@njit(cache=True)
def exact_sum_groups_acc(values, group, n_groups):
    """Normalised accumulators of the column sums of ``values[n, k]`` per group: row i adds to
    group ``group[i]`` (0 <= group < n_groups): ``int64[n_groups * k, NLIMBS]``, group-major.
    O(n k), whatever the number of groups (e.g. the force on each of many rigid boxes)."""
    n, k = values.shape
    accs = np.zeros((n_groups * k, NLIMBS), dtype=np.int64)
    for i in range(n):
        g = group[i]
        for j in range(k):
            acc_add(accs[g * k + j], values[i, j])
    for r in range(n_groups * k):
        acc_normalize(accs[r])
    return accs


@njit(cache=True)
def exact_sum_rows(values):
    """Column sums of ``values[n, k]``, each exact and correctly rounded: ``float64[k]``."""
    return acc_values(exact_sum_rows_acc(values))
