"""The overlap artefact of the breakable oedometer (issue #32): how far the load pushed the
contacts, how much the grains broke, and how much of that breakage happened while the overlaps
were large (thesis 4.5, table 4.15, fig. 4.25: clumps loaded at E_k = 5.55e9 Pa, 100x softer than
the 5.55e11 Pa the thesis identified for its rigid clumps, with the full 1.5 MN).

    python -m analysis oedometer-overlap PATH [PATH ...] [--out DIR] [--threshold 0.05 0.1] [--large N]

PATH: a run directory (or its results.h5) of a breakable oedometer, or a campaign directory of
such runs (jobs/campaigns/validation_oedometer_overlap.toml: members grouped by case over the seeds). It
reads the load record's overlap statistics (`pdem.scenes.oedometer`, pdem >= 0.3.0:
``<group>_overlap_max``, ``<group>_overlap_mean`` [-] of the groups ``pair`` (spheres of different
grains or fragments), ``bond`` (intact bonds) and ``boundary`` (base, cylinder, platen), and
``intact_bonds`` [-]) and the fragment records, and writes ``overlap.png``, ``overlap.txt`` and
``overlap.json`` (default: RUN/analysis, beside the run's other analysis; a campaign:
DIR/analysis; several paths: the first one's).

Per run:

- overlap δ over the smaller radius r: the largest (of any contact, and per group) and the mean
  (per group) against the applied platen load, at the peak load and the largest over the load;
- breakage during the load: the intact bonds at the start of the load b_0 and at its end, the
  bonds broken b_0 - b_end, as a fraction of b_0;
- the share of that breakage that happened while the overlaps exceeded a threshold θ: the
  bonds lost between two samples k-1, k count as "above θ" when the largest δ/r of any contact
  exceeded θ at sample k-1, before they broke (a lower bound: ``share_before``), or at either
  sample (an upper bound: ``share_above``; a burst of breakage rearranges the grains and may
  itself make the large overlap at k). The samples are the record's, every ``run.output_every``
  steps: a sampled, not a continuous, maximum. Also the applied load when the largest δ/r
  first passed θ;
- grading after loading (record "unloaded", else the last), by mass and by number of
  fragments: single spheres [%] and fragments of >= ``large`` spheres [%] (default 135, the
  thesis's "135 and more", or the intact grain's size if smaller), as the thesis's fig. 4.25
  (by mass) and text (by number) give them; the record before loading ("vibrated", else
  "initial") the same.

The thresholds (default θ = 0.05 and 0.10 of the radius) are conventions, not derived from the
thesis. Why these: the linear law has no limit of its own, and the run's stability guard stops
only at 0.5; at 0.05-0.10 r the overlap is no longer small against the member spheres (the
contact circle of two equal spheres, radius √(r δ - δ²/4), is 0.22-0.31 r; a column of the ~20
members across the 150 mm sample shortens by 20 δ = 1-2 r, a member's diameter, by
interpenetration alone), while the identified modulus gives the same forces overlaps 100x
smaller (0.0005-0.001 r). Breakage that happens only above them is breakage a stiffer contact
would not see the same way; the control runs (identified modulus) decide whether it matters.

A campaign: per case (the members that differ only by their seed) the mean and its Student-t
interval over the seeds of each figure; the conclusion compares each case's bonds broken and
single spheres (by mass) with the first case's (Welch's t-test, two-sided, 5 %): "not an
overlap artefact" when the stiff control breaks as much, "breakage depends on the overlap" when
it breaks significantly less, no conclusion with fewer than two seeds a case; and it warns
where a case starts the load with more than 1 % fewer intact bonds than the first (grains
broken in the preparation, e.g. by the platen falling onto the cut sample: a stiffer contact
makes that impact's forces larger against the same bonds).

Units: δ/r [-], loads [N] (tables and plots [kN]), fractions [-] (tables [%]). Imports numpy,
scipy, `pdem.format` and this package; matplotlib only when a plot is drawn.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from pdem.format.groups import read_fragments
from pdem.format.read import ResultFileError, read_finite, results_file

from .campaign import CampaignError, group_members, interval_text, read_campaign, stats
from .figures import default_out, figure, save
from .grading import INTACT_MEMBERS, summarise

GROUPS = ("pair", "bond", "boundary")
GROUP_LABEL = {"pair": "between grains / fragments", "bond": "intact bonds (within a grain)",
               "boundary": "base, cylinder, platen"}
COLUMNS = ("platen_load", "intact_bonds") + tuple(f"{g}_overlap_{s}" for g in GROUPS for s in ("max", "mean"))
THRESHOLDS = (0.05, 0.10)
AFTER, BEFORE = ("unloaded",), ("vibrated", "initial")
KN, PCT = 1e-3, 1e2
SIGNIFICANCE = 0.05


# ---------------------------------------------------------------------------- one run
def read_overlap(path):
    """The load record (`pdem.format.read.Results`) of a breakable oedometer with the overlap
    statistics; a ResultFileError naming what is missing."""
    res = read_finite(results_file(path), COLUMNS, min_samples=3)
    if res.attrs.get("kind") != "oedometer":
        raise ResultFileError(res.path, f"kind is {res.attrs.get('kind')!r}, not an oedometer")
    return res


def breakage_above(bonds, largest, threshold):
    """(bonds broken between samples k-1, k while ``largest`` [-] exceeded ``threshold`` at k-1,
    the same at k-1 or k, bonds broken in all): the load record's breakage split by the overlap."""
    bonds, largest = np.asarray(bonds, np.float64), np.asarray(largest, np.float64)
    lost = np.maximum(bonds[:-1] - bonds[1:], 0.0)
    before = largest[:-1] > threshold
    either = before | (largest[1:] > threshold)
    return float(lost[before].sum()), float(lost[either].sum()), float(lost.sum())


