"""Blast layer: stress on the ceiling, its impulse and the amplification (SPEC 2.5; Szklennik,
"Prognoza redukcji ciśnienia wybuchu warstwą materiału ziarnistego", Biuletyn WAT 65(3), 2016).

This module owns the analysis of a kind "blast" result (layout in `pdem.format.schema`), its
figure and tables (``blast.png``, ``blast.txt``, ``blast.json``), and the comparison of several
runs (seeds x plates: ``blast_compare.txt``, ``.json``, ``.png``). Quantities:

- sigma_0(t) [Pa]: force of the grains on the ceiling / ceiling area (``/series/ceiling_stress``).
- impulse on the ceiling I_s = integral of sigma_0 dt over the record [Pa s] (trapezoidal rule;
  the paper integrates over its 9 ms). Also I_s,dyn = integral of (sigma_0 - sigma_static) dt,
  sigma_static = sigma_0 at the first sample (the weight of the layer and the plate, before
  the load arrives): the paper does not say whether its I_s holds the static part.
- input impulse I_in = F0 tau / 2 / ceiling area [Pa s] (the integral of F0 (1 - t/tau) over
  0..tau per unit area; paper: 9 MN x 1e-4 s / 2 / 0.09 m^2 = 5e-3 MPa s), and as a check the
  trapezoidal integral of ``/series/input_force`` / area.
- amplification I_s / I_in [-] (= ratio of the total impulses on ceiling and plate).
- peak sigma_0 and its time; arrival time (sigma_0 - sigma_static first reaches
  `ARRIVAL_FRACTION` of its peak); plate displacement dp = z - z(0) (the paper's Fig. 4).
- layer stiffness k_A [Pa/m]: least-squares slope (through 0) of sigma_0 - sigma_static against
  the plate's drop d = z(0) - z while the plate goes down (up to its largest drop); and the
  amplification of a one-degree-of-freedom model, 1 - cos(omega T), omega = sqrt(k_A / mu):
  a rigid plate of areal mass mu on a massless linear layer, hit by an impulse short against
  its period, passes I_in (1 - cos omega T) to the ceiling within T (the layer force k_A d(t),
  d = I_in sin(omega t) / (mu omega)). It holds for plates much heavier than the layer.

The paper's values (section 4): I_in = 5e-3 MPa s; I_s = 7.97e-3, 7.96e-3, 8.88e-3 MPa s for
plates of 10 780, 2 700, 244 kg/m^2, i.e. amplification 1.59 for both heavy plates
(7.97/5 = 1.594, 7.96/5 = 1.592) and 1.78 for the light one (8.88/5 = 1.776).

Units: [s], [m], [m/s], [N], [Pa], [Pa s]; tables and plots show [ms], [mm], [MPa],
[MPa s]. Imports numpy, `pdem.format` and this package; matplotlib only when a plot is drawn.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from pdem.format.groups import BlastParameters, read_blast
from pdem.format.read import Results, results_file

from .figures import default_out

ARRIVAL_FRACTION = 0.05
PAPER_INPUT_IMPULSE = 5.0e3   # [Pa s] = 5e-3 MPa s
# plate areal mass [kg/m^2] -> (I_s [Pa s], amplification [-]) as published
PAPER = {10780.0: (7.97e3, 1.59), 2700.0: (7.96e3, 1.59), 244.0: (8.88e3, 1.78)}
PLATE_MATCH = 0.01            # relative tolerance when matching a plate to the paper's
MS, MM, MPA = 1e3, 1e3, 1e-6  # SI -> shown


@dataclass(frozen=True)
class BlastAnalysis:
    """Everything derived from one blast run (SI units).

    Attributes
    ----------
    results : Results
    params : BlastParameters
    time, cumulative_impulse : ndarray [s], [Pa s]
        The running integral of sigma_0.
    impulse, impulse_dynamic : float [Pa s]
        I_s and I_s,dyn (static part removed) up to `until`.
    static_stress : float [Pa]
    input_impulse, input_impulse_series : float [Pa s]
        F0 tau / 2 / area, and the integral of the input_force series / area.
    amplification, amplification_dynamic : float [-]
    peak_stress, peak_time, arrival_time : float [Pa], [s], [s] (NaN if no rise)
    plate_drop, plate_drop_time : float [m], [s]
        Largest downward plate displacement (>= 0) and when.
    plate_velocity_end : float [m/s]
    layer_stiffness : float [Pa/m]
        k_A, NaN if the plate did not go down.
    sdof_amplification : float [-]
        1 - cos(sqrt(k_A / mu) T) over the record's length T.
    until : float [s]
        End of the integration (the last sample unless limited).
    paper : tuple (areal mass, I_s, amplification) or None
        The paper's plate of the same areal mass.
    """

    results: Results
    params: BlastParameters
    time: np.ndarray
    cumulative_impulse: np.ndarray
    impulse: float
    impulse_dynamic: float
    static_stress: float
    input_impulse: float
    input_impulse_series: float
    amplification: float
    amplification_dynamic: float
    peak_stress: float
    peak_time: float
    arrival_time: float
    plate_drop: float
    plate_drop_time: float
    plate_velocity_end: float
    layer_stiffness: float
    sdof_amplification: float
    until: float
    paper: tuple | None


def cumulative_trapezoid(y, t) -> np.ndarray:
    """Running trapezoidal integral of y over t, starting at 0 (units of y times [s])."""
    y, t = np.asarray(y, dtype=np.float64), np.asarray(t, dtype=np.float64)
    return np.concatenate(([0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))))


def input_impulse(params: BlastParameters) -> float:
    """I_in = F0 tau / 2 / ceiling area [Pa s]: the triangular load F0 (1 - t/tau) per area."""
    return params.F0 * params.tau / 2.0 / params.ceiling_area


def layer_stiffness(stress_rise, drop) -> float:
    """k_A [Pa/m]: least-squares slope through 0 of the ceiling's stress rise [Pa] against the
    plate's drop [m] (> 0 down), from the start to the largest drop; NaN without a drop."""
    j = int(np.argmax(drop))
    d, s = drop[: j + 1], stress_rise[: j + 1]
    dd = float(np.dot(d, d))
    return float(np.dot(d, s) / dd) if drop[j] > 0 and dd > 0 else float("nan")


