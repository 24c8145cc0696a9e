"""PNG plots of a cyclic test: force-settlement loops, settlement per cycle, stiffness per cycle.

This module owns the figures of the cyclic test (made and written by `analysis.figures`). Inputs
are SI arrays ([m], [N], [N/m]); the axes show engineering units ([mm], [kN], [MN/m]).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import figure, log_cycle_axis, save

MM, KN, MN_PER_M = 1e3, 1e-3, 1e-6  # SI -> plotted units
LOG_X_ABOVE = 20  # use a logarithmic cycle axis beyond this many cycles
DISCRETE_CYCLES = 10  # up to this many cycles: one colour each with a legend (no colour bar)


def cycle_axis(ax, n_cycles):
    """The cycle axis: logarithmic beyond `LOG_X_ABOVE` cycles, else linear with integer ticks."""
    from matplotlib.ticker import MaxNLocator

    if n_cycles > LOG_X_ABOVE:
        log_cycle_axis(ax)
    else:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def plot_loops(force, settlement, bounds, path) -> Path:
    """Force-settlement loops, one line per cycle: a colour each with a legend up to
    `DISCRETE_CYCLES` cycles, else coloured by cycle number on a colour bar with integer ticks.

    Parameters
    ----------
    force : ndarray [N]
        Force of the ballast on the sleeper.
    settlement : ndarray [m]
    bounds : ndarray of int
        Cycle boundaries (`analysis.cycles`).
    path : str or Path
        PNG to write.
    """
    from matplotlib.collections import LineCollection

    from .cycles import cycle_slices

    slices = cycle_slices(bounds)
    u, f = np.asarray(settlement) * MM, np.asarray(force) * KN
    lines = [np.column_stack((u[s], f[s])) for s in slices]
    fig, ax = figure()
    if len(lines) <= DISCRETE_CYCLES:
        for k, line in enumerate(lines):
            ax.plot(line[:, 0], line[:, 1], lw=1.0, color=f"C{k}", label=f"cycle {k + 1}")
        if lines:
            ax.legend(fontsize="small")
    else:
        from matplotlib.ticker import MaxNLocator

        lc = LineCollection(lines, cmap="viridis", linewidths=1.0)
        lc.set_array(np.arange(1, len(lines) + 1))
        ax.add_collection(lc)
        ax.autoscale()
        bar = fig.colorbar(lc, ax=ax, label="cycle N [-]")
        bar.locator = MaxNLocator(integer=True)
        bar.update_ticks()
    ax.set(xlabel="sleeper settlement [mm]", ylabel="ballast force on sleeper [kN]",
           title=f"Force-settlement loops ({len(lines)} cycles)")
    ax.grid(True, alpha=0.3)
    return save(fig, path)


def plot_settlement(cycle, permanent, path, log_fit=None, power_fit=None, peak=None) -> Path:
    """Permanent settlement per cycle with the log and power-law fits.

    Parameters
    ----------
    cycle : ndarray [-]
    permanent : ndarray [m]
        Settlement at the end of each cycle.
    path : str or Path
    log_fit, power_fit : LogFit, PowerFit, optional
    peak : ndarray [m], optional
        Settlement at peak load, drawn for comparison.
    """
    cycle = np.asarray(cycle, dtype=np.float64)
    fig, ax = figure()
    ax.plot(cycle, np.asarray(permanent) * MM, "o", color="C0", ms=4,
            label="permanent (end of cycle)")
    if peak is not None:
        ax.plot(cycle, np.asarray(peak) * MM, "^", color="C7", ms=3, label="at peak load")
    n = np.geomspace(1.0, max(cycle.max(), 2.0), 200)  # the fits exist from MIN_FIT_POINTS cycles on
    if log_fit is not None:
        ax.plot(n, log_fit(n) * MM, "-", color="C1",
                label=f"a + b ln N: a={log_fit.a * MM:.4g} mm, b={log_fit.b * MM:.4g} mm, "
                      f"R²={log_fit.r2:.4f}")
    if power_fit is not None:
        ax.plot(n, power_fit(n) * MM, "--", color="C2",
                label=f"S1 N^b: S1={power_fit.s1 * MM:.4g} mm, b={power_fit.b:.4g}, "
                      f"R²={power_fit.r2:.4f}")
    cycle_axis(ax, len(cycle))
    ax.set(xlabel="cycle N [-]", ylabel="sleeper settlement [mm]", title="Settlement per cycle")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


def plot_stiffness(cycle, stiffness, path) -> Path:
    """Resilient, loading and unloading stiffness per cycle.

    Parameters
    ----------
    cycle : ndarray [-]
    stiffness : CycleStiffness [N/m]
    path : str or Path
    """
    cycle = np.asarray(cycle, dtype=np.float64)
    fig, ax = figure()
    for name, marker in (("resilient", "o-"), ("loading", "s--"), ("unloading", "^:")):
        k = np.asarray(getattr(stiffness, name))
        if np.any(np.isfinite(k)):
            ax.plot(cycle, k * MN_PER_M, marker, ms=4, label=name)
    cycle_axis(ax, len(cycle))
    ax.set(xlabel="cycle N [-]", ylabel="stiffness [MN/m]", title="Stiffness per cycle")
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small")
    return save(fig, path)