def grading_figures(record, density, large):
    """Single spheres and fragments of >= ``large`` spheres, by mass and by number [-]."""
    s = summarise(record, density, large)
    return {"label": record.label, "fragments": s.n_fragments, "single_mass": s.fraction_single,
            "large_mass": s.fraction_large, "single_number": s.count_single, "large_number": s.count_large}


def _record(fragments, labels):
    by = {r.label: r for r in fragments.records}
    return next((by[k] for k in labels if k in by), None)


def analyse_run(path, thresholds=THRESHOLDS, large=None) -> dict:
    """Every figure of one run (the module docstring): SI units and fractions [-]."""
    res = read_overlap(path)
    s = res.series
    load = np.asarray(s["platen_load"], np.float64)
    peak = int(np.argmax(load))
    largest = np.max([s[f"{g}_overlap_max"] for g in GROUPS], axis=0)
    bonds = np.asarray(s["intact_bonds"], np.float64)
    out = {"path": str(res.path), "samples": len(load), "peak_load": float(load[peak]),
           "largest_at_peak": float(largest[peak]), "largest": float(largest.max()),
           "largest_at_load": float(load[int(np.argmax(largest))]), "groups": {},
           "bonds_start": float(bonds[0]), "bonds_end": float(bonds[-1])}
    for g in GROUPS:
        mx, mean = np.asarray(s[f"{g}_overlap_max"]), np.asarray(s[f"{g}_overlap_mean"])
        out["groups"][g] = {"max_at_peak": float(mx[peak]), "mean_at_peak": float(mean[peak]),
                            "max": float(mx.max()), "mean_max": float(mean.max())}
    broken = bonds[0] - bonds[-1]
    out["bonds_broken"] = float(broken)
    out["broken_fraction"] = float(broken / bonds[0]) if bonds[0] > 0 else math.nan
    out["thresholds"] = []
    for th in thresholds:
        before, above, total = breakage_above(bonds, largest, th)
        first = np.flatnonzero(largest > th)
        out["thresholds"].append({
            "threshold": float(th), "share_before": before / total if total > 0 else math.nan,
            "share_above": above / total if total > 0 else math.nan,
            "first_load": float(load[first[0]]) if len(first) else math.nan,
            "samples_above": int(np.count_nonzero(largest > th))})
    try:
        fr = read_fragments(res.path)
    except ResultFileError:  # no fragment records: grains that cannot break
        fr = None
    out["grading"] = {}
    if fr is not None:
        n_intact = int(max(r.n_members.max() for r in fr.records))
        out["large"] = int(large) if large is not None else min(INTACT_MEMBERS, n_intact)
        for key, labels in (("before", BEFORE), ("after", AFTER)):
            rec = _record(fr, labels) or (fr.records[-1] if key == "after" else fr.records[0])
            out["grading"][key] = grading_figures(rec, fr.density, out["large"])
    out["series"] = {"load": load.tolist(), "largest": largest.tolist(), "bonds": bonds.tolist(),
                     **{f"{g}_{k}": np.asarray(s[f"{g}_overlap_{k}"]).tolist() for g in GROUPS
                        for k in ("max", "mean")}}
    return out


