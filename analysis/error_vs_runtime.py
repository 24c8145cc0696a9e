"""Error against run time (SPEC.md 4): what cheaper settings cost in accuracy and save in time.

``python -m analysis error-vs-runtime DIR --reference SEL`` splits the finished members of a
campaign into groups that differ only by their seed (`analysis.campaign.group_members`). One
group is the reference (SEL: a case name, or ``key=value[,key=value]`` with full or last-part
keys; default the manifest's ``[analysis] reference``); every other group is a cheaper setting
(scaled stiffness, a larger Δt safety factor, faster loading, fewer particles: any varied keys).
For each quantity (as in `analysis.campaign`, default the manifest's ``[analysis] quantities``):

- reference value q_ref = mean over the reference group, its seed scatter s_ref (sample standard
  deviation);
- error of a member: |q − q_ref| / |q_ref|; error of a group: that of its mean;
- noise floor: s_ref / |q_ref|, the error a single run of the reference setting itself shows
  from its seed alone; for a group of n seeds against n_ref the floor of the difference of the
  means is s_ref / |q_ref| · sqrt(1/n + 1/n_ref). An error below its floor is noise.
- cost: the member's measured wall time (all attempts, from run.json) and its CPU-hours (the
  CPU time its processes used, measured by the campaign runner; on a shared machine the cost that
  does not depend on the load; core-hours = wall × ranks × threads where it was not measured); a
  group's cost is the mean over its members; its speed-up is the reference's wall time over its
  own, its cost ratio the reference's CPU-hours over its own.

Writes ``error_vs_runtime.png`` (error against wall time and against core-hours, one row per
quantity, the floor as a shaded band), ``error_vs_runtime.txt`` and ``.json`` into DIR/analysis
(or --out). Imports numpy, matplotlib (plots) and `analysis` only.
"""

from __future__ import annotations

import json
from math import isclose, sqrt
from pathlib import Path

import numpy as np

from .campaign import (CampaignError, Quantity, _columns, _finite, display, group_members,
                       read_campaign, short_key)
from .figures import save


NOISE_WORDS = {True: "yes", False: "no", None: "unknown"}  # error below the floor; None: no floor


def _parse_value(text):
    try:
        return float(text)
    except ValueError:
        return text


def _matches(params, key, value):
    full = [k for k in params if k == key or k.split(".")[-1] == key]
    if len(full) != 1:
        return False
    v = params[full[0]]
    if isinstance(value, float) and isinstance(v, (int, float)) and not isinstance(v, bool):
        return isclose(float(v), value, rel_tol=1e-9, abs_tol=0.0)
    return str(v) == str(value)


def select_reference(groups, selector):
    """The one group that ``selector`` picks: a {key: value} table, or text of comma-separated
    ``key=value`` parts and case names."""
    if isinstance(selector, dict):
        conds = [(k, v if not isinstance(v, str) else _parse_value(v)) for k, v in selector.items()]
    else:
        conds = []
        for part in str(selector).split(","):
            k, eq, v = part.partition("=")
            conds.append((k.strip(), _parse_value(v.strip())) if eq else ("case", k.strip()))
    hit = [g for g in groups if all(_matches(g.params, k, v) for k, v in conds)]
    if len(hit) != 1:
        have = "; ".join(g.label for g in groups)
        raise CampaignError(f"reference {selector!r} matches {len(hit)} groups of finished members, not one "
                            f"(groups: {have})")
    return hit[0]


