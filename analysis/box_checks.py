"""The box test's calibration and its independent checks against the thesis (issue #14).

    python -m analysis box-checks CALIBRATION_DIR CHECKS_DIR [--out DIR] [--confidence 0.95]

reads two pdem campaign directories: the calibration (``jobs/campaigns/box_calibration.toml``:
the thesis's seed study under each compaction option set) and the checks
(``jobs/campaigns/box_checks.toml``: the thesis's other studies under one option set). It writes
into OUT (default CHECKS_DIR/analysis):

- ``checks.md`` and ``checks.json``: one row per check: what is compared, the thesis's value,
  pdem's (mean ± confidence interval of the mean over the seeds, n), pdem / thesis for numbers
  or whether the thesis's finding holds, and the option set used;
- ``checks_calibration.png`` (settlement at the peak by option set, the thesis's range),
  ``checks_ten_cycles.png`` (settlement within each of 10 cycles), ``checks_stiffness.png``
  (settlement at the peak against E_k) and ``checks_loops.png`` (force–settlement loops of the
  damping and frequency studies). A check whose cases have no finished member yet is a "not
  run yet" row, so a campaign in progress can be looked at.

**The calibration** is the case of the calibration campaign whose mean settlement at the peak of
its cycle is nearest the thesis's mean. Its option set is the keys that case sets. The checks
campaign must set every one of them to the same value in every member ("without retuning"),
else `CampaignError` names the first key that differs.

**The thesis's values** (thesis 5.2.1, tables 5.2–5.8; SPEC.md 2.3), all at 0 ↔ 3 kN, 1 Hz:
study A (E_k 2.8e6 Pa, radii (0.6–1.4) r, 10 seeds) 55.1–76.0 mm at the peak, mean 63.5 mm;
study B (E_k 2.8e7 Pa, constant radius, 10 cycles) settlement within a cycle 26.5 mm in the
first, 3.35 mm in the tenth. Its findings: the settlement falls with E_k and a softer ballast
gives more rebound at unloading (fig. 5.10); the unloading stiffness does not depend on the
radius spread and is higher for clumps; damping (λ_D 0.2–0.9) changes how much ballast is pushed
out beside the sleeper, not the shape of the loops (fig. 5.13); at 1 Hz the loop is rounded
(the sleeper's momentum), at 0.01 Hz it has a sharp tip (fig. 5.12).

Measures (cycle 1 unless said; from the per-cycle table of each results file, `pdem.scenes.cycles`):
settlement at the peak = ``settlement_peak`` (from the sleeper's position when loading starts);
settlement within a cycle = ``settlement_peak − settlement_start``; sinking after the force
peak = (``settlement_max − settlement_at_force_max``) / ``settlement_max`` (0: a sharp tip);
kept fraction = ``settlement_end / settlement_max`` (the loop's shape: 1 means no rebound);
rebound = ``settlement_max − settlement_end``; unloading stiffness from `analysis.box`.
Units: [m] and [N/m] in the files and the JSON, [mm] and [MN/m] in the table.

Imports numpy, scipy (Welch's t-test), `pdem.format` and matplotlib through this package.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy import stats as sps

from .campaign import CampaignError, _finite, group_members, read_campaign, stats
from .figures import figure, save

THESIS_MEAN, THESIS_MIN, THESIS_MAX = 63.5e-3, 55.1e-3, 76.0e-3  # study A, settlement at the peak [m]
THESIS_WITHIN = (26.5e-3, 3.35e-3)  # study B, settlement within cycle 1 and cycle 10 [m]
STIFFNESS_CASES = (("constant-radius", 2.8e6, 1), ("ten-cycles", 2.8e7, 1), ("stiffness-2.8e8", 2.8e8, 1),
                   ("stiffness-2.8e9", 2.8e9, 1), ("stiffness-2.8e10", 2.8e10, 1))  # (case, E_k [Pa], cycle)
DAMPING_CASES = (("damping-0.2", 0.2), ("constant-radius", 0.3), ("damping-0.6", 0.6), ("damping-0.9", 0.9))
FREQUENCY_CASES = (("ten-cycles", 1.0), ("frequency-0.1", 0.1), ("frequency-0.01", 0.01))  # (case, [Hz])
MM, MN = 1e3, 1e-6


@dataclass
class Check:
    """One row of the table: numbers in SI units (None where not a number)."""

    check: str
    thesis: str
    pdem: str
    verdict: str  # "pdem/thesis = x" for a number, "holds" / "does not hold" for a finding
    n: int
    options: str
    thesis_value: float | None = None
    pdem_mean: float | None = None
    pdem_ci: tuple | None = None


# ---------------------------------------------------------------------------- members
def by_case(camp):
    """{case: [done members]} of a campaign made of [[case]] tables (`group_members`' groups)."""
    return {g.params.get("case", ""): g.members for g in group_members(camp.done, camp.seed_key)}


def cycles(member):
    """The /cycles table of a member's results file."""
    c = member.results().cycles
    if c is None:
        raise CampaignError(f"{member.results_path}: no /cycles table")
    return c


def column(member, name, cycle=1):
    c = cycles(member)
    if name not in c:
        raise CampaignError(f"{member.results_path}: no /cycles/{name}")
    return float(c[name][cycle - 1]) if len(c[name]) >= cycle else math.nan


def within(member):
    """Settlement within each cycle, peak − start [m]."""
    c = cycles(member)
    return np.asarray(c["settlement_peak"] - c["settlement_start"], dtype=np.float64)


def sinking_after_peak(member, cycle=1):
    s_max = column(member, "settlement_max", cycle)
    return (s_max - column(member, "settlement_at_force_max", cycle)) / s_max


def kept_fraction(member, cycle=1):
    return column(member, "settlement_end", cycle) / column(member, "settlement_max", cycle)


def rebound(member, cycle=1):
    return column(member, "settlement_max", cycle) - column(member, "settlement_end", cycle)


def unloading_stiffness(member, cycle=1):
    return float(member.box().stiffness.unloading[cycle - 1])


def options_of(member, seed_key):
    """The keys a member's campaign set for it (member.json overrides), without the seed."""
    try:
        over = json.loads((member.dir / "member.json").read_text())["overrides"]
    except (FileNotFoundError, ValueError, KeyError):
        raise CampaignError(f"{member.dir / 'member.json'}: missing or without overrides") from None
    return {k: v for k, v in over.items() if k != seed_key}


# ---------------------------------------------------------------------------- calibration
def choose_option_set(calib, confidence):
    """(case, its option set, {case: stats of the settlement at the peak}) of the calibration."""
    cases = by_case(calib)
    if not cases:
        raise CampaignError(f"{calib.dir}: no member is done yet")
    peak = {case: stats([column(m, "settlement_peak") for m in ms], confidence) for case, ms in cases.items()}
    best = min(peak, key=lambda c: abs(peak[c]["mean"] - THESIS_MEAN) if np.isfinite(peak[c]["mean"]) else np.inf)
    every = [options_of(ms[0], calib.seed_key) for ms in cases.values()]
    # the option set: what the chosen case sets beyond the settings common to all cases ([set])
    opts = {k: v for k, v in every[list(cases).index(best)].items() if not all(o.get(k, object()) == v for o in every)}
    return best, opts, peak


def verify_option_set(checks, opts):
    """CampaignError unless every member of the checks campaign sets ``opts`` as given."""
    for m in checks.done:
        got = options_of(m, checks.seed_key)
        for k, v in opts.items():
            if got.get(k, "(not set)") != v:
                raise CampaignError(f"{m.dir}: {k} = {got.get(k, '(not set)')!r}, but the calibration chose {v!r} "
                                    f"(its option set: {describe(opts)}); rerun the checks with that option set")


def describe(opts):
    return ", ".join(f"{k.split('.')[-1]} = {v}" for k, v in opts.items()) or "the base scene's defaults"


# ---------------------------------------------------------------------------- the checks
def _mean_ci(values, f, confidence):
    s = stats(values, confidence)
    text = f"{s['mean'] * f:.4g}" + (f" ± {(s['ci_high'] - s['mean']) * f:.2g}" if np.isfinite(s["ci_high"]) else "")
    return s, text


def number_row(name, thesis, values, f, unit, options, confidence):
    s, text = _mean_ci(values, f, confidence)
    return Check(name, f"{thesis * f:.4g} {unit}".strip(), f"{text} {unit}".strip(),
                 f"pdem/thesis = {s['mean'] / thesis:.3g}", s["n"], options, thesis, s["mean"],
                 (s["ci_low"], s["ci_high"]))


def finding_row(name, thesis, pdem_text, holds, n, options):
    return Check(name, thesis, pdem_text, "holds" if holds else "does not hold", n, options)


def welch(a, b):
    """Two-sided p-value of Welch's t-test (NaN with fewer than 2 values in either)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if len(a) < 2 or len(b) < 2:
        return math.nan
    return float(sps.ttest_ind(a, b, equal_var=False).pvalue)


def series_text(values, f, unit, fmt=".3g"):
    return ", ".join(f"{v * f:{fmt}}" for v in values) + (f" {unit}" if unit else "")


def not_run(name, cases, options):
    """The row of a check whose case(s) have no finished member yet."""
    return Check(name, "", f"not run yet: no finished member of {', '.join(cases)}", "—", 0, options)


def build_checks(calib, checks, confidence=0.95):
    """(rows, context for the plots) of the calibration and the checks. A check whose cases
    have no finished member yet is a "not run yet" row (a sweep uses the points it has, at least
    two), so a campaign in progress can be looked at."""
    best, opts, peak = choose_option_set(calib, confidence)
    verify_option_set(checks, opts)
    cal = by_case(calib)
    case = by_case(checks)
    label = f"{best} ({describe(opts)})"
    rows = []

    # the calibration and the seed scatter (study A)
    a = [column(m, "settlement_peak") for m in cal[best]]
    rows.append(number_row("calibration: settlement at the peak, A (E_k 2.8e6, radii ±40 %)", THESIS_MEAN, a, MM,
                           "mm", label, confidence))
    spread = (max(a) - min(a)) / np.mean(a)
    thesis_spread = (THESIS_MAX - THESIS_MIN) / THESIS_MEAN
    rows.append(Check("seed scatter of A: (max − min) / mean", f"{thesis_spread:.3g} (55.1–76.0 mm)",
                      f"{spread:.3g} ({min(a) * MM:.1f}–{max(a) * MM:.1f} mm, "
                      f"CoV {np.std(a, ddof=1) / np.mean(a):.2g})",
                      f"pdem/thesis = {spread / thesis_spread:.3g}", len(a), label, thesis_spread, spread))

    # the 10-cycle study (B)
    w = None
    if "ten-cycles" not in case:
        rows.append(not_run("B (E_k 2.8e7, 10 cycles)", ["ten-cycles"], label))
    else:
        w = np.array([within(m) for m in case["ten-cycles"]])
        rows.append(number_row("B (E_k 2.8e7, 10 cycles): settlement within cycle 1", THESIS_WITHIN[0], w[:, 0], MM,
                               "mm", label, confidence))
        rows.append(number_row("B: settlement within cycle 10", THESIS_WITHIN[1], w[:, -1], MM, "mm", label,
                               confidence))
        rows.append(number_row("B: within cycle 1 / within cycle 10", THESIS_WITHIN[0] / THESIS_WITHIN[1],
                               w[:, 0] / w[:, -1], 1.0, "", label, confidence))
        rows.append(number_row("A / B: settlement at the first peak, E_k 2.8e6 over 2.8e7 (10x stiffer)",
                               THESIS_MEAN / THESIS_WITHIN[0], [np.mean(a) / x for x in w[:, 0]], 1.0, "", label,
                               confidence))

    # the stiffness study (the points there are)
    sweep = [(c, e, k) for c, e, k in STIFFNESS_CASES if c in case]
    e_peak = [[column(m, "settlement_peak", k) for m in case[c]] for c, _, k in sweep]
    if len(sweep) < 2:
        rows.append(not_run("stiffness study", [c for c, *_ in STIFFNESS_CASES if c not in case], label))
    else:
        means = [float(np.mean(v)) for v in e_peak]
        reb = [float(np.mean([rebound(m, k) for m in case[c]])) for c, _, k in sweep]
        at = "E_k " + ", ".join(f"{e:.2g}".replace("e+0", "e").replace("e+", "e") for _, e, _ in sweep)
        rows.append(finding_row(f"stiffness study: settlement at the peak falls with E_k ({at})", "falls",
                                series_text(means, MM, "mm"), all(np.diff(means) < 0), len(e_peak[0]), label))
        rows.append(finding_row(f"stiffness study: the rebound at unloading is larger for softer ballast ({at})",
                                "larger when softer", series_text(reb, MM, "mm"), all(np.diff(reb) < 0),
                                len(e_peak[0]), label))

    # unloading stiffness: radius spread and clumps
    if "constant-radius" not in case:
        rows.append(not_run("unloading stiffness, radii ±40 % against constant", ["constant-radius"], label))
    else:
        k_spread = [unloading_stiffness(m) for m in cal[best]]
        k_const = [unloading_stiffness(m) for m in case["constant-radius"]]
        p = welch(k_spread, k_const)
        rows.append(finding_row("unloading stiffness, radii ±40 % against constant (E_k 2.8e6)", "independent",
                                f"{np.mean(k_spread) * MN:.3g} / {np.mean(k_const) * MN:.3g} MN/m, Welch p = {p:.2g}",
                                p >= 0.05, len(k_const), label))
    gone = [c for c in ("spheres-3e6", "clumps-3e6") if c not in case]
    if gone:
        rows.append(not_run("unloading stiffness, 8-sphere clumps against spheres", gone, label))
    else:
        k_sph = [unloading_stiffness(m) for m in case["spheres-3e6"]]
        k_clu = [unloading_stiffness(m) for m in case["clumps-3e6"]]
        p = welch(k_clu, k_sph)
        rows.append(finding_row("unloading stiffness, 8-sphere clumps against spheres (E_k 3e6)", "higher for clumps",
                                f"{np.mean(k_clu) * MN:.3g} / {np.mean(k_sph) * MN:.3g} MN/m, Welch p = {p:.2g}",
                                np.mean(k_clu) > np.mean(k_sph) and p < 0.05, len(k_clu), label))

    # damping: magnitude against shape
    damp = [(c, lam) for c, lam in DAMPING_CASES if c in case]
    if len(damp) < 2:
        rows.append(not_run("damping study", [c for c, _ in DAMPING_CASES if c not in case], label))
    else:
        d_max = [float(np.mean([column(m, "settlement_max") for m in case[c]])) for c, _ in damp]
        d_kept = [float(np.mean([kept_fraction(m) for m in case[c]])) for c, _ in damp]
        mag, shape = max(d_max) / min(d_max), max(d_kept) / min(d_kept)
        at = "/".join(f"{lam:g}" for _, lam in damp)
        rows.append(finding_row(f"damping λ_D {at}: changes the magnitude (max/min of the largest settlement) "
                                "more than the shape (max/min of the kept fraction)", "magnitude, not shape",
                                f"{series_text(d_max, MM, 'mm')} ({mag:.3g}x); kept {series_text(d_kept, 1, '')} "
                                f"({shape:.3g}x)", shape < mag, len(case[damp[0][0]]), label))

    # frequency: sinking after the force peak
    freq = [(c, f) for c, f in FREQUENCY_CASES if c in case]
    if len(freq) < 2:
        rows.append(not_run("frequency study", [c for c, _ in FREQUENCY_CASES if c not in case], label))
    else:
        fr = [float(np.mean([sinking_after_peak(m) for m in case[c]])) for c, _ in freq]
        at = "/".join(f"{f:g}" for _, f in freq)
        rows.append(finding_row(f"frequency {at} Hz: sinking after the force peak (share of the largest settlement)",
                                "rounded at 1 Hz, sharp tip at 0.01 Hz", series_text(fr, 1, ""),
                                all(np.diff(fr) < 0), len(case[freq[0][0]]), label))
    ctx = dict(best=best, opts=opts, peak=peak, within=w, sweep=sweep, stiffness=e_peak, damping=damp,
               frequency=freq, case=case, confidence=confidence)
    return rows, ctx


# ---------------------------------------------------------------------------- output
def write_table(rows, out, calib, checks, ctx):
    head = "| check | thesis | pdem (mean ± CI, n) | pdem / thesis or finding | option set |\n|---|---|---|---|---|\n"
    body = "".join(f"| {r.check} | {r.thesis} | {r.pdem} (n = {r.n}) | {r.verdict} | "
                   f"{r.options if i == 0 else '〃'} |\n" for i, r in enumerate(rows))
    cases = "".join(f"| {c} | {s['n']} | {s['mean'] * MM:.4g} | {s['ci_low'] * MM:.4g}–{s['ci_high'] * MM:.4g} |\n"
                    for c, s in ctx["peak"].items())
    text = (f"# Box test: calibration and independent checks\n\ncalibration {calib.dir}, checks {checks.dir}; "
            f"{100 * ctx['confidence']:g} % Student-t intervals of the mean over the seeds.\n\n"
            f"## Calibration: settlement at the peak [mm] by option set (thesis {THESIS_MEAN * MM:g}, "
            f"{THESIS_MIN * MM:g}–{THESIS_MAX * MM:g})\n\n"
            f"| option set | n | mean | CI |\n|---|---|---|---|\n{cases}\n"
            f"Chosen: **{ctx['best']}**, the nearest mean.\n\n## Checks\n\n{head}{body}")
    (out / "checks.md").write_text(text)
    data = {"calibration": str(calib.dir), "checks": str(checks.dir), "chosen": ctx["best"], "option_set": ctx["opts"],
            "calibration_cases": ctx["peak"], "rows": [asdict(r) for r in rows]}
    (out / "checks.json").write_text(json.dumps(_finite(data), indent=1) + "\n")
    return [out / "checks.md", out / "checks.json"]


def plot_calibration(path, ctx):
    fig, ax = figure(h=4.5)
    names = list(ctx["peak"])
    for i, c in enumerate(names):
        s = ctx["peak"][c]
        color = "C3" if c == ctx["best"] else "C0"
        err = ([[(s["mean"] - s["ci_low"]) * MM], [(s["ci_high"] - s["mean"]) * MM]]
               if np.isfinite(s["ci_low"]) else None)
        ax.errorbar([s["mean"] * MM], [i], xerr=err, fmt="o", color=color, capsize=3)
    ax.axvspan(THESIS_MIN * MM, THESIS_MAX * MM, color="0.5", alpha=0.2, label="thesis, 10 seeds")
    ax.axvline(THESIS_MEAN * MM, color="0.3", ls="--", label="thesis mean")
    ax.set_yticks(range(len(names)), names)
    ax.set(xlabel="settlement at the peak [mm]", title="calibration (A: E_k 2.8e6, radii ±40 %, 0 ↔ 3 kN)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


def plot_ten_cycles(path, ctx):
    if ctx["within"] is None:
        return None
    fig, ax = figure(h=4.5)
    w = ctx["within"] * MM
    k = np.arange(1, w.shape[1] + 1)
    for row in w:
        ax.plot(k, row, color="C0", alpha=0.4, lw=0.8)
    ax.plot(k, w.mean(axis=0), "o-", color="C0", label=f"pdem, mean of {len(w)} seeds")
    ax.plot([1, 10], np.array(THESIS_WITHIN) * MM, "s", color="C3", label="thesis")
    ax.set(xlabel="cycle", ylabel="settlement within the cycle [mm]", yscale="log",
           title="B: E_k 2.8e7, 0 ↔ 3 kN, 10 cycles")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


def plot_stiffness(path, ctx):
    if len(ctx["sweep"]) < 2:
        return None
    fig, ax = figure(h=4.5)
    e = np.array([x for _, x, _ in ctx["sweep"]])
    for j, vals in enumerate(ctx["stiffness"]):
        ax.plot([e[j]] * len(vals), np.array(vals) * MM, ".", color="C0", alpha=0.5)
    ax.plot(e, [np.mean(v) * MM for v in ctx["stiffness"]], "o-", color="C0", label="pdem (constant radius), mean")
    ax.plot([2.8e6, 2.8e7], [THESIS_MEAN * MM, THESIS_WITHIN[0] * MM], "s", color="C3",
            label="thesis: A (radii ±40 %), B")
    ax.set(xlabel="E_k [Pa]", ylabel="settlement at the first peak [mm]", xscale="log", yscale="log",
           title="stiffness study, 0 ↔ 3 kN")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


def plot_loops(path, ctx):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4.5), layout="constrained")
    for ax, study, title in ((fig.add_subplot(1, 2, 1), ctx["damping"], "damping λ_D (E_k 2.8e6)"),
                             (fig.add_subplot(1, 2, 2), ctx["frequency"], "frequency [Hz] (E_k 2.8e7)")):
        m = None
        for c, v in study:
            m = ctx["case"][c][0]
            s = m.results().series
            t_end = s["time"][0] + (1.0 / v if study is ctx["frequency"] else np.inf)
            keep = s["time"] <= t_end
            ax.plot(s["sleeper_settlement"][keep] * MM, s["sleeper_force"][keep] * 1e-3, lw=0.8, label=f"{v:g}")
        seed = m.params.get("box_test.seed", "") if m is not None else "-"
        ax.set(xlabel="sleeper settlement [mm]", ylabel="ballast force on the sleeper [kN]",
               title=f"{title}, seed {seed}, cycle 1")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    return save(fig, path)


def box_checks_report(calibration, checks, out=None, confidence=0.95):
    """Write the table and the plots; returns the files written."""
    calib, chk = read_campaign(calibration), read_campaign(checks)
    rows, ctx = build_checks(calib, chk, confidence)
    out = Path(out) if out is not None else Path(checks) / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    written = write_table(rows, out, calib, chk, ctx)
    for name, plot in (("calibration", plot_calibration), ("ten_cycles", plot_ten_cycles),
                       ("stiffness", plot_stiffness), ("loops", plot_loops)):
        path = plot(out / f"checks_{name}.png", ctx)
        if path is not None:
            written.append(path)
    return written


def add_parser(sub):
    p = sub.add_parser("box-checks", help="box test: the calibration and the independent checks against the thesis",
                       description="Choose the calibration's option set and compare the checks campaign made with "
                                   "it against the thesis (docs/box_test.md).")
    p.add_argument("calibration", type=Path, metavar="CALIBRATION_DIR", help="campaign directory of box_calibration")
    p.add_argument("checks", type=Path, metavar="CHECKS_DIR", help="campaign directory of box_checks")
    p.add_argument("--confidence", type=float, default=0.95, help="of the interval of the mean (default 0.95)")
    p.add_argument("--out", type=Path, metavar="OUT", help="output directory (default CHECKS_DIR/analysis)")
    return p


def run(args):
    if not 0 < args.confidence < 1:
        raise CampaignError(f"--confidence {args.confidence}: must be in (0, 1)")
    return box_checks_report(args.calibration, args.checks, args.out, args.confidence)