# ---------------------------------------------------------------------------- a campaign
def welch(a, b):
    """Two-sided p of Welch's t-test of the means of ``a`` and ``b`` (NaN with < 2 values each)."""
    from scipy.stats import ttest_ind

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if len(a) < 2 or len(b) < 2:
        return math.nan
    if np.ptp(a) == 0 and np.ptp(b) == 0:
        return 1.0 if a[0] == b[0] else 0.0
    return float(ttest_ind(a, b, equal_var=False).pvalue)


FIGURES = (("largest_at_peak", "largest δ/r at the peak"), ("pair_mean_at_peak", "mean δ/r between grains at peak"),
           ("broken_fraction", "bonds broken in the load"), ("single_mass", "single spheres by mass"),
           ("large_mass", ">= large by mass"), ("single_number", "single spheres by number"),
           ("large_number", ">= large by number"))


def figures_of(run) -> dict:
    """The scalar figures of one run that a case's statistics take."""
    after = run["grading"].get("after", {})
    f = {"largest_at_peak": run["largest_at_peak"], "pair_mean_at_peak": run["groups"]["pair"]["mean_at_peak"],
         "bonds_start": run["bonds_start"], "broken_fraction": run["broken_fraction"],
         **{k: after.get(k, math.nan) for k in ("single_mass", "large_mass", "single_number", "large_number")}}
    for t in run["thresholds"]:
        f[f"share_before_{t['threshold']:g}"] = t["share_before"]
        f[f"share_above_{t['threshold']:g}"] = t["share_above"]
    return f


def conclusion(cases) -> str:
    """Each later case against the first: does it break as much (Welch, 5 %)? And a warning where a
    case starts the load with fewer intact bonds than the first (grains broken in the preparation:
    its grading after loading is not the load's alone)."""
    if len(cases) < 2:
        return "one case only: nothing to compare"
    ref, parts = cases[0], []
    for c in cases[1:]:
        warn = ""
        start, ref_start = (float(np.mean(x["values"]["bonds_start"])) if x["values"].get("bonds_start") else math.nan
                            for x in (c, ref))
        if start < 0.99 * ref_start:
            warn = (f" (warning: it starts the load with {start:.0f} intact bonds against {ref_start:.0f}, "
                    f"{PCT * (1 - start / ref_start):.3g} % fewer: grains broke before the load, or fewer were cut in; "
                    "its grading after loading is not the load's alone)")
        if min(c["n"], ref["n"]) < 2:
            parts.append(f"{c['case']}: fewer than two seeds, no conclusion{warn}")
            continue
        verdicts = []
        for key, what in (("broken_fraction", "bonds broken"), ("single_mass", "single spheres by mass")):
            a, b = ref["values"][key], c["values"][key]
            p = welch(a, b)
            ma, mb = float(np.nanmean(a)), float(np.nanmean(b))
            if not math.isfinite(p):
                verdicts.append(f"{what} not comparable")
            elif p < SIGNIFICANCE and mb < ma:
                verdicts.append(f"{what} {PCT * mb:.3g} % < {PCT * ma:.3g} % (p = {p:.2g}): "
                                "breakage depends on the overlap")
            elif p < SIGNIFICANCE:
                verdicts.append(f"{what} {PCT * mb:.3g} % > {PCT * ma:.3g} % (p = {p:.2g}): more breakage "
                                "with smaller overlaps, not an overlap artefact")
            else:
                verdicts.append(f"{what} {PCT * mb:.3g} % vs {PCT * ma:.3g} % (p = {p:.2g}): no significant "
                                "difference, not an overlap artefact")
        parts.append(f"{c['case']} against {ref['case']}: " + "; ".join(verdicts) + warn)
    return " | ".join(parts)


