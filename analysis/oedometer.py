"""Oedometer: force–displacement of the platen, loading and unloading stiffness, grading of the
breakable clumps, and the identification of E_k by equal unloading stiffness (SPEC 2.2; thesis
ch. 4.3, 4.4, table 4.14; Nottingham test, Lim 2004).

This module owns the analysis of a kind "oedometer" result (layout in `pdem.format.schema`:
``platen_force`` [N, the ballast on the platen, up], ``platen_load`` [N, the program],
``platen_displacement`` [m, down, zero when loading starts]) and writes ``oedometer.png``
(force–displacement with the unloading branch enlarged, as the thesis's figures, and the
largest overlap over the smaller radius, ``max_overlap_ratio`` [-], where recorded),
``oedometer.txt``, ``oedometer.json`` and, with ``/fragments``, the grading of
`analysis.grading` (``grading.png``, ``breakage.png``, ``grading.txt``, ``grading.json``).

- loading stiffness: least-squares slope of force on displacement over a force window of the
  loading branch (`analysis.stiffness.loading_stiffness`, 10–90 % by default) [N/m];
- unloading stiffness: slope over the first part of the unloading branch
  (`analysis.stiffness.unloading_stiffness`; thesis 4.3: "at the start of unloading mostly
  the stiffness of the grains shows") [N/m]; the peak is the maximum of the applied program;
- `identify_modulus`: the thesis identified E_k per grain type by trial and error so that every
  model has the same unloading stiffness (table 4.14). With runs at several moduli E_i giving
  unloading stiffnesses k_i, k(E) is fitted as a power law k = C E^b (least squares in log–log,
  `scipy.stats.linregress`; b = 1 for a packing that does not rearrange: linear contacts) and
  E_k = (k_target / C)^(1/b).

Units: [N], [m], [N/m], [Pa]; tables and plots show [kN], [mm], [kN/mm]. Imports numpy,
scipy, `pdem.format` and this package; matplotlib only when a plot is drawn.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from pdem.format.read import open_results, read_finite

from .figures import figure, save
from .stiffness import LOADING_WINDOW, loading_stiffness, slope, unloading_stiffness

OEDOMETER_SERIES = ("platen_load", "platen_force", "platen_displacement")
UNLOADING_FRACTION = 0.3   # part of the force drop of the unloading slope (the start of unloading)
KN, MM = 1e-3, 1e3


@dataclass(frozen=True)
class OedometerResult:
    """Figures of one oedometer run (SI units)."""

    f_max: float                 # largest ballast force on the platen [N]
    load_max: float              # largest applied load [N]
    u_max: float                 # largest platen displacement [m]
    u_end: float                 # displacement at the end (permanent) [m]
    loading_stiffness: float     # [N/m]
    unloading_stiffness: float   # [N/m]
    n_samples: int
    max_overlap_ratio: float | None = None  # largest overlap / smaller radius of the run [-], if recorded


def read_oedometer(path):
    """The series of a kind "oedometer" result (finite, >= 3 samples: a finished load)."""
    return read_finite(path, OEDOMETER_SERIES, min_samples=3)


def analyse(series, window=LOADING_WINDOW, fraction=UNLOADING_FRACTION) -> OedometerResult:
    """Stiffnesses and extremes of a load–unload record (dict of arrays as in /series)."""
    f, u, load = (np.asarray(series[k], np.float64) for k in ("platen_force", "platen_displacement", "platen_load"))
    peak = int(np.argmax(load))
    if peak == len(f) - 1:
        raise ValueError("the record ends at its largest load: no unloading branch")
    try:
        k_unload = unloading_stiffness(f, u, fraction, peak=peak)
    except ValueError:  # a sparse record: the first drop is already beyond the fraction
        k_unload = slope(f[peak:peak + 2], u[peak:peak + 2])
    return OedometerResult(
        f_max=float(f.max()), load_max=float(load.max()), u_max=float(u.max()), u_end=float(u[-1]),
        loading_stiffness=loading_stiffness(f, u, window, peak=peak), unloading_stiffness=k_unload,
        n_samples=len(f),
        max_overlap_ratio=float(np.max(series["max_overlap_ratio"])) if "max_overlap_ratio" in series else None)


def identify_modulus(moduli, stiffnesses, target):
    """E_k [Pa] giving the unloading stiffness ``target`` [N/m], from runs at ``moduli`` [Pa]
    with unloading stiffnesses ``stiffnesses`` [N/m] (thesis table 4.14: equal unloading
    stiffness). Returns (E_k, b, C) of the fit k = C E^b.

    Raises ValueError with fewer than two distinct moduli or a non-positive value."""
    from scipy.stats import linregress

    e, k = np.asarray(moduli, np.float64), np.asarray(stiffnesses, np.float64)
    if e.shape != k.shape or e.ndim != 1:
        raise ValueError("moduli and stiffnesses must be 1-D arrays of equal length")
    if len(np.unique(e)) < 2:
        raise ValueError(f"identify_modulus needs runs at two or more distinct moduli, got {e.tolist()}")
    if np.any(e <= 0) or np.any(k <= 0) or not np.all(np.isfinite(k)) or not target > 0:
        raise ValueError("moduli, stiffnesses and the target stiffness must be finite and > 0")
    fit = linregress(np.log(e), np.log(k))
    if fit.slope <= 0:
        raise ValueError(f"the unloading stiffness does not grow with the modulus (exponent {fit.slope:.3g})")
    return float(math.exp((math.log(target) - fit.intercept) / fit.slope)), float(fit.slope), \
        float(math.exp(fit.intercept))


# --- output ---

def result_lines(r: OedometerResult) -> list[str]:
    return [
        "oedometer (platen force of the ballast vs platen displacement)",
        f"  largest load {r.load_max * KN:.4g} kN, ballast force {r.f_max * KN:.4g} kN",
        f"  largest displacement {r.u_max * MM:.4g} mm, permanent {r.u_end * MM:.4g} mm",
        f"  loading stiffness {r.loading_stiffness * KN / MM:.5g} kN/mm "
        f"(window {LOADING_WINDOW[0]:g}-{LOADING_WINDOW[1]:g} of the loading branch)",
        f"  unloading stiffness {r.unloading_stiffness * KN / MM:.5g} kN/mm "
        f"(first {UNLOADING_FRACTION:g} of the force drop)",
    ] + ([] if r.max_overlap_ratio is None else
         [f"  largest overlap {r.max_overlap_ratio:.3g} of the smaller radius of its pair"])


def plot_oedometer(series, r: OedometerResult, path) -> Path:
    """Force–displacement, the unloading branch enlarged in an inset."""
    f, u, load = (np.asarray(series[k]) for k in ("platen_force", "platen_displacement", "platen_load"))
    peak = int(np.argmax(load))
    fig, ax = figure(7, 5)
    ax.plot(u * MM, f * KN, label="ballast on the platen")
    ax.plot(u * MM, load * KN, lw=0.8, ls="--", label="applied load")
    ax.set_xlabel("platen displacement u [mm]")
    ax.set_ylabel("force F [kN]")
    ax.set_title(f"oedometer: k_load {r.loading_stiffness * KN / MM:.4g}, "
                 f"k_unload {r.unloading_stiffness * KN / MM:.4g} kN/mm")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize="small")
    if "max_overlap_ratio" in series:  # how far the contacts were pushed (0.5 stops a run)
        ov = ax.twinx()
        ov.plot(u * MM, np.asarray(series["max_overlap_ratio"]), lw=0.6, color="0.55")
        ov.set_ylabel("largest overlap / smaller radius [-] (grey)", color="0.4")
        ov.set_ylim(bottom=0.0)
        ax.set_zorder(ov.get_zorder() + 1)  # the force curves and the inset above the grey line
        ax.patch.set_visible(False)
    ins = ax.inset_axes([0.1, 0.5, 0.38, 0.38])
    ins.plot((u[peak:] - u[peak]) * MM, f[peak:] * KN)
    ins.set_title("unloading (u - u_peak [mm], F [kN])", fontsize="x-small")
    ins.tick_params(labelsize="x-small")
    return save(fig, path)


def run_oedometer(run_or_file, out=None, intact_members=135) -> list[Path]:
    """Analyse one oedometer run; write its PNG, table and JSON (and the grading)."""
    from . import grading

    res = read_oedometer(run_or_file)
    r = analyse(res.series)
    out = Path(out) if out is not None else res.path.with_name(res.path.stem + "-analysis")
    out.mkdir(parents=True, exist_ok=True)
    lines = result_lines(r)
    written = [plot_oedometer(res.series, r, out / "oedometer.png")]
    with open_results(res.path) as fh:
        has_fragments = "fragments" in fh and len(fh["fragments"]) > 0
    if has_fragments:
        written += grading.run_grading(res.path, out, intact_members=intact_members)
        lines += ["", (out / "grading.txt").read_text().rstrip()]
    text, js = out / "oedometer.txt", out / "oedometer.json"
    text.write_text("\n".join(lines) + "\n")
    js.write_text(json.dumps(asdict(r), indent=1) + "\n")
    return written + [text, js]


def add_parser(sub) -> None:
    """The ``oedometer`` subcommand of ``python -m analysis``."""
    p = sub.add_parser(
        "oedometer", help="oedometer: force-displacement, loading/unloading stiffness, grading",
        description="Write oedometer.png, oedometer.txt and oedometer.json (and with /fragments the "
                    "grading files) for a kind 'oedometer' result.")
    p.add_argument("results", type=Path, metavar="RUN_OR_FILE", help="run directory (with results.h5) or results file")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (default: RESULTS-analysis beside the file)")
    p.add_argument("--intact-members", type=int, default=135, metavar="N",
                   help="spheres of an intact grain (default: %(default)s, Nottingham)")
    p.set_defaults(run=lambda a: run_oedometer(a.results, a.out, a.intact_members))
