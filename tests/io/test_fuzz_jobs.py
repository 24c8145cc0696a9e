"""Fuzzing the shipped job files: every mutant of jobs/*.toml and jobs/campaigns/*.toml is either
accepted or refused as promised (docs/reliability.md, "Fuzzed job files").

Each shipped scene file and campaign file is mutated by a fixed-seed generator (`mutants`):
a number as text ("0.3") or as true, its sign flipped, times or divided by 1000, 0, nan, ±inf;
a list element as text; a list one longer or shorter; a key dropped; an unknown key added; a
table replaced by a number or a string. Each mutant is checked in-process as ``pdem run MUTANT
--check`` (scene files) or ``pdem campaign check MUTANT`` (campaign files) would: the exit status
is 0, 2 or 4 (pdem.errors), a refusal is exactly one line ``pdem: ...`` and no traceback, an
acceptance one line ``ok ...``. Mutants that are nonsense by construction (nan, inf, a number
given as text or as a boolean, an unknown key, a table that is not a table, a section key of
`pdem.scenes.common.bounds` moved out of its plausible range) must be refused; the others may be
accepted (a dropped key takes its default, a changed sign or size may be valid). The counts of
mutants and outcomes are printed with the test's output. A handful of mutants also go through the
real command line on 2 ranks (`test_mutants_through_the_cli_on_2_ranks`).
"""
import contextlib
import copy
import io
import math
import os
import random
import time
import tomllib
from collections import Counter
from pathlib import Path

import pytest

from pdem.campaign.tomlw import dumps
from pdem.scenes.common.bounds import BOUNDS, PREPARATION_BOUNDS
from pdem_cli import needs_mpiexec, run_pdem

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "jobs").glob("*.toml"))
CAMPAIGNS = sorted((ROOT / "jobs" / "campaigns").glob("*.toml"))
SEED = int(os.environ.get("PDEM_FUZZ_SEED", "33"))
# mutants per scene file and per campaign file (each check expands and checks every member); more
# with PDEM_FUZZ_SCALE=k (k times as many; the test takes about k times as long)
SCALE = int(os.environ.get("PDEM_FUZZ_SCALE", "1"))
PER_SCENE = 12 * SCALE
PER_CAMPAIGN = 6 * SCALE
NONSENSE = {"text", "bool", "nan", "inf", "-inf", "elem_text", "extra_key", "table_type"}
UNCHECKED = ("analysis",)  # campaign tables copied to the manifest, not read by pdem (docs/campaigns.md)


def _leaves(node, path=()):
    """(path, value) of every scalar or list of scalars, and (path, table) of every table."""
    if isinstance(node, dict):
        yield path, node
        for k, v in node.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(node, list) and node and all(isinstance(x, dict) for x in node):
        for i, v in enumerate(node):
            yield from _leaves(v, path + (i,))
    else:
        yield path, node


def _get(doc, path):
    for p in path:
        doc = doc[p]
    return doc


def _set(doc, path, value):
    _get(doc, path[:-1])[path[-1]] = value


def _number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _ops(path, value):
    """The mutations that apply to the leaf or table at ``path``."""
    if isinstance(value, dict):
        return ["extra_key"] + (["table_type"] if path else []) + (["drop"] if path else [])
    ops = ["drop"]
    if _number(value):
        ops += ["text", "bool", "neg", "x1000", "/1000", "zero", "nan", "inf", "-inf"]
    elif isinstance(value, str):
        ops += ["type_str"]
    elif isinstance(value, list) and value and all(_number(x) for x in value):
        ops += ["elem_text", "elem_x1000", "longer", "shorter"]
    return ops


def _mutate(doc, path, op, rng):
    """Apply ``op`` at ``path`` to a copy of ``doc``; returns (mutant, must_refuse)."""
    m = copy.deepcopy(doc)
    v = _get(m, path)
    if op == "drop":
        del _get(m, path[:-1])[path[-1]]
        return m, False
    if op == "extra_key":
        v["not_a_key"] = 1.0
        return m, True
    if op == "table_type":
        _set(m, path, rng.choice([1.0, "table"]))
        return m, True
    new = {"text": lambda: repr(v), "bool": lambda: True, "neg": lambda: -v, "x1000": lambda: v * 1000,
           "/1000": lambda: v / 1000, "zero": lambda: 0 * v, "nan": lambda: math.nan, "inf": lambda: math.inf,
           "-inf": lambda: -math.inf, "type_str": lambda: 1.0,
           "elem_text": lambda: [repr(x) if i == 0 else x for i, x in enumerate(v)],
           "elem_x1000": lambda: [x * 1000 if i == 0 else x for i, x in enumerate(v)],
           "longer": lambda: v + [v[-1]], "shorter": lambda: v[:-1]}[op]()
    _set(m, path, new)
    return m, op in NONSENSE or _out_of_bounds(path, v, new)