def analyse_campaign(path, thresholds=THRESHOLDS, large=None, confidence=0.95) -> dict:
    """Every done member's figures, grouped by case, with their statistics and the conclusion."""
    camp = read_campaign(path)
    if not camp.done:
        raise CampaignError(f"{path}: no member is done yet ({len(camp.members)} members; see pdem campaign status)")
    runs = {m.name: analyse_run(m.dir, thresholds, large) for m in camp.done}
    cases = []
    for g in group_members(camp.done, camp.seed_key):
        figs = [figures_of(runs[m.name]) for m in g.members]
        values = {k: [f[k] for f in figs] for k in figs[0]}
        cases.append({"case": str(g.params.get("case", g.label)), "params": g.params, "n": len(g.members),
                      "members": [m.name for m in g.members], "values": values,
                      "stats": {k: stats(v, confidence) for k, v in values.items()}})
    return {"campaign": camp.name, "dir": str(camp.dir), "runs": runs, "cases": cases,
            "not_used": [f"{m.name} ({m.state})" for m in camp.members if not m.done],
            "confidence": confidence, "conclusion": conclusion(cases)}


# ---------------------------------------------------------------------------- output
def _pct(x, spec=".3g"):
    return format(PCT * x, spec) if isinstance(x, (int, float)) and math.isfinite(x) else "-"


def run_lines(name, r) -> list[str]:
    out = [f"{name}: {r['path']}",
           f"  load: peak {r['peak_load'] * KN:.4g} kN; {r['samples']} samples",
           f"  largest overlap / smaller radius of any contact: {r['largest_at_peak']:.4g} at the peak, "
           f"{r['largest']:.4g} at most (at {r['largest_at_load'] * KN:.4g} kN)"]
    for g in GROUPS:
        e = r["groups"][g]
        out.append(f"    {g:<8} ({GROUP_LABEL[g]}): largest {e['max_at_peak']:.4g} / mean {e['mean_at_peak']:.4g} "
                   f"at the peak; largest {e['max']:.4g}, mean up to {e['mean_max']:.4g} over the load")
    out.append(f"  intact bonds {r['bonds_start']:.0f} at the start of the load, {r['bonds_end']:.0f} at its end: "
               f"{r['bonds_broken']:.0f} broken ({_pct(r['broken_fraction'])} %)")
    for t in r["thresholds"]:
        first = (f"first passed at {t['first_load'] * KN:.4g} kN" if math.isfinite(t["first_load"])
                 else "never passed")
        out.append(f"  threshold {t['threshold']:g} r: {_pct(t['share_before'])}-{_pct(t['share_above'])} % of the "
                   f"load's breakage while the largest overlap exceeded it (before the bonds broke - at either "
                   f"sample; {first}; {t['samples_above']} samples above)")
    if r["grading"]:
        out.append(f"  grading (fragments of >= {r['large']} spheres: 'large'):  by mass: single / large;  "
                   "by number: single / large")
        for key in ("before", "after"):
            g = r["grading"][key]
            out.append(f"    {key:<6} ({g['label']}, {g['fragments']} fragments): {_pct(g['single_mass'])} % / "
                       f"{_pct(g['large_mass'])} %;  {_pct(g['single_number'])} % / {_pct(g['large_number'])} %")
    return out


def campaign_lines(result) -> list[str]:
    conf = f"{100 * result['confidence']:g} %"
    out = [f"oedometer overlap: campaign {result['campaign']} ({result['dir']}), "
           f"{sum(c['n'] for c in result['cases'])} members done"]
    if result["not_used"]:
        out.append("not used (not done): " + ", ".join(result["not_used"]))
    out += [f"per case: mean [{conf} Student-t interval of the mean] over the seeds (fractions [-])", ""]
    keys = list(result["cases"][0]["stats"])
    width = max(len(k) for k in keys)
    for c in result["cases"]:
        out.append(f"case {c['case']} (n = {c['n']}: {', '.join(c['members'])}):")
        out += [f"  {k:<{width}}  {interval_text(c['stats'][k])}" for k in keys]
    out.append("")
    for name, r in result["runs"].items():
        out += run_lines(name, r) + [""]
    out.append(f"conclusion: {result['conclusion']}")
    return out


