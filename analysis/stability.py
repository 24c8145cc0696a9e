"""Stability map: did every member of one or more campaigns run stably or stop naming the cause?

``python -m analysis stability DIR [DIR ...] [--out OUT] [--tolerance 0.1]`` reads each campaign
directory (``campaign.json`` and the members' ``run.json``, ``pdem.log`` and output files, as
written by ``pdem campaign``) and gives every member one verdict (SPEC.md 4, "Stability"):

- ``stable``: the run ended with exit status 0, and, where the run records its energies and does
  no external work, the energy balance holds (below);
- ``stopped``: exit status 4 with pdem's one-line message (``pdem: unstable: step K: ...``) naming
  the step, the body or quantity and the cause;
- ``FAILED``: anything else that ended: exit status 1 (a bug), 2 (bad input), 5 (the system), 4
  without a message, a stable run whose energy rose beyond the tolerance, a NaN or infinity in any
  output, or an outcome other than the one the campaign expects for the case;
- ``incomplete`` (stopped on a signal, exit 3, or interrupted) and ``pending`` (never run): the
  map is not finished.

The map passes (exit status 0 of the command) only if every member is stable or stopped, as
expected, with no non-finite value anywhere; otherwise the command exits with status 1 after
writing its report.

Energy balance of a run without external work (root attribute ``external_work`` = 0 of the
results file, /series ``total_energy`` [J]: kinetic + rotational + potential + elastic,
synchronised to the positions as `pdem.checks.diagnostics.energy` does): the total mechanical energy E
can only fall (damping, friction). Its largest rise above its previous minimum,
G = max_t (E(t) - min_{s<=t} E(s)), is compared with the largest kinetic + elastic energy of the
run, S = max_t (K + U_el): the balance holds if G <= tolerance * S (default 10 %). A stable
leapfrog step keeps E within a few per cent of S through the hardest impacts (friction and
contacts opening break the exact conservation of its shadow energy: 3 % measured in the small
undamped case of the map); an unstable one makes it grow without bound (the map's case with a
fixed Δt 3 times the stable one gained 51 % of S in 500 steps before pdem stopped it). Sampled
at the output steps only. Also reported: the energy dissipated, E(0) - E(end), as a fraction
of the energy released into motion, E(0) - P(end) (potential energy lost plus the initial
kinetic and elastic energy). If the series holds ``external_work`` [J] (work done on the system
by boundaries and loads, cumulative), the balance is checked on E - W instead; a run with
external work and no such column is reported as "not checked".

Non-finite values: every dataset and every numeric attribute of every HDF5 file under a member's
directory (results, checkpoints, snapshots, ...), the float values of JSON attributes and JSON
files, and the numbers of its text files (``*.txt``, ``*.log``, ``*.xmf``) are scanned for NaN and
infinities; any is a failure.

Writes into OUT (default ``DIR/analysis`` for one directory; required for several):
``stability.txt`` (one line per member, then the table), ``stability.md`` (the table in
markdown), ``stability.json`` and ``stability.png`` (the energy rise per member against the
tolerance, and E(t) - E(0) over S per member against its fraction of the run).

Expected outcomes: the campaign file's ``[analysis] expect = {case = "stable" | "stopped"}``
(copied to the manifest) names what each case must do. The log's attempt marker is the one
`pdem.format.campaign` names (``=== pdem campaign: attempt``). Imports numpy, h5py (to scan every
HDF5 file of a member), `pdem.format` and, for the plot, matplotlib.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from pdem.format.campaign import ATTEMPT_MARK, LOG, read_run
from pdem.format.read import read_results

from .campaign import CampaignError, read_campaign
from .figures import save

TOLERANCE = 0.10          # largest rise of the mechanical energy over the largest kinetic+elastic [-]
VERDICTS = ("stable", "stopped", "FAILED", "incomplete", "pending")
EXPECTABLE = ("stable", "stopped")
TEXT_SUFFIXES = (".txt", ".log", ".xmf")
_NONFINITE_WORD = re.compile(r"(?<![A-Za-z0-9_.])[-+]?(nan|inf|infinity)(?![A-Za-z0-9_])", re.IGNORECASE)
_STEP = re.compile(r"^step (\d+): ")


@dataclass
class Verdict:
    """What one member did: ``verdict`` one of VERDICTS, ``line`` its sentence."""

    campaign: str
    member: str
    case: str
    exit: int | None
    verdict: str
    line: str
    expected: str | None = None
    steps: int | None = None
    time: float | None = None
    energy: dict | None = None
    nonfinite: list = field(default_factory=list)
    message: str = ""
    dir: Path | None = None

    @property
    def ok(self):
        return self.verdict in EXPECTABLE


# ---------------------------------------------------------------------------- non-finite values
def _count(a):
    """(NaN count, infinity count) of a numeric array (0, 0 for other types)."""
    a = np.asarray(a)
    if a.dtype.names:
        n = [_count(a[k]) for k in a.dtype.names]
        return sum(x for x, _ in n), sum(y for _, y in n)
    if a.dtype.kind not in "fc":
        return 0, 0
    return int(np.count_nonzero(np.isnan(a))), int(np.count_nonzero(np.isinf(a)))


def _json_counts(value):
    """(NaN, inf) among the floats of a decoded JSON value."""
    if isinstance(value, float):
        return int(math.isnan(value)), int(math.isinf(value))
    items = value.values() if isinstance(value, dict) else value if isinstance(value, list) else ()
    n = i = 0
    for v in items:
        a, b = _json_counts(v)
        n, i = n + a, i + b
    return n, i


def _attr_counts(value):
    if isinstance(value, (bytes, str)):
        text = value.decode(errors="replace") if isinstance(value, bytes) else value
        if text[:1] in "[{":
            try:
                return _json_counts(json.loads(text))
            except ValueError:
                return 0, 0
        return 0, 0
    try:
        return _count(value)
    except (TypeError, ValueError):
        return 0, 0


def scan_hdf5(path):
    """[(where, NaN count, inf count)] of every dataset and attribute of one HDF5 file holding a
    non-finite value; an unreadable file is one entry with count -1."""
    found = []
    try:
        with h5py.File(path, "r") as f:
            def visit(name, obj):
                where = "/" + name if name else "/"
                for key, value in obj.attrs.items():
                    n, i = _attr_counts(value)
                    if n or i:
                        found.append((f"{where} attribute {key}", n, i))
                if isinstance(obj, h5py.Dataset):
                    n, i = _count(obj[()])
                    if n or i:
                        found.append((where, n, i))

            visit("", f)
            f.visititems(visit)
    except OSError as err:
        found.append((f"cannot be read ({' '.join(str(err).split())})", -1, -1))
    return found


def scan_text(path):
    """[(where, NaN count, inf count)] of a text or JSON file holding a non-finite number."""
    text = path.read_text(errors="replace")
    if path.suffix == ".json":
        try:
            n, i = _json_counts(json.loads(text))
        except ValueError:
            return []
        return [("", n, i)] if n or i else []
    out = []
    for k, line in enumerate(text.splitlines(), 1):
        words = [m.group(1).lower() for m in _NONFINITE_WORD.finditer(line)]
        if words:
            out.append((f"line {k}: {line.strip()[:120]}", words.count("nan"), len(words) - words.count("nan")))
    return out


def scan_member(d):
    """[(file relative to d, where, NaN count, inf count)] over every output of member directory d."""
    d = Path(d)
    found = []
    for p in sorted(d.rglob("*")):
        if not p.is_file() or p.name.startswith("."):
            continue
        if h5py.is_hdf5(p):
            hits = scan_hdf5(p)
        elif p.suffix in TEXT_SUFFIXES + (".json",):
            hits = scan_text(p)
        else:
            continue
        found += [(str(p.relative_to(d)), w, n, i) for w, n, i in hits]
    return found


# ---------------------------------------------------------------------------- energy balance
def energy_balance(series, attrs, tolerance=TOLERANCE):
    """The energy balance of one run's /series (dict of arrays) and root attributes: a dict with
    ``checked`` (bool), ``reason`` (why not), ``rise`` G [J], ``scale`` S [J], ``rise_ratio`` G/S,
    ``dissipated`` [J], ``released`` [J], ``ok``; or with ``checked`` False."""
    if "total_energy" not in series:
        return {"checked": False, "ok": True, "reason": "no total_energy in the results (not recorded by this kind "
                                                         "of run)"}
    work = series.get("external_work")
    if work is None and int(attrs.get("external_work", 1)) != 0:
        why = ("boundaries move or loads act" if "external_work" in attrs else
               "the results do not say whether boundaries move or loads act")
        return {"checked": False, "ok": True, "reason": f"external work ({why}) and no external_work record"}
    e = np.asarray(series["total_energy"], float)
    if len(e) == 0:
        return {"checked": False, "ok": True, "reason": "no samples"}
    if work is not None:
        e = e - np.asarray(work, float)
    k = np.asarray(series.get("kinetic_energy", np.zeros_like(e)), float)
    el = np.asarray(series.get("elastic_energy", np.zeros_like(e)), float)
    pot = np.asarray(series.get("potential_energy", e - k - el), float)
    rise = float(np.max(e - np.minimum.accumulate(e)))
    at = int(np.argmax(e - np.minimum.accumulate(e)))
    scale = float(np.max(k + el))
    ratio = rise / scale if scale > 0 else (0.0 if rise == 0 else math.inf)
    released = float(e[0] - pot[-1])
    return {"checked": True, "ok": bool(ratio <= tolerance), "tolerance": tolerance, "rise": rise,
            "rise_ratio": ratio, "rise_step": int(series["step"][at]) if "step" in series else at, "scale": scale,
            "dissipated": float(e[0] - e[-1]), "released": released, "initial": float(e[0]), "final": float(e[-1]),
            "work": work is not None}


def _balance_text(b):
    if not b["checked"]:
        return f"energy balance not checked: {b['reason']}"
    tol = f"tolerance {100 * b['tolerance']:g} %"
    rise = (f"the mechanical energy never rose (tolerance {100 * b['tolerance']:g} %)" if b["rise"] <= 0 else
            f"the mechanical energy rose at most {_pct(b['rise_ratio'])} of the largest kinetic+elastic energy "
            f"{b['scale']:.3g} J ({tol})")
    if b["released"] > 0:
        share = _pct(b["dissipated"] / b["released"])
        spent = f"{b['dissipated']:.3g} J of the {b['released']:.3g} J released dissipated ({share})"
    else:
        spent = f"{b['dissipated']:.3g} J dissipated"
    return f"energy balance: {rise}; {spent}" + (" (net of the external work)" if b["work"] else "")


def _pct(x):
    if not np.isfinite(x):
        return str(x)
    return f"{100 * x:.2g} %" if abs(x) < 0.1 else f"{100 * x:.3g} %"


# ---------------------------------------------------------------------------- one member
def last_message(d):
    """The last ``pdem: unstable``/``pdem: error`` line of the member's last attempt ('' if none)."""
    try:
        text = (Path(d) / LOG).read_text(errors="replace")
    except FileNotFoundError:
        return ""
    lines = [x.strip() for x in text.rsplit(ATTEMPT_MARK, 1)[-1].splitlines()[1:]]
    tagged = [x for x in lines if x.startswith(("pdem: unstable", "pdem: error", "pdem: internal error"))]
    return tagged[-1] if tagged else ""


