"""The validation table (issue #32): pdem against every figure and table of the seed documents.

``python -m analysis validate`` (``make validate``) reads the row list ``jobs/validation/rows.toml``
(one row per figure or table of the thesis and the blast paper: the seed's words and number, the
campaign that makes pdem's number, the differences from the seed's setup, the explanation's
status) and the result files each row names, and writes ``docs/validation_table.md``. No number
of pdem's is typed anywhere: each comes from a named extractor (``EXTRACTORS``) applied to a file.

Two steps:

1. *refresh*: a row whose extractor is ``campaign`` names a campaign directory (``runs``) and a
   committed values file (``file``, ``docs/validation/<campaign>/values.json``). When the directory
   holds finished members, every quantity the rows ask of it is computed from each member's
   ``results.h5`` and written to the values file (members, parameters, values in SI units, the
   result file of each value). Without the directory the committed file is used as it is.
2. *table*: every row's extractor reads its file(s); a missing file gives "not run here", never a
   number. A row may name ``[[row.fallback]]`` extractors (a committed result of an earlier, smaller
   campaign) used, and said to be used, while its own campaign has not run.

Statistics: pdem's number is the mean over the seeds found with the Student-t 95 % interval of the
mean, t_{0.975, n−1} s/√n (`analysis.variability`, scipy). Verdicts, computed from the numbers:

- ``value``: "agrees within scatter" if the seed's value is inside pdem's interval, or pdem's mean
  inside the seed's stated range; otherwise "differs, explanation tested|untested" as the row's
  ``explanation.status`` says;
- ``scatter``: the seed's (max − min)/mean of ``seed_n`` runs against the interval of what pdem's
  scatter predicts for that many runs: d₂(n) σ/mean with σ in its χ² 95 % interval, d₂(n) the
  expected range of n standard normal values (numerical integral);
- ``trend``: the group means ordered as the seed states (``increasing``, ``decreasing``,
  ``first_largest_last_smallest``) and, with ≥ 2 seeds per group, a one-way ANOVA from the groups'
  n, mean and standard deviation: p < 0.05 for an ordering or ``differ``, p ≥ 0.05 for ``equal``
  (no difference detected: a weak statement with few seeds). With one run per group only the
  ordering is checked;
- ``none``: "not comparable" (the row's ``reason``).

This module owns the row file's schema, the extractors, the verdict rules and the table's text.
Imports numpy, scipy, `pdem.format` and the sibling analysis modules (files only).
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import integrate, stats

from .variability import student_t_quantile, variability

ROWS = Path("jobs/validation/rows.toml")
TABLE = Path("docs/validation_table.md")
VALUES_FORMAT = "pdem-validation-values"
CONFIDENCE = 0.95
FEW_SEEDS = 5
NOT_RUN = "not run here"
COMPARISONS = ("value", "scatter", "trend", "none")
TRENDS = ("increasing", "decreasing", "equal", "differ", "first_largest_last_smallest")


class ValidationError(Exception):
    """A row file or result file that cannot be used; the message is one line."""


# ---------------------------------------------------------------------------- samples
@dataclass(frozen=True)
class Sample:
    """pdem's number for one group: n runs (values when the file has them), mean, std, half CI."""

    label: str
    n: int
    mean: float
    std: float
    half: float
    values: tuple = ()
    sources: tuple = ()

    @property
    def low(self):
        return self.mean - self.half

    @property
    def high(self):
        return self.mean + self.half


