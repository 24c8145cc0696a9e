"""Box-test analysis: from a results file to per-cycle settlement, stiffness and fits.

This module owns `BoxAnalysis` (plain result of one box test) and `analyse_box`, which ties
`cycles`, `settlement` and `stiffness` together. Units: [s], [m], [N], [N/m]. Imports numpy and
this package only (no plotting, no pdem).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cycles import CycleTable, bounds_from_t_start, cycle_table, detect_bounds
from pdem.format.read import Results

from .settlement import (MIN_FIT_POINTS, LogFit, PowerFit, fit_log, fit_power, permanent_settlement,
                         plastic_settlement, resilient_settlement)
from .stiffness import (LOADING_WINDOW, UNLOADING_FRACTION, CycleStiffness,
                        cycle_stiffness)


@dataclass(frozen=True)
class BoxAnalysis:
    """Everything derived from one box test.

    Attributes
    ----------
    results : Results
        The file it came from.
    cycles_source : str
        "file" (the /cycles table) or "detected" (minima of sleeper_load).
    bounds : ndarray of int
        Cycle boundaries in the series (`analysis.cycles`).
    table : CycleTable
    plastic, resilient : ndarray [m]
        Settlement kept / recovered in each cycle.
    stiffness : CycleStiffness [N/m]
    log_fit : LogFit or None
    power_fit : PowerFit or None
    notes : tuple of str
        Why a fit is missing, if one is.
    window, fraction
        Parameters used for the loading and unloading stiffness.
    """

    results: Results
    cycles_source: str
    bounds: np.ndarray
    table: CycleTable
    plastic: np.ndarray
    resilient: np.ndarray
    stiffness: CycleStiffness
    log_fit: LogFit | None
    power_fit: PowerFit | None
    notes: tuple
    window: tuple
    fraction: float

    @property
    def permanent(self) -> np.ndarray:
        return permanent_settlement(self.table)


def analyse_box(results: Results, window=LOADING_WINDOW,
                fraction=UNLOADING_FRACTION) -> BoxAnalysis:
    """Analyse a box test read by `pdem.format.read.read_box_test`.

    Raises
    ------
    ValueError
        If the record holds no complete load cycle or its /cycles table does not fit the series.
    """
    s = results.series
    time, load = s["time"], s["sleeper_load"]
    force, settlement = s["sleeper_force"], s["sleeper_settlement"]
    if results.cycles is not None:
        source = "file"
        table = CycleTable.from_mapping(results.cycles)
        bounds = bounds_from_t_start(time, table.t_start)
    else:
        source = "detected"
        bounds = detect_bounds(load)
        if len(bounds) < 2:
            raise ValueError("no complete load cycle in /series/sleeper_load")
        table = cycle_table(time, force, settlement, bounds)
    if len(table) == 0:
        raise ValueError("the /cycles table is empty")
    stiffness = cycle_stiffness(force, settlement, bounds, table, load=load,
                                window=window, fraction=fraction)
    log_fit, power_fit, notes = _fits(table)
    return BoxAnalysis(results=results, cycles_source=source, bounds=bounds, table=table,
                       plastic=plastic_settlement(table), resilient=resilient_settlement(table),
                       stiffness=stiffness, log_fit=log_fit, power_fit=power_fit,
                       notes=tuple(notes), window=tuple(window), fraction=float(fraction))


def _fits(table: CycleTable):
    """Both settlement fits; a fit that cannot be made is None with a note why."""
    n, s = table.cycle, permanent_settlement(table)
    if len(np.unique(n)) < MIN_FIT_POINTS:  # one note for both laws
        return None, None, [f"settlement laws not fitted: {len(np.unique(n))} cycle(s), at least {MIN_FIT_POINTS} "
                            "needed"]
    fits, notes = [], []
    for name, fit in (("log", fit_log), ("power-law", fit_power)):
        try:
            fits.append(fit(n, s))
        except ValueError as err:
            fits.append(None)
            notes.append(f"{name} fit skipped: {err}")
    return fits[0], fits[1], notes
