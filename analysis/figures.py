"""The figure helpers of every plot of the analysis, where an analysis writes by default
(`default_out`), and the plot of a run's preparation.

This module owns how a figure is made and written (matplotlib's object API with the Agg renderer:
no pyplot, no global backend switch; matplotlib is imported only when a plot is drawn, so
``import analysis`` stays light), the logarithmic cycle axis, the kinetic-energy axis, and the
plots of a run's own records against time [s]: `plot_preparation` (preparation.h5 of a staged
run: bed top [m], rigid-body height [m], kinetic energy [J], unbalanced force ratio [-], stages
marked) and `plot_run_series` (results.h5 of a plain run: kinetic energy [J], contacts per
particle [-], unbalanced force ratio [-], force on the floor [N]).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pdem.format.read import read_results, read_series


def default_out(results) -> Path:
    """The default output directory of an analysis of the results file ``results``: RUN/analysis
    for a run folder's file (beside a run_info.json: where ``pdem run``'s post-processing
    writes), else RESULTS-analysis beside the file."""
    from pdem.format.run import RUN_INFO

    results = Path(results)
    if (results.parent / RUN_INFO).exists():
        return results.parent / "analysis"
    return results.with_name(results.stem + "-analysis")


def figure(w=7.0, h=5.0, rows=None, cols=1, sharex=False):
    """(figure, axes) of size w x h [inch]: one axes, or a grid of ``rows`` x ``cols``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), layout="constrained")
    return fig, (fig.add_subplot() if rows is None else fig.subplots(rows, cols, sharex=sharex))


def save(fig, path, dpi=120) -> Path:
    """Write ``fig`` as a PNG; returns the path."""
    path = Path(path)
    fig.savefig(path, dpi=dpi, format="png")
    return path


def log_cycle_axis(ax):
    """Logarithmic cycle axis labelled 1, 10, 100 (not 10^0, 10^1)."""
    from matplotlib.ticker import StrMethodFormatter

    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(StrMethodFormatter("{x:g}"))


def plot_energy(ax, t, kinetic):
    """Kinetic energy [J] on a log axis, clipped 12 decades below its maximum (it starts at 0)."""
    ax.semilogy(t, np.maximum(kinetic, 1e-12 * max(float(np.max(kinetic)), 1e-300)))
    ax.set_ylabel("kinetic energy [J]")


def plot_preparation(h5_path, png_path, stages, body="sleeper centre") -> Path:
    """Bed top, the rigid body's height (``body``: its label), kinetic energy and unbalanced
    force over the preparation; a line where each of ``stages`` (names) after the first starts."""
    s = read_series(h5_path, required=("time", "bed_top", "sleeper_z", "kinetic_energy", "unbalanced_force", "stage"))
    t = s["time"]
    fig, ax = figure(8, 8, rows=3, sharex=True)
    ax[0].plot(t, s["bed_top"], label="top of the bed")
    ax[0].plot(t, np.where(s["sleeper_z"] == 0.0, np.nan, s["sleeper_z"]), label=body)
    ax[0].set_ylabel("height [m]")
    ax[0].legend()
    plot_energy(ax[1], t, s["kinetic_energy"])
    ax[2].semilogy(t, np.maximum(s["unbalanced_force"], 1e-6))
    ax[2].set_ylabel("unbalanced force ratio [-]")
    ax[2].set_xlabel("time [s]")
    for k in range(1, len(stages)):
        starts = t[s["stage"] == k]
        if len(starts):
            for a in ax:
                a.axvline(starts[0], color="0.7", lw=0.8)
            ax[0].text(starts[0], ax[0].get_ylim()[1], stages[k], fontsize=8, va="top")
    return save(fig, png_path, dpi=110)


def plot_run_series(results_path, png_path) -> Path:
    """Kinetic energy, contacts per particle, unbalanced force ratio and the force on the floor of
    a plain run's /series."""
    s = read_results(results_path, required=("kinetic_energy", "contacts_per_particle", "unbalanced_force",
                                             "floor_force_z")).series
    t = s["time"]
    fig, ax = figure(10, 7, rows=2, cols=2, sharex=True)
    plot_energy(ax[0, 0], t, s["kinetic_energy"])
    ax[0, 1].plot(t, s["contacts_per_particle"])
    ax[0, 1].set_ylabel("contacts per particle [-]")
    ax[1, 0].semilogy(t, np.maximum(s["unbalanced_force"], 1e-12))
    ax[1, 0].set_ylabel("unbalanced force ratio [-]")
    ax[1, 1].plot(t, s["floor_force_z"])
    ax[1, 1].set_ylabel("force on the floor, z [N]")
    for a in ax[1]:
        a.set_xlabel("time [s]")
    return save(fig, png_path, dpi=110)
