"""Permanent deformation per cycle and its fits [m].

This module owns the split of each cycle's settlement into a plastic part (kept after the
cycle) and a resilient part (recovered on unloading), the permanent settlement after N cycles,
and the usual fits of it against the cycle number N:
logarithmic S = a + b ln N and power law S = S1 N^b. Settlement in [m], positive downward;
N [-] counts from 1. A two-parameter law is fitted only to `MIN_FIT_POINTS` or more cycles (through
3 points any smooth monotone curve passes with R² near 1: the fit would carry no information).
Imports numpy only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

MIN_FIT_POINTS = 5  # cycles (or passages) before a settlement law is fitted against N


class LogFit(NamedTuple):
    """S = a + b ln N; a [m], b [m], r2 [-] (coefficient of determination)."""

    a: float
    b: float
    r2: float

    def __call__(self, n):
        return self.a + self.b * np.log(np.asarray(n, dtype=np.float64))


class PowerFit(NamedTuple):
    """S = s1 N^b; s1 [m] (settlement after the first cycle), b [-], r2 [-] (on S)."""

    s1: float
    b: float
    r2: float

    def __call__(self, n):
        return self.s1 * np.asarray(n, dtype=np.float64) ** self.b


def permanent_settlement(table) -> np.ndarray:
    """Settlement at the end of each cycle [m] (a `CycleTable`)."""
    return np.asarray(table.settlement_end, dtype=np.float64)


def plastic_settlement(table) -> np.ndarray:
    """Settlement kept by each cycle: end minus start [m]."""
    return np.asarray(table.settlement_end - table.settlement_start, dtype=np.float64)


def resilient_settlement(table) -> np.ndarray:
    """Settlement recovered on unloading in each cycle: peak minus end [m]."""
    return np.asarray(table.settlement_peak - table.settlement_end, dtype=np.float64)


def fit_log(n, s) -> LogFit:
    """Least-squares fit S = a + b ln N.

    Parameters
    ----------
    n : array [-]
        Cycle numbers, >= 1, at least `MIN_FIT_POINTS` distinct.
    s : array [m]
        Permanent settlement after each of them.
    """
    n, s = _fit_arrays(n, s)
    (b, a) = np.polyfit(np.log(n), s, 1)
    fit = LogFit(float(a), float(b), np.nan)
    return fit._replace(r2=r_squared(s, fit(n)))


def fit_power(n, s) -> PowerFit:
    """Fit S = S1 N^b by least squares on ln S = ln S1 + b ln N.

    R² is computed on S itself, so it compares directly with `fit_log`.

    Raises
    ------
    ValueError
        If any settlement is <= 0 (the power law has no logarithm there).
    """
    n, s = _fit_arrays(n, s)
    if np.any(s <= 0):
        raise ValueError("power-law fit needs positive settlement in every cycle")
    (b, ln_s1) = np.polyfit(np.log(n), np.log(s), 1)
    fit = PowerFit(float(np.exp(ln_s1)), float(b), np.nan)
    return fit._replace(r2=r_squared(s, fit(n)))


def r_squared(observed, predicted) -> float:
    """1 - SS_res / SS_tot; 1 for a perfect fit of constant data."""
    observed = np.asarray(observed, dtype=np.float64)
    ss_res = float(np.sum((observed - predicted) ** 2))
    ss_tot = float(np.sum((observed - observed.mean()) ** 2))
    if ss_tot == 0.0:
        return 1.0 if ss_res == 0.0 else 0.0
    return 1.0 - ss_res / ss_tot


def _fit_arrays(n, s):
    n = np.asarray(n, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    if n.shape != s.shape or n.ndim != 1:
        raise ValueError(f"N and S must be 1-D of equal length, got {n.shape} and {s.shape}")
    keep = np.isfinite(s)
    n, s = n[keep], s[keep]
    if np.any(n < 1):
        raise ValueError("cycle numbers must be >= 1")
    if len(np.unique(n)) < MIN_FIT_POINTS:
        raise ValueError(f"not fitted: {len(np.unique(n))} cycle(s), at least {MIN_FIT_POINTS} needed")
    return n, s