def _out_of_bounds(path, old, new):
    """True if ``path`` is a key of `BOUNDS` whose shipped value was inside its range and the mutant's is not."""
    prepared = ("track", "oedometer", "box_test", "shear_box")  # the scenes of pdem.scenes.common.preparation
    bounds = {**BOUNDS.get(path[0], {}), **(PREPARATION_BOUNDS if path[0] in prepared else {})}
    if len(path) != 2 or path[1] not in bounds:
        return False
    lo, hi, _, _ = bounds[path[1]]
    olds, news = (x if isinstance(x, list) else [x] for x in (old, new))
    inside = all(_number(x) and lo <= x <= hi for x in olds)
    return inside and any(_number(x) and not lo <= x <= hi for x in news)


def mutants(path, count, rng):
    """``count`` (name, mutated document, must_refuse) of the TOML file ``path``, drawn by ``rng``."""
    doc = tomllib.loads(path.read_text())
    if "campaign" in doc:  # the base scene by its absolute path: the mutant is written elsewhere
        doc["campaign"]["base"] = str((path.parent / doc["campaign"]["base"]).resolve())
    sites = [(p, op) for p, v in _leaves(doc) if not (p and p[0] in UNCHECKED) for op in _ops(p, v)]
    out = []
    for p, op in rng.sample(sites, min(count, len(sites))):
        m, refuse = _mutate(doc, p, op, rng)
        out.append((f"{path.name}:{'.'.join(map(str, p)) or '<root>'}:{op}", m, refuse))
    return out


def _check_in_process(kind, file, out):
    """(status, output text, seconds) of ``pdem run FILE --check`` or ``pdem campaign check FILE``, in this process."""
    from pdem.cli import main

    argv = ["run", str(file), "--check", "--out", str(out)] if kind == "scene" else \
        ["campaign", "check", str(file), "--out", str(out)]
    text = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code
        except Exception as exc:  # noqa: BLE001 - a bug: counted as such
            import traceback

            text.write("".join(traceback.format_exception(exc)))
            status = 1
    return status, text.getvalue(), time.perf_counter() - t0


def _verdict(status, text, must_refuse):
    """'' if the outcome keeps the promise, else why not."""
    lines = [x for x in text.splitlines() if x.strip()]
    if "Traceback" in text:
        return "traceback"
    if status not in (0, 2, 4):
        return f"exit status {status}"
    if len(lines) != 1:
        return f"{len(lines)} lines of output"
    if status == 0:
        return "accepted nonsense" if must_refuse else ("" if lines[0].startswith("ok ") else "no 'ok' line")
    return "" if lines[0].startswith("pdem: ") else "the line does not start with 'pdem: '"


def _all_mutants():
    rng = random.Random(SEED)
    out = [("scene", f, *m) for f in SCENES for m in mutants(f, PER_SCENE, rng)]
    out += [("campaign", f, *m) for f in CAMPAIGNS for m in mutants(f, PER_CAMPAIGN, rng)]
    return out


@pytest.mark.timeout(900)
def test_every_mutant_of_the_shipped_jobs_is_refused_in_one_line_or_valid(tmp_path, capsys):
    assert SCENES and CAMPAIGNS
    outcomes, bad, times = Counter(), [], []
    for k, (kind, src, name, doc, must_refuse) in enumerate(_all_mutants()):
        file = tmp_path / f"m{k}_{src.name}"
        file.write_text(dumps(doc))
        status, text, seconds = _check_in_process(kind, file, tmp_path / f"out{k}")
        times.append((seconds, name))
        why = _verdict(status, text, must_refuse)
        outcomes[(kind, status)] += 1
        if why:
            bad.append(f"{name}: {why}: exit {status}: {text.strip()[-600:]}")
    total = sum(outcomes.values())
    with capsys.disabled():
        print(f"\nfuzzed job files: {len(SCENES)} scene files and {len(CAMPAIGNS)} campaign files, {total} mutants "
              f"(seed {SEED}): " + ", ".join(f"{kind} exit {s}: {n}" for (kind, s), n in sorted(outcomes.items()))
              + f"; broken promises: {len(bad)}; slowest checks: "
              + ", ".join(f"{t:.2f} s ({n})" for t, n in sorted(times, reverse=True)[:3]))
    assert not bad, "\n".join(bad)


# one mutant of each refusing class, through the real command line on 2 ranks
CLI_MUTANTS = [("track_beam.toml", ("traffic", "axle_load"), 200.0, "traffic.axle_load = 200.0"),
               ("oedometer_ci.toml", ("oedometer", "diameter"), math.nan, "oedometer.diameter = nan"),
               ("box_test.toml", ("box_test", "cycles"), "3", "box_test.cycles = '3'"),
               ("blast.toml", ("blast", "not_a_key"), 1.0, "blast.not_a_key: unknown key")]


@pytest.mark.slow
@needs_mpiexec
@pytest.mark.parametrize("job, path, value, words", CLI_MUTANTS)
def test_mutants_through_the_cli_on_2_ranks(tmp_path, job, path, value, words):
    doc = tomllib.loads((ROOT / "jobs" / job).read_text())
    _set(doc, path, value)
    scene = tmp_path / job
    scene.write_text(dumps(doc))
    r = run_pdem(2, scene, tmp_path / "out", "--check", expect=2)
    lines = [x for x in (r.stdout + r.stderr).splitlines() if x.strip()]
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in r.stderr, r.stdout + r.stderr
    assert not (tmp_path / "out").exists()  # --check writes nothing