def _read_series(d):
    """(series dict, root attrs) of d/results.h5 (empty if missing or not a valid result)."""
    r = read_results(d, lenient=True)
    return ({}, {}) if r is None else (r.series, r.attrs)


def _facts(series):
    """Short facts of the run from its series: steps, simulated time, largest overlap, contacts."""
    out = []
    if "max_overlap_ratio" in series and len(series["max_overlap_ratio"]):
        out.append(f"largest overlap {float(np.max(series['max_overlap_ratio'])):.3g} of the smaller radius")
    if "contacts_per_particle" in series and len(series["contacts_per_particle"]):
        out.append(f"up to {float(np.max(series['contacts_per_particle'])):.3g} contacts per particle")
    if "step" in series and len(series["step"]):
        out.append(f"{int(series['step'][-1])} steps, {float(series['time'][-1]):.4g} s")
    return "; ".join(out)


def judge_member(campaign, member, tolerance=TOLERANCE, expected=None):
    """The `Verdict` of one member (`analysis.campaign.Member`) of campaign named ``campaign``."""
    d = member.dir
    case = str(member.params.get("case", ""))
    attempts = (read_run(d) or {}).get("attempts", [])
    v = Verdict(campaign=campaign, member=member.name, case=case, exit=None, verdict="pending",
                line="pending: never run", expected=expected, dir=Path(d))
    if not attempts:
        return v
    last = attempts[-1]
    v.exit = last.get("exit")
    series, attrs = _read_series(d)
    if "step" in series and len(series["step"]):
        v.steps, v.time = int(series["step"][-1]), float(series["time"][-1])
    v.nonfinite = scan_member(d)
    v.message = last_message(d)
    facts = _facts(series)
    if last.get("end") is None or v.exit == 3:
        v.verdict = "incomplete"
        v.line = ("incomplete: stopped on a signal (exit 3) at step " + (str(v.steps) if v.steps is not None else "?")
                  + "; run the campaign again to finish it") if v.exit == 3 else \
            "incomplete: running, or interrupted (no exit status recorded); run the campaign again to finish it"
        if series:  # what the recorded part shows
            v.energy = energy_balance(series, attrs, tolerance)
            v.line += f" (so far: {_balance_text(v.energy)}" + (f"; {facts}" if facts else "") + ")"
    elif v.exit == 0:
        b = energy_balance(series, attrs, tolerance) if series else {"checked": False, "ok": False,
                                                                    "reason": "no results.h5 with a /series"}
        v.energy = b
        if not b["ok"]:
            v.verdict = "FAILED"
            v.line = (f"FAILED: ran to the end, but the mechanical energy rose by {_pct(b['rise_ratio'])} of the "
                      f"largest kinetic+elastic energy (more than the tolerance {100 * tolerance:g} %) "
                      f"{'beyond the external work' if b['work'] else 'without external work'}, at step "
                      f"{b['rise_step']}: an instability pdem did not stop"
                      if b.get("checked") else f"FAILED: ran to the end, but {b['reason']}")
        else:
            v.verdict = "stable"
            v.line = f"ran stably ({_balance_text(b)}" + (f"; {facts}" if facts else "") + ")"
    elif v.exit == 4 and v.message.startswith("pdem: unstable: ") and _STEP.match(v.message[16:]):
        v.verdict = "stopped"
        v.line = "stopped: " + v.message[len("pdem: unstable: "):]
        if series:
            v.energy = energy_balance(series, attrs, tolerance)
    else:
        what = {1: "an internal error (a bug)", 2: "bad input", 4: "unstable without a message naming the cause",
                5: "the system failed the run"}.get(v.exit, f"exit status {v.exit}")
        v.verdict = "FAILED"
        v.line = f"FAILED: exit {v.exit}, {what}" + (f": {v.message}" if v.message else "")
    if v.nonfinite:
        nan = sum(max(n, 0) for _, _, n, _ in v.nonfinite)
        inf = sum(max(i, 0) for _, _, _, i in v.nonfinite)
        first = v.nonfinite[0]
        v.line = (f"FAILED: {nan} NaN and {inf} infinite values in its outputs (first: {first[0]} {first[1]}); "
                  f"was: {v.line}")
        v.verdict = "FAILED"
    if expected is not None and v.verdict in EXPECTABLE and v.verdict != expected:
        v.line = f"FAILED: expected to be {expected}, but {v.line}"
        v.verdict = "FAILED"
    return v