def sdof_amplification(stiffness: float, areal_mass: float, duration: float) -> float:
    """1 - cos(omega T), omega = sqrt(k_A / mu) [1/s]: the impulse a plate of areal mass mu
    [kg/m^2] on a massless layer of stiffness k_A [Pa/m] passes to the ceiling within T [s], per
    unit input impulse."""
    return 1.0 - math.cos(math.sqrt(stiffness / areal_mass) * duration) if stiffness > 0 else float("nan")


def paper_plate(areal_mass: float):
    """(areal mass, I_s [Pa s], amplification) of the paper's plate within `PLATE_MATCH`."""
    for mass, (impulse, amp) in PAPER.items():
        if abs(areal_mass - mass) <= PLATE_MATCH * mass:
            return mass, impulse, amp
    return None


def analyse_blast(results: Results, params: BlastParameters,
                  until: float | None = None) -> BlastAnalysis:
    """Impulse, amplification, peak and plate motion of a blast run.

    Parameters
    ----------
    results, params : from `pdem.format.groups.read_blast`
    until : float [s], optional
        Integrate up to this time (default: the whole record).

    Raises
    ------
    ValueError
        If `until` leaves fewer than 2 samples.
    """
    s = results.series
    t = s["time"]
    keep = t <= until * (1 + 1e-12) if until is not None else np.ones(len(t), bool)
    if np.count_nonzero(keep) < 2:
        raise ValueError(f"--until {until} s leaves fewer than 2 samples "
                         f"(record starts at {t[0]:g} s)")
    t = t[keep]
    sigma = s["ceiling_stress"][keep]
    z = s["plate_position"][keep]
    cumulative = cumulative_trapezoid(sigma, t)
    static = float(sigma[0])
    impulse = float(cumulative[-1])
    dynamic = impulse - static * float(t[-1] - t[0])
    i_in = input_impulse(params)
    i_series = float(cumulative_trapezoid(s["input_force"][keep], t)[-1]) / params.ceiling_area
    k = int(np.argmax(sigma))
    rise = sigma - static
    arrival = float("nan")
    if rise[k] > 0:
        arrival = float(t[np.argmax(rise >= ARRIVAL_FRACTION * rise[k])])
    dz = z - z[0]
    j = int(np.argmin(dz))
    k_a = layer_stiffness(rise, -dz)
    return BlastAnalysis(
        results=results, params=params, time=t, cumulative_impulse=cumulative,
        impulse=impulse, impulse_dynamic=dynamic, static_stress=static, input_impulse=i_in,
        input_impulse_series=i_series, amplification=impulse / i_in,
        amplification_dynamic=dynamic / i_in, peak_stress=float(sigma[k]),
        peak_time=float(t[k]), arrival_time=arrival, plate_drop=float(max(-dz[j], 0.0)),
        plate_drop_time=float(t[j]), plate_velocity_end=float(s["plate_velocity"][keep][-1]),
        layer_stiffness=k_a,
        sdof_amplification=sdof_amplification(k_a, params.plate_areal_mass, float(t[-1] - t[0])),
        until=float(t[-1]), paper=paper_plate(params.plate_areal_mass))


