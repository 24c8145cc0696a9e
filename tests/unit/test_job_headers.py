"""Every shipped job's header is true (issue #34): the comment block at the top of each
jobs/*.toml and jobs/campaigns/*.toml.

Checked against independent truth, the repository and the file itself:
- every command it names parses with the current command line (``pdem run``, ``pdem campaign``,
  ``python -m analysis``: the parsers of `pdem.cli`, `pdem.campaign.cli`, `analysis.__main__`), and
  the scene or campaign file it runs exists; a launcher script it names exists;
- every repository path it names exists (jobs/, docs/, tests/, pdem/, analysis/, a ``NAME.md``
  in the repository or docs/, a dotted ``pdem.x.y`` module);
- the numbers it quotes where a key of the file holds them (`CLAIMS`: the value as the header
  writes it, the key it stands for, the factor from the header's unit to the file's SI unit).
"""
import re
import shlex
import tomllib
from importlib import import_module
from importlib.util import find_spec
from pathlib import Path

import pytest

from test_docs_links import PLACEHOLDER, TOP, _exists

ROOT = Path(__file__).resolve().parents[2]
JOBS = sorted((ROOT / "jobs").glob("*.toml")) + sorted((ROOT / "jobs" / "campaigns").glob("*.toml"))

# job -> [(number as the header writes it, dotted key of the file, header unit -> file unit)]
MM = 1e-3
CLAIMS = {
    "box_test.toml": [("700", "box_test.box.0", MM), ("300", "box_test.box.1", MM), ("450", "box_test.box.2", MM),
                      ("16.25", "box_test.radius", MM), ("250", "box_test.sleeper_size.0", MM),
                      ("150", "box_test.sleeper_size.2", MM), ("34", "box_test.sleeper_mass", 1.0),
                      ("2.8e7", "materials.ballast.young", 1.0), ("3", "box_test.f_max", 1e3),
                      ("1", "box_test.frequency", 1.0), ("3", "box_test.cycles", 1.0)],
    "box_test_full.toml": [("2.8e11", "materials.ballast.young", 1.0), ("3", "box_test.f_min", 1e3),
                           ("40", "box_test.f_max", 1e3), ("100", "box_test.cycles", 1.0),
                           ("0.3", "simulation.damping", 1.0)],
    "deposition.toml": [("1000", "deposition.count", 1.0), ("16.25", "deposition.radius", MM),
                        ("40", "deposition.radius_spread", 1e-2),
                        ("2.8e7", "materials.ballast.young", 1.0), ("0.3", "simulation.damping", 1.0)],
    "track_breakable.toml": [("15", "track.clumps.member_radius", MM), ("2.8e6", "materials.ballast.young", 1.0),
                             ("1.4e6", "materials.rubber.young", 1.0),
                             ("8.17e4", "materials.ballast.normal_cohesion", 1.0),
                             ("4", "traffic.passages", 1.0), ("1", "traffic.axle_load", 1e3),
                             ("10", "traffic.speed", 1.0)],
    "track_beam.toml": [("5", "track.sleepers", 1.0), ("8", "traffic.passages", 1.0), ("1", "traffic.axle_load", 1e3),
                        ("10", "traffic.speed", 1.0), ("2.8e6", "materials.ballast.young", 1.0)],
    "shear_box.toml": [("100", "shear_box.side", MM), ("60", "shear_box.height", MM), ("4", "shear_box.radius", MM),
                       ("10", "shear_box.normal_stress", 1e3), ("8", "shear_box.shear_displacement", MM),
                       ("0.1", "shear_box.shear_velocity", 1.0), ("5e6", "materials.grains.young", 1.0)],
    "oedometer_ci.toml": [("90", "oedometer.diameter", MM), ("40", "oedometer.height", MM),
                          ("3", "oedometer.clumps.member_radius", MM), ("5.55e6", "materials.ballast.young", 1.0),
                          ("162.04", "materials.ballast.normal_cohesion", 1e3), ("150", "oedometer.f_max", 1.0)],
}

COMMAND = re.compile(r"(?:^|\s)((?:\S*/)?(?:python3?|pdem)\s+(?:-m\s+\S+\s+)?.*)$")


