"""Blast layer: sensitivity of I_s / I_in to the paper's unstated inputs (issue #32;
``jobs/campaigns/blast_sensitivity.toml``, docs/blast.md "Sensitivity to the paper's unstated inputs").

``python -m analysis blast-sensitivity DIR`` reads a campaign directory of the blast scene (written by
``pdem campaign``: ``DIR/campaign.json``; each member one prepared layer loaded with the paper's three
plates, ``<member>/plate_<m>/results.h5``), groups the finished members that differ only by their seed
(`analysis.campaign.group_members`: one group per case) and writes into ``DIR/analysis`` (or ``--out``):

- ``blast_sensitivity.txt`` / ``.json``: per case and plate the amplification I_s / I_in over the seeds,
  mean and Student-t interval of the mean (`analysis.campaign.stats`), in two variants computed from the
  same ceiling-stress record (`analysis.blast.analyse_blast`):
  *with the static weight*: I_s = integral of sigma_0 dt over the record (``amplification``);
  *without the static weight*: I_s,dyn = integral of (sigma_0 - sigma_0(0)) dt over the same window,
  sigma_0(0) the first row (t = 0, the ceiling carrying the layer and the plate at rest before the
  impulse; ``amplification_dynamic``). Also per case the prepared layer: spheres, contacts per sphere
  and solid fraction (``preparation.h5``: the last row of the settle stage; solid fraction = spheres x
  the mean sphere volume of radii uniform in [d_min/2, d_max/2] / the layer volume, the cloud's
  distribution, `pdem.scenes.blast.cloud`);
- ``blast_sensitivity.png``: one panel per plate, per case both variants with their intervals, the
  paper's value and its band of +- ``tolerance``;
- a one-line conclusion computed from the numbers: which cases (and variant) bring all three plates'
  intervals within ``tolerance`` of the paper's values (distance of the paper's value from the
  interval, relative to the paper's value; 0 inside it), the closest case otherwise, and where the
  paper's pattern holds, heavy plate ~ middle plate (their means within ``tolerance`` of each other,
  as the paper's 1.594 and 1.592 are).

The paper's values are its I_s / I_in (`analysis.blast.PAPER`: 7.97, 7.96, 8.88e-3 MPa s over 5e-3:
1.594, 1.592, 1.776 for 10 780, 2 700, 244 kg/m^2; published rounded as 1.59, 1.59, 1.78). A member's
plate is matched to the paper's within `analysis.blast.PLATE_MATCH`. Imports numpy, scipy (through
`analysis.campaign`), `pdem.format` and, for the plot, matplotlib.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from pdem.format.groups import read_blast
from pdem.format.read import ResultFileError, read_series

from .blast import PAPER, PAPER_INPUT_IMPULSE, analyse_blast, paper_plate
from .campaign import CampaignError, group_members, interval_text, read_campaign, stats

TOLERANCE = 0.05
VARIANTS = (("amplification", "with the static weight", "I_s = ∫σ0 dt"),
            ("amplification_dynamic", "without the static weight", "I_s,dyn = ∫(σ0 − σ0(0)) dt"))
PLATES = tuple(PAPER)  # heavy, middle, light [kg/m^2]
HEAVY, MIDDLE = PLATES[0], PLATES[1]
SETTLE_STAGE = 1  # pdem.scenes.blast: pour (0), settle (1): the prepared layer is the end of stage 1


def paper_ratio(mass) -> float:
    """The paper's I_s / I_in for its plate ``mass`` [kg/m^2]."""
    return PAPER[mass][0] / PAPER_INPUT_IMPULSE


def member_values(member) -> dict:
    """I_s / I_in of each of the paper's plates of one member (both variants), and its prepared layer."""
    plates, scene = {}, None
    for d in sorted(member.dir.glob("plate_*")):
        if not (d / "results.h5").is_file():
            continue
        results, params = read_blast(d)
        match = paper_plate(params.plate_areal_mass)
        if match is None:
            continue
        a = analyse_blast(results, params)
        plates[match[0]] = {name: float(getattr(a, name)) for name, _, _ in VARIANTS}
        plates[match[0]]["static_stress"] = a.static_stress
        scene = json.loads(results.attrs["scene"])
    if not plates:
        raise CampaignError(f"{member.dir}: no plate_<m>/results.h5 of the paper's plates "
                            f"({', '.join(f'{m:g}' for m in PLATES)} kg/m^2)")
    return {"plates": plates, **prepared_layer(member.dir / "preparation.h5", scene["blast"])}


