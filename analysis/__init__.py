"""pdem analysis: turns pdem HDF5 result files into the numbers and figures a track engineer uses.

Reads only pdem's files, with `pdem.format` (the one part of pdem it imports: no numba, mpi4py
or engine). Units are SI throughout ([s], [m], [N], [N/m]); plots and the text summary show [mm], [kN],
[MN/m]. Importing the package has no side effects and does not import matplotlib.

Modules: `cycles` (cycle split and per-cycle table), `stiffness`, `settlement` (permanent
deformation and fits), `box` (box-test pipeline), `plots`, `summary`, ``__main__`` (CLI
``python -m analysis box RESULTS.h5``).
"""

from .box import BoxAnalysis, analyse_box
from .cycles import CycleTable, bounds_from_t_start, cycle_slices, cycle_table, detect_bounds
from .plots import plot_loops, plot_settlement, plot_stiffness
from .settlement import (LogFit, PowerFit, fit_log, fit_power, permanent_settlement,
                         plastic_settlement, resilient_settlement)
from .stiffness import (CycleStiffness, cycle_stiffness, loading_stiffness,
                        resilient_stiffness, slope, unloading_stiffness)
from .summary import summary_dict, write_summary_json, write_summary_text

__all__ = [
    "BoxAnalysis", "CycleStiffness", "CycleTable", "LogFit", "PowerFit", "analyse_box",
    "bounds_from_t_start", "cycle_slices", "cycle_stiffness", "cycle_table", "detect_bounds",
    "fit_log", "fit_power", "loading_stiffness", "permanent_settlement", "plastic_settlement",
    "plot_loops", "plot_settlement", "plot_stiffness", "resilient_settlement",
    "resilient_stiffness", "slope", "summary_dict", "unloading_stiffness", "write_summary_json",
    "write_summary_text",
]