SCALARS = (  # name, header, units shown, scale SI -> shown
    ("impulse", "I_s", "MPa s", MPA),
    ("impulse_dynamic", "I_s,dyn", "MPa s", MPA),
    ("input_impulse", "I_in", "MPa s", MPA),
    ("input_impulse_series", "I_in(series)", "MPa s", MPA),
    ("amplification", "I_s/I_in", "-", 1.0),
    ("amplification_dynamic", "I_s,dyn/I_in", "-", 1.0),
    ("static_stress", "sigma_static", "MPa", MPA),
    ("peak_stress", "sigma_peak", "MPa", MPA),
    ("peak_time", "t_peak", "ms", MS),
    ("arrival_time", "t_arrival", "ms", MS),
    ("plate_drop", "plate_drop", "mm", MM),
    ("plate_drop_time", "t_drop", "ms", MS),
    ("plate_velocity_end", "v_plate_end", "m/s", 1.0),
    ("layer_stiffness", "k_A", "MPa/mm", MPA / MM),
    ("sdof_amplification", "1-cos(wT)", "-", 1.0),
    ("until", "t_end", "ms", MS),
)
SI_UNITS = {"impulse": "Pa s", "impulse_dynamic": "Pa s", "input_impulse": "Pa s",
            "input_impulse_series": "Pa s", "amplification": "-",
            "amplification_dynamic": "-", "static_stress": "Pa", "peak_stress": "Pa",
            "peak_time": "s", "arrival_time": "s", "plate_drop": "m", "plate_drop_time": "s",
            "plate_velocity_end": "m/s", "layer_stiffness": "Pa/m", "sdof_amplification": "-", "until": "s"}


def blast_lines(result: BlastAnalysis) -> list[str]:
    """Text report of one run."""
    p, r = result.params, result.results
    lines = [
        f"pdem blast layer: {r.path}",
        f"kind {r.kind}, pdem {r.attrs['pdem_version']}; plate {p.plate_areal_mass:g} kg/m^2, "
        f"ceiling area {p.ceiling_area:g} m^2, load F0 = {p.F0:g} N over tau = {p.tau:g} s",
        "I_s = integral of sigma_0 dt (trapezoidal); I_s,dyn without the static stress "
        "(sigma_0 at the first sample); I_in = F0 tau / 2 / area",
        "",
    ]
    for name, header, units, scale in SCALARS:
        value = getattr(result, name) * scale
        lines.append(f"  {header:>14} = {value:12.5g} [{units}]")
    if result.paper is not None:
        mass, impulse, amp = result.paper
        lines += ["", f"paper (plate {mass:g} kg/m^2): I_s = {impulse * MPA:.3g} MPa s, "
                      f"amplification {amp:.2f}, I_in = {PAPER_INPUT_IMPULSE * MPA:.3g} MPa s; "
                      f"this run: I_s {_rel(result.impulse, impulse)}, "
                      f"I_s,dyn {_rel(result.impulse_dynamic, impulse)}"]
    else:
        lines += ["", "paper: no plate of this areal mass (published: "
                      + ", ".join(f"{m:g}" for m in PAPER) + " kg/m^2)"]
    return lines


