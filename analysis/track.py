"""Track section under traffic: settlement of each sleeper per passage, voids under the sleepers,
contact force distributions (SPEC 2.4; thesis ch. 6 and the multi-sleeper track it left for
future work).

This module owns the analysis of a kind "track" result (layout in `pdem.format.schema`: per-sleeper
series ``/track``, the per-passage table ``/passages``, force records ``/forces/<label>``), its
figures (``track_settlement.png``: permanent settlement along the track per passage and a
passage x sleeper map; ``track_passages.png``: settlement of every sleeper against the number
of passages with the fits, and with a beam rail the peak load on every sleeper per passage as a
sleeper x passage map; ``track_voids.png``; ``track_forces.png``: histograms and exceedance
curves; ``track_sleepers.png``: settlement and force of each sleeper in time; with turning
sleepers ``track_tilt.png``, ``track_shares.png`` and ``track_turning_passages.png``: tilt, end
void and load share of every sleeper against the passage number) and tables
(``track.txt``, ``track.json``), with breakable grains (``/fragments``: "prepared" and one record
per passage) the grading per passage of `analysis.grading` (``grading.png``, ``breakage.png``,
``grading.txt``, ``grading.json``), and `passage_table`, which builds the per-passage table from
the series (for the scene driver and for checks). Definitions:

- permanent settlement after passage p: settlement of each sleeper at the end of the passage
  (unloaded); increment = its change in the passage; differential settlement = the largest
  difference between neighbouring sleepers [m];
- peak settlement: largest settlement during the passage [m];
- gap: void under the sleeper at the end of the passage [m]; a sleeper is "hanging" when its
  gap exceeds `HANGING_GAP`;
- peak load: the largest load of the rail on a sleeper during the passage [N] (written when
  the rail is a beam: the load share the beam and the bed give each sleeper);
- turning sleepers (``[track] sleeper_rotation``): tilt about x and y at the end of the passage
  [rad; shown mrad], the settlement of each end of the sleeper body along its y axis (lo, hi)
  [m], the void under each end third (lo, hi) [m]; with the beam the load share: the largest
  load of the rails on the sleeper in the passage less its load at rest, per wheel load on its
  rail seats [-] (docs/track.md "Turning sleepers");
- settlement against the number of passages N: the mean permanent settlement after passage N
  fitted (least squares, `scipy.optimize.curve_fit`) by the two forms used for ballast,
  S = a + b·log10 N [m] and S = a·N^b [m, -], only with at least `MIN_FIT_PASSAGES` passages;
  the same fits of every sleeper's own permanent settlement (``fits_per_sleeper``);
- tilt drift of a turning sleeper: its tilt after the last passage less its tilt after the
  first [rad] (the tilts are absolute: a sleeper placed level rocks onto the grains before the
  traffic starts);
- force distribution: for forces f_i > 0 of one kind at one instant, mean <f>, quantiles
  (linear interpolation), and the exceedance P(F >= f) = (n - i)/n for the i-th smallest
  (i = 0..n-1), plotted against f/<f> with the exponential exp(-f/<f>) for reference.

Units: [s], [m], [N]; tables and plots show [mm], [kN]. Imports numpy, `pdem.format` and
this package; matplotlib only when a plot is drawn.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pdem.format.groups import ForceRecord, TrackRecord, read_fragments, read_track
from pdem.format.read import results_file

from .figures import default_out
from .grading import run_grading
from .settlement import MIN_FIT_POINTS

HANGING_GAP = 1e-4   # [m] a gap above this (0.1 mm) counts as a hanging sleeper
MIN_FIT_PASSAGES = MIN_FIT_POINTS  # passages needed before settlement is fitted against N
MAX_LINES = 12       # passages drawn as lines (evenly chosen, always the first and last)
MM, KN, MRAD = 1e3, 1e-3, 1e3
QUANTILES = (0.5, 0.95, 0.99)


def passage_table(time, settlement, t_start, t_end):
    """Per-passage peak and permanent settlement from the per-sleeper series.

    Parameters
    ----------
    time : array [n_samples] [s]
    settlement : array [n_samples, n_sleepers] [m]
    t_start, t_end : array [n_passages] [s]

    Returns
    -------
    peak : ndarray [n_passages, n_sleepers] [m]
        Largest settlement over the samples with t_start <= t <= t_end.
    permanent : ndarray [n_passages, n_sleepers] [m]
        Settlement at the last sample with t <= t_end.

    Raises
    ------
    ValueError
        If a passage holds no sample.
    """
    time = np.asarray(time, dtype=np.float64)
    s = np.asarray(settlement, dtype=np.float64)
    peak, permanent = [], []
    for p, (t0, t1) in enumerate(zip(np.atleast_1d(t_start), np.atleast_1d(t_end)), start=1):
        inside = np.flatnonzero((time >= t0 - 1e-12 * abs(t0)) & (time <= t1 + 1e-12 * abs(t1)))
        if len(inside) == 0:
            raise ValueError(f"passage {p} ({t0:g} .. {t1:g} s) holds no sample")
        peak.append(s[inside].max(axis=0))
        permanent.append(s[inside[-1]])
    return np.array(peak), np.array(permanent)


@dataclass(frozen=True)
class ForceStatistics:
    """Statistics of one force distribution [N] (``max_over_mean`` [-])."""

    n: int
    mean: float
    std: float
    median: float
    q95: float
    q99: float
    maximum: float
    max_over_mean: float


@dataclass(frozen=True)
class SettlementFits:
    """The fits of the mean permanent settlement S [m] against the number of passages N.

    ``forms`` maps "a + b log10 N" and "a N^b" to {"a", "b", "rms"} (rms residual [m]);
    empty, with ``reason`` saying why, when they were not fitted."""

    forms: dict
    reason: str = ""


FIT_FORMS = {"a + b log10 N": lambda n, a, b: a + b * np.log10(n),
             "a N^b": lambda n, a, b: a * np.power(n, b)}


def fit_settlement(n, s) -> SettlementFits:
    """Fit S(N) by `FIT_FORMS` (``n`` passage numbers, ``s`` settlement [m]); none with fewer
    than `MIN_FIT_PASSAGES` passages, and a form that cannot be fitted says why."""
    from scipy.optimize import curve_fit

    n, s = np.asarray(n, np.float64), np.asarray(s, np.float64)
    if len(n) < MIN_FIT_PASSAGES:
        return SettlementFits({}, f"not fitted: {len(n)} passage(s), at least {MIN_FIT_PASSAGES} needed")
    forms = {}
    for name, f in FIT_FORMS.items():
        p0 = (float(s[0]) if s[0] != 0 else 1e-4, 0.1 if name == "a N^b" else float(s[-1] - s[0]))
        try:
            (a, b), _ = curve_fit(f, n, s, p0=p0, maxfev=10000)
        except (RuntimeError, ValueError) as exc:  # no convergence
            forms[name] = {"a": float("nan"), "b": float("nan"), "rms": float("nan"), "failed": str(exc)}
            continue
        forms[name] = {"a": float(a), "b": float(b), "rms": float(np.sqrt(np.mean((f(n, a, b) - s) ** 2)))}
    return SettlementFits(forms)


def force_statistics(forces) -> ForceStatistics:
    """n, mean, std (population), median, 95 and 99 % quantiles, maximum of forces [N]."""
    f = np.asarray(forces, dtype=np.float64)
    if len(f) == 0:
        nan = float("nan")
        return ForceStatistics(0, nan, nan, nan, nan, nan, nan, nan)
    q = np.quantile(f, QUANTILES)
    mean = float(f.mean())
    return ForceStatistics(n=len(f), mean=mean, std=float(f.std()), median=float(q[0]),
                           q95=float(q[1]), q99=float(q[2]), maximum=float(f.max()),
                           max_over_mean=float(f.max() / mean) if mean > 0 else float("nan"))


def exceedance(forces):
    """Sorted forces and the fraction of contacts carrying at least each: (n - i)/n."""
    f = np.sort(np.asarray(forces, dtype=np.float64))
    n = len(f)
    return f, (n - np.arange(n)) / n if n else np.empty(0)


@dataclass(frozen=True)
class TrackAnalysis:
    """Everything derived from one track run.

    Attributes
    ----------
    record : TrackRecord
    per_passage : dict of str -> ndarray [n_passages]
        ``passage``, ``t_start``, ``t_end`` and ``mean_permanent``, ``min_permanent``,
        ``max_permanent``, ``increment`` (change of the mean permanent settlement in the
        passage), ``differential`` (largest difference between neighbouring sleepers),
        ``mean_peak``, ``max_peak`` [m]; with gaps ``mean_gap``, ``max_gap`` [m] and
        ``hanging`` [-] (sleepers with gap > `hanging_gap`); with peak loads
        ``mean_load_peak``, ``max_load_peak`` [N].
    forces : dict of label -> dict of kind -> ForceStatistics
        kind is "sleeper_ballast" or "ballast_ballast".
    hanging_gap : float [m]
    fits : SettlementFits
        The mean permanent settlement against the number of passages.
    fits_per_sleeper : list of SettlementFits
        Each sleeper's permanent settlement against the number of passages.
    """

    record: TrackRecord
    per_passage: dict
    forces: dict
    hanging_gap: float
    fits: SettlementFits
    fits_per_sleeper: tuple = ()

    @property
    def has_gap(self) -> bool:
        return "gap" in self.record.passages


def analyse_track(record: TrackRecord, hanging_gap: float = HANGING_GAP) -> TrackAnalysis:
    """Per-passage summary and force statistics of a track run."""
    p = record.passages
    perm, peak = p["settlement_permanent"], p["settlement_peak"]
    mean_perm = perm.mean(axis=1)
    table = {
        "passage": p["passage"], "t_start": p["t_start"], "t_end": p["t_end"],
        "mean_permanent": mean_perm, "min_permanent": perm.min(axis=1),
        "max_permanent": perm.max(axis=1),
        "increment": np.diff(mean_perm, prepend=0.0),
        "differential": (np.abs(np.diff(perm, axis=1)).max(axis=1) if record.n_sleepers > 1
                         else np.zeros(len(perm))),
        "mean_peak": peak.mean(axis=1), "max_peak": peak.max(axis=1),
    }
    if "gap" in p:
        table.update(mean_gap=p["gap"].mean(axis=1), max_gap=p["gap"].max(axis=1),
                     hanging=np.count_nonzero(p["gap"] > hanging_gap, axis=1).astype(float))
    if "load_peak" in p:
        table.update(mean_load_peak=p["load_peak"].mean(axis=1), max_load_peak=p["load_peak"].max(axis=1))
    if "tilt_x" in p:  # turning sleepers
        table.update(max_tilt_x=np.abs(p["tilt_x"]).max(axis=1), max_tilt_y=np.abs(p["tilt_y"]).max(axis=1),
                     max_end_gap=np.maximum(p["gap_lo"], p["gap_hi"]).max(axis=1))
    if "load_share" in p:
        table.update(max_load_share=p["load_share"].max(axis=1))
    if "load_work" in p:  # the energy ledger: what the bed dissipated is the work not stored
        table.update(load_work=p["load_work"], energy_change=p["energy_change"],
                     dissipated=p["load_work"] - p["energy_change"])
    forces = {}
    for label, rec in record.forces.items():
        forces[label] = {kind: force_statistics(getattr(rec, kind))
                         for kind in ("sleeper_ballast", "ballast_ballast")
                         if getattr(rec, kind) is not None}
    return TrackAnalysis(record=record, per_passage=table, forces=forces,
                         hanging_gap=float(hanging_gap), fits=fit_settlement(p["passage"], mean_perm),
                         fits_per_sleeper=tuple(fit_settlement(p["passage"], perm[:, k])
                                                for k in range(record.n_sleepers)))


# --- output: tables, JSON, PNG, command line ---

PASSAGE_COLUMNS = (  # name, header, scale SI -> shown, units shown, format
    ("passage", "passage", 1.0, "-", "{:8.0f}"),
    ("t_end", "t_end", 1.0, "s", "{:10.4g}"),
    ("mean_permanent", "S_mean", MM, "mm", "{:9.4f}"),
    ("min_permanent", "S_min", MM, "mm", "{:9.4f}"),
    ("max_permanent", "S_max", MM, "mm", "{:9.4f}"),
    ("increment", "dS_mean", MM, "mm", "{:9.4f}"),
    ("differential", "dS_neigh", MM, "mm", "{:9.4f}"),
    ("mean_peak", "Speak_mean", MM, "mm", "{:10.4f}"),
    ("max_peak", "Speak_max", MM, "mm", "{:10.4f}"),
    ("mean_gap", "gap_mean", MM, "mm", "{:9.4f}"),
    ("max_gap", "gap_max", MM, "mm", "{:9.4f}"),
    ("hanging", "hanging", 1.0, "-", "{:8.0f}"),
    ("mean_load_peak", "Fpeak_mean", KN, "kN", "{:10.4f}"),
    ("max_load_peak", "Fpeak_max", KN, "kN", "{:10.4f}"),
    ("max_tilt_x", "|tilt_x|max", MRAD, "mrad", "{:11.4f}"),
    ("max_tilt_y", "|tilt_y|max", MRAD, "mrad", "{:11.4f}"),
    ("max_end_gap", "endgap_max", MM, "mm", "{:10.4f}"),
    ("max_load_share", "share_max", 1.0, "-", "{:9.4f}"),
    ("load_work", "W_load", 1.0, "J", "{:10.4g}"),
    ("energy_change", "dE", 1.0, "J", "{:10.4g}"),
    ("dissipated", "W-dE", 1.0, "J", "{:10.4g}"),
)
SI_UNITS = {"passage": "-", "t_start": "s", "t_end": "s", "mean_permanent": "m",
            "min_permanent": "m", "max_permanent": "m", "increment": "m", "differential": "m",
            "mean_peak": "m", "max_peak": "m", "mean_gap": "m", "max_gap": "m", "hanging": "-",
            "mean_load_peak": "N", "max_load_peak": "N", "max_tilt_x": "rad", "max_tilt_y": "rad",
            "max_end_gap": "m", "max_load_share": "-", "load_work": "J", "energy_change": "J", "dissipated": "J"}
TURNING = ("settlement_lo", "settlement_hi", "tilt_x", "tilt_y", "gap_lo", "gap_hi", "load_share")


def track_lines(result: TrackAnalysis) -> list[str]:
    """Text report: per passage, per sleeper after the last passage, force statistics."""
    rec = result.record
    r = rec.results
    p = rec.passages
    columns = [c for c in PASSAGE_COLUMNS if c[0] in result.per_passage]
    widths = [len(fmt.format(0.0)) for *_, fmt in columns]
    lines = [
        f"pdem track section: {r.path}",
        f"kind {r.kind}, pdem {r.attrs['pdem_version']}; {rec.n_sleepers} sleepers at "
        f"x = {rec.sleeper_x[0]:.4g} .. {rec.sleeper_x[-1]:.4g} m; "
        f"{len(p['passage'])} passage(s); settlement positive downward",
        "S = permanent settlement at the end of each passage; dS_mean its change in the "
        "passage; dS_neigh the largest difference between neighbouring sleepers; Speak the "
        "largest settlement during the passage"
        + (f"; hanging = sleepers with gap > {result.hanging_gap * MM:g} mm" if result.has_gap
           else "; no gap data")
        + ("; Fpeak the largest load of the rail (a beam) on a sleeper in the passage"
           if "load_peak" in p else "")
        + ("; W_load the loads' work on the sleepers in the passage, dE the change of the mechanical "
           "energy of sleepers and ballast, W-dE what the bed dissipated" if "load_work" in p else ""),
        "",
        " ".join(h.rjust(w) for (_, h, *_), w in zip(columns, widths)),
        " ".join(f"[{u}]".rjust(w) for (_, _, _, u, _), w in zip(columns, widths)),
    ]
    for i in range(len(p["passage"])):
        lines.append(" ".join(fmt.format(result.per_passage[name][i] * scale)
                              for name, _, scale, _, fmt in columns))
    last = len(p["passage"])
    lines += ["", f"per sleeper (passage 1 and passage {last}):",
              f"{'sleeper':>8} {'x':>9} {'S_1':>9} {f'S_{last}':>9} {f'Speak_{last}':>10}"
              + (f" {f'gap_{last}':>9}" if result.has_gap else ""),
              f"{'[-]':>8} {'[m]':>9} {'[mm]':>9} {'[mm]':>9} {'[mm]':>10}"
              + (f" {'[mm]':>9}" if result.has_gap else "")]
    perm, peak = p["settlement_permanent"], p["settlement_peak"]
    for k in range(rec.n_sleepers):
        row = (f"{k:>8d} {rec.sleeper_x[k]:>9.4f} {perm[0, k] * MM:>9.4f} "
               f"{perm[-1, k] * MM:>9.4f} {peak[-1, k] * MM:>10.4f}")
        if result.has_gap:
            row += f" {p['gap'][-1, k] * MM:>9.4f}"
        lines.append(row)
    lines += turning_lines(result)
    lines += ["", *fit_lines(result.fits)]
    lines += sleeper_fit_lines(result)
    lines += ["", "contact force distributions (quantiles by linear interpolation):"]
    if not result.forces:
        lines.append("  (no /forces records)")
    else:
        lines.append(f"{'instant':>20} {'contacts':>16} {'n':>8} {'mean':>10} {'std':>10} "
                     f"{'median':>10} {'q95':>10} {'q99':>10} {'max':>10} {'max/mean':>9}")
        lines.append(f"{'':>20} {'':>16} {'[-]':>8} " + " ".join(f"{'[kN]':>10}"
                                                                for _ in range(6))
                     + f" {'[-]':>9}")
        for label, kinds in result.forces.items():
            for kind, s in kinds.items():
                lines.append(f"{label:>20} {kind:>16} {s.n:>8d} {s.mean * KN:>10.4f} "
                             f"{s.std * KN:>10.4f} {s.median * KN:>10.4f} {s.q95 * KN:>10.4f} "
                             f"{s.q99 * KN:>10.4f} {s.maximum * KN:>10.4f} "
                             f"{s.max_over_mean:>9.3f}")
    return lines


def turning_lines(result: TrackAnalysis) -> list[str]:
    """Turning sleepers: per sleeper after the last passage, the tilts, the ends' settlement, the
    voids under the end thirds and the largest load share over the passages ([] without them)."""
    rec, p = result.record, result.record.passages
    if "tilt_x" not in p:
        return []
    last, share = len(p["passage"]), "load_share" in p
    lines = ["", f"turning sleepers after passage {last} (dtilt: the tilt after passage {last} less after passage 1; "
                 "lo, hi: the ends of the sleeper body along its y axis; gaps under its end thirds"
                 + ("; share: the largest load share of a wheel over the passages)" if share else ")"),
             f"{'sleeper':>8} {'tilt_x':>9} {'tilt_y':>9} {'dtilt_x':>9} {'dtilt_y':>9} {'S_lo':>9} {'S_hi':>9} "
             f"{'gap_lo':>9} {'gap_hi':>9}" + (f" {'share':>9}" if share else ""),
             f"{'[-]':>8} {'[mrad]':>9} {'[mrad]':>9} {'[mrad]':>9} {'[mrad]':>9} {'[mm]':>9} {'[mm]':>9} "
             f"{'[mm]':>9} {'[mm]':>9}" + (f" {'[-]':>9}" if share else "")]
    drift_x, drift_y = tilt_drift(p)
    for k in range(rec.n_sleepers):
        lines.append(f"{k:>8d} {p['tilt_x'][-1, k] * MRAD:>9.4f} {p['tilt_y'][-1, k] * MRAD:>9.4f} "
                     f"{drift_x[k] * MRAD:>9.4f} {drift_y[k] * MRAD:>9.4f} "
                     f"{p['settlement_lo'][-1, k] * MM:>9.4f} {p['settlement_hi'][-1, k] * MM:>9.4f} "
                     f"{p['gap_lo'][-1, k] * MM:>9.4f} {p['gap_hi'][-1, k] * MM:>9.4f}"
                     + (f" {p['load_share'][:, k].max():>9.4f}" if share else ""))
    return lines


def fit_lines(fits: SettlementFits) -> list[str]:
    """The fits of the mean permanent settlement against N, one line each (or why none)."""
    head = "mean permanent settlement S against the number of passages N"
    if not fits.forms:
        return [f"{head}: {fits.reason}"]
    lines = [f"{head} (least squares):"]
    for name, f in fits.forms.items():
        if "failed" in f:
            lines.append(f"  S = {name}: no fit ({f['failed']})")
        elif name == "a N^b":
            lines.append(f"  S = {name}: a = {f['a'] * MM:.4g} mm, b = {f['b']:.4g}; rms residual "
                         f"{f['rms'] * MM:.3g} mm")
        else:
            lines.append(f"  S = {name}: a = {f['a'] * MM:.4g} mm, b = {f['b'] * MM:.4g} mm; rms residual "
                         f"{f['rms'] * MM:.3g} mm")
    return lines


def tilt_drift(passages):
    """(tilt_x, tilt_y) after the last passage less after the first, per sleeper [rad]."""
    return passages["tilt_x"][-1] - passages["tilt_x"][0], passages["tilt_y"][-1] - passages["tilt_y"][0]


def sleeper_fit_lines(result: TrackAnalysis) -> list[str]:
    """The fits of every sleeper's permanent settlement against N, a row per sleeper (none when
    the mean was not fitted: the same reason holds)."""
    if not result.fits.forms:
        return []
    lines = ["", "permanent settlement of each sleeper against N (least squares; a, b as above, rms residual):",
             f"{'sleeper':>8} {'a (log)':>10} {'b (log)':>10} {'rms':>8} {'a (pow)':>10} {'b (pow)':>9} {'rms':>8}",
             f"{'[-]':>8} {'[mm]':>10} {'[mm]':>10} {'[mm]':>8} {'[mm]':>10} {'[-]':>9} {'[mm]':>8}"]
    for k, fits in enumerate(result.fits_per_sleeper):
        lg, pw = fits.forms["a + b log10 N"], fits.forms["a N^b"]
        lines.append(f"{k:>8d} {lg['a'] * MM:>10.4f} {lg['b'] * MM:>10.4f} {lg['rms'] * MM:>8.4f} "
                     f"{pw['a'] * MM:>10.4f} {pw['b']:>9.4f} {pw['rms'] * MM:>8.4f}")
    return lines


def track_dict(result: TrackAnalysis) -> dict:
    """The report as JSON-ready data [SI]."""
    rec = result.record
    return {
        "file": str(rec.results.path), "kind": rec.results.kind,
        "n_sleepers": rec.n_sleepers, "sleeper_x": _floats(rec.sleeper_x),
        "hanging_gap": result.hanging_gap,
        "units": {**{k: v for k, v in SI_UNITS.items() if k in result.per_passage},
                  "sleeper_x": "m", "settlement_permanent": "m", "settlement_peak": "m",
                  "gap": "m", "forces": "N", "hanging_gap": "m",
                  **{name: "rad" if name.startswith("tilt") else "-" if name == "load_share" else "m"
                     for name in TURNING if name in rec.passages}},
        "passages": {k: _floats(v) for k, v in result.per_passage.items()},
        "settlement_permanent": [_floats(row) for row in rec.passages["settlement_permanent"]],
        "settlement_peak": [_floats(row) for row in rec.passages["settlement_peak"]],
        "gap": ([_floats(row) for row in rec.passages["gap"]] if result.has_gap else None),
        "load_peak": ([_floats(row) for row in rec.passages["load_peak"]]
                      if "load_peak" in rec.passages else None),
        **{name: [_floats(row) for row in rec.passages[name]] for name in TURNING if name in rec.passages},
        "fits": {"of": "mean permanent settlement [m] against the passage number N",
                 "forms": {k: {n: _json(v) if n != "failed" else v for n, v in f.items()}
                           for k, f in result.fits.forms.items()}, "reason": result.fits.reason},
        "fits_per_sleeper": [{k: {n: _json(v) if n != "failed" else v for n, v in f.items()}
                              for k, f in fits.forms.items()} for fits in result.fits_per_sleeper],
        **({"tilt_drift": {"of": "tilt after the last passage less after the first [rad]",
                           "tilt_x": _floats(tilt_drift(rec.passages)[0]),
                           "tilt_y": _floats(tilt_drift(rec.passages)[1])}} if "tilt_x" in rec.passages else {}),
        "forces": {label: {kind: {k: _json(v) for k, v in vars(s).items()}
                           for kind, s in kinds.items()}
                   for label, kinds in result.forces.items()},
    }


def plot_settlement_map(result: TrackAnalysis, path) -> Path:
    """Permanent settlement along the track per passage (lines) and passage x sleeper map."""
    from matplotlib.figure import Figure

    from .figures import save

    rec = result.record
    passages = rec.passages["passage"]
    fig = Figure(figsize=(12.0, 4.8), layout="constrained")
    ax, ax_map = fig.subplots(1, 2)
    _along_and_map(fig, ax, ax_map, rec, rec.passages["settlement_permanent"] * MM,
                   "sleeper settlement [mm] (down)", "Permanent settlement along the track",
                   "permanent settlement [mm]", "Settlement: passage × sleeper", down=True)
    ax.plot(rec.sleeper_x, rec.passages["settlement_peak"][-1] * MM, "^--", ms=3, color="C3",
            lw=0.8, label=f"peak in passage {passages[-1]:.0f}")
    ax.legend(fontsize="x-small")
    return save(fig, path)


def _along_and_map(fig, ax, ax_map, rec, values, ylabel, title, map_label, map_title, down=False,
                   cmap="viridis"):
    """``values`` [n_passages, n_sleepers] along the track after chosen passages (lines on
    ``ax``) and as a passage x sleeper map (``ax_map``)."""
    from matplotlib.ticker import MaxNLocator

    passages = rec.passages["passage"]
    chosen = _chosen(len(passages))
    for i, colour in zip(chosen, _colours(len(chosen))):
        ax.plot(rec.sleeper_x, values[i], "o-", ms=3, color=colour, label=f"after passage {passages[i]:.0f}")
    if down:
        ax.invert_yaxis()
    ax.set(xlabel="position along the track x [m]", ylabel=ylabel, title=title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    signed = {}
    if cmap == "coolwarm":  # a signed quantity: zero in the middle of the colour map
        lim = float(np.max(np.abs(values))) or 1.0
        signed = {"vmin": -lim, "vmax": lim}
    mesh = ax_map.pcolormesh(_edges(np.arange(rec.n_sleepers, dtype=float)), _edges(passages.astype(float)),
                             values, cmap=cmap, shading="flat", **signed)
    fig.colorbar(mesh, ax=ax_map, label=map_label)
    ax_map.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_map.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax_map.set(xlabel="sleeper [-]", ylabel="passage [-]", title=map_title)


TURNING_PLOTS = (  # /passages table, scale, label, down, colour map: turning sleepers (track_tilt.png)
    ("tilt_x", MRAD, "tilt about x (across the track) [mrad]", False, "coolwarm"),
    ("tilt_y", MRAD, "tilt about y (along the track) [mrad]", False, "coolwarm"),
    ("settlement_lo", MM, "settlement of the lo end [mm] (down)", True, "viridis"),
    ("settlement_hi", MM, "settlement of the hi end [mm] (down)", True, "viridis"),
    ("gap_lo", MM, "void under the lo end third [mm]", False, "magma"),
    ("gap_hi", MM, "void under the hi end third [mm]", False, "magma"),
)


def plot_tilt(result: TrackAnalysis, path) -> Path:
    """Turning sleepers: tilt about x and y, settlement of each end and the void under each end
    third, after every chosen passage along the track (lines) and as passage x sleeper maps."""
    from matplotlib.figure import Figure

    from .figures import save

    rec = result.record
    fig = Figure(figsize=(12.0, 3.4 * len(TURNING_PLOTS)), layout="constrained")
    for (name, scale, label, down, cmap), (ax, ax_map) in zip(TURNING_PLOTS, fig.subplots(len(TURNING_PLOTS), 2)):
        _along_and_map(fig, ax, ax_map, rec, rec.passages[name] * scale, label, label.split(" [")[0],
                       label, f"{name}: passage × sleeper", down=down, cmap=cmap)
    return save(fig, path)


def plot_shares(result: TrackAnalysis, path) -> Path:
    """The load share of every sleeper per passage (the beam): along the track and as a map."""
    from matplotlib.figure import Figure

    from .figures import save

    rec = result.record
    fig = Figure(figsize=(12.0, 4.8), layout="constrained")
    ax, ax_map = fig.subplots(1, 2)
    _along_and_map(fig, ax, ax_map, rec, rec.passages["load_share"], "load share of a wheel [-]",
                   "Load share per sleeper (the rail as a beam)", "load share [-]", "Load share: passage × sleeper",
                   cmap="magma")
    return save(fig, path)


TURNING_AGAINST_N = (  # /passages table (or a pair: the larger), scale, label: track_turning_passages.png
    ("tilt_x", MRAD, "tilt about x (across the track) [mrad]"),
    ("tilt_y", MRAD, "tilt about y (along the track) [mrad]"),
    (("gap_lo", "gap_hi"), MM, "void under the end thirds, the larger [mm]"),
    ("load_share", 1.0, "load share of a wheel [-]"),
)


def plot_turning_passages(result: TrackAnalysis, path) -> Path:
    """Turning sleepers: tilt about x and y, the larger void under an end third and (with the
    beam) the load share of every sleeper against the passage number, a line per sleeper."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from .figures import save

    rec = result.record
    p = rec.passages
    panels = [q for q in TURNING_AGAINST_N if isinstance(q[0], tuple) or q[0] in p]
    fig = Figure(figsize=(12.0, 4.0 * math.ceil(len(panels) / 2)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(math.ceil(len(panels) / 2), 2)).ravel()
    for (name, scale, label), ax in zip(panels, axes):
        values = np.maximum(p[name[0]], p[name[1]]) if isinstance(name, tuple) else p[name]
        for k, colour in enumerate(_colours(rec.n_sleepers)):
            ax.plot(p["passage"], values[:, k] * scale, "o-", ms=3, lw=0.8, color=colour,
                    label=f"sleeper {k}" if rec.n_sleepers <= 12 else None)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set(xlabel="passage N [-]", ylabel=label, title=label.split(" [")[0] + " per sleeper and passage")
        ax.grid(True, alpha=0.3)
        if rec.n_sleepers <= 12:
            ax.legend(fontsize="x-small", ncol=2)
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    return save(fig, path)


def plot_passages(result: TrackAnalysis, path) -> Path:
    """Permanent settlement of every sleeper against the passage number, with the mean and its
    fits; with peak loads, the peak load on every sleeper as a sleeper x passage map."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from .figures import save

    rec = result.record
    p = rec.passages
    n = p["passage"]
    loads = "load_peak" in p
    fig = Figure(figsize=(12.0 if loads else 6.5, 4.8), layout="constrained")
    axes = fig.subplots(1, 2 if loads else 1)
    ax = axes[0] if loads else axes
    for k, colour in enumerate(_colours(rec.n_sleepers)):
        ax.plot(n, p["settlement_permanent"][:, k] * MM, "o-", ms=3, lw=0.8, color=colour,
                label=f"sleeper {k}" if rec.n_sleepers <= 12 else None)
    ax.plot(n, result.per_passage["mean_permanent"] * MM, "k-", lw=2.0, label="mean")
    grid = np.linspace(1.0, n[-1], 200)
    for (name, f), style in zip(result.fits.forms.items(), ("--", ":")):
        if "failed" not in f:
            ax.plot(grid, FIT_FORMS[name](grid, f["a"], f["b"]) * MM, style, color="C3", lw=1.5,
                    label=f"fit S = {name}")
    ax.invert_yaxis()
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set(xlabel="passage N [-]", ylabel="permanent settlement [mm] (down)",
           title="Settlement per sleeper and passage" + ("" if result.fits.forms else
                                                         f"\n({result.fits.reason})"))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small", ncol=2)
    if loads:
        ax_map = axes[1]
        mesh = ax_map.pcolormesh(_edges(np.arange(rec.n_sleepers, dtype=float)), _edges(n.astype(float)),
                                 p["load_peak"] * KN, cmap="magma", shading="flat")
        fig.colorbar(mesh, ax=ax_map, label="peak load of the rail on the sleeper [kN]")
        ax_map.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax_map.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax_map.set(xlabel="sleeper [-]", ylabel="passage [-]", title="Sleeper load from the rail: passage × sleeper")
    return save(fig, path)


def plot_voids(result: TrackAnalysis, path) -> Path:
    """Gap under each sleeper per passage, and the mean, largest gap and hanging sleepers."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from .figures import save

    rec = result.record
    gap = rec.passages["gap"] * MM
    passages = rec.passages["passage"]
    fig = Figure(figsize=(12.0, 4.8), layout="constrained")
    ax, ax_p = fig.subplots(1, 2)
    chosen = _chosen(len(passages))
    for i, colour in zip(chosen, _colours(len(chosen))):
        ax.plot(rec.sleeper_x, gap[i], "o-", ms=3, color=colour,
                label=f"after passage {passages[i]:.0f}")
    ax.axhline(result.hanging_gap * MM, color="0.5", ls=":", lw=1.0, label="hanging threshold")
    ax.set(xlabel="position along the track x [m]", ylabel="gap under the sleeper [mm]",
           title="Voids under the sleepers")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    t = result.per_passage
    ax_p.plot(passages, t["mean_gap"] * MM, "o-", ms=3, label="mean gap")
    ax_p.plot(passages, t["max_gap"] * MM, "s--", ms=3, label="largest gap")
    ax_h = ax_p.twinx()
    ax_h.step(passages, t["hanging"], where="mid", color="C3", label="hanging sleepers")
    ax_h.set_ylabel("hanging sleepers [-]", color="C3")
    ax_p.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_p.set(xlabel="passage N [-]", ylabel="gap [mm]", title="Voids per passage")
    ax_p.grid(True, alpha=0.3)
    h1, l1 = ax_p.get_legend_handles_labels()
    h2, l2 = ax_h.get_legend_handles_labels()
    ax_p.legend(h1 + h2, l1 + l2, fontsize="x-small")
    return save(fig, path)


def plot_forces(result: TrackAnalysis, path) -> Path:
    """Histogram of f/<f> and exceedance P(F >= f), one curve per instant, per contact kind."""
    from matplotlib.figure import Figure

    from .figures import save

    kinds = [k for k in ("sleeper_ballast", "ballast_ballast")
             if any(k in v for v in result.forces.values())]
    fig = Figure(figsize=(11.0, 4.2 * len(kinds)), layout="constrained")
    axes = np.atleast_2d(fig.subplots(len(kinds), 2))
    labels = list(result.forces)
    colours = _colours(len(labels))
    titles = {"sleeper_ballast": "sleeper-ballast normal forces",
              "ballast_ballast": "ballast contact forces"}
    for row, kind in zip(axes, kinds):
        ax_h, ax_e = row
        top = 1.0
        for label, colour in zip(labels, colours):
            rec: ForceRecord = result.record.forces[label]
            f = getattr(rec, kind)
            if f is None or len(f) == 0:
                continue
            mean = f.mean()
            if mean <= 0:
                continue
            x = f / mean
            top = max(top, x.max())
            text = f"{label} (n={len(f)}, <f>={mean * KN:.3g} kN)"
            ax_h.hist(x, bins=min(40, max(5, len(f) // 5)), density=True, histtype="step",
                      color=colour, label=text)
            xs, frac = exceedance(x)
            ax_e.step(xs, frac, where="post", color=colour, label=text)
        grid = np.linspace(0.0, top, 100)
        ax_e.plot(grid, np.exp(-grid), color="0.5", ls="--", lw=0.8, label="exp(-f/<f>)")
        ax_h.set(xlabel="f / <f> [-]", ylabel="probability density [-]",
                 title=f"Distribution of {titles[kind]}")
        ax_e.set_yscale("log")
        ax_e.set(xlabel="f / <f> [-]", ylabel="P(F ≥ f) [-]", title="Exceedance")
        for ax in row:
            ax.grid(True, which="both", alpha=0.3)
        ax_h.legend(fontsize="x-small")
    return save(fig, path)


def plot_sleepers(result: TrackAnalysis, path) -> Path:
    """Settlement and ballast force of each sleeper in time, passages shaded."""
    from matplotlib.figure import Figure

    from .figures import save

    rec = result.record
    t = rec.results.series["time"]
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    ax_s, ax_f = fig.subplots(2, 1, sharex=True)
    colours = _colours(rec.n_sleepers)
    for k, colour in enumerate(colours):
        label = f"sleeper {k}" if rec.n_sleepers <= 12 else None
        ax_s.plot(t, rec.settlement[:, k] * MM, color=colour, lw=0.8, label=label)
        ax_f.plot(t, rec.force[:, k] * KN, color=colour, lw=0.8)
    for i, (t0, t1) in enumerate(zip(rec.passages["t_start"], rec.passages["t_end"])):
        for ax in (ax_s, ax_f):
            ax.axvspan(t0, t1, color="0.9" if i % 2 == 0 else "0.95", zorder=0)
    ax_s.invert_yaxis()
    ax_s.set(ylabel="settlement [mm] (down)", title="Sleepers in time (passages shaded)")
    ax_f.set(xlabel="time [s]", ylabel="ballast force on sleeper [kN]")
    for ax in (ax_s, ax_f):
        ax.grid(True, alpha=0.3)
    if rec.n_sleepers <= 12:
        ax_s.legend(fontsize="x-small", ncol=2)
    return save(fig, path)


def grain_members(path) -> int | None:
    """Spheres of an intact grain of a track run with breakable grains: the largest fragment of
    its first fragment record (the prepared bed, where no grain has broken yet); None without
    fragment records."""
    import h5py

    from pdem.format.schema import FRAGMENTS

    with h5py.File(path, "r") as f:
        if FRAGMENTS not in f:
            return None
    return int(read_fragments(path).records[0].n_members.max())


def run_track(run_or_file, out=None, hanging_gap=HANGING_GAP) -> list[Path]:
    """Analyse a track run: track_*.png, track.txt, track.json; with breakable grains the
    grading per passage too (`analysis.grading.run_grading`: grading.png with a curve per
    passage, breakage.png with the indices and the bonds broken per passage, grading.txt,
    grading.json; intact grains counted by the grain's size)."""
    path = results_file(run_or_file)
    result = analyse_track(read_track(path), hanging_gap=hanging_gap)
    out = Path(out) if out is not None else default_out(path)
    out.mkdir(parents=True, exist_ok=True)
    written = [plot_settlement_map(result, out / "track_settlement.png"),
               plot_passages(result, out / "track_passages.png"),
               plot_sleepers(result, out / "track_sleepers.png")]
    if result.has_gap:
        written.append(plot_voids(result, out / "track_voids.png"))
    if result.forces:
        written.append(plot_forces(result, out / "track_forces.png"))
    if "tilt_x" in result.record.passages:
        written.append(plot_tilt(result, out / "track_tilt.png"))
        written.append(plot_turning_passages(result, out / "track_turning_passages.png"))
    if "load_share" in result.record.passages:
        written.append(plot_shares(result, out / "track_shares.png"))
    (out / "track.txt").write_text("\n".join(track_lines(result)) + "\n")
    (out / "track.json").write_text(json.dumps(track_dict(result), indent=1,
                                               allow_nan=False) + "\n")
    members = grain_members(path)
    if members is not None:
        written += run_grading(path, out, intact_members=members)
    return written + [out / "track.txt", out / "track.json"]


def add_parser(sub) -> None:
    """The ``track`` subcommand of ``python -m analysis``."""
    p = sub.add_parser(
        "track", help="track section: settlement per sleeper and passage, voids, forces",
        description="Write track_settlement.png, track_passages.png, track_sleepers.png, track_voids.png (with "
                    "gap data), track_forces.png (with /forces records), track_tilt.png, track_turning_passages.png "
                    "and track_shares.png (turning sleepers, the beam's load shares), track.txt and track.json for a "
                    "track run; with breakable grains the grading per passage (grading.png, breakage.png, "
                    "grading.txt, grading.json).")
    p.add_argument("results", type=Path, metavar="RUN",
                   help="run directory (with results.h5) or results file")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (default: RUN/analysis of a run folder, else RESULTS-analysis)")
    p.add_argument("--hanging-gap", type=float, default=HANGING_GAP * MM, metavar="MM",
                   help="gap above which a sleeper counts as hanging, mm "
                        "(default: %(default)s)")
    p.set_defaults(run=lambda a: run_track(a.results, a.out, a.hanging_gap / MM))


def _chosen(n: int) -> list[int]:
    """Up to `MAX_LINES` passage indices, evenly spread, first and last included."""
    if n <= MAX_LINES:
        return list(range(n))
    return sorted(set(np.linspace(0, n - 1, MAX_LINES).round().astype(int).tolist()))


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around centres (for pcolormesh)."""
    if len(centres) == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    mid = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate(([2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]))


def _colours(n):
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    return [cmap(0.9 * i / max(n - 1, 1)) for i in range(n)]


def _floats(values) -> list:
    return [_json(v) for v in np.asarray(values, dtype=np.float64)]


def _json(value):
    if isinstance(value, (int, np.integer)):
        return int(value)
    value = float(value)
    return value if math.isfinite(value) else None