def header(path):
    """The comment lines before the first line that is not a comment, without their '#'."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].strip())
    return lines


def commands(lines):
    """(program, arguments) of every ``pdem ...``/``python -m pdem|analysis ...`` command named."""
    found = []
    for line in lines:
        if "`" in line:  # `python -m analysis box-checks` refuses ...: the command is what the backticks hold
            line = " ".join(re.findall(r"`([^`]*)`", line))
        line = re.sub(r"\s\(.*$", "", line)  # "(2 members at a time)": a note after the command
        try:
            words = shlex.split(line)
        except ValueError:  # an apostrophe in the prose
            words = line.split()
        for i, w in enumerate(words):
            if w == "-m" and i + 1 < len(words) and words[i + 1] in ("pdem", "analysis"):
                found.append((words[i + 1], words[i + 2:]))
            elif i and words[i - 1] == "-m":
                continue
            elif w.endswith("/pdem") or (w == "pdem" and i + 1 < len(words) and words[i + 1] in ("run", "campaign")):
                found.append(("pdem", words[i + 1:]))
    return found


def parse(program, args):
    """Parse ``args`` with the current parser of ``program``; returns the namespace (SystemExit(2)
    if it does not parse). A sub-command named alone (prose: "`python -m analysis box-checks`
    refuses ...") is asked for its --help: SystemExit(0) if it exists."""
    args = [a.rstrip(".,;:") for a in args]
    if len(args) == 1 or args[:1] == ["campaign"] and len(args) == 2:
        args = [*args, "--help"]
    if program == "pdem" and args[:1] == ["campaign"]:
        from pdem.campaign.cli import _parser

        return _parser().parse_args(args[1:])
    if program == "pdem":
        from pdem.cli import build_parser

        return build_parser().parse_args(args)
    from analysis.__main__ import build_parser

    return build_parser().parse_args(args)


def named_paths(lines):
    """Repository paths, NAME.md files and pdem modules the header names."""
    paths = []
    for line in lines:
        for word in line.split():
            word = word.strip(",;:()'\"`.")
            if "/" in word and word.split("/")[0] in TOP and not PLACEHOLDER.search(word):
                paths.append(("path", word))
            elif re.fullmatch(r"[\w-]+\.md", word):
                paths.append(("md", word))
            elif re.fullmatch(r"pdem(\.\w+)+", word):
                paths.append(("module", word))
    return paths


def module_exists(name):
    """``name`` is a module, or a name in one (pdem.driver.stages.Stage)."""
    try:
        if find_spec(name) is not None:
            return True
    except ModuleNotFoundError:  # a name in a module (pdem.driver.stages is no package)
        pass
    parent, attr = name.rsplit(".", 1)
    try:
        return hasattr(import_module(parent), attr)
    except ImportError:
        return False


def lookup(doc, key):
    value = doc
    for part in key.split("."):
        value = value[int(part)] if isinstance(value, list) else value[part]
    return value


@pytest.mark.parametrize("job", JOBS, ids=lambda p: p.relative_to(ROOT / "jobs").as_posix())
def test_the_commands_of_the_header_parse_and_run_files_that_exist(job):
    lines = header(job)
    bad = []
    for program, args in commands(lines):
        try:
            ns = parse(program, args)
        except SystemExit as exc:
            if exc.code != 0:
                bad.append(f"does not parse: {program} {' '.join(args)}")
            continue
        target = getattr(ns, "scene", None) or getattr(ns, "file", None)
        if target and not PLACEHOLDER.search(target) and not (ROOT / target).exists():
            bad.append(f"{program} {args[0]}: no file {target}")
    assert bad == []


@pytest.mark.parametrize("job", JOBS, ids=lambda p: p.relative_to(ROOT / "jobs").as_posix())
def test_the_files_and_modules_the_header_names_exist(job):
    missing = []
    for kind, name in named_paths(header(job)):
        if kind == "path" and not _exists(name):
            missing.append(name)
        elif kind == "md" and not any((d / name).exists() for d in (ROOT, ROOT / "docs", job.parent)):
            missing.append(name)
        elif kind == "module" and not module_exists(name):
            missing.append(name)
    assert missing == []


@pytest.mark.parametrize("name", sorted(CLAIMS))
def test_the_numbers_the_header_quotes_are_the_files(name):
    job = ROOT / "jobs" / name
    text = " ".join(header(job))
    doc = tomllib.loads(job.read_text())
    wrong = []
    for quoted, key, unit in CLAIMS[name]:
        assert re.search(rf"(?<![\d.]){re.escape(quoted)}(?![\d])", text), f"the header no longer quotes {quoted}"
        if lookup(doc, key) != pytest.approx(float(quoted) * unit, rel=1e-9):
            wrong.append(f"header {quoted} but {key} = {lookup(doc, key)}")
    assert wrong == []


def test_the_checker_finds_stale_headers(tmp_path):
    lines = ["Run: mpiexec -n 2 python -m pdem run jobs/no_such_job.toml --out runs/x --no-such-option",
             "  .venv/bin/python -m pdem run jobs/gone.toml --out runs/gone",
             "see docs/no_such_page.md and pdem.scenes.no_such_scene; NOPE_SPEC.md 2.3"]
    bad = []
    for program, args in commands(lines):
        try:
            parse(program, args)
        except SystemExit:
            bad.append(args[1])
    assert bad == ["jobs/no_such_job.toml"]
    names = named_paths(lines)
    assert ("path", "jobs/gone.toml") in names and ("path", "docs/no_such_page.md") in names
    assert ("md", "NOPE_SPEC.md") in names and ("module", "pdem.scenes.no_such_scene") in names
    assert not _exists("jobs/gone.toml") and not module_exists("pdem.scenes.no_such_scene")
    assert module_exists("pdem.driver.stages.Stage") and module_exists("pdem.scenes.blast")


def test_a_header_that_says_make_run_is_the_job_make_run_runs():
    recipe = re.search(r"^run:.*\n((?:\t.*\n)+)", (ROOT / "Makefile").read_text(), re.M).group(1)
    claims = [job.name for job in JOBS if "make run" in " ".join(header(job))
              and re.search(r"default of `?make run`?", " ".join(header(job)))]
    assert [name for name in claims if f"jobs/{name}" not in recipe] == []


def test_the_commands_are_found():
    """The checks above see the commands: every job with a ``pdem run`` line yields it."""
    found = {job.name: commands(header(job)) for job in JOBS}
    assert ("pdem", ["run", "jobs/track_beam.toml", "--out", "runs/track_beam"]) in found["track_beam.toml"]
    assert sum(len(c) for c in found.values()) >= 20