def blast_dict(result: BlastAnalysis) -> dict:
    """The report as JSON-ready data [SI]."""
    return {
        "file": str(result.results.path), "kind": result.results.kind,
        "parameters": asdict(result.params),
        "units": {**SI_UNITS, "plate_areal_mass": "kg/m^2", "ceiling_area": "m^2",
                  "F0": "N", "tau": "s"},
        **{name: _json(getattr(result, name)) for name in SI_UNITS},
        "paper": None if result.paper is None else
        {"plate_areal_mass": result.paper[0], "impulse": result.paper[1],
         "amplification": result.paper[2], "input_impulse": PAPER_INPUT_IMPULSE},
    }


def plot_blast(result: BlastAnalysis, path) -> Path:
    """sigma_0(t) with the input pressure, plate motion, and the cumulative impulse."""
    from matplotlib.figure import Figure

    from .figures import save

    s, p = result.results.series, result.params
    keep = slice(0, len(result.time))
    t = result.time * MS
    fig = Figure(figsize=(7.5, 9.0), layout="constrained")
    ax_s, ax_p, ax_i = fig.subplots(3, 1, sharex=True)

    ax_s.plot(t, s["ceiling_stress"][keep] * MPA, color="C0", label="σ0 on the ceiling")
    ax_s.plot(result.peak_time * MS, result.peak_stress * MPA, "v", color="C3",
              label=f"peak {result.peak_stress * MPA:.4g} MPa at {result.peak_time * MS:.3g} ms")
    ax_f = ax_s.twinx()
    ax_f.plot(t, s["input_force"][keep] / p.ceiling_area * MPA, color="C7", lw=0.8, ls="--",
              label="input F(t)/area")
    ax_f.set_ylabel("input pressure [MPa]", color="C7")
    ax_s.set(ylabel="σ0 [MPa]", title=f"Blast layer, plate {p.plate_areal_mass:g} kg/m²")
    _legend(ax_s, ax_f)

    ax_p.plot(t, (s["plate_position"][keep] - s["plate_position"][0]) * MM, color="C2",
              label="plate Δp")
    ax_v = ax_p.twinx()
    ax_v.plot(t, s["plate_velocity"][keep], color="C1", lw=0.8, label="plate velocity")
    ax_v.set_ylabel("plate velocity [m/s]", color="C1")
    ax_p.set(ylabel="plate displacement Δp [mm]")
    _legend(ax_p, ax_v)

    ax_i.plot(t, result.cumulative_impulse * MPA * 1e3, color="C0",
              label=f"∫σ0 dt: I_s = {result.impulse * MPA * 1e3:.3f}e-3 MPa·s "
                    f"(×{result.amplification:.3f})")
    ax_i.axhline(result.input_impulse * MPA * 1e3, color="C7", ls="--",
                 label=f"I_in = {result.input_impulse * MPA * 1e3:.3f}e-3 MPa·s")
    for mass, (impulse, amp) in PAPER.items():
        mine = result.paper is not None and result.paper[0] == mass
        ax_i.axhline(impulse * MPA * 1e3, color="C3" if mine else "0.6", ls=":",
                     lw=1.5 if mine else 0.8,
                     label=f"paper, {mass:g} kg/m²: {impulse * MPA * 1e3:.2f}e-3 (×{amp:.2f})")
    ax_i.set(xlabel="time [ms]", ylabel="impulse [1e-3 MPa·s]")
    ax_i.legend(fontsize="x-small", loc="lower right")
    for ax in (ax_s, ax_p, ax_i):
        ax.grid(True, alpha=0.3)
    return save(fig, path)