def error_table(groups, ref, q):
    """Per-group rows for quantity ``q``: reference statistics and each group's error and cost."""
    vals = {id(g): np.array([q.value(m) for m in g.members], dtype=np.float64) for g in groups}
    r = vals[id(ref)]
    r = r[np.isfinite(r)]
    if len(r) == 0:
        raise CampaignError(f"{q.text}: no finite value in the reference group ({ref.label})")
    q_ref = float(r.mean())
    if q_ref == 0.0:
        raise CampaignError(f"{q.text}: the reference value is 0; a relative error is undefined")
    s_ref = float(r.std(ddof=1)) if len(r) >= 2 else float("nan")
    floor = s_ref / abs(q_ref)
    rows = []
    for g in groups:
        v = vals[id(g)]
        ok = np.isfinite(v)
        n = int(ok.sum())
        mean = float(v[ok].mean()) if n else float("nan")
        wall = float(np.mean([m.wall_s for m in g.members]))
        core = float(np.mean([_cpu_or_core(m) for m in g.members]))
        rows.append({"group": g.label, "params": g.params, "reference": g is ref, "n": n, "mean": mean,
                     "error": (mean - q_ref) / abs(q_ref), "abs_error": abs(mean - q_ref) / abs(q_ref),
                     "member_errors": [abs(x - q_ref) / abs(q_ref) for x in v.tolist()],
                     "member_wall_s": [m.wall_s for m in g.members],
                     "member_core_h": [_cpu_or_core(m) / 3600 for m in g.members],
                     "floor": floor * sqrt(1 / max(n, 1) + 1 / len(r)) if n else float("nan"),
                     "wall_s": wall, "core_h": core / 3600, "members": [m.name for m in g.members]})
    ref_row = next(x for x in rows if x["reference"])
    for x in rows:
        x["speedup"] = ref_row["wall_s"] / x["wall_s"] if x["wall_s"] > 0 else float("nan")
        x["cost_ratio"] = ref_row["core_h"] / x["core_h"] if x["core_h"] > 0 else float("nan")
        # no floor (a reference of one seed): whether the error is noise is unknown (None)
        x["noise"] = (bool(x["abs_error"] <= x["floor"]) if np.isfinite(x["floor"]) else None) \
            if not x["reference"] else None
    return {"quantity": q.text, "units": q.units(ref.members[0]), "q_ref": q_ref, "s_ref": s_ref, "n_ref": len(r),
            "floor": floor, "rows": rows}


def _cpu_or_core(m):
    """Cost of a member [s]: its measured CPU time, else wall × ranks × threads."""
    return m.cpu_s if np.isfinite(m.cpu_s) else m.core_s


def error_report(path, quantities, reference, out=None):
    """The error-vs-runtime report of campaign directory ``path``; returns the files written."""
    camp = read_campaign(path)
    done = camp.done
    if not done:
        raise CampaignError(f"{path}: no member is done yet")
    groups = group_members(done, camp.seed_key)
    ref = select_reference(groups, reference)
    if len(groups) < 2:
        raise CampaignError(f"{path}: only the reference group has finished members; nothing to compare")
    qs = [Quantity.parse(q) for q in quantities]
    tables = [error_table(groups, ref, q) for q in qs]
    units = {q.text: q.units(done[0]) for q in qs}
    out = Path(out) if out is not None else Path(path) / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    lines = [f"error against run time: campaign {camp.name} ({path})", f"reference: {ref.label} "
             f"({len(ref.members)} member(s)); error = |q - q_ref| / |q_ref|; floor = seed scatter of the "
             "reference s_ref/|q_ref| * sqrt(1/n + 1/n_ref)", ""]
    for t in tables:
        f, u = display(units[t["quantity"]])
        lines.append(f"{t['quantity']}: q_ref = {t['q_ref'] * f:.6g} {u}, s_ref = "
                     f"{t['s_ref'] * f:.4g} {u} (n_ref = {t['n_ref']}), single-run noise floor {t['floor']:.4g}")
        head = [
            "group",
            "n",
            f"mean [{u}]",
            "error",
            "|error|",
            "floor",
            "noise?",
            "wall [s]",
            "CPU-h",
            "speed-up",
            "cost ratio",
        ]
        rows = [[x["group"], str(x["n"]), f"{x['mean'] * f:.6g}", f"{x['error']:+.4g}", f"{x['abs_error']:.4g}",
                 f"{x['floor']:.4g}", "reference" if x["reference"] else NOISE_WORDS[x["noise"]],
                 f"{x['wall_s']:.1f}", f"{x['core_h']:.4f}", f"{x['speedup']:.2f}",
                 f"{x['cost_ratio']:.2f}"] for x in t["rows"]]
        lines += _columns(head, rows) + [""]
    (out / "error_vs_runtime.txt").write_text("\n".join(lines))
    (out / "error_vs_runtime.json").write_text(json.dumps(_finite({"campaign": camp.name, "reference": ref.params,
                                                                   "units": units, "quantities": tables}),
                                                          indent=1) + "\n")
    png = plot_error_vs_runtime(out / "error_vs_runtime.png", tables, camp.name)
    return [out / "error_vs_runtime.txt", out / "error_vs_runtime.json", png]