def prepared_layer(path, blast) -> dict:
    """Spheres, contacts per sphere and solid fraction of the prepared layer (NaN without a settle
    stage in ``path``: a run that loaded another's layer)."""
    nan = {"spheres": math.nan, "contacts_per_sphere": math.nan, "solid_fraction": math.nan}
    try:
        s = read_series(path, required=("stage", "n_spheres", "contacts_per_particle"))
    except (ResultFileError, OSError):
        return nan
    rows = np.flatnonzero(s["stage"] == SETTLE_STAGE)
    if not len(rows):
        return nan
    k = rows[-1]
    lx, ly, h = blast.get("box", [0.3, 0.3, 0.3])
    r_lo, r_hi = 0.5 * blast.get("diameter_min", 0.009), 0.5 * blast.get("diameter_max", 0.010)
    mean_r3 = r_lo ** 3 if r_hi == r_lo else (r_hi ** 4 - r_lo ** 4) / (4.0 * (r_hi - r_lo))
    n = float(s["n_spheres"][k])
    return {"spheres": n, "contacts_per_sphere": float(s["contacts_per_particle"][k]),
            "solid_fraction": n * 4.0 / 3.0 * math.pi * mean_r3 / (lx * ly * h)}


def distance(entry, paper) -> float:
    """Relative distance of ``paper`` from the interval [ci_low, ci_high] of ``entry`` (0 inside; the
    mean stands for the interval of a single run)."""
    lo, hi = entry["ci_low"], entry["ci_high"]
    if not (math.isfinite(lo) and math.isfinite(hi)):
        lo = hi = entry["mean"]
    if not math.isfinite(lo):
        return math.nan
    return max(lo - paper, paper - hi, 0.0) / paper


def sensitivity(path, tolerance=TOLERANCE, confidence=0.95) -> dict:
    """The per-case statistics, the verdicts and the conclusion of a campaign directory (SI, [-])."""
    camp = read_campaign(path)
    done = camp.done
    if not done:
        raise CampaignError(f"{path}: no member is done yet ({len(camp.members)} members; see pdem campaign status)")
    values = {m.name: member_values(m) for m in done}
    cases = []
    for g in group_members(done, camp.seed_key):
        vals = [values[m.name] for m in g.members]
        case = {"case": g.params.get("case", g.label), "params": g.params, "n": len(g.members),
                "members": [m.name for m in g.members],
                "seeds": [m.params.get(camp.seed_key) for m in g.members],
                "values": {m.name: values[m.name] for m in g.members},
                "layer": {k: stats([v[k] for v in vals], confidence)
                          for k in ("spheres", "contacts_per_sphere", "solid_fraction")},
                "variants": {}}
        for name, _, _ in VARIANTS:
            plates = {}
            for mass in PLATES:
                x = [v["plates"][mass][name] for v in vals if mass in v["plates"]]
                e = stats(x, confidence)
                e.update(values=x, paper=paper_ratio(mass), distance=distance(e, paper_ratio(mass)))
                plates[mass] = e
            worst = [plates[m]["distance"] for m in PLATES]
            heavy, middle = plates[HEAVY]["mean"], plates[MIDDLE]["mean"]
            pattern = (heavy - middle) / (0.5 * (heavy + middle))
            case["variants"][name] = {
                "plates": plates,
                "distance": max(worst) if all(math.isfinite(d) for d in worst) else math.nan,
                "heavy_minus_middle": pattern,
                "heavy_equals_middle": bool(abs(pattern) <= tolerance)}
            case["variants"][name]["reaches_paper"] = bool(case["variants"][name]["distance"] <= tolerance)
        cases.append(case)
    result = {"campaign": camp.name, "dir": str(camp.dir), "members": len(camp.members), "used": len(done),
              "not_used": [f"{m.name} ({m.state})" for m in camp.members if not m.done],
              "tolerance": tolerance, "confidence": confidence,
              "paper": {f"{m:g}": paper_ratio(m) for m in PLATES}, "cases": cases}
    result["conclusion"] = conclusion(result)
    return result