# --- several runs: mean and scatter per plate ---

@dataclass(frozen=True)
class PlateStatistics:
    """Statistics of the runs with one plate areal mass [kg/m^2].

    For each of `COMPARED`: mean, std (sample, n - 1; NaN for one run), minimum, maximum, and the
    95 % confidence interval of the mean (Student's t; NaN for one run).
    """

    plate_areal_mass: float
    n: int
    runs: tuple
    stats: dict
    paper: tuple | None


COMPARED = ("impulse", "impulse_dynamic", "amplification", "amplification_dynamic",
            "peak_stress", "peak_time", "plate_drop", "layer_stiffness", "sdof_amplification")


def compare_blast(analyses) -> list[PlateStatistics]:
    """Group runs by plate areal mass (within `PLATE_MATCH`) and summarise each group."""
    from .variability import variability

    groups: list[list[BlastAnalysis]] = []
    for a in sorted(analyses, key=lambda a: -a.params.plate_areal_mass):
        m = a.params.plate_areal_mass
        for g in groups:
            if abs(g[0].params.plate_areal_mass - m) <= PLATE_MATCH * m:
                g.append(a)
                break
        else:
            groups.append([a])
    out = []
    for g in groups:
        stats = {}
        for name in COMPARED:
            x = np.array([getattr(a, name) for a in g], dtype=np.float64)
            entry = {"mean": float(np.mean(x)), "std": float("nan"), "min": float(np.min(x)),
                     "max": float(np.max(x)), "ci_low": float("nan"), "ci_high": float("nan")}
            if len(x) >= 2 and np.all(np.isfinite(x)):
                v = variability(x)
                entry.update(std=v.std, ci_low=v.ci_low, ci_high=v.ci_high)
            stats[name] = entry
        m = g[0].params.plate_areal_mass
        out.append(PlateStatistics(plate_areal_mass=m, n=len(g),
                                   runs=tuple(str(a.results.path) for a in g), stats=stats,
                                   paper=paper_plate(m)))
    return out


def compare_lines(groups) -> list[str]:
    lines = ["pdem blast layer: runs compared per plate (mean ± sample std, [min, max]; "
             "95 % CI of the mean)", ""]
    shown = dict((name, (header, units, scale)) for name, header, units, scale in SCALARS)
    for g in groups:
        paper = ("" if g.paper is None else
                 f"; paper I_s = {g.paper[1] * MPA:.3g} MPa s, ×{g.paper[2]:.2f}")
        lines.append(f"plate {g.plate_areal_mass:g} kg/m^2: {g.n} run(s){paper}")
        for name in COMPARED:
            header, units, scale = shown[name]
            e = g.stats[name]
            lines.append(f"  {header:>14} = {e['mean'] * scale:10.5g} ± {e['std'] * scale:<10.3g}"
                         f" [{e['min'] * scale:.5g}, {e['max'] * scale:.5g}]"
                         f"  CI [{e['ci_low'] * scale:.5g}, {e['ci_high'] * scale:.5g}] [{units}]")
        for run in g.runs:
            lines.append(f"    {run}")
        lines.append("")
    return lines


def compare_dict(groups) -> dict:
    return {"units": {k: SI_UNITS[k] for k in COMPARED} | {"plate_areal_mass": "kg/m^2"},
            "plates": [{"plate_areal_mass": g.plate_areal_mass, "n": g.n, "runs": list(g.runs),
                        "stats": {k: {s: _json(v) for s, v in e.items()}
                                  for k, e in g.stats.items()},
                        "paper": None if g.paper is None else
                        {"impulse": g.paper[1], "amplification": g.paper[2]}}
                       for g in groups]}