def sample_of(values, label="", sources=()) -> Sample:
    """Mean, standard deviation and the t interval of the mean of the values (n ≥ 1)."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    if not v:
        raise ValidationError(f"{label or 'a group'}: no finite value in {', '.join(map(str, sources))}")
    if len(v) == 1:
        return Sample(label, 1, v[0], math.nan, math.nan, tuple(v), tuple(sources))
    s = variability(v, CONFIDENCE)
    return Sample(label, s.n, s.mean, s.std, s.mean - s.ci_low, tuple(v), tuple(sources))


def sample_from_summary(label, n, mean, std=None, half=None, sources=()) -> Sample:
    """A sample known by its n, mean and standard deviation or half interval (no values)."""
    n = int(n)
    t = student_t_quantile(0.5 + 0.5 * CONFIDENCE, n - 1) if n >= 2 else math.nan
    if std is None and half is not None and n >= 2:
        std = float(half) * math.sqrt(n) / t
    std = math.nan if std is None or n < 2 else float(std)
    half = t * std / math.sqrt(n) if n >= 2 else math.nan
    return Sample(label, n, float(mean), std, half, (), tuple(sources))


# ---------------------------------------------------------------------------- extractors
def _path(root, name):
    return Path(root) / name


def _read_text(root, spec):
    p = _path(root, spec["file"])
    if not p.is_file():
        return None, p
    return p.read_text(), p


def extract_text(spec, root):
    """``file`` and a regular expression ``pattern`` with named groups: ``value`` (the first match,
    or every match with ``all = true``: one value per run, or one group per match with ``labels``)
    or ``mean``, ``half``, ``n`` (a summary written by a campaign analysis), or ``v0``, ``v1``, ... and
    ``n`` (the means of several groups of n runs each, named by ``labels``; no interval)."""
    text, p = _read_text(root, spec)
    if text is None:
        return None
    pat = re.compile(spec["pattern"])
    matches = list(pat.finditer(text))
    if not matches:
        raise ValidationError(f"{p}: pattern {spec['pattern']!r} matches nothing")
    src = (str(spec["file"]),)
    if "value" in pat.groupindex:
        chosen = matches if spec.get("all") else matches[:1]
        values = [float(m.group("value")) for m in chosen]
        if "labels" in spec:  # one run per match, each its own group
            if len(spec["labels"]) != len(values):
                raise ValidationError(f"{p}: {len(values)} matches of {spec['pattern']!r} for "
                                      f"{len(spec['labels'])} labels")
            return [sample_of([v], label, src) for v, label in zip(values, spec["labels"], strict=True)]
        return [sample_of(values, spec.get("label", ""), src)]
    m = matches[0]
    if "v0" in pat.groupindex:  # one group mean per vK, all over n runs (a summary table's row)
        keys = sorted((k for k in pat.groupindex if re.fullmatch(r"v\d+", k)), key=lambda k: int(k[1:]))
        labels = spec.get("labels", keys)
        if len(labels) != len(keys):
            raise ValidationError(f"{p}: {len(keys)} groups v0.. in the pattern for {len(labels)} labels")
        return [sample_from_summary(label, int(m.group("n")), float(m.group(k)), sources=src)
                for k, label in zip(keys, labels, strict=True)]
    return [sample_from_summary(spec.get("label", ""), int(m.group("n")), float(m.group("mean")),
                                half=float(m.group("half")), sources=src)]


def extract_json(spec, root):
    """``file`` (JSON) and ``paths`` (dotted keys), one run each; ``labels`` name them."""
    p = _path(root, spec["file"])
    if not p.is_file():
        return None
    data = json.loads(p.read_text())
    out = []
    for key, label in zip(spec["paths"], spec.get("labels", spec["paths"]), strict=True):
        v = data
        for part in key.split("."):
            if not isinstance(v, dict) or part not in v:
                raise ValidationError(f"{p}: no {key}")
            v = v[part]
        out.append(sample_of([v], label, (str(spec["file"]),)))
    return out


def extract_campaign_txt(spec, root):
    """The per-member table of a committed ``analysis campaign`` report (``campaign.txt``):
    column ``quantity`` of the members whose columns match ``select``."""
    text, p = _read_text(root, spec)
    if text is None:
        return None
    lines = text.splitlines()
    try:
        start = lines.index("per member:") + 1
    except ValueError:
        raise ValidationError(f"{p}: no 'per member:' table") from None
    head = re.split(r"\s{2,}", lines[start].strip())
    if spec["quantity"] not in head:
        raise ValidationError(f"{p}: no column {spec['quantity']!r} (has {', '.join(head)})")
    col = head.index(spec["quantity"])
    values = []
    for line in lines[start + 1:]:
        cells = line.split()
        if len(cells) != len(head):
            break
        row = dict(zip(head, cells, strict=True))
        if all(row.get(k) == str(v) for k, v in spec.get("select", {}).items()):
            values.append(float(cells[col]))
    if not values:
        return []
    return [sample_of(values, spec.get("label", ""), (str(spec["file"]),))]


_PLATE = re.compile(r"^plate (\d+) kg/m\^2: (\d+) run")


def extract_blast_compare(spec, root):
    """``analysis blast``'s compare.txt: the ``quantity`` line (mean ± sample std) of ``plate``
    or of each of ``plates``."""
    text, p = _read_text(root, spec)
    if text is None:
        return None
    blocks, current = {}, None
    for line in text.splitlines():
        m = _PLATE.match(line)
        if m:
            current = int(m.group(1))
            blocks[current] = {"n": int(m.group(2))}
            continue
        m = re.match(r"^\s*(\S+) =\s+([0-9.eE+-]+) ± ([0-9.eE+-]+)", line)
        if m and current is not None:
            blocks[current][m.group(1)] = (float(m.group(2)), float(m.group(3)))
    plates = spec.get("plates", [spec.get("plate")])
    labels = spec.get("labels", [str(x) for x in plates])
    out = []
    for plate, label in zip(plates, labels, strict=True):
        b = blocks.get(int(plate))
        if b is None or spec["quantity"] not in b:
            raise ValidationError(f"{p}: no {spec['quantity']} for plate {plate}")
        mean, std = b[spec["quantity"]]
        out.append(sample_from_summary(label, b["n"], mean, std=std, sources=(str(spec["file"]),)))
    return out


def extract_campaign(spec, root):
    """A values file written by `refresh` (``file``): the ``quantity`` of the members matching
    ``select`` (one sample) or each of ``groups`` (labels ``labels``), times ``scale``."""
    p = _path(root, spec["file"])
    if not p.is_file():
        return None
    data = json.loads(p.read_text())
    if data.get("format") != VALUES_FORMAT:
        raise ValidationError(f"{p}: not a {VALUES_FORMAT} file")
    groups = spec.get("groups", [spec.get("select", {})])
    labels = spec.get("labels", [""] * len(groups))
    scale = float(spec.get("scale", 1.0))
    out = []
    for sel, label in zip(groups, labels, strict=True):
        members = [m for m in data["members"]
                   if all(m["params"].get(k) == v for k, v in sel.items())
                   and m["values"].get(spec["quantity"]) is not None]
        if not members:
            return None  # the group was not run (yet): the row says so
        out.append(sample_of([m["values"][spec["quantity"]] * scale for m in members], label,
                             tuple(m["results"] for m in members)))
    return out


def extract_none(spec, root):
    return []


EXTRACTORS = {"text": extract_text, "json": extract_json, "campaign_txt": extract_campaign_txt,
              "blast_compare": extract_blast_compare, "campaign": extract_campaign, "none": extract_none}


# ---------------------------------------------------------------------------- refresh from runs
def member_quantity(member, quantity):
    """One quantity of a finished campaign member, in SI units (or NaN)."""
    group, _, name = quantity.partition(".")
    if group == "oedometer":
        from .oedometer import analyse, read_oedometer

        r = analyse(read_oedometer(member.results_path).series)
        return {"unloading_kN_per_mm": r.unloading_stiffness * 1e-6, "loading_kN_per_mm": r.loading_stiffness * 1e-6,
                "u_max_mm": r.u_max * 1e3, "u_end_mm": r.u_end * 1e3}[name]
    if group == "grading":
        from pdem.format.groups import read_fragments

        from .grading import analyse_grading

        last = analyse_grading(read_fragments(member.results_path)).summaries[-1]
        return 100.0 * {"single_mass_percent": last.fraction_single, "large_mass_percent": last.fraction_large,
                        "single_count_percent": last.count_single, "large_count_percent": last.count_large}[name]
    if group == "checks":  # the measures of analysis.box_checks, NAME@CYCLE
        from . import box_checks

        fname, _, at = name.partition("@")
        cycle = int(at or 1)
        if fname == "within":
            return float(box_checks.within(member)[cycle - 1])
        return float({"sinking_after_peak": box_checks.sinking_after_peak, "rebound": box_checks.rebound,
                      "kept_fraction": box_checks.kept_fraction}[fname](member, cycle))
    if group == "track":  # a track run's /passages, NAME@PASSAGE, the mean over the sleepers [m]
        return track_quantity(member.results_path, name)
    from .campaign import Quantity

    return Quantity.parse(quantity).value(member)


TRACK_QUANTITIES = ("settlement_peak", "settlement_permanent", "settlement_at_max_load")


def track_quantity(path, name):
    """``NAME@PASSAGE`` (default passage 1) of a kind "track" result file, the mean over its
    sleepers, counted from the load start [m]: ``settlement_peak`` (the passage's largest
    settlement), ``settlement_permanent`` (at the passage's end), ``settlement_at_max_load``
    (at the sample of the largest ``/series/applied_load`` within the passage); NaN for a
    passage that does not exist."""
    from pdem.format.groups import read_track

    fname, _, at = name.partition("@")
    if fname not in TRACK_QUANTITIES:
        raise ValidationError(f"track.{name}: must be track.NAME@PASSAGE with NAME one of "
                              f"{', '.join(TRACK_QUANTITIES)}")
    rec = read_track(path)
    p = rec.passages
    k = int(at or 1) - 1
    if not 0 <= k < len(p["passage"]):
        return math.nan
    if fname != "settlement_at_max_load":
        return float(np.mean(p[fname][k]))
    t, load = rec.results.series["time"], rec.results.series["applied_load"]
    inside = np.flatnonzero((t >= p["t_start"][k]) & (t <= p["t_end"][k]))
    if inside.size == 0:
        return math.nan
    return float(np.mean(rec.settlement[inside[np.argmax(load[inside])]]))



def merged_members(old, new, campaign):
    """The members of a values file: ``new`` (the finished members found under runs/) and those
    of the ``old`` file (or None) that are not among them but still belong to the campaign with
    the same parameters (run on another machine or in an earlier session, whose result files
    are not here), in the campaign's member order; ``campaign`` lists (name, params)."""
    by_name = {m["name"]: m for m in (old or {}).get("members", [])}
    by_name.update({m["name"]: m for m in new})  # (a fresh member has the campaign's parameters)
    return [by_name[name] for name, params in campaign if name in by_name and by_name[name]["params"] == params]


def refresh(rows, root) -> list[Path]:
    """Rewrite the values file of every ``campaign`` row whose campaign directory has finished
    members; members the file already holds and that are not finished here stay (`merged_members`)."""
    from .campaign import read_campaign

    wanted = {}
    for row in rows:
        spec = row["pdem"]
        if spec.get("extractor") == "campaign" and spec.get("runs"):
            wanted.setdefault((spec["runs"], spec["file"]), set()).add(spec["quantity"])
    written = []
    for (runs, file), quantities in sorted(wanted.items()):
        d = _path(root, runs)
        if not (d / "campaign.json").is_file():
            continue
        camp = read_campaign(d)
        if not camp.done:
            continue
        members = []
        for m in camp.done:
            values = {}
            for q in sorted(quantities):
                v = member_quantity(m, q)
                values[q] = v if math.isfinite(v) else None
            members.append({"name": m.name, "params": m.params,
                            "results": str(Path(runs) / m.dir.name / "results.h5"), "values": values})
        out = _path(root, file)
        previous = out.read_text() if out.is_file() else None
        members = merged_members(json.loads(previous) if previous else None, members,
                                 [(m.name, m.params) for m in camp.members])
        done = {m["name"] for m in members}
        data = {"format": VALUES_FORMAT, "campaign": camp.name, "runs": runs,
                "not_done": [m.name for m in camp.members if m.name not in done], "members": members}
        out.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps(data, indent=1) + "\n"
        if text != previous:
            out.write_text(text)
        written.append(out)
    return written


# ---------------------------------------------------------------------------- verdicts
def anova(samples):
    """p of a one-way ANOVA from the groups' n, mean and std (None if a group has n < 2)."""
    if any(s.n < 2 or not math.isfinite(s.std) for s in samples) or len(samples) < 2:
        return None
    n = np.array([s.n for s in samples], float)
    m = np.array([s.mean for s in samples])
    sd = np.array([s.std for s in samples])
    grand = float((n * m).sum() / n.sum())
    k, total = len(samples), n.sum()
    between = float((n * (m - grand) ** 2).sum()) / (k - 1)
    within = float(((n - 1) * sd ** 2).sum()) / (total - k)
    if within == 0.0:
        return 0.0 if between > 0 else 1.0
    return float(stats.f.sf(between / within, k - 1, total - k))


def expected_range(n: int) -> float:
    """d₂(n): the expected range of n independent standard normal values."""
    def integrand(x):
        phi = stats.norm.cdf(x)
        return 1.0 - phi ** n - (1.0 - phi) ** n
    return float(integrate.quad(integrand, -np.inf, np.inf)[0])


def scatter_interval(sample: Sample, n_runs: int):
    """(pdem's own (max − min)/mean, 95 % interval of d₂(n_runs) σ/mean from the χ² interval of σ)."""
    own = (max(sample.values) - min(sample.values)) / sample.mean
    dof = sample.n - 1
    lo = sample.std * math.sqrt(dof / stats.chi2.ppf(0.5 + 0.5 * CONFIDENCE, dof))
    hi = sample.std * math.sqrt(dof / stats.chi2.ppf(0.5 - 0.5 * CONFIDENCE, dof))
    d2 = expected_range(n_runs)
    return own, (d2 * lo / sample.mean, d2 * hi / sample.mean)


def _ordered(means, trend):
    d = np.diff(means)
    if trend == "increasing":
        return bool(np.all(d > 0))
    if trend == "decreasing":
        return bool(np.all(d < 0))
    if trend == "first_largest_last_smallest":
        return bool(means[0] == max(means) and means[-1] == min(means))
    return True


def _differs(row):
    status = row.get("explanation", {}).get("status", "untested")
    return f"differs, explanation {status}"


@dataclass
class RowResult:
    """One evaluated row: the text of pdem's cell, the numbers in it, the verdict."""

    row: dict
    samples: list | None
    spec: dict = field(default_factory=dict)  # the [row.pdem] or [[row.fallback]] that gave the samples
    cell: str = NOT_RUN
    numbers: list = field(default_factory=list)
    verdict: str = ""
    rule: str = ""


def fmt(x) -> str:
    """A number as the table writes it (4 significant digits; integers as such)."""
    if isinstance(x, int):
        return str(x)
    return f"{x:.4g}"


def _sample_text(s: Sample, numbers):
    if s.n >= 2 and not math.isfinite(s.half):  # a mean from a summary without its spread
        numbers += [s.mean, s.n]
        return f"{fmt(s.mean)} (mean of n = {s.n}; no interval in the file)"
    if s.n >= 2:
        numbers += [s.mean, s.half, s.n]
        return f"{fmt(s.mean)} ± {fmt(s.half)} (n = {s.n})"
    numbers += [s.mean, s.n]
    return f"{fmt(s.mean)} (n = {s.n})"


def evaluate(row, root) -> RowResult:
    """Extract pdem's numbers of a row and compute its verdict."""
    samples, used = None, None
    for spec in [row["pdem"]] + list(row.get("fallback", [])):
        try:
            samples = EXTRACTORS[spec["extractor"]](spec, root)
        except KeyError as err:
            raise ValidationError(f"row {row['id']}: {err} missing or unknown (extractors: "
                                  f"{', '.join(EXTRACTORS)})") from None
        used = spec
        if samples is not None:
            break
    spec = used if samples is not None else row["pdem"]
    res = RowResult(row, samples, spec=spec)
    kind = row["comparison"]
    if samples is None or (not samples and spec["extractor"] != "none"):
        res.verdict = "not comparable" if kind == "none" else f"{NOT_RUN}: no verdict"
        res.rule = row.get("reason", "")
        return res
    numbers = []
    if not samples:
        res.cell = "–"
    elif kind == "trend" or len(samples) > 1:
        parts = [f"{s.label} → {_sample_text(s, numbers)}" for s in samples]
        res.cell = "; ".join(parts)
    else:
        res.cell = _sample_text(samples[0], numbers)
    if kind == "none":
        res.verdict, res.rule = "not comparable", row["reason"]
    elif kind == "value":
        s, seed = samples[0], float(row["seed"])
        has_ci = s.n >= 2 and math.isfinite(s.half)
        in_ci = has_ci and s.low <= seed <= s.high
        rng = row.get("seed_range")
        in_range = rng is not None and rng[0] <= s.mean <= rng[1]
        res.verdict = "agrees within scatter" if in_ci or in_range else _differs(row)
        res.rule = ("seed inside pdem's 95 % CI" if in_ci else "pdem's mean inside the seed's range" if in_range else
                    "seed outside pdem's 95 % CI" + (" and pdem's mean outside the seed's range" if rng else "")
                    if has_ci else "no CI (one run, or a mean without its spread)"
                    + ("; pdem outside the seed's range" if rng else ""))
    elif kind == "scatter":
        s, n_runs = samples[0], int(row.get("seed_n", 10))
        own, (lo, hi) = scatter_interval(s, n_runs)
        numbers += [own, lo, hi]
        res.cell += f"; (max − min)/mean {fmt(own)}, expected for {n_runs} runs {fmt(lo)}–{fmt(hi)}"
        numbers.append(n_runs)
        ok = lo <= float(row["seed"]) <= hi
        res.verdict = "agrees within scatter" if ok else _differs(row)
        res.rule = f"seed {'inside' if ok else 'outside'} the 95 % interval of d₂({n_runs}) σ/mean"
    else:
        trend = row["trend"]
        if trend not in TRENDS:
            raise ValidationError(f"row {row['id']}: trend = {trend!r}: must be one of {', '.join(TRENDS)}")
        means = [s.mean for s in samples]
        ordered = _ordered(means, trend)
        p = anova(samples)
        if p is not None:
            numbers.append(p)
            res.cell += f"; ANOVA p = {fmt(p)}"
        if trend == "equal":
            ok = p is not None and p >= 0.05
            rule = "no difference detected (ANOVA p ≥ 0.05)" if ok else "groups differ (ANOVA p < 0.05)"
        elif trend == "differ":
            ok = p is not None and p < 0.05
            rule = "groups differ (ANOVA p < 0.05)" if ok else "no difference detected (ANOVA p ≥ 0.05)"
        else:
            ok = ordered and (p is None or p < 0.05)
            rule = (f"means {'in' if ordered else 'not in'} the stated order ({trend.replace('_', ' ')})"
                    + ("" if p is None else "; ANOVA p < 0.05" if p < 0.05 else "; ANOVA p ≥ 0.05"))
        if p is None and trend in ("equal", "differ"):
            rule = "no spread per group in the file: no test"
        if p is None and ok:
            rule += "; no spread per group in the file: ordering only"
        res.verdict = "agrees within scatter" if ok else _differs(row)
        res.rule = rule
    res.numbers = numbers
    return res


# ---------------------------------------------------------------------------- table
def _cell(text) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _made_by(row, res):
    spec = res.spec or row["pdem"]
    parts = [f"`{row['campaign']}`"]
    if spec is not row["pdem"]:
        parts.append(f"not run here yet; the committed fallback ({spec.get('note', 'an earlier campaign')}) is shown")
    if spec["extractor"] != "none":
        sources = sorted({src for s in (res.samples or []) for src in s.sources})
        if sources:
            files = sources if len(sources) <= 2 else [spec["file"]]
            parts.append("files: " + ", ".join(f"`{f}`" for f in files)
                         + (f" (+{len(sources) - 2} more)" if len(sources) > 2 else ""))
        else:  # not run: the file it would write is named without a link (it does not exist yet)
            parts.append(f"its values file once run: {spec['file']}")
        parts.append(f"extractor `{spec['extractor']}`" + (f" `{spec['quantity']}`" if "quantity" in spec else ""))
    parts.append(f"cost: {row['cost']}")
    n = min((s.n for s in res.samples), default=0) if res.samples else 0
    if res.samples and n < FEW_SEEDS:
        why = row.get("few_seeds") or (spec.get("note") if spec is not row["pdem"] else None) or "fewer seeds finished"
        parts.append(f"**n < {FEW_SEEDS}**: {why}")
    return "; ".join(parts)


def table_lines(results, rows_file) -> list[str]:
    n_num = sum(1 for r in results if r.samples)
    counts = {}
    for r in results:
        key = r.verdict.split(":")[0]
        counts[key] = counts.get(key, 0) + 1
    lines = [
        "# Validation table (generated)",
        "",
        f"Generated by `python -m analysis validate` (`make validate`) from `{rows_file}` and the result files "
        "named in each row; do not edit by hand (docs/validation.md explains the method). pdem's number is the "
        f"mean ± the Student-t {CONFIDENCE:.0%} interval of the mean over the n runs (seeds) found; "
        f"\"{NOT_RUN}\" means the result file is absent here and the campaign file in the same row makes it.",
        "",
        f"{len(results)} rows; {n_num} with pdem's numbers; verdicts: "
        + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + ".",
        "",
        "| # | seed: where, exact words | seed's number | pdem: mean ± 95 % CI (n) | made by | "
        "differences from the seed's setup | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(results, 1):
        row = r.row
        seed = (f"{row['seed']:g}" + (f" ({row['seed_range'][0]:g}–{row['seed_range'][1]:g})"
                                      if row.get("seed_range") else "")
                + (f" {row['unit']}" if row.get("unit") and row["unit"] != "-" else "")) if "seed" in row else (
            f"trend: {row['trend'].replace('_', ' ')}" if row["comparison"] == "trend" else "–")
        words = f"**{row['title']}** — {row['where']}: „{row['quote']}“ ({row['english']})"
        cell = r.cell + (f" [{row['unit']}]" if r.samples and row.get("unit") and row["unit"] != "-" else "")
        diffs = "; ".join(row.get("differences", [])) or "–"
        verdict = f"**{r.verdict}**" + (f": {r.rule}" if r.rule else "")
        expl = row.get("explanation")
        if expl and r.verdict.startswith("differs"):
            verdict += f". Explanation ({expl['status']}): {expl['text']}"
        lines.append("| " + " | ".join(_cell(c) for c in
                                         (f"{i} `{row['id']}`", words, seed, cell, _made_by(row, r), diffs, verdict))
                     + " |")
    return lines


def read_rows(path) -> list[dict]:
    """The rows of a row file, checked for the keys the table needs (ValidationError names the row)."""
    path = Path(path)
    try:
        rows = tomllib.loads(path.read_text()).get("row", [])
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ValidationError(f"{path}: {' '.join(str(err).split())}") from None
    seen = set()
    for i, row in enumerate(rows):
        rid = row.get("id", f"#{i + 1}")
        for key in ("id", "title", "where", "quote", "english", "comparison", "campaign", "cost", "pdem"):
            if key not in row:
                raise ValidationError(f"{path}: row {rid}: {key} is missing")
        if rid in seen:
            raise ValidationError(f"{path}: row {rid}: id used twice")
        seen.add(rid)
        if row["comparison"] not in COMPARISONS:
            raise ValidationError(f"{path}: row {rid}: comparison = {row['comparison']!r}: must be one of "
                                  f"{', '.join(COMPARISONS)}")
        if row["comparison"] in ("value", "scatter") and "seed" not in row:
            raise ValidationError(f"{path}: row {rid}: comparison {row['comparison']} needs seed")
        if row["comparison"] == "none" and "reason" not in row:
            raise ValidationError(f"{path}: row {rid}: comparison none needs reason")
        status = row.get("explanation", {}).get("status", "untested")
        if status not in ("tested", "untested"):
            raise ValidationError(f"{path}: row {rid}: explanation.status = {status!r}: must be tested or untested")
        for where, spec in [("pdem", row["pdem"])] + [("fallback", f) for f in row.get("fallback", [])]:
            if spec.get("extractor") not in EXTRACTORS:
                raise ValidationError(f"{path}: row {rid}: {where}.extractor = {spec.get('extractor')!r}: "
                                      f"must be one of {', '.join(EXTRACTORS)}")
    return rows


def build(rows_file=ROWS, root=".", do_refresh=True):
    """(rows, results, refreshed files) for the row file, reading files under ``root``."""
    rows = read_rows(_path(root, rows_file) if not Path(rows_file).is_absolute() else rows_file)
    refreshed = refresh(rows, root) if do_refresh else []
    return rows, [evaluate(r, root) for r in rows], refreshed


def write_table(rows_file=ROWS, out=TABLE, root=".", do_refresh=True) -> list[Path]:
    _, results, refreshed = build(rows_file, root, do_refresh)
    out = _path(root, out) if not Path(out).is_absolute() else Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(table_lines(results, rows_file)) + "\n")
    return refreshed + [out]


# ---------------------------------------------------------------------------- cost projection
@dataclass(frozen=True)
class CostProjection:
    """A short run's measured rate and the cost of the steps a full run needs."""

    steps_done: int
    wall_s: float          # wall time of the short run [s]
    ranks: int
    dt_last: float         # the short run's last time step [s]
    steps_needed: float
    wall_needed_s: float   # projected wall time [s]
    core_hours: float      # projected wall x ranks [h]

    def lines(self):
        rate = self.steps_done / self.wall_s
        return [f"measured: {self.steps_done} steps in {self.wall_s:.1f} s wall on {self.ranks} rank(s): "
                f"{rate:.4g} steps/s (last dt {self.dt_last:.4g} s)",
                f"projected: {self.steps_needed:.4g} steps: {self.wall_needed_s / 3600:.3g} h wall, "
                f"{self.core_hours:.3g} core-h"]


def project(steps_done, wall_s, ranks, steps_needed, dt_last=math.nan) -> CostProjection:
    """Measured steps/s x the steps needed (wall) and x ranks (core-hours)."""
    if steps_done <= 0 or wall_s <= 0:
        raise ValidationError(f"a short run of {steps_done} steps in {wall_s} s cannot be projected")
    wall = float(steps_needed) * float(wall_s) / float(steps_done)
    return CostProjection(int(steps_done), float(wall_s), int(ranks), float(dt_last), float(steps_needed), wall,
                          wall * ranks / 3600.0)


_PROGRESS = re.compile(r"^(?:stage \d+/\d+ (?P<stage>\S+)\s+)?step\s+(?P<step>\d+)\s+t = \S+ s\s+dt = (?P<dt>\S+) s"
                       r".*?(?P<rate>[0-9.]+) M particle-steps/s")
_STAGE_START = re.compile(r"^stage (?P<stage>\S+)(?: \(resumed\))?: (?P<n>\d+) spheres, t = ")
_STAGE_DONE = re.compile(r"^stage (?P<stage>\S+) done at t = \S+ s, step (?P<step>\d+)")
_RANKS = re.compile(r" on (?P<ranks>\d+) rank\(s\)")


def stopped_run_rate(run_dir, stage=None):
    """(steps, wall [s], ranks, last Δt [s], stage) measured by a run that was stopped (``timeout
    -s TERM``, a SLURM time limit: no run_info.json) from its log.txt, the last invocation's: the
    last progress line of ``stage`` (default: the last stage with one) gives the stage's rate in
    particle-steps/s since its first step (numba's compilation excluded), the stage's line its
    spheres, and the steps since the stage began (0, or the previous stage's end); the wall time
    is those steps at that rate. Needs ``run.progress_every`` > 0."""
    log = Path(run_dir) / "log.txt"
    if not log.is_file():
        raise ValidationError(f"{run_dir}: neither run_info.json (a finished run) nor log.txt (a stopped one)")
    lines = log.read_text(errors="replace").splitlines()
    starts = [k for k, line in enumerate(lines) if line.startswith("# pdem ")]
    lines = lines[starts[-1]:] if starts else lines
    ranks, spheres, begin, last, done = 1, {}, {}, {}, 0
    for line in lines:
        if m := _RANKS.search(line):
            ranks = int(m["ranks"])
        if m := _STAGE_START.match(line):
            spheres[m["stage"]] = int(m["n"])
            begin[m["stage"]] = done
        elif m := _STAGE_DONE.match(line):
            done = int(m["step"])
        elif (m := _PROGRESS.match(line)) and m["stage"]:
            last[m["stage"]] = (int(m["step"]), float(m["dt"]), float(m["rate"]) * 1e6)
    name = stage if stage is not None else (list(last)[-1] if last else None)
    if name not in last or name not in spheres:
        raise ValidationError(f"{log}: no progress line of stage {name!r} (run.progress_every > 0 prints them)")
    step, dt, rate = last[name]
    steps = step - begin[name]
    return steps, steps * spheres[name] / rate, ranks, dt, name


def project_run(run_dir, steps=None, simulated_time=None, stage=None) -> CostProjection:
    """The projection from a short run: the steps and wall time of one finished stage (``stage``,
    default the last one) from its run_info.json, its ranks, and the last Δt of its results.h5
    series; the steps needed are ``steps`` or ``simulated_time`` / that Δt. A stopped run (no
    run_info.json): the rate of its log's last progress line (`stopped_run_rate`)."""
    from pdem.format.read import read_results

    run_dir = Path(run_dir)
    info_path = run_dir / "run_info.json"
    if not info_path.is_file():
        done, wall, ranks, dt_last, _ = stopped_run_rate(run_dir, stage)
        if steps is None:
            if simulated_time is None:
                raise ValidationError("give --steps or --simulated-time")
            steps = simulated_time / dt_last
        return project(done, wall, ranks, steps, dt_last)
    info = json.loads(info_path.read_text())
    stages = info.get("stages") or []
    names = [st["stage"] for st in stages]
    if not stages or (stage is not None and stage not in names):
        raise ValidationError(f"{info_path}: stage {stage!r} not finished (finished: {', '.join(names) or 'none'})")
    k = names.index(stage) if stage is not None else len(stages) - 1
    before = stages[k - 1]["step_end"] if k > 0 else 0
    done, wall = int(stages[k]["step_end"] - before), float(stages[k]["wall_s"])
    r = read_results(run_dir / "results.h5", lenient=True)
    dt_last = float(r.series["dt"][-1]) if r is not None and "dt" in r.series and len(r.series["dt"]) else math.nan
    if steps is None:
        if simulated_time is None or not math.isfinite(dt_last):
            raise ValidationError("give --steps or --simulated-time (with a /series/dt in the run)")
        steps = simulated_time / dt_last
    return project(done, wall, int(info.get("ranks", 1)), steps, dt_last)


def add_cost_parser(sub) -> None:
    p = sub.add_parser(
        "cost", help="project a campaign member's cost from a short run",
        description="Measured steps/s of one stage of a short run (its run_info.json; e.g. a member with one "
                    "load cycle instead of ten; or a run stopped by a signal: its log.txt's last progress line) x "
                    "the steps a full run needs: wall time and core-hours.")
    p.add_argument("results", type=Path, metavar="RUN_DIR", help="the short run's directory")
    p.add_argument("--steps", type=float, help="steps the full run needs")
    p.add_argument("--simulated-time", type=float, metavar="S", help="or: simulated time it needs (÷ last Δt)")
    p.add_argument("--stage", help="the stage whose rate is measured (default: the last finished)")

    def run(a):
        proj = project_run(a.results, a.steps, a.simulated_time, a.stage)
        print("\n".join(proj.lines()))
        return []
    p.set_defaults(run=run)


def add_parser(sub) -> None:
    add_cost_parser(sub)
    p = sub.add_parser(
        "validate", help="the validation table: pdem against the seeds' figures and tables",
        description="Read the row list and the result files it names (refreshing committed values files from "
                    "campaign directories under runs/ that hold finished members) and write the table.")
    p.add_argument("--rows", type=Path, default=ROWS, help="row file (default: %(default)s)")
    p.add_argument("--out", type=Path, default=TABLE, help="table (default: %(default)s)")
    p.add_argument("--root", type=Path, default=Path("."), help="repository root the paths are relative to")
    p.add_argument("--no-refresh", action="store_true", help="use the committed values files only")
    p.set_defaults(run=lambda a: write_table(a.rows, a.out, a.root, not a.no_refresh), results=[])
