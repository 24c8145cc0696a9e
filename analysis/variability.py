"""Seed variability of a scalar result over a campaign (SPEC.md 4): mean, standard deviation,
coefficient of variation, range and the confidence interval of the mean.

The interval is Student's t: mean ± t_{1−α/2, n−1} · s/√n with s the sample standard deviation
(n − 1 in the denominator), the t quantile from scipy.stats. Imports numpy and scipy.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import sqrt

import numpy as np
from scipy.stats import t as _t


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


def student_t_cdf(t, dof):
    """P(T ≤ t) for Student's t with ``dof`` degrees of freedom (scipy.stats.t)."""
    return float(_t.cdf(t, dof))


def student_t_quantile(p, dof):
    """t with P(T ≤ t) = p (0 < p < 1) (scipy.stats.t)."""
    return float(_t.ppf(p, dof))


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