def conclusion(result) -> str:
    """One line: the cases reaching all three paper values (or the closest), and heavy ~ middle."""
    tol = f"{100 * result['tolerance']:g} %"
    both = [(c, name, label) for c in result["cases"] for name, label, _ in VARIANTS]
    reach = [f"{c['case']} ({label})" for c, name, label in both if c["variants"][name]["reaches_paper"]]
    paper = ", ".join(f"{paper_ratio(m):.3g}" for m in PLATES)
    if reach:
        first = f"reaching the paper's three values ({paper}) within {tol}: " + ", ".join(reach)
    else:
        ranked = sorted((c["variants"][name]["distance"], c["case"], label) for c, name, label in both
                        if math.isfinite(c["variants"][name]["distance"]))
        first = f"no case reaches the paper's three values ({paper}) within {tol}"
        if ranked:
            d, case, label = ranked[0]
            first += f"; closest {case} ({label}), its farthest plate {100 * d:.1f} % away"
    pattern = [f"{c['case']} ({label})" for c, name, label in both if c["variants"][name]["heavy_equals_middle"]]
    second = (f"heavy ≈ middle plate (means within {tol}): " + (", ".join(pattern) if pattern else "no case"))
    return f"{first}; {second}"


# ---------------------------------------------------------------------------- output
def lines(result) -> list[str]:
    conf = f"{100 * result['confidence']:g} %"
    out = [f"blast sensitivity: campaign {result['campaign']} ({result['dir']}): {result['members']} members, "
           f"{result['used']} done and used"]
    if result["not_used"]:
        out.append("not used (not done): " + ", ".join(result["not_used"]))
    out += [f"I_s / I_in per case and plate: mean [{conf} Student-t interval of the mean] over the seeds; "
            "paper " + ", ".join(f"{m:g} kg/m^2: {paper_ratio(m):.4g}" for m in PLATES)
            + " (its I_s / 5e-3 MPa s)",
            f"dist: the farthest plate's distance of the paper's value from the interval (0 inside), "
            f"relative; heavy-middle: (heavy - middle) / their mean; tolerance {100 * result['tolerance']:g} %", ""]
    for name, label, formula in VARIANTS:
        out.append(f"{label} ({formula}):")
        head = ["case", "n"] + [f"{m:g} kg/m^2" for m in PLATES] + ["dist", "heavy-middle", "reaches"]
        rows = [[c["case"], str(c["n"])] + [interval_text(c["variants"][name]["plates"][m]) for m in PLATES]
                + [f"{100 * c['variants'][name]['distance']:.1f} %",
                   f"{100 * c['variants'][name]['heavy_minus_middle']:+.1f} %",
                   "yes" if c["variants"][name]["reaches_paper"] else "no"] for c in result["cases"]]
        out += _columns(head, rows) + [""]
    out.append("prepared layer (end of the settle stage; mean over the seeds):")
    rows = [[c["case"], _fmt(c["layer"]["spheres"]["mean"], ".0f"), _fmt(c["layer"]["contacts_per_sphere"]["mean"]),
             _fmt(c["layer"]["solid_fraction"]["mean"])] for c in result["cases"]]
    out += _columns(["case", "spheres", "contacts/sphere", "solid fraction"], rows) + [""]
    out.append("per member, I_s / I_in with / without the static weight:")
    with_, without = VARIANTS[0][0], VARIANTS[1][0]
    for c in result["cases"]:
        for member, v in c["values"].items():
            out.append(f"  {member}: " + "; ".join(
                f"{m:g}: {v['plates'][m][with_]:.4g} / {v['plates'][m][without]:.4g}" for m in PLATES
                if m in v["plates"]))
    out += ["", f"conclusion: {result['conclusion']}"]
    return out


