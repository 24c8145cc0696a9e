"""Splitting a cyclic record into load cycles, and the per-cycle table.

This module owns `CycleTable` (one entry per completed cycle, SI units: [s], [m], [N]) and the
cycle boundaries: sample indices ``bounds`` (length n_cycles + 1) such that cycle k spans samples
``bounds[k] .. bounds[k+1]`` inclusive (the end of one cycle is the start of the next).
Boundaries come from the ``/cycles`` ``t_start`` column when the file has one, otherwise from
the minima of the load program. Imports numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

# Hysteresis band of the cycle detector, as fractions of the load range: a cycle starts when
# the load rises above HIGH and is complete when it falls back below LOW.
LOW, HIGH = 0.4, 0.6


@dataclass(frozen=True)
class CycleTable:
    """Per-cycle values, each a float64 array of length n_cycles.

    cycle [-] (1..N), t_start [s], settlement_start, settlement_peak, settlement_end [m]
    (positive downward), force_peak, force_min [N].
    """

    cycle: np.ndarray
    t_start: np.ndarray
    settlement_start: np.ndarray
    settlement_peak: np.ndarray
    settlement_end: np.ndarray
    force_peak: np.ndarray
    force_min: np.ndarray

    def __post_init__(self):
        lengths = {len(np.asarray(getattr(self, f.name))) for f in fields(self)}
        if len(lengths) > 1:
            raise ValueError(f"cycle table columns differ in length {sorted(lengths)}")

    def __len__(self) -> int:
        return len(self.cycle)

    @classmethod
    def from_mapping(cls, data) -> "CycleTable":
        """Build from a mapping with the field names (e.g. `Results.cycles`)."""
        return cls(**{f.name: np.asarray(data[f.name], dtype=np.float64) for f in fields(cls)})

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def detect_bounds(load: np.ndarray) -> np.ndarray:
    """Cycle boundaries at the minima of a cyclic load program.

    A cycle is a rise of the load above the fraction HIGH of its range followed by a fall below
    the fraction LOW (hysteresis, so noise near mid-range does not split cycles). Its start is the
    last sample at the minimum of the preceding valley (the moment the load starts to rise); its
    end is the start of the next cycle, or the last minimum of the record. A final cycle whose
    load never falls back is incomplete and dropped.

    Parameters
    ----------
    load : ndarray
        Applied load program [N] (any units; only its shape matters).

    Returns
    -------
    ndarray of int
        ``bounds``, length n_cycles + 1 (empty if no complete cycle).
    """
    load = np.asarray(load, dtype=np.float64)
    lo, hi = load.min(), load.max()
    if not hi > lo:
        return np.zeros(0, dtype=np.int64)
    state = _hysteresis_state(load, lo + LOW * (hi - lo), lo + HIGH * (hi - lo))
    change = np.diff(state)
    rises = np.flatnonzero(change > 0) + 1
    falls = np.flatnonzero(change < 0) + 1
    n = len(falls)  # states alternate from "low", so falls[k] follows rises[k]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    valley_from = np.concatenate(([0], falls))
    valley_to = np.concatenate((rises, [len(load) - 1]))[: n + 1]
    tol = 1e-9 * (hi - lo)
    return np.array([_last_argmin(load[a:b + 1], tol) + a
                     for a, b in zip(valley_from, valley_to)], dtype=np.int64)


def bounds_from_t_start(time: np.ndarray, t_start: np.ndarray) -> np.ndarray:
    """Cycle boundaries from the cycle start times: nearest samples; the last cycle ends at
    the last sample.

    Raises
    ------
    ValueError
        If the start times are not increasing or lie outside the record.
    """
    time = np.asarray(time, dtype=np.float64)
    t_start = np.asarray(t_start, dtype=np.float64)
    if len(t_start) == 0:
        return np.zeros(0, dtype=np.int64)
    if np.any(np.diff(t_start) <= 0):
        raise ValueError("cycle t_start values are not increasing")
    if t_start[0] < time[0] or t_start[-1] >= time[-1]:
        raise ValueError(f"cycle t_start outside the record [{time[0]:g}, {time[-1]:g}] s")
    right = np.clip(np.searchsorted(time, t_start), 1, len(time) - 1)
    nearer_left = (t_start - time[right - 1]) <= (time[right] - t_start)
    starts = np.where(nearer_left, right - 1, right)
    bounds = np.append(starts, len(time) - 1).astype(np.int64)
    if np.any(np.diff(bounds) <= 0):
        raise ValueError("cycles shorter than the output interval")
    return bounds


def cycle_table(time, force, settlement, bounds) -> CycleTable:
    """Per-cycle table from the series and cycle boundaries.

    Parameters
    ----------
    time : ndarray [s]
    force : ndarray [N]
        Force of the ballast on the sleeper (positive upward).
    settlement : ndarray [m]
        Positive downward.
    bounds : ndarray of int
        From `detect_bounds` or `bounds_from_t_start`.
    """
    bounds = np.asarray(bounds, dtype=np.int64)
    if len(bounds) < 2:
        raise ValueError("no complete load cycle in the record")
    time, force, settlement = (np.asarray(a, dtype=np.float64) for a in (time, force, settlement))
    start, end = bounds[:-1], bounds[1:]
    return CycleTable(
        cycle=np.arange(1, len(start) + 1, dtype=np.float64),
        t_start=time[start],
        settlement_start=settlement[start],
        settlement_peak=_segment_reduce(np.maximum, settlement, bounds),
        settlement_end=settlement[end],
        force_peak=_segment_reduce(np.maximum, force, bounds),
        force_min=_segment_reduce(np.minimum, force, bounds),
    )


def cycle_slices(bounds) -> list[slice]:
    """One slice per cycle, end sample included."""
    return [slice(int(a), int(b) + 1) for a, b in zip(bounds[:-1], bounds[1:])]


def _segment_reduce(ufunc, values: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """ufunc over each inclusive segment values[bounds[k]:bounds[k+1]+1]."""
    head = ufunc.reduceat(values[: bounds[-1]], bounds[:-1])
    return ufunc(head, values[bounds[1:]])


def _hysteresis_state(x: np.ndarray, low: float, high: float) -> np.ndarray:
    """1 after x rises above `high`, 0 after it falls below `low`; starts at 0."""
    defined = (x > high) | (x < low)
    last = np.maximum.accumulate(np.where(defined, np.arange(len(x)), -1))
    state = np.where(last >= 0, x[np.maximum(last, 0)] > high, False)
    return state.astype(np.int8)


def _last_argmin(x: np.ndarray, tol: float) -> int:
    return int(np.flatnonzero(x <= x.min() + tol)[-1])
