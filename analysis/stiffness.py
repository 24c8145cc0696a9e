"""Stiffness of force-displacement records [N/m].

This module owns the loading stiffness (least-squares slope over a force window of the loading
branch), the unloading stiffness (slope over the start of the unloading branch, as the thesis
identified E_k from it, ch. 4.3) and the per-cycle stiffnesses of cyclic tests, including the
resilient stiffness (F_peak - F_min) / (resilient displacement). Forces in [N], displacements
in [m] (settlement, positive downward, so the slopes are positive). Imports numpy only.

The slope is the least-squares fit of force on displacement: in pdem the force of the ballast
on a body is the noisy quantity (contact chatter) while the body's displacement is smooth, so
force is the dependent variable.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .cycles import CycleTable, cycle_slices
from .settlement import resilient_settlement

LOADING_WINDOW = (0.1, 0.9)  # fractions of the loading branch's force range
UNLOADING_FRACTION = 0.5     # fraction of the force drop that the unloading slope uses


class CycleStiffness(NamedTuple):
    """Per-cycle stiffness [N/m], arrays of length n_cycles (NaN where undefined)."""

    loading: np.ndarray
    unloading: np.ndarray
    resilient: np.ndarray


def slope(force, disp) -> float:
    """Least-squares slope dF/du [N/m]; inf if the displacement does not vary.

    Raises
    ------
    ValueError
        With fewer than two samples.
    """
    force = np.asarray(force, dtype=np.float64)
    disp = np.asarray(disp, dtype=np.float64)
    if len(force) < 2:
        raise ValueError(f"stiffness needs at least 2 samples, got {len(force)}")
    du = disp - disp.mean()
    var = np.dot(du, du)
    cov = np.dot(du, force - force.mean())
    if var == 0.0:
        return np.inf if cov == 0.0 else np.copysign(np.inf, cov)
    return float(cov / var)


def loading_stiffness(force, disp, window=LOADING_WINDOW, peak: int | None = None) -> float:
    """Slope of the loading branch over a force window [N/m].

    Parameters
    ----------
    force, disp : ndarray
        One load cycle or one monotonic test [N], [m].
    window : (float, float)
        Force window as fractions of the branch's force range (min to peak), default 10-90 %.
    peak : int, optional
        Index of the peak (end of loading); default the force maximum.
    """
    lo, hi = _check_window(window)
    force, disp = _arrays(force, disp)
    peak = int(np.argmax(force)) if peak is None else int(peak)
    f, u = force[: peak + 1], disp[: peak + 1]
    f0, f1 = f.min(), f.max()
    inside = (f >= f0 + lo * (f1 - f0)) & (f <= f0 + hi * (f1 - f0))
    return slope(f[inside], u[inside])


def unloading_stiffness(force, disp, fraction=UNLOADING_FRACTION,
                        peak: int | None = None) -> float:
    """Slope of the start of the unloading branch [N/m].

    Uses the samples from the peak onward, as long as the force has dropped by less than
    `fraction` of the whole drop (peak to the minimum after it).

    Parameters
    ----------
    force, disp : ndarray
        One load cycle or one load-unload test [N], [m].
    fraction : float
        Part of the force drop used, 0 < fraction <= 1 (default 0.5).
    peak : int, optional
        Index of the peak (start of unloading); default the force maximum.
    """
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"unloading fraction must be in (0, 1], got {fraction}")
    force, disp = _arrays(force, disp)
    peak = int(np.argmax(force)) if peak is None else int(peak)
    f, u = force[peak:], disp[peak:]
    threshold = f[0] - fraction * (f[0] - f.min())
    below = np.flatnonzero(f < threshold)
    stop = below[0] if len(below) else len(f)
    return slope(f[:stop], u[:stop])


def resilient_stiffness(table: CycleTable) -> np.ndarray:
    """(F_peak - F_min) / (settlement_peak - settlement_end) per cycle [N/m].

    NaN where the sleeper did not rebound (resilient displacement <= 0).
    """
    rebound = resilient_settlement(table)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = (table.force_peak - table.force_min) / rebound
    return np.where(rebound > 0, k, np.nan)


def cycle_stiffness(force, disp, bounds, table: CycleTable, load=None,
                    window=LOADING_WINDOW, fraction=UNLOADING_FRACTION) -> CycleStiffness:
    """Loading, unloading and resilient stiffness of every cycle [N/m].

    Parameters
    ----------
    force, disp : ndarray
        Ballast force on the sleeper [N], settlement [m].
    bounds : ndarray of int
        Cycle boundaries (`analysis.cycles`).
    table : CycleTable
        Per-cycle table (for the resilient stiffness).
    load : ndarray, optional
        Applied load program [N]; its maximum marks the peak of each cycle (smoother than the
        force). Default: the force maximum.
    window, fraction
        As in `loading_stiffness` and `unloading_stiffness`.
    """
    force, disp = _arrays(force, disp)
    marker = force if load is None else np.asarray(load, dtype=np.float64)
    slices = cycle_slices(bounds)
    k_load = np.full(len(slices), np.nan)
    k_unload = np.full(len(slices), np.nan)
    for i, s in enumerate(slices):
        peak = int(np.argmax(marker[s]))
        try:
            k_load[i] = loading_stiffness(force[s], disp[s], window, peak)
        except ValueError:
            pass  # too few samples in the window: left NaN
        try:
            k_unload[i] = unloading_stiffness(force[s], disp[s], fraction, peak)
        except ValueError:
            pass
    return CycleStiffness(k_load, k_unload, resilient_stiffness(table))


def _arrays(force, disp):
    force = np.asarray(force, dtype=np.float64)
    disp = np.asarray(disp, dtype=np.float64)
    if force.shape != disp.shape or force.ndim != 1:
        raise ValueError(f"force and displacement must be 1-D of equal length, "
                         f"got {force.shape} and {disp.shape}")
    if len(force) == 0:
        raise ValueError("empty force-displacement record")
    return force, disp


def _check_window(window):
    lo, hi = (float(w) for w in window)
    if not 0.0 <= lo < hi <= 1.0:
        raise ValueError(f"force window must satisfy 0 <= lo < hi <= 1, got {window}")
    return lo, hi
