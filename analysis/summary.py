"""Text and JSON summaries of a box-test analysis, and `run_box` (the ``box`` command: read,
analyse, plot, summarise).

This module owns the two summary files: ``summary.txt`` (a per-cycle table in [mm], [kN],
[MN/m] for reading, plus the fit parameters) and ``summary.json`` (the same in SI units, [s],
[m], [N], [N/m], NaN written as null). Imports numpy and this package only.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from pdem.format.read import read_box_test

from .box import BoxAnalysis, analyse_box
from .figures import default_out
from .plots import plot_loops, plot_settlement, plot_stiffness
from .stiffness import LOADING_WINDOW, UNLOADING_FRACTION

# name, header, units shown, scale SI -> shown, format
COLUMNS = (
    ("cycle", "cycle", "-", 1.0, "{:6.0f}"),
    ("t_start", "t_start", "s", 1.0, "{:10.4f}"),
    ("settlement_start", "S_start", "mm", 1e3, "{:10.4f}"),
    ("settlement_peak", "S_peak", "mm", 1e3, "{:10.4f}"),
    ("settlement_end", "S_end", "mm", 1e3, "{:10.4f}"),
    ("plastic", "plastic", "mm", 1e3, "{:10.4f}"),
    ("resilient", "resilient", "mm", 1e3, "{:10.4f}"),
    ("force_peak", "F_peak", "kN", 1e-3, "{:10.3f}"),
    ("force_min", "F_min", "kN", 1e-3, "{:10.3f}"),
    ("k_resilient", "k_res", "MN/m", 1e-6, "{:10.3f}"),
    ("k_loading", "k_load", "MN/m", 1e-6, "{:10.3f}"),
    ("k_unloading", "k_unload", "MN/m", 1e-6, "{:10.3f}"),
)
SI_UNITS = {"cycle": "-", "t_start": "s", "settlement_start": "m", "settlement_peak": "m",
            "settlement_end": "m", "plastic": "m", "resilient": "m", "force_peak": "N",
            "force_min": "N", "k_resilient": "N/m", "k_loading": "N/m", "k_unloading": "N/m"}


def per_cycle_columns(result: BoxAnalysis) -> dict:
    """name -> per-cycle array [SI], in `COLUMNS` order."""
    columns = dict(result.table.as_dict())
    columns.update(plastic=result.plastic, resilient=result.resilient,
                   k_resilient=result.stiffness.resilient, k_loading=result.stiffness.loading,
                   k_unloading=result.stiffness.unloading)
    return {name: np.asarray(columns[name], dtype=np.float64) for name, *_ in COLUMNS}


def summary_dict(result: BoxAnalysis) -> dict:
    """The summary as plain JSON-ready data [SI]."""
    r = result.results
    return {
        "file": str(r.path),
        "kind": r.kind,
        "pdem_version": r.attrs["pdem_version"],
        "schema_version": r.attrs["schema_version"],
        "cycles_source": result.cycles_source,
        "n_cycles": len(result.table),
        "parameters": {"loading_window": list(result.window),
                       "unloading_fraction": result.fraction},
        "units": SI_UNITS,
        "cycles": {k: [_json_float(x) for x in v] for k, v in per_cycle_columns(result).items()},
        "fits": {
            "log": None if result.log_fit is None else
            {"formula": "S = a + b ln N", **_fit_fields(result.log_fit), "units": {"a": "m", "b": "m"}},
            "power": None if result.power_fit is None else
            {"formula": "S = s1 N^b", **_fit_fields(result.power_fit), "units": {"s1": "m", "b": "-"}},
        },
        "notes": list(result.notes),
    }


def write_summary_json(result: BoxAnalysis, path) -> Path:
    path = Path(path)
    path.write_text(json.dumps(summary_dict(result), indent=1, allow_nan=False) + "\n")
    return path


def write_summary_text(result: BoxAnalysis, path) -> Path:
    path = Path(path)
    path.write_text("\n".join(summary_lines(result)) + "\n")
    return path


def summary_lines(result: BoxAnalysis) -> list[str]:
    r = result.results
    source = ("/cycles table of the file" if result.cycles_source == "file"
              else "detected from the minima of sleeper_load")
    lo, hi = result.window
    lines = [
        f"pdem box test: {r.path}",
        f"kind {r.kind}, pdem {r.attrs['pdem_version']}, schema_version {r.attrs['schema_version']}",
        f"cycles: {len(result.table)} ({source})",
        f"stiffness: loading = slope over {lo:.0%}-{hi:.0%} of the loading force range; "
        f"unloading = slope over the first {result.fraction:.0%} of the force drop; "
        f"resilient = (F_peak - F_min) / resilient settlement",
        "",
    ]
    widths = [len(fmt.format(0.0)) for *_, fmt in COLUMNS]
    lines.append(" ".join(h.rjust(w) for (_, h, *_), w in zip(COLUMNS, widths)))
    lines.append(" ".join(f"[{u}]".rjust(w) for (_, _, u, *_), w in zip(COLUMNS, widths)))
    columns = per_cycle_columns(result)
    for i in range(len(result.table)):
        cells = [fmt.format(columns[name][i] * scale)
                 for name, _, _, scale, fmt in COLUMNS]
        lines.append(" ".join(cells))
    lines += ["", "fits of the permanent settlement S(N), N = cycle:"]
    if result.log_fit is not None:
        f = result.log_fit
        lines.append(f"  S = a + b ln N : a = {f.a * 1e3:.4f} mm, b = {f.b * 1e3:.4f} mm, R^2 = {f.r2:.6f}")
    if result.power_fit is not None:
        f = result.power_fit
        lines.append(f"  S = S1 N^b     : S1 = {f.s1 * 1e3:.4f} mm, b = {f.b:.6f}, R^2 = {f.r2:.6f}")
    lines += [f"  {note}" for note in result.notes]
    return lines


def _fit_fields(fit) -> dict:
    return {k: _json_float(v) for k, v in fit._asdict().items()}


def _json_float(x):
    x = float(x)
    return x if math.isfinite(x) else None


def run_box(results_path: Path, out: Path | None, window=LOADING_WINDOW,
            fraction=UNLOADING_FRACTION) -> list[Path]:
    """Analyse one box test and write its plots and summaries; return the written files."""
    results = read_box_test(results_path)
    result = analyse_box(results, window=window, fraction=fraction)
    out = out if out is not None else default_out(results_path)
    out.mkdir(parents=True, exist_ok=True)
    s = results.series
    return [
        plot_loops(s["sleeper_force"], s["sleeper_settlement"], result.bounds,
                   out / "loops.png"),
        plot_settlement(result.table.cycle, result.permanent, out / "settlement.png",
                        result.log_fit, result.power_fit, peak=result.table.settlement_peak),
        plot_stiffness(result.table.cycle, result.stiffness, out / "stiffness.png"),
        write_summary_text(result, out / "summary.txt"),
        write_summary_json(result, out / "summary.json"),
    ]