def _json(x):
    if isinstance(x, dict):
        return {str(k): _json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def plot(runs, path, thresholds, case_of=None) -> Path:
    """Left: the largest (solid) and the mean between grains (dotted) δ/r against the applied
    load, loading and unloading; right: the load's breakage (bonds broken / bonds at its start)
    against the load. One colour per run (per case for a campaign)."""
    fig, (ov, br) = figure(12, 5, rows=1, cols=2)
    colours = {}
    for name, r in runs.items():
        key = case_of(name) if case_of else Path(name).name
        label = None if key in colours else key  # one legend entry per case
        colour = colours.setdefault(key, f"C{len(colours) % 10}")
        s = r["series"]
        load = np.asarray(s["load"]) * KN
        b = np.asarray(s["bonds"])
        broken = (b[0] - b) / b[0] if b[0] > 0 else np.zeros_like(b)
        peak = int(np.argmax(load))
        for part, alpha in ((slice(0, peak + 1), 1.0), (slice(peak, None), 0.35)):  # loading, unloading
            ov.plot(load[part], np.asarray(s["largest"])[part], color=colour, lw=1.0, alpha=alpha, label=label)
            ov.plot(load[part], np.asarray(s["pair_mean"])[part], color=colour, lw=0.8, ls=":", alpha=alpha)
            br.plot(load[part], broken[part], color=colour, lw=1.0, alpha=alpha, label=label)
            label = None
    for th in thresholds:
        ov.axhline(th, color="0.5", lw=0.6, ls="--")
        ov.annotate(f"θ = {th:g}", (0.01, th), xycoords=("axes fraction", "data"), fontsize="x-small",
                    va="bottom", color="0.4")
    ov.set_yscale("log")
    ov.set_xlabel("applied platen load [kN] (unloading pale)")
    ov.set_ylabel("overlap δ / smaller radius r [-]")
    ov.set_title("largest δ/r of any contact (solid), mean δ/r between grains (dotted)", fontsize="medium")
    br.set_xlabel("applied platen load [kN] (unloading pale)")
    br.set_ylabel("bonds broken since the load began / bonds then [-]")
    br.set_title("breakage against the load", fontsize="medium")
    for ax in (ov, br):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small", loc="best")
    return save(fig, path)


def write(paths, out=None, thresholds=THRESHOLDS, large=None, confidence=0.95) -> list[Path]:
    """Analyse the run directories / results files / campaign directories ``paths``; returns the
    files written (overlap.txt, overlap.json, overlap.png)."""
    paths = [Path(p) for p in paths]
    if any(not 0 < t < 1 for t in thresholds):
        raise ValueError(f"--threshold {list(thresholds)}: each must be in (0, 1) [-, of the radius]")
    campaigns = [p for p in paths if p.is_dir() and (p / "campaign.json").is_file()]
    if campaigns and len(paths) > 1:
        raise ValueError("give one campaign directory, or run directories only")
    try:
        if campaigns:
            result = analyse_campaign(campaigns[0], thresholds, large, confidence)
            runs, lines = result["runs"], campaign_lines(result)
            members = {m: c["case"] for c in result["cases"] for m in c["members"]}
            case_of = members.get
            out = Path(out) if out is not None else campaigns[0] / "analysis"
        else:
            runs = {str(p): analyse_run(p, thresholds, large) for p in paths}
            result = {"runs": runs}
            lines = [x for name, r in runs.items() for x in run_lines(name, r) + [""]]
            case_of = None
            out = Path(out) if out is not None else default_out(results_file(paths[0]))
    except CampaignError as err:
        raise ValueError(str(err)) from None
    out.mkdir(parents=True, exist_ok=True)
    text, js = out / "overlap.txt", out / "overlap.json"
    text.write_text("\n".join(lines).rstrip() + "\n")
    js.write_text(json.dumps(_json(result), indent=1, allow_nan=False) + "\n")
    return [text, js, plot(runs, out / "overlap.png", thresholds, case_of)]


def add_parser(sub) -> None:
    p = sub.add_parser(
        "oedometer-overlap", help="breakable oedometer: overlaps against the load, breakage above a threshold, grading",
        description="The overlap artefact test of issue #32: the overlap statistics against the applied load, the "
                    "share of the load's breakage that happened while overlaps exceeded a threshold, and the "
                    "grading by mass and by number after loading (overlap.txt/.json/.png).")
    p.add_argument("results", type=Path, nargs="+", metavar="PATH",
                   help="run directories or results files, or one campaign directory")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (default: RUN/analysis, a campaign's DIR/analysis)")
    p.add_argument("--threshold", type=float, nargs="+", default=list(THRESHOLDS), metavar="θ",
                   help="overlap / radius thresholds [-] (default: %(default)s)")
    p.add_argument("--large", type=int, metavar="N",
                   help="fragments of >= N spheres count as large (default: 135, or the intact grain's size if "
                        "smaller)")
    p.add_argument("--confidence", type=float, default=0.95, help="of a campaign's intervals (default 0.95)")
    p.set_defaults(run=lambda a: write(a.results, a.out, tuple(a.threshold), a.large, a.confidence))