# ---------------------------------------------------------------------------- the map
def expectations(manifest, where):
    """{case: "stable"|"stopped"} from the manifest's [analysis] expect (CampaignError if malformed)."""
    exp = manifest.get("analysis", {}).get("expect", {})
    if not isinstance(exp, dict) or any(v not in EXPECTABLE for v in exp.values()):
        raise CampaignError(f"{where}: [analysis] expect must map case names to \"stable\" or \"stopped\", got {exp!r}")
    return exp


def judge_campaigns(dirs, tolerance=TOLERANCE):
    """Verdicts of every member of every campaign directory in ``dirs``, in manifest order."""
    verdicts = []
    for d in dirs:
        camp = read_campaign(d)
        exp = expectations(camp.manifest, d)
        cases = {str(m.params.get("case", "")) for m in camp.members}
        unknown = sorted(set(exp) - cases)
        if unknown:
            raise CampaignError(f"{d}: [analysis] expect names cases the campaign does not have: {', '.join(unknown)}")
        for m in camp.members:
            case = str(m.params.get("case", ""))
            verdicts.append(judge_member(camp.name, m, tolerance, exp.get(case)))
    return verdicts


def map_ok(verdicts):
    return bool(verdicts) and all(v.ok for v in verdicts)


def _row(v):
    b = v.energy or {}
    rise = _pct(b["rise_ratio"]) if b.get("checked") else "-"
    spent = _pct(b["dissipated"] / b["released"]) if b.get("checked") and b["released"] > 0 else "-"
    nan = sum(max(n, 0) for _, _, n, _ in v.nonfinite) + sum(max(i, 0) for _, _, _, i in v.nonfinite)
    return [v.campaign, v.member, v.verdict, "-" if v.exit is None else str(v.exit), v.expected or "-",
            "-" if v.steps is None else str(v.steps), "-" if v.time is None else f"{v.time:.4g}", rise, spent,
            str(nan), v.line if v.verdict != "stable" else _short_stable(v)]


