"""The box test prepared the thesis's way, calibrated at each stiffness it is used at, and the
trade-off between the thesis and the lab (issue #32).

    python -m analysis box-thesis-procedure SOFT_DIR FULL_DIR [--out DIR] [--confidence 0.95]

reads two pdem campaign directories whose [[case]] tables have the same names and differ only in
the vibration's length (``box_test.vibration_time`` [s]; the thesis vibrates "the same way as in
the oedometer test" and states no strength, so the length is the knob):

- SOFT_DIR, ``jobs/campaigns/box_thesis_procedure_soft.toml``: the thesis's seed study (b),
  E_k = 2.8e6 Pa, radii ±40 %, 0 ↔ 3 kN; the thesis's target is its 10 seeds at the peak,
  55.1–76.0 mm, mean 63.5 mm (thesis 5.2.1; `analysis.box_checks.THESIS_MEAN`);
- FULL_DIR, ``jobs/campaigns/box_thesis_procedure_full.toml``: E_k = 2.8e11 Pa, 3 ↔ 40 kN, the
  Nottingham test: "naměřená deformace během prvního zatěžovacího cyklu v experimentu byla kolem
  17 mm" (about 17 mm during the first cycle) and "deformace kameniva přibližně 15 mm po 1
  zatěžovacím cyklu" (about 15 mm after it) (thesis 5.1). pdem compares 17 mm with the settlement
  at the cycle's force peak and 15 mm with the settlement at its end; end − peak, ~−2 mm, is the
  lab's rebound (negative: the sleeper rose as the force fell).

Each stiffness is calibrated on its own target: the case whose mean settlement at the peak is
nearest it. What is not fitted is checked: at full stiffness the settlement at the cycle's end
and the change from the peak to the end (``settlement_end − settlement_peak``) against the lab's
15 mm and ~−2 mm, and the
unloading stiffness (`analysis.box`; the lab's is not in the seeds, so it is reported, not
judged). A case *fits* a target when the target lies in its confidence interval of the mean (or,
for a range, the interval overlaps the range). Writes into OUT (default FULL_DIR/analysis):
``thesis_procedure.md``, ``thesis_procedure.json`` and ``thesis_procedure.png`` (settlement at the
peak against the vibration's length at both stiffnesses with the targets, and the trade-off:
each case as the point (soft / thesis, full / lab), the target at (1, 1)).
Units: [m] and [N/m] in the JSON, [mm] and [MN/m] in the table.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .box_checks import MM, MN, THESIS_MAX, THESIS_MEAN, THESIS_MIN, by_case, column, options_of, \
    unloading_stiffness
from .campaign import CampaignError, _finite, interval_text, read_campaign, stats
from .figures import figure, save

LAB_PEAK, LAB_END = 17e-3, 15e-3  # Nottingham, cycle 1: during it and after it [m] (thesis 5.1)
LAB_AFTER_PEAK = LAB_END - LAB_PEAK  # end − peak of cycle 1 [m]: the lab's sleeper rose 2 mm
KNOB = "box_test.vibration_time"


def case_values(camp, confidence):
    """{case: {"vibration_time", "peak", "end", "after_peak", "unloading"}}: `stats` over the seeds
    of the settlement at the peak and at the end of cycle 1 [m], end − peak [m] and the unloading
    stiffness [N/m]."""
    out = {}
    for case, ms in by_case(camp).items():
        knob = options_of(ms[0], camp.seed_key).get(KNOB)
        if knob is None:
            raise CampaignError(f"{ms[0].dir}: case {case!r} does not set {KNOB}")
        out[case] = {"vibration_time": float(knob),
                     "peak": stats([column(m, "settlement_peak") for m in ms], confidence),
                     "end": stats([column(m, "settlement_end") for m in ms], confidence),
                     "after_peak": stats([column(m, "settlement_end") - column(m, "settlement_peak") for m in ms],
                                         confidence),
                     "unloading": stats([unloading_stiffness(m) for m in ms], confidence)}
    if not out:
        raise CampaignError(f"{camp.dir}: no member is done yet")
    return dict(sorted(out.items(), key=lambda kv: kv[1]["vibration_time"]))


def covers(s, lo, hi):
    """The interval of the mean of ``s`` meets [lo, hi] (a single value: lo = hi)."""
    return bool(np.isfinite(s["ci_low"]) and s["ci_low"] <= hi and s["ci_high"] >= lo)


def nearest(cases, target):
    return min(cases, key=lambda c: abs(cases[c]["peak"]["mean"] - target))


def build(soft, full, confidence=0.95):
    """The comparison as plain data (the JSON): every case of each campaign, the trade-off over the
    cases finished in both."""
    s, f = case_values(soft, confidence), case_values(full, confidence)
    both = [c for c in s if c in f]
    fits = {c: {} for c in {**s, **f}}
    for c in s:
        fits[c]["thesis"] = covers(s[c]["peak"], THESIS_MIN, THESIS_MAX)
    for c in f:
        fits[c].update(lab_peak=covers(f[c]["peak"], LAB_PEAK, LAB_PEAK), lab_end=covers(f[c]["end"], LAB_END, LAB_END),
                       lab_after_peak=covers(f[c]["after_peak"], LAB_AFTER_PEAK, LAB_AFTER_PEAK))
    return {"soft": str(soft.dir), "full": str(full.dir), "confidence": confidence,
            "cases": sorted(fits, key=lambda c: {**f, **s}[c]["vibration_time"]), "both": both,
            "soft_values": s, "full_values": f, "chosen_soft": nearest(s, THESIS_MEAN),
            "chosen_full": nearest(f, LAB_PEAK), "fits": fits,
            "fits_both": [c for c in both if fits[c]["thesis"] and fits[c]["lab_peak"]]}


def _scaled(e, f):
    """`interval_text` of a `stats` entry in other units (its count unscaled)."""
    return interval_text({k: v if k == "n" else v * f for k, v in e.items()})


def _mm(e):
    return _scaled(e, MM)


def _reached(fit):
    return "reached" if fit else "not reached"


def verdict(d):
    """The conclusion in plain words."""
    cs, cf = d["chosen_soft"], d["chosen_full"]
    s, f = d["soft_values"], d["full_values"]
    if d["fits_both"]:
        head = (f"The option set(s) {', '.join(d['fits_both'])} fit both the thesis's seed study and the lab's "
                "first peak.")
    else:
        head = (f"No option set fits both. At E_k 2.8e6 Pa the nearest to the thesis is **{cs}** "
                f"({_mm(s[cs]['peak'])} mm against 55.1–76.0 mm: {_reached(d['fits'][cs]['thesis'])}); at full "
                f"stiffness the nearest to the lab is **{cf}** ({_mm(f[cf]['peak'])} mm against ~17 mm: "
                f"{_reached(d['fits'][cf]['lab_peak'])}).")
    r = f[cf]
    checks = (f"Not fitted, at full stiffness with {cf}: end of cycle 1 {_mm(r['end'])} mm (lab ~15 mm, "
              f"{_reached(d['fits'][cf]['lab_end'])}), end − peak {_mm(r['after_peak'])} mm "
              f"(lab ~−2 mm: {_reached(d['fits'][cf]['lab_after_peak'])}), unloading stiffness "
              f"{_scaled(r['unloading'], MN)} MN/m (the lab's is not in the seeds).")
    return head + " " + checks


def write_table(d, out):
    def cell(side, c, key):
        v = d[side].get(c)
        return "not run" if v is None else (_mm(v[key]) if key != "unloading" else
                                            _scaled(v[key], MN))

    def n(side, c):
        return d[side][c]["peak"]["n"] if c in d[side] else 0

    t = {c: v["vibration_time"] for side in ("full_values", "soft_values") for c, v in d[side].items()}
    rows = "".join(f"| {c} | {t[c]:g} | {cell('soft_values', c, 'peak')} | "
                   + " | ".join(cell("full_values", c, k) for k in ("peak", "end", "after_peak", "unloading"))
                   + f" | {n('soft_values', c)} / {n('full_values', c)} |\n" for c in d["cases"])
    text = (f"# Box test prepared the thesis's way: calibration at each stiffness and the trade-off\n\n"
            f"soft {d['soft']}, full {d['full']}; mean [{100 * d['confidence']:g} % Student-t interval of the "
            f"mean] over the seeds.\n\n"
            "| case | vibration [s] | E_k 2.8e6, 0 ↔ 3 kN: at the peak [mm] (thesis 63.5, 55.1–76.0) | "
            "E_k 2.8e11, 3 ↔ 40 kN: at the peak [mm] (lab ~17) | at the end [mm] (lab ~15) | "
            "end − peak [mm] (lab ~−2) | unloading stiffness [MN/m] | n soft / full |\n"
            "|---|---|---|---|---|---|---|---|\n"
            f"{rows}\n{verdict(d)}\n")
    (out / "thesis_procedure.md").write_text(text)
    (out / "thesis_procedure.json").write_text(json.dumps(_finite(d), indent=1) + "\n")
    return [out / "thesis_procedure.md", out / "thesis_procedure.json"]


def _errorbar(ax, x, e, f, **kw):
    err = [[(e["mean"] - e["ci_low"]) * f], [(e["ci_high"] - e["mean"]) * f]] if math.isfinite(e["ci_low"]) else None
    ax.errorbar([x], [e["mean"] * f], yerr=err, fmt="o", capsize=3, **kw)


def plot(path, d):
    fig, (a, b, c) = figure(w=15.0, h=4.5, rows=1, cols=3)
    panels = ((a, "soft_values", THESIS_MIN, THESIS_MAX, "E_k 2.8e6 Pa, 0 ↔ 3 kN (thesis study b)"),
              (b, "full_values", LAB_END, LAB_PEAK, "E_k 2.8e11 Pa, 3 ↔ 40 kN (Nottingham)"))
    for ax, key, lo, hi, title in panels:
        for v in d[key].values():
            _errorbar(ax, v["vibration_time"], v["peak"], MM, color="C0")
            if key == "full_values":
                _errorbar(ax, v["vibration_time"], v["end"], MM, color="C1")
        ax.axhspan(lo * MM, hi * MM, color="0.5", alpha=0.2, label="thesis, 10 seeds" if key == "soft_values"
                   else "lab: ~17 mm in cycle 1, ~15 mm after")
        ax.plot([], [], "o", color="C0", label="pdem at the peak, mean ± CI")
        if key == "full_values":
            ax.plot([], [], "o", color="C1", label="pdem at the cycle's end")
        ax.set(xlabel="vibration time [s]", ylabel="settlement, cycle 1 [mm]", title=title)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    for case in d["both"]:
        s, f = d["soft_values"][case]["peak"], d["full_values"][case]["peak"]
        c.plot(s["mean"] / THESIS_MEAN, f["mean"] / LAB_PEAK, "o")
        c.annotate(case, (s["mean"] / THESIS_MEAN, f["mean"] / LAB_PEAK), fontsize="small", xytext=(4, 4),
                   textcoords="offset points")
    c.axvspan(THESIS_MIN / THESIS_MEAN, THESIS_MAX / THESIS_MEAN, color="C2", alpha=0.15, label="thesis range")
    c.axhspan(LAB_END / LAB_PEAK, 1.0, color="C3", alpha=0.15, label="lab 15–17 mm")
    c.plot([1], [1], "*", color="k", ms=12, label="both targets")
    c.set(xlabel="E_k 2.8e6: settlement at the peak / thesis 63.5 mm",
          ylabel="E_k 2.8e11: settlement at the peak / lab 17 mm", title="trade-off (one point per vibration)")
    c.grid(True, alpha=0.3)
    c.legend(fontsize="small")
    return save(fig, path)


def report(soft, full, out=None, confidence=0.95):
    """Write the table, the JSON and the plot; returns the files written."""
    d = build(read_campaign(soft), read_campaign(full), confidence)
    out = Path(out) if out is not None else Path(full) / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    return write_table(d, out) + [plot(out / "thesis_procedure.png", d)]


def add_parser(sub):
    p = sub.add_parser("box-thesis-procedure", help="box test prepared the thesis's way: calibration at each "
                       "stiffness and the trade-off between the thesis and the lab",
                       description="Compare the box_thesis_procedure_soft and _full campaigns with the thesis's "
                                   "seed study and the Nottingham test (docs/box_test.md).")
    p.add_argument("soft", type=Path, metavar="SOFT_DIR", help="campaign directory of box_thesis_procedure_soft")
    p.add_argument("full", type=Path, metavar="FULL_DIR", help="campaign directory of box_thesis_procedure_full")
    p.add_argument("--confidence", type=float, default=0.95, help="of the interval of the mean (default 0.95)")
    p.add_argument("--out", type=Path, metavar="OUT", help="output directory (default FULL_DIR/analysis)")
    return p


def run(args):
    if not 0 < args.confidence < 1:
        raise CampaignError(f"--confidence {args.confidence}: must be in (0, 1)")
    return report(args.soft, args.full, args.out, args.confidence)
