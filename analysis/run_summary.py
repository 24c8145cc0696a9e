"""``python -m analysis summary RUN``: the post-processing of a run (a plain scene, or a staged one:
box test, oedometer, blast, track), launched by ``pdem run`` after a successful run.

This module owns the run's summary: it reads the run's account (``RUN/run_info.json``,
`pdem.format.run`: what only the run knows) and its results, and writes

- ``RUN/preparation.png`` (`analysis.figures.plot_preparation`) if the run prepared a bed;
- ``RUN/results.png`` for a plain scene (`analysis.figures.plot_run_series`);
- ``RUN/analysis/``: the analysis of the run's kind (``summary`` of run_info.json): box test
  (`analysis.summary.run_box`: loops, settlement, stiffness, summary.txt/.json), oedometer
  (`analysis.oedometer`, with the grading), blast (`analysis.blast`, every plate), track
  (`analysis.track`, after traffic), shear box (`shear_box`: shear stress against displacement);
- ``RUN/summary.txt``: title, pdem version and end date, the scene file's seeds and materials,
  ranks, wall time [s], what the run tells of itself, the stage table of a staged run (end time
  [s], steps, spheres, unbalanced force ratio [-], bed top [mm], the scene's own columns with
  lengths in [mm], wall time [s]), the
  run's notes, the table of its kind (cycles [mm], [N]; the oedometer report; impulse per plate
  [MPa s]; passages [mm]; the shear box's peak) and the timing table; it is also printed.

A failing analysis (bad results) is reported in summary.txt and on stderr; the rest is written.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from pdem.format.groups import read_blast, read_fragments, read_track
from pdem.format.read import ResultFileError, read_results
from pdem.format.run import RUN_INFO, read_run_info

from .blast import analyse_blast, blast_dict, write_blast
from .figures import figure, plot_preparation, plot_run_series, save
from .grading import bond_lines
from .oedometer import run_oedometer
from .summary import run_box
from .track import KN, fit_lines, fit_settlement, grain_members, run_track

MM = 1e3
# stage table: the columns every staged run has (key, label, format); the scene adds its own
STAGE_COLUMNS = (("t_end", "t_end [s]", ".6g"), ("step_end", "steps", "d"), ("spheres", "spheres", "d"),
                 ("unbalanced_force", "unbalanced", ".3g"), ("bed_top", "bed top [m]", ".5g"))
LENGTH_FORMAT = ".2f"  # every length [m] of a table is shown in [mm] with this format


def summarize(run) -> list[Path]:
    """Write the summary of the run directory ``run``; returns the written files."""
    run = Path(run)
    info = read_run_info(run)
    if info is None:
        raise ValueError(f"no {RUN_INFO}: not a complete run")
    written = []
    prep = info.get("preparation")
    if prep and (run / "preparation.h5").exists():
        try:
            written.append(plot_preparation(run / "preparation.h5", run / "preparation.png", prep["stages"],
                                            prep["body"]))
        except (ResultFileError, KeyError, ValueError) as err:  # a run that loaded a prepared bed has few rows
            print(f"no preparation plot: {_one_line(err)}", flush=True)
    try:
        kind_lines, files = KINDS[info["summary"]](run, info)
    except (ResultFileError, ValueError, OSError) as err:
        kind_lines, files = [f"analysis failed: {_one_line(err)}"], []
        print(f"python -m analysis summary: error: {_one_line(err)}", file=sys.stderr, flush=True)
    sections = [[f"{info['title']}: {info['scene_file']}", *provenance(info), f"ranks: {info['ranks']}",
                 f"wall time: {info['wall_s']:.1f} s", *info["about"]],
                stage_table(info["stages"], info["stage_columns"]) if info["stages"] else [],
                info["notes"], kind_lines, [info["timing"]]]
    text = "\n\n".join("\n".join(s) for s in sections if s)
    (run / "summary.txt").write_text(text + "\n")
    print(text, flush=True)
    return written + files + [run / "summary.txt"]


def provenance(info) -> list[str]:
    """The lines of what made the run: pdem version and end date, the scene file's seeds and
    materials (runs written before pdem 0.3 have none of these: nothing is shown)."""
    lines = []
    if "pdem_version" in info:
        lines.append(f"pdem {info['pdem_version']}, finished {info.get('finished', '?')}")
    if "seeds" in info:
        seeds = ", ".join(f"{k} = {v}" for k, v in info["seeds"].items())
        lines.append(f"seeds: {seeds or 'none in the scene file'}")
    for name, m in info.get("materials", {}).items():
        values = (f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in m.items())
        lines.append(f"material {name} (SI units): " + ", ".join(values))
    return lines


def stage_table(rows, extra_columns) -> list[str]:
    """One line per stage: its name, `STAGE_COLUMNS`, the scene's ``extra_columns`` and the wall
    time; a missing or null entry is shown as "-". Lengths (a label ending in "[m]") are shown
    in [mm], as every displacement of the summary."""
    columns = [(key, label[:-3] + "[mm]", LENGTH_FORMAT, MM) if label.endswith("[m]") else (key, label, fmt, 1)
               for key, label, fmt in (*STAGE_COLUMNS, *extra_columns, ("wall_s", "wall [s]", ".1f"))]
    name_width = max([8] + [len(r["stage"]) for r in rows])
    widths = [max(len(label), 9) for _, label, _, _ in columns]
    lines = [f"{'stage':<{name_width}} " + " ".join(f"{label:>{w}}" for (_, label, _, _), w in zip(columns, widths))]
    for r in rows:
        cells = [("-" if r.get(key) is None else format(scale * r[key], fmt)) for key, _, fmt, scale in columns]
        lines.append(f"{r['stage']:<{name_width}} " + " ".join(f"{c:>{w}}" for c, w in zip(cells, widths)))
    return lines


def scene(run, info):
    """A plain scene: the plot of its series."""
    return [], [plot_run_series(run / "results.h5", run / "results.png")]


def box_test(run, info):
    """The cycles table and the box-test analysis."""
    cycles = read_results(run / "results.h5").cycles
    lines = ["cycle  settlement start/peak/end [mm]     ballast force min/max [N]"]
    for k in range(0 if cycles is None else len(cycles["cycle"])):
        lines.append(f"{int(cycles['cycle'][k]):5d}  {MM * cycles['settlement_start'][k]:9.3f} "
                     f"{MM * cycles['settlement_peak'][k]:9.3f} {MM * cycles['settlement_end'][k]:9.3f}   "
                     f"{cycles['force_min'][k]:10.1f} {cycles['force_peak'][k]:10.1f}")
    return lines, run_box(run / "results.h5", run / "analysis")


def oedometer(run, info):
    """The oedometer analysis (with the grading) and its report."""
    written = run_oedometer(run, run / "analysis", info["intact_members"])
    return [(run / "analysis" / "oedometer.txt").read_text().rstrip()], written


def blast(run, info):
    """The blast analysis of every plate and the impulse table against the paper."""
    plates = [(mass, run / d / "results.h5") for mass, d in info["plates"]]
    analyses = [analyse_blast(*read_blast(path)) for _, path in plates]
    written = write_blast([p for _, p in plates], analyses, run / "analysis") if plates else []
    lines = ["plate [kg/m^2]   I_s [MPa s]   I_s/I_in   I_s,dyn/I_in   peak sigma_0 [MPa]   paper I_s   "
             "paper I_s/I_in"]
    for (mass, _), a in zip(plates, analyses):
        r = blast_dict(a)
        paper = r["paper"] or {}
        lines.append(f"{mass:14g}   {r['impulse'] * 1e-6:11.4e}   {r['amplification']:8.3f}   "
                     f"{r['amplification_dynamic']:12.3f}   {r['peak_stress'] * 1e-6:18.3f}   "
                     f"{paper.get('impulse', float('nan')) * 1e-6:9.3e}   "
                     f"{paper.get('amplification', float('nan')):14.2f}")
    return lines, written


def track(run, info):
    """After traffic: the passages table and the track analysis."""
    if not info["traffic"]:
        return [], []
    p = read_track(run / "results.h5").passages
    lines = ["passage  t_end [s]  settlement peak mean/max [mm]  permanent mean/min/max [mm]  gap max [mm]"]
    for i in range(len(p["passage"])):
        peak, permanent = p["settlement_peak"][i], p["settlement_permanent"][i]
        gap = f"{MM * p['gap'][i].max():9.3f}" if "gap" in p else "-"
        lines.append(f"{int(p['passage'][i]):7d} {p['t_end'][i]:10.4f}  {MM * peak.mean():9.3f} {MM * peak.max():9.3f}"
                     f"            {MM * permanent.mean():8.3f} {MM * permanent.min():8.3f} "
                     f"{MM * permanent.max():8.3f}   {gap}")
    if "load_peak" in p:
        lines += ["peak load of the rail (a beam) on each sleeper per passage [kN]:"]
        lines += [f"{int(p['passage'][i]):7d}  " + " ".join(f"{KN * f:7.3f}" for f in p["load_peak"][i])
                  for i in range(len(p["passage"]))]
    fits = fit_settlement(p["passage"], p["settlement_permanent"].mean(axis=1))
    written = run_track(run, run / "analysis")
    if grain_members(run / "results.h5") is not None:  # breakable grains: the bonds per passage
        lines += bond_lines(read_fragments(run / "results.h5").records)
    return lines + fit_lines(fits), written


def shear_box(run, info):
    """The shear box: τ = shear force / area and σ = normal force / area [Pa] against the
    displacement; the peak τ/σ and its friction angle; analysis/shear_box.png."""
    s = read_results(run / "results.h5", required=("shear_displacement", "shear_force", "normal_force")).series
    d, tau, sigma = s["shear_displacement"], s["shear_force"] / info["area"], s["normal_force"] / info["area"]
    k = int(np.argmax(tau / np.maximum(sigma, 1e-300)))
    fig, ax = figure()
    ax.plot(MM * d, tau * 1e-3, label="shear stress")
    ax.plot(MM * d, sigma * 1e-3, label="normal stress")
    ax.set(xlabel="shear displacement [mm]", ylabel="stress [kPa]")
    ax.legend()
    (run / "analysis").mkdir(exist_ok=True)
    lines = [f"peak tau/sigma {tau[k] / sigma[k]:.4f} (friction angle {np.degrees(np.arctan(tau[k] / sigma[k])):.2f} "
             f"deg) at {MM * d[k]:.3f} mm: tau {tau[k]:.6g} Pa, sigma {sigma[k]:.6g} Pa"]
    return lines, [save(fig, run / "analysis" / "shear_box.png")]


KINDS = {"scene": scene, "box_test": box_test, "oedometer": oedometer, "blast": blast, "track": track,
         "shear_box": shear_box}


def add_parser(sub) -> None:
    """The ``summary`` subcommand of ``python -m analysis``."""
    p = sub.add_parser(
        "summary", help="a staged run's summary.txt, preparation.png and analysis/ (from its run_info.json)",
        description="Write RUN/summary.txt and the plots and analysis of a complete run: results.png of a "
                    "plain scene; preparation.png and analysis/ of a box test, oedometer, blast or track run "
                    "(pdem run does this after a successful run).")
    p.add_argument("results", type=Path, metavar="RUN", help="run directory (with run_info.json)")
    p.set_defaults(run=lambda a: summarize(a.results))


def _one_line(message) -> str:
    return " ".join(str(message).split())