def _short_stable(v):
    b = v.energy or {}
    return "ran stably" + (f" (energy rise {_pct(b['rise_ratio'])})" if b.get("checked") else
                           f" ({b.get('reason', 'energy balance not checked')})")


HEAD = ["campaign", "member", "verdict", "exit", "expected", "steps", "time [s]", "energy rise", "dissipated",
        "non-finite", "what happened"]


def _columns(head, rows):
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows)][:-1]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths) + "  {}"
    return [fmt.format(*head), fmt.format(*("-" * w for w in widths), "-" * len(head[-1]))] + \
        [fmt.format(*r) for r in rows]


def _md_cell(x):
    return str(x).replace("|", "\\|")


def summary_line(verdicts):
    counts = {k: sum(v.verdict == k for v in verdicts) for k in VERDICTS}
    state = "PASSED" if map_ok(verdicts) else "FAILED" if counts["FAILED"] else "NOT FINISHED"
    return (f"stability map {state}: {len(verdicts)} members: " + ", ".join(f"{counts[k]} {k}" for k in VERDICTS)
            + "; no NaN or infinity in any output" * (not any(v.nonfinite for v in verdicts)))


def stability_report(dirs, out=None, tolerance=TOLERANCE):
    """Write the report of campaign directories ``dirs``; returns (files written, passed)."""
    dirs = [Path(d) for d in dirs]
    if out is None:
        if len(dirs) > 1:
            raise CampaignError("several campaign directories: give --out for the report")
        out = dirs[0] / "analysis"
    verdicts = judge_campaigns(dirs, tolerance)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [_row(v) for v in verdicts]
    head = summary_line(verdicts)
    lines = [head, f"campaigns: {', '.join(str(d) for d in dirs)}; energy tolerance {100 * tolerance:g} % of the "
             "largest kinetic+elastic energy", ""]
    lines += [f"{v.campaign}/{v.member}: {v.line}" for v in verdicts] + [""] + _columns(HEAD, rows)
    for v in verdicts:
        for f, w, n, i in v.nonfinite:
            lines.append(f"non-finite: {v.campaign}/{v.member}/{f} {w}: {n} NaN, {i} inf")
    (out / "stability.txt").write_text("\n".join(lines) + "\n")
    md = [f"**{head}**", "", "| " + " | ".join(HEAD) + " |", "|" + "---|" * len(HEAD)]
    md += ["| " + " | ".join(_md_cell(x) for x in r) + " |" for r in rows]
    (out / "stability.md").write_text("\n".join(md) + "\n")
    doc = {"passed": map_ok(verdicts), "summary": head, "tolerance": tolerance, "campaigns": [str(d) for d in dirs],
           "members": [{"campaign": v.campaign, "member": v.member, "case": v.case, "verdict": v.verdict,
                        "exit": v.exit, "expected": v.expected, "steps": v.steps, "time": v.time, "line": v.line,
                        "message": v.message, "energy": v.energy,
                        "nonfinite": [{"file": f, "where": w, "nan": n, "inf": i} for f, w, n, i in v.nonfinite]}
                       for v in verdicts]}
    (out / "stability.json").write_text(json.dumps(_jsonable(doc), indent=1) + "\n")
    png = plot_stability(out / "stability.png", verdicts, tolerance)
    return [out / "stability.txt", out / "stability.md", out / "stability.json", png], map_ok(verdicts)