def plot_compare(groups, path) -> Path:
    """I_s per plate (mean ± std and each run) against the paper's values."""
    from matplotlib.figure import Figure

    from .figures import save

    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    ax = fig.add_subplot()
    for i, g in enumerate(groups):
        e = g.stats["impulse"]
        std = e["std"] if math.isfinite(e["std"]) else 0.0
        ax.errorbar(g.plate_areal_mass, e["mean"] * MPA * 1e3, yerr=std * MPA * 1e3, fmt="o",
                    color="C0", capsize=4, label="pdem: mean ± std" if i == 0 else None)
    ax.plot(list(PAPER), [v[0] * MPA * 1e3 for v in PAPER.values()], "s", color="C3",
            mfc="none", label="paper (Szklennik 2016)")
    ax.axhline(PAPER_INPUT_IMPULSE * MPA * 1e3, color="C7", ls="--", label="I_in (paper)")
    ax.set_xscale("log")
    ax.set(xlabel="plate areal mass [kg/m²]", ylabel="I_s [1e-3 MPa·s]",
           title="Impulse on the ceiling per plate")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


# --- command line ---

def run_blast(runs, out=None, until=None) -> list[Path]:
    """Analyse one or more blast runs; with several, also compare them (needs `out`)."""
    paths = [results_file(r) for r in runs]
    return write_blast(paths, [analyse_blast(*read_blast(p), until=until) for p in paths], out)


def write_blast(paths, analyses, out=None) -> list[Path]:
    """The files of `run_blast` for the analyses of the results files ``paths``."""
    if len(paths) > 1 and out is None:
        raise ValueError("several runs need --out DIR for the comparison")
    written = []
    names = _run_names(paths)
    for path, name, result in zip(paths, names, analyses):
        if len(paths) == 1:
            where = Path(out) if out is not None else default_out(path)
        else:
            where = Path(out) / name
        where.mkdir(parents=True, exist_ok=True)
        (where / "blast.txt").write_text("\n".join(blast_lines(result)) + "\n")
        (where / "blast.json").write_text(json.dumps(blast_dict(result), indent=1,
                                                     allow_nan=False) + "\n")
        written += [plot_blast(result, where / "blast.png"), where / "blast.txt",
                    where / "blast.json"]
    if len(paths) > 1:
        out = Path(out)
        groups = compare_blast(analyses)
        (out / "blast_compare.txt").write_text("\n".join(compare_lines(groups)) + "\n")
        (out / "blast_compare.json").write_text(json.dumps(compare_dict(groups), indent=1,
                                                           allow_nan=False) + "\n")
        written += [plot_compare(groups, out / "blast_compare.png"), out / "blast_compare.txt",
                    out / "blast_compare.json"]
    return written


def add_parser(sub) -> None:
    """The ``blast`` subcommand of ``python -m analysis``."""
    p = sub.add_parser(
        "blast", help="blast layer: ceiling stress, impulse, amplification; compare runs",
        description="Write blast.png, blast.txt and blast.json for each run (sigma_0(t), "
                    "plate motion, cumulative impulse with the paper's values); with several "
                    "runs also blast_compare.txt/.json/.png (mean and scatter per plate).")
    p.add_argument("results", type=Path, nargs="+", metavar="RUN",
                   help="run directory (with results.h5) or results file")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (one run: default RUN/analysis of a run folder, else RESULTS-analysis; "
                        "several runs: required, one subdirectory per run)")
    p.add_argument("--until", type=float, metavar="SECONDS",
                   help="integrate up to this time (default: the whole record)")
    p.set_defaults(run=lambda a: run_blast(a.results, a.out, a.until))


def _run_names(paths) -> list[str]:
    """A directory name per run: the run directory's name for RUN/results.h5, else the stem."""
    names, seen = [], {}
    for p in paths:
        name = p.parent.name if p.name == "results.h5" and p.parent.name else p.stem
        seen[name] = seen.get(name, 0) + 1
        names.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    return names


def _legend(ax, twin):
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = twin.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize="x-small", loc="upper right")


def _rel(value, reference) -> str:
    return f"{value * MPA:.4g} MPa s ({(value / reference - 1.0) * 100:+.1f} %)"


def _json(value):
    value = float(value)
    return value if math.isfinite(value) else None
