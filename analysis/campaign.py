"""Campaign analysis: one scalar or curve from every member of a campaign directory.

``python -m analysis campaign DIR`` reads the campaign's manifest (``DIR/campaign.json``,
written by ``pdem campaign``), each finished member's ``results.h5`` and ``run.json``, and
writes into ``DIR/analysis`` (or ``--out``):

- ``campaign.txt`` / ``campaign.json``: every member's values, and per group of members that
  differ only by their seed the seed variability (SPEC.md 4): n, mean, standard deviation, CoV,
  Student-t confidence interval of the mean, min, max;
- ``variability_<quantity>.png``: the members' values with each group's mean and interval;
- ``envelope_<curve>.png``: every member's curve, each group's mean and envelope (min..max);
- ``param_<key>_<quantity>.png``: for each varied parameter other than the seed (and ``case``),
  the group means with their intervals against its values (one line per setting of the others).

A quantity is ``GROUP.NAME@AT``: ``cycles.NAME`` (a column of the /cycles table),
``stiffness.loading|unloading|resilient`` and ``settlement.permanent|plastic|resilient`` (per cycle,
from `analysis.box`), with AT a cycle number (1-based; negative counts from the last) or
last|first|max|min|mean (default last); or ``series.NAME`` with AT last|first|max|min|mean. A curve is
the same without ``@``: per-cycle curves are drawn against the cycle number, series against the
time since their first sample. Only members whose run.json says done (exit 0) are used.

This module owns the campaign as the analysis sees it (members and their cost), quantities, curves
and grouping; the manifest and run records are read by `pdem.format.campaign`. Imports numpy,
scipy (through `analysis.variability`), `pdem.format` and, for the plots, matplotlib.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pdem.format.campaign import ManifestError, read_manifest, read_run
from pdem.format.read import ResultFileError, read_box_test, read_results

from .figures import figure, save
from .variability import variability

AT_WORDS = ("last", "first", "max", "min", "mean")
PER_CYCLE = {"stiffness": ("loading", "unloading", "resilient"),
             "settlement": ("permanent", "plastic", "resilient")}
UNITS = {"stiffness": "N/m", "settlement": "m"}
# SI units -> (factor, shown units) for tables and plots
DISPLAY = {"m": (1e3, "mm"), "N": (1e-3, "kN"), "N/m": (1e-6, "MN/m")}


class CampaignError(Exception):
    """A campaign directory or a request that cannot be analysed; the message is one line."""


@dataclass
class Member:
    """A member of the campaign as the analysis sees it (cost from run.json)."""

    name: str
    dir: Path
    params: dict
    done: bool
    state: str
    wall_s: float
    core_s: float
    cpu_s: float  # CPU time its processes used [s] (NaN where the runner did not measure it)
    ranks: int
    threads: int
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def results_path(self):
        return self.dir / "results.h5"

    def results(self):
        if "results" not in self._cache:
            self._cache["results"] = read_results(self.results_path)
        return self._cache["results"]

    def box(self):
        """`analysis.box.BoxAnalysis` of the member (read once)."""
        if "box" not in self._cache:
            from .box import analyse_box

            self._cache["box"] = analyse_box(read_box_test(self.results_path))
        return self._cache["box"]


@dataclass
class Campaign:
    name: str
    dir: Path
    manifest: dict
    members: list
    seed_key: str | None
    varied: list

    @property
    def done(self):
        return [m for m in self.members if m.done]


def read_campaign(path) -> Campaign:
    """The manifest and members of a campaign directory (CampaignError if it is not one)."""
    path = Path(path)
    try:
        man = read_manifest(path)
    except ManifestError as err:
        raise CampaignError(str(err)) from None
    members = []
    for e in man.get("members", []):
        d = path / e["dir"]
        rec = read_run(d)
        attempts = (rec or {}).get("attempts") or []
        last = attempts[-1] if attempts else None
        done = bool(last and last.get("end") and last.get("exit") == 0)
        state = ("pending" if last is None else "done" if done else "running/stopped" if not last.get("end")
                 else f"exit {last.get('exit')}")
        ended = [a for a in attempts if a.get("end")]
        members.append(Member(name=e["name"], dir=d, params=dict(e.get("params", {})), done=done, state=state,
                              wall_s=float(sum(a["wall_s"] for a in ended)),
                              core_s=float(sum(a["core_s"] for a in ended)),
                              cpu_s=_cpu_seconds(ended),
                              ranks=int(e.get("ranks", 1)), threads=int(e.get("threads", 1))))
    return Campaign(name=man.get("name", path.name), dir=path, manifest=man, members=members,
                    seed_key=man.get("seed_key"), varied=list(man.get("varied", [])))


def _cpu_seconds(attempts):
    cpu = [a.get("cpu_s") for a in attempts]
    return float(sum(cpu)) if cpu and None not in cpu else float("nan")


# ---------------------------------------------------------------------------- quantities
_SPEC = re.compile(r"^(cycles|series|stiffness|settlement)\.([A-Za-z0-9_]+)(?:@(-?\d+|[a-z]+))?$")


@dataclass(frozen=True)
class Quantity:
    """A scalar of one result file: ``GROUP.NAME@AT`` (module docstring)."""

    group: str
    name: str
    at: object = "last"

    @classmethod
    def parse(cls, text, curve=False):
        m = _SPEC.match(text.strip())
        if not m or (curve and m.group(3) is not None):
            form = "GROUP.NAME" if curve else "GROUP.NAME[@AT]"
            what = "curve" if curve else "quantity"
            raise CampaignError(f"{what} {text!r}: must be {form} with GROUP one of cycles, series, stiffness, "
                                f"settlement (e.g. cycles.settlement_peak{'' if curve else '@3'})")
        group, name, at = m.group(1), m.group(2), m.group(3) or "last"
        if group in PER_CYCLE and name not in PER_CYCLE[group]:
            raise CampaignError(f"{text}: {group} has {', '.join(PER_CYCLE[group])}")
        if at.lstrip("-").isdigit():
            at = int(at)
            if group == "series":
                raise CampaignError(f"{text}: a series takes @{'|'.join(AT_WORDS)}, not a number")
            if at == 0:
                raise CampaignError(f"{text}: cycles are numbered from 1 (negative: from the last)")
        elif at not in AT_WORDS:
            raise CampaignError(f"{text}: @{at} must be a cycle number or one of {', '.join(AT_WORDS)}")
        return cls(group, name, at)

    @property
    def text(self):
        return f"{self.group}.{self.name}" + (f"@{self.at}" if self.at is not None else "")

    @property
    def slug(self):
        return re.sub(r"[^A-Za-z0-9]+", "_", self.text.replace("@-", "@m")).strip("_")

    def units(self, member=None):
        if self.group in UNITS:
            return UNITS[self.group]
        if self.group == "series" and member is not None:
            return member.results().units.get(self.name, "")
        n = self.name
        return ("m" if n.startswith("settlement") else "N" if n.startswith(("force", "load")) else
                "s" if n.startswith("t_") or n == "time" else "-")

    def values(self, member):
        """(x, y) of the whole per-cycle or series record of ``member``."""
        try:
            if self.group == "series":
                r = member.results()
                if self.name not in r.series:
                    raise CampaignError(f"{member.results_path}: no /series/{self.name} "
                                        f"(has {', '.join(sorted(r.series))})")
                t = r.series["time"]
                return t - t[0], r.series[self.name]
            if self.group == "cycles":
                r = member.results()
                if r.cycles is None or self.name not in r.cycles:
                    have = ", ".join(sorted(r.cycles)) if r.cycles else "no /cycles table"
                    raise CampaignError(f"{member.results_path}: no /cycles/{self.name} ({have})")
                return r.cycles["cycle"], r.cycles[self.name]
            b = member.box()
            y = getattr(b.stiffness, self.name) if self.group == "stiffness" else {
                "permanent": b.permanent, "plastic": b.plastic, "resilient": b.resilient}[self.name]
            return b.table.cycle, np.asarray(y, dtype=np.float64)
        except (ResultFileError, ValueError) as err:
            raise CampaignError(" ".join(str(err).split())) from None

    def value(self, member):
        """The scalar of ``member`` (NaN if the cycle asked for does not exist)."""
        _, y = self.values(member)
        if len(y) == 0:
            return float("nan")
        if isinstance(self.at, int):
            k = self.at - 1 if self.at > 0 else len(y) + self.at
            return float(y[k]) if 0 <= k < len(y) else float("nan")
        return float({"last": y[-1], "first": y[0], "max": np.nanmax(y), "min": np.nanmin(y),
                      "mean": np.nanmean(y)}[self.at])


def curve(text):
    q = Quantity.parse(text, curve=True)
    return Quantity(q.group, q.name, None)


def default_quantities(camp):
    """From the manifest's [analysis] table, else the box test's settlement at the peak of the last cycle."""
    q = camp.manifest.get("analysis", {}).get("quantities")
    if q:
        return [q] if isinstance(q, str) else list(q)
    return ["cycles.settlement_peak@last"]


def default_curves(camp):
    c = camp.manifest.get("analysis", {}).get("curves")
    if c is not None:
        return [c] if isinstance(c, str) else list(c)
    return ["cycles.settlement_peak"]


# ---------------------------------------------------------------------------- groups
@dataclass
class Group:
    """Members that differ only by their seed; ``params`` what they share."""

    params: dict
    members: list

    @property
    def label(self):
        return ", ".join(f"{short_key(k)} = {show(v)}" for k, v in self.params.items()) or "all members"


def show(v):
    """A parameter value as text (floats in 6 significant digits)."""
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def short_key(key):
    return key if key == "case" else key.split(".")[-1]


def group_members(members, seed_key):
    """Groups of members whose parameters other than ``seed_key`` are equal, in manifest order."""
    groups = {}
    for m in members:
        p = {k: v for k, v in m.params.items() if k != seed_key}
        groups.setdefault(json.dumps(p, sort_keys=True), Group(p, [])).members.append(m)
    return list(groups.values())


def stats(values, confidence):
    """`analysis.variability.variability` as a dict, or n/mean only for fewer than 2 values."""
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=np.float64)
    if len(v) >= 2:
        s = variability(v, confidence)
        return {"n": s.n, "mean": s.mean, "std": s.std, "cov": s.cov, "ci_low": s.ci_low, "ci_high": s.ci_high,
                "min": s.minimum, "max": s.maximum}
    nan = float("nan")
    mean = float(v[0]) if len(v) else nan
    return {"n": len(v), "mean": mean, "std": nan, "cov": nan, "ci_low": nan, "ci_high": nan, "min": mean, "max": mean}


def interval_text(e) -> str:
    """A `stats` entry as text: "mean [ci_low, ci_high]", "mean (n = 1)" without an interval, "-"."""
    if not math.isfinite(e["mean"]):
        return "-"
    if not math.isfinite(e["ci_low"]):
        return f"{e['mean']:.4g} (n = {e['n']})"
    return f"{e['mean']:.4g} [{e['ci_low']:.4g}, {e['ci_high']:.4g}]"


def display(units):
    return DISPLAY.get(units, (1.0, units))


# ---------------------------------------------------------------------------- report
def campaign_report(path, quantities, curves=(), out=None, confidence=0.95):
    """Analyse the campaign directory ``path``; returns the files written."""
    camp = read_campaign(path)
    qs = [Quantity.parse(q) for q in quantities]
    cs = [curve(c) for c in curves]
    done = camp.done
    if not done:
        raise CampaignError(f"{path}: no member is done yet ({len(camp.members)} members; see pdem campaign status)")
    out = Path(out) if out is not None else Path(path) / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    values = {q.text: [q.value(m) for m in done] for q in qs}
    units = {q.text: q.units(done[0]) for q in qs}
    groups = group_members(done, camp.seed_key)
    index = {m.name: i for i, m in enumerate(done)}
    gstats = [{q.text: stats([values[q.text][index[m.name]] for m in g.members], confidence) for q in qs}
              for g in groups]
    written = [_write_tables(out, camp, qs, values, units, groups, gstats, confidence)]
    written.append(out / "campaign.json")
    for q in qs:
        written.append(plot_variability(out / f"variability_{q.slug}.png", q, units[q.text], groups, gstats, values,
                                        index, confidence, camp))
        for key in [k for k in camp.varied if k != camp.seed_key] + (["case"] if camp.manifest.get("cases") else []):
            p = plot_parameter(out / f"param_{re.sub(r'[^A-Za-z0-9]+', '_', key)}_{q.slug}.png", key, q,
                               units[q.text], groups, gstats, confidence)
            if p is not None:
                written.append(p)
    for c in cs:
        written.append(plot_envelope(out / f"envelope_{c.slug}.png", c, groups, camp))
    return written


def _fmt(x, factor=1.0):
    return "-" if x is None or not np.isfinite(x) else f"{x * factor:.6g}"


def _write_tables(out, camp, qs, values, units, groups, gstats, confidence):
    done = camp.done
    keys = [k for k in camp.varied] + (["case"] if camp.manifest.get("cases") else [])
    keys = ["case"] + [k for k in keys if k != "case"] if "case" in keys else keys
    lines = [f"campaign {camp.name} ({camp.dir}): {len(camp.members)} members, {len(done)} done and used"]
    left = [m for m in camp.members if not m.done]
    if left:
        lines.append("not used (not done): " + ", ".join(f"{m.name} ({m.state})" for m in left))
    lines += ["", "quantities: " + "; ".join(f"{q.text} [{display(units[q.text])[1]}]" for q in qs), "",
              "per member:"]
    head = ["member"] + [short_key(k) for k in keys] + [f"{q.text} [{display(units[q.text])[1]}]" for q in qs] + \
        ["wall [s]", "core-h"]
    rows = [[m.name] + [show(m.params.get(k, "")) for k in keys]
            + [_fmt(values[q.text][i], display(units[q.text])[0]) for q in qs]
            + [f"{m.wall_s:.1f}", f"{m.core_s / 3600:.4f}"] for i, m in enumerate(done)]
    lines += _columns(head, rows)
    pct = f"{100 * confidence:g} %"
    for q in qs:
        f, u = display(units[q.text])
        lines += ["", f"{q.text} [{u}] by group (seed variability; {pct} Student-t interval of the mean):"]
        head = ["group", "n", "mean", "std", "CoV", "CI low", "CI high", "min", "max"]
        rows = [[g.label, str(s[q.text]["n"])] + [_fmt(s[q.text][k], f) for k in ("mean", "std")]
                + [_fmt(s[q.text]["cov"])] + [_fmt(s[q.text][k], f) for k in ("ci_low", "ci_high", "min", "max")]
                for g, s in zip(groups, gstats)]
        lines += _columns(head, rows)
    (out / "campaign.txt").write_text("\n".join(lines) + "\n")
    data = {"campaign": camp.name, "confidence": confidence, "units": units,
            "members": [{"name": m.name, "params": m.params, "wall_s": m.wall_s, "core_s": m.core_s,
                         "values": {q.text: values[q.text][i] for q in qs}} for i, m in enumerate(done)],
            "groups": [{"params": g.params, "members": [m.name for m in g.members], "stats": s}
                       for g, s in zip(groups, gstats)],
            "not_done": [m.name for m in left]}
    (out / "campaign.json").write_text(json.dumps(_finite(data), indent=1) + "\n")
    return out / "campaign.txt"


def _finite(x):
    if isinstance(x, float) and not np.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite(v) for v in x]
    return x


def _columns(head, rows):
    w = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]
    return ["  ".join(str(c).ljust(w[i]) if i == 0 else str(c).rjust(w[i]) for i, c in enumerate(r))
            for r in [head] + rows]


# ---------------------------------------------------------------------------- plots
def plot_variability(path, q, units, groups, gstats, values, index, confidence, camp):
    """Every member's value (x: its seed, or its index) per group, with the group's mean,
    confidence interval of the mean (band) and min/max (dashed)."""
    f, u = display(units)
    fig, ax = figure(h=4.5)
    for gi, (g, s) in enumerate(zip(groups, gstats)):
        color = f"C{gi % 10}"
        xs = [m.params.get(camp.seed_key, j + 1) if camp.seed_key else j + 1 for j, m in enumerate(g.members)]
        ys = [values[q.text][index[m.name]] * f for m in g.members]
        ax.plot(xs, ys, "o", color=color, label=g.label if len(groups) > 1 else "members")
        st = s[q.text]
        lo, hi = min(xs), max(xs)
        if np.isfinite(st["mean"]):
            cov = f", CoV {st['cov']:.3g}" if np.isfinite(st["cov"]) else ""
            ax.hlines(st["mean"] * f, lo, hi, color=color, lw=1.5, label=f"mean {st['mean'] * f:.4g} {u}{cov}")
        if np.isfinite(st["ci_low"]):
            ax.fill_between([lo, hi], st["ci_low"] * f, st["ci_high"] * f, color=color, alpha=0.15,
                            label=f"{100 * confidence:g} % CI of the mean")
            ax.hlines([st["min"] * f, st["max"] * f], lo, hi, color=color, ls="--", lw=0.8,
                      label="min and max" if gi == 0 else None)
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set(xlabel=f"seed ({camp.seed_key})" if camp.seed_key else "member", ylabel=f"{q.text} [{u}]",
           title=f"{camp.name}: {q.text} over {sum(len(g.members) for g in groups)} members")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


def _numeric(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def plot_parameter(path, key, q, units, groups, gstats, confidence):
    """Group means (with their confidence intervals, and the members as small dots) against the
    values of ``key``, one line per setting of the other parameters. None if ``key`` has one value."""
    xs_all = [g.params.get(key) for g in groups]
    if len({json.dumps(x) for x in xs_all}) < 2:
        return None
    f, u = display(units)
    numeric = all(_numeric(x) for x in xs_all)
    cats = sorted({str(x) for x in xs_all}) if not numeric else None
    lines = {}
    for g, s in zip(groups, gstats):
        rest = {k: v for k, v in g.params.items() if k != key}
        lines.setdefault(json.dumps(rest, sort_keys=True), (rest, []))[1].append((g, s))
    fig, ax = figure(h=4.5)
    for li, (rest, items) in enumerate(lines.values()):
        pts = sorted(((g.params[key] if numeric else cats.index(str(g.params[key]))), s[q.text]) for g, s in items)
        x = np.array([p[0] for p in pts], dtype=float)
        mean = np.array([p[1]["mean"] for p in pts]) * f
        lo = np.array([p[1]["ci_low"] for p in pts]) * f
        hi = np.array([p[1]["ci_high"] for p in pts]) * f
        label = ", ".join(f"{short_key(k)} = {show(v)}" for k, v in rest.items()) or None
        err = np.where(np.isfinite(lo), [mean - lo, hi - mean], 0.0)
        ax.errorbar(x, mean, yerr=err, fmt="o-", color=f"C{li % 10}", capsize=3, label=label)
    if numeric and all(v > 0 for v in xs_all) and max(xs_all) / min(xs_all) > 20:
        ax.set_xscale("log")
    if cats is not None:
        ax.set_xticks(range(len(cats)), cats)
    ax.set(xlabel=key, ylabel=f"{q.text} [{u}]",
           title=f"{q.text} against {short_key(key)} (mean, {100 * confidence:g} % CI over seeds)")
    ax.grid(True, alpha=0.3)
    if any(label for label in ax.get_legend_handles_labels()[1]):
        ax.legend(fontsize="small")
    return save(fig, path)


def envelope(curves, per_cycle, n_grid=400):
    """(x, mean, min, max) of curves [(x, y), ...] on their common range: per-cycle curves on
    the cycles all of them have, series interpolated on a uniform grid (None if nothing is common)."""
    curves = [(np.asarray(x, float), np.asarray(y, float)) for x, y in curves if len(x)]
    if not curves:
        return None
    if per_cycle:
        common = sorted(set.intersection(*(set(x.tolist()) for x, _ in curves)))
        x = np.array(common, dtype=float)
        ys = np.array([[y[np.flatnonzero(cx == v)[0]] for v in x] for cx, y in curves])
    else:
        lo, hi = max(cx[0] for cx, _ in curves), min(cx[-1] for cx, _ in curves)
        if not hi > lo:
            return None
        x = np.linspace(lo, hi, n_grid)
        ys = np.array([np.interp(x, cx, y) for cx, y in curves])
    if len(x) == 0:
        return None
    return x, ys.mean(axis=0), ys.min(axis=0), ys.max(axis=0)


def plot_envelope(path, c, groups, camp):
    """Every member's curve (thin), each group's mean (thick) and envelope min..max (band)."""
    fig, ax = figure(h=4.5)
    units = c.units(groups[0].members[0])
    f, u = display(units)
    per_cycle = c.group != "series"
    for gi, g in enumerate(groups):
        color = f"C{gi % 10}"
        curves = [c.values(m) for m in g.members]
        for x, y in curves:
            ax.plot(x, np.asarray(y) * f, color=color, lw=0.6, alpha=0.5, marker="." if per_cycle else None)
        env = envelope(curves, per_cycle)
        if env is not None:
            x, mean, lo, hi = env
            ax.fill_between(x, lo * f, hi * f, color=color, alpha=0.2)
            ax.plot(x, mean * f, color=color, lw=2,
                    label=f"{g.label + ': ' if len(groups) > 1 else ''}mean and envelope (min..max) of {len(curves)}")
    if per_cycle:
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set(xlabel="cycle" if per_cycle else "time since the first sample [s]", ylabel=f"{c.group}.{c.name} [{u}]",
           title=f"{camp.name}: {c.group}.{c.name}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return save(fig, path)


# ---------------------------------------------------------------------------- command line
def add_parser(sub):
    p = sub.add_parser("campaign", help="a campaign: seed variability, envelopes, parameter studies",
                       description="Gather quantities from every finished member of a pdem campaign directory "
                                   "(docs/campaigns.md).")
    p.add_argument("dir", type=Path, metavar="DIR", help="campaign directory (holds campaign.json)")
    p.add_argument("--quantity", "-q", action="append", metavar="Q",
                   help="scalar GROUP.NAME@AT, e.g. cycles.settlement_peak@3 or series.bed_top@last (repeat; "
                        "default: the campaign's [analysis] quantities, else cycles.settlement_peak@last)")
    p.add_argument("--curve", "-c", action="append", metavar="C",
                   help="curve GROUP.NAME for the envelope, e.g. cycles.settlement_peak (repeat; default: "
                        "[analysis] curves, else cycles.settlement_peak; 'none' for none)")
    p.add_argument("--confidence", type=float, default=0.95, help="of the interval of the mean (default 0.95)")
    p.add_argument("--out", type=Path, metavar="OUT", help="output directory (default DIR/analysis)")
    return p


def run(args):
    camp = read_campaign(args.dir)
    qs = args.quantity or default_quantities(camp)
    cs = args.curve if args.curve is not None else default_curves(camp)
    cs = [c for c in cs if c != "none"]
    if not 0 < args.confidence < 1:
        raise CampaignError(f"--confidence {args.confidence}: must be in (0, 1)")
    return campaign_report(args.dir, qs, cs, args.out, args.confidence)