def _jsonable(x):
    if isinstance(x, float) and not math.isfinite(x):
        return repr(x)
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return x


COLORS = {"stable": "tab:green", "stopped": "tab:orange", "FAILED": "tab:red", "incomplete": "0.5", "pending": "0.75"}


def plot_stability(path, verdicts, tolerance):
    """Left: each member's largest energy rise over its largest kinetic+elastic energy (log
    scale), coloured by verdict, with the tolerance. Right: (E(t) - E(0)) / S against the fraction
    of the run for each member with a checked balance (stops marked with a cross)."""
    from matplotlib.figure import Figure

    n = max(len(verdicts), 1)
    fig = Figure(figsize=(13, 1.2 + 0.38 * n), layout="constrained")
    ax, ax2 = fig.subplots(1, 2, width_ratios=(1, 1.3))
    labels = [f"{v.member}" if len({x.campaign for x in verdicts}) == 1 else f"{v.campaign}/{v.member}"
              for v in verdicts]
    floor = tolerance * 1e-4
    for k, v in enumerate(verdicts):
        b = v.energy or {}
        x = max(b["rise_ratio"], floor) if b.get("checked") else floor
        ax.barh(k, x, color=COLORS[v.verdict], left=0)
        text = v.verdict + (f": rise {_pct(b['rise_ratio'])}" if b.get("checked") and b["rise"] > 0 else
                            ": no rise" if b.get("checked") else " (balance not checked)")
        ax.text(floor * 1.3, k, text, va="center", fontsize=8)
    ax.axvline(tolerance, color="k", ls="--", lw=1, label=f"tolerance {100 * tolerance:g} %")
    ax.set_xscale("log")
    ax.set_xlim(floor, max(1.0, 3 * tolerance))
    ax.set_yticks(range(len(verdicts)), labels, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("largest rise of the mechanical energy / largest kinetic+elastic energy")
    ax.legend(loc="lower right", fontsize=8)
    drawn = 0
    for k, v in enumerate(verdicts):
        series, _ = _read_series(v.dir) if v.dir is not None else ({}, {})
        b = v.energy or {}
        if not b.get("checked") or "total_energy" not in series or len(series["total_energy"]) < 1:
            continue
        e = np.asarray(series["total_energy"], float) - np.asarray(series.get("external_work", 0.0), float)
        s = series["step"].astype(float)
        frac = (s - s[0]) / max(s[-1] - s[0], 1.0)
        y = (e - e[0]) / b["scale"] if b["scale"] > 0 else e - e[0]
        ax2.plot(frac, y, color=f"C{k % 10}", lw=1.2, label=labels[k])
        if v.verdict == "stopped":
            ax2.plot(frac[-1:], y[-1:], "x", color=f"C{k % 10}", ms=9, mew=2)
        drawn += 1
    ax2.axhline(0.0, color="0.6", lw=0.8)
    ax2.set_xlabel("fraction of the run's recorded steps")
    ax2.set_ylabel("(E(t) - E(0)) / largest kinetic+elastic energy")
    if drawn:
        ax2.legend(fontsize=7, ncol=2)
    fig.suptitle(summary_line(verdicts), fontsize=10)
    return save(fig, path, dpi=110)


def add_parser(sub):
    p = sub.add_parser("stability", help="stability map: every member stable or stopped naming the cause",
                       description="Verdict of every member of one or more campaign directories: ran stably "
                                   "(energy balance) or stopped naming the cause; never NaN (docs/stability.md). "
                                   "Exit status 1 if the map fails or is not finished.")
    p.add_argument("dirs", type=Path, nargs="+", metavar="DIR", help="campaign directories (each holds campaign.json)")
    p.add_argument("--out", type=Path, metavar="OUT", help="output directory (default DIR/analysis; required for "
                                                            "several directories)")
    p.add_argument("--tolerance", type=float, default=TOLERANCE, metavar="F",
                   help="largest allowed rise of the mechanical energy over the largest kinetic+elastic energy "
                        "(default: %(default)s)")
    return p


def run(args):
    """(files written, passed) for the command line."""
    if not (0.0 < args.tolerance < 1e6):
        raise CampaignError(f"--tolerance {args.tolerance}: must be a number > 0")
    return stability_report(args.dirs, args.out, args.tolerance)


__all__ = ["Verdict", "energy_balance", "judge_member", "judge_campaigns", "scan_member", "stability_report"]