def plot_error_vs_runtime(path, tables, name):
    """Rows: quantities; columns: against wall time per member [s], against core-hours per member.
    Each cheaper group: its members (small) and its mean (large, labelled); the reference members'
    own errors (grey) and the single-run noise floor (band below the line)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 4.2 * len(tables)), layout="constrained")
    axes = fig.subplots(len(tables), 2, squeeze=False)
    for t, row in zip(tables, axes):
        positive = [e for x in t["rows"] for e in x["member_errors"] + [x["abs_error"]] if e > 0 and np.isfinite(e)]
        if np.isfinite(t["floor"]) and t["floor"] > 0:
            positive.append(t["floor"])
        tiny = min(positive) / 3 if positive else 1e-6  # where exact zeros are drawn on the log axis
        for ax, cost, member_cost, ratio, label in (
            (row[0], "wall_s", "member_wall_s", "speedup", "wall time per member [s]"),
            (row[1], "core_h", "member_core_h", "cost_ratio", "CPU-hours per member (core-hours if not measured)"),
        ):
            ci = 0
            for x in t["rows"]:
                errs = np.maximum(np.asarray(x["member_errors"], float), tiny)
                if x["reference"]:
                    ax.plot(x[member_cost], errs, "o", color="0.55", ms=4, label="reference members (seed scatter)")
                    ax.axvline(x[cost], color="0.4", ls=":", lw=1)
                    continue
                color = f"C{ci % 10}"
                ci += 1
                ax.plot(x[member_cost], errs, "o", color=color, ms=3, alpha=0.5)
                ax.plot([x[cost]], [max(x["abs_error"], tiny)], "D", color=color, ms=8, label=x["group"])
                ax.annotate(f"{x[ratio]:.1f}x", (x[cost], max(x["abs_error"], tiny)), textcoords="offset points",
                            xytext=(6, 4), fontsize=8, color=color)
            if np.isfinite(t["floor"]):
                ax.axhline(t["floor"], color="k", ls="--", lw=1, label=f"noise floor (reference CoV {t['floor']:.3g})")
                ax.axhspan(tiny, t["floor"], color="0.85", alpha=0.5, zorder=0)
            costs = [c for x in t["rows"] for c in x[member_cost] if c > 0]
            if costs and max(costs) > 3 * min(costs):
                ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set(xlabel=label, ylabel=f"relative error of {t['quantity']}")
            ax.grid(True, which="both", alpha=0.3)
        row[0].legend(fontsize="small")
        f, u = display(t["units"])
        row[0].set_title(f"{name}: {t['quantity']} (reference {t['q_ref'] * f:.4g} {u}; dotted: its cost)")
    return save(fig, path)


def add_parser(sub):
    p = sub.add_parser("error-vs-runtime", help="a campaign: error of cheaper settings against their run time",
                       description="Error of chosen quantities of cheaper members against a reference group, "
                                   "against wall time and core-hours (docs/campaigns.md).")
    p.add_argument("dir", type=Path, metavar="DIR", help="campaign directory (holds campaign.json)")
    p.add_argument("--reference", "-r", metavar="SEL",
                   help="the reference group: a case name or key=value[,key=value] (default: [analysis] reference)")
    p.add_argument("--quantity", "-q", action="append", metavar="Q",
                   help="as in `campaign` (repeat; default: [analysis] quantities, else cycles.settlement_peak@last)")
    p.add_argument("--out", type=Path, metavar="OUT", help="output directory (default DIR/analysis)")
    return p


def run(args):
    from .campaign import default_quantities

    camp = read_campaign(args.dir)
    reference = args.reference or camp.manifest.get("analysis", {}).get("reference")
    if reference is None:
        raise CampaignError("no reference: give --reference (a case name or key=value) or [analysis] reference "
                            "in the campaign file")
    return error_report(args.dir, args.quantity or default_quantities(camp), reference, args.out)


__all__ = ["error_report", "error_table", "select_reference", "short_key"]
