"""Seed variability of a scalar result over a campaign (SPEC.md 4): mean, standard deviation,
coefficient of variation, range and the confidence interval of the mean.

The interval is Student's t: mean ± t_{1−α/2, n−1} · s/√n with s the sample standard deviation
(n − 1 in the denominator). Imports numpy only; the t quantile is computed here (bisection on
the regularised incomplete beta function by continued fraction, Numerical Recipes §6.4), so no
scipy is needed.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import exp, lgamma, log, sqrt

import numpy as np


@dataclass(frozen=True)
class Variability:
    """Statistics of n values (units of the values; ``cov`` [-])."""

    n: int
    mean: float
    std: float
    cov: float
    minimum: float
    maximum: float
    ci_low: float
    ci_high: float
    confidence: float


def _betacf(a, b, x):
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / d
    h = d
    for m in range(1, 300):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 / (1.0 + aa * d)
        c = 1.0 + aa / c
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 / (1.0 + aa * d)
        c = 1.0 + aa / c
        h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return h


def _betai(a, b, x):
    """Regularised incomplete beta function I_x(a, b)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = exp(lgamma(a + b) - lgamma(a) - lgamma(b) + a * log(x) + b * log(1.0 - x))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _betacf(a, b, x) / a
    return 1.0 - front * _betacf(b, a, 1.0 - x) / b


def student_t_cdf(t, dof):
    """P(T ≤ t) for Student's t with ``dof`` degrees of freedom."""
    tail = 0.5 * _betai(0.5 * dof, 0.5, dof / (dof + t * t))
    return 1.0 - tail if t >= 0 else tail


def student_t_quantile(p, dof):
    """t with P(T ≤ t) = p (0 < p < 1), by bisection to 1e-12."""
    lo, hi = -1e3, 1e3
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if student_t_cdf(mid, dof) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12:
            break
    return 0.5 * (lo + hi)


def variability(values, confidence=0.95) -> Variability:
    """Statistics of a campaign's values (at least 2, all finite)."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size < 2 or not np.all(np.isfinite(x)):
        raise ValueError(f"variability needs at least 2 finite values, got {x.tolist()}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence = {confidence!r}: must be in (0, 1)")
    n = int(x.size)
    mean = float(x.mean())
    std = float(x.std(ddof=1))
    half = student_t_quantile(0.5 + 0.5 * confidence, n - 1) * std / sqrt(n)
    return Variability(n=n, mean=mean, std=std, cov=std / abs(mean) if mean != 0 else float("inf"),
                       minimum=float(x.min()), maximum=float(x.max()), ci_low=mean - half, ci_high=mean + half,
                       confidence=confidence)