def _fmt(x, spec=".4g"):
    return format(x, spec) if math.isfinite(x) else "-"


def _columns(head, rows):
    w = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]
    return ["  ".join(str(v).ljust(w[i]) for i, v in enumerate(r)).rstrip() for r in [head] + rows]


def _json(x):
    if isinstance(x, dict):
        return {str(k if not isinstance(k, float) else f"{k:g}"): _json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def plot(result, path) -> Path:
    """One panel per plate: each case's mean and interval with and without the static weight, the
    paper's value and its tolerance band."""
    from .figures import figure, save

    cases = result["cases"]
    fig, axes = figure(w=4.0 * len(PLATES), h=4.8, rows=1, cols=len(PLATES))
    x = np.arange(len(cases))
    tol = result["tolerance"]
    for ax, mass in zip(axes, PLATES):
        paper = paper_ratio(mass)
        ax.axhspan(paper * (1 - tol), paper * (1 + tol), color="C3", alpha=0.12,
                   label=f"paper ± {100 * tol:g} %")
        ax.axhline(paper, color="C3", lw=1.5, label=f"paper {paper:.3g}")
        for k, (name, label, _) in enumerate(VARIANTS):
            es = [c["variants"][name]["plates"][mass] for c in cases]
            mean = np.array([e["mean"] for e in es])
            lo = np.array([e["ci_low"] for e in es])
            hi = np.array([e["ci_high"] for e in es])
            err = np.where(np.isfinite(lo), [mean - lo, hi - mean], 0.0)
            ax.errorbar(x + (k - 0.5) * 0.25, mean, yerr=err, fmt="o" if k == 0 else "s",
                        mfc=None if k == 0 else "none", color=f"C{k}", capsize=3, label=f"pdem, {label}")
        ax.set_xticks(x, [c["case"] for c in cases], rotation=60, ha="right", fontsize="small")
        ax.set(title=f"plate {mass:g} kg/m²", ylabel="I_s / I_in [-]" if mass == PLATES[0] else None)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0].legend(fontsize="x-small")
    fig.suptitle(f"{result['campaign']}: mean and {100 * result['confidence']:g} % CI over the seeds",
                 fontsize="medium")
    return save(fig, path)


def write(path, out=None, tolerance=TOLERANCE, confidence=0.95) -> list[Path]:
    """Analyse the campaign directory ``path``; returns the files written."""
    result = sensitivity(path, tolerance, confidence)
    out = Path(out) if out is not None else Path(path) / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    text = out / "blast_sensitivity.txt"
    text.write_text("\n".join(lines(result)) + "\n")
    js = out / "blast_sensitivity.json"
    js.write_text(json.dumps(_json(result), indent=1, allow_nan=False) + "\n")
    return [text, js, plot(result, out / "blast_sensitivity.png")]


def add_parser(sub):
    p = sub.add_parser(
        "blast-sensitivity", help="blast layer: I_s / I_in per case of a sensitivity campaign against the paper",
        description="Per case of a blast campaign directory (jobs/campaigns/blast_sensitivity.toml): the three "
                    "plates' I_s / I_in with and without the static weight over the seeds, the paper's values, "
                    "and a one-line conclusion (blast_sensitivity.txt/.json/.png).")
    p.add_argument("dir", type=Path, metavar="DIR", help="campaign directory (holds campaign.json)")
    p.add_argument("--tolerance", type=float, default=TOLERANCE,
                   help="relative distance from the paper's value that counts as reaching it (default %(default)s)")
    p.add_argument("--confidence", type=float, default=0.95, help="of the interval of the mean (default 0.95)")
    p.add_argument("--out", type=Path, metavar="OUT", help="output directory (default DIR/analysis)")
    return p


def run(args):
    if not 0 < args.confidence < 1:
        raise CampaignError(f"--confidence {args.confidence}: must be in (0, 1)")
    if not 0 <= args.tolerance < 1:
        raise CampaignError(f"--tolerance {args.tolerance}: must be in [0, 1)")
    return write(args.dir, args.out, args.tolerance, args.confidence)
