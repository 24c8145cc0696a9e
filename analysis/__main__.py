"""Command line: ``python -m analysis box RUN_DIR|RESULTS.h5 [--out DIR]``; also ``grading``, ``blast``,
``track``, ``oedometer``, ``oedometer-overlap`` (each defined by its module's ``add_parser``),
``campaign DIR`` (`analysis.campaign`),
``blast-sensitivity DIR`` (`analysis.blast_sensitivity`), ``error-vs-runtime DIR`` (`analysis.error_vs_runtime`),
``stability DIR [DIR ...]``
(`analysis.stability`: exit status 1 when the stability map fails or is not finished) and
``box-checks CALIBRATION_DIR CHECKS_DIR`` (`analysis.box_checks`),
``box-thesis-procedure SOFT_DIR FULL_DIR`` (`analysis.box_thesis_procedure`) and ``validate``
(`analysis.validation`: the validation table from jobs/validation/rows.toml).

This module owns the CLI only: argument parsing, the output directory and exit status. Bad
input (not a pdem result, no complete cycle, unwritable output) exits with status 2 and one
line on stderr, without a traceback; so does a missing optional package (`NEEDS`: pdem's
``analysis`` extra), named before any work.
"""

from __future__ import annotations

import argparse
import sys
from importlib.util import find_spec
from pathlib import Path

from pdem.format.read import ResultFileError, results_file

# the sub-commands' modules import matplotlib and scipy: they are imported after `missing_package`

PROG = f"python -m {__package__}"  # analysis (a checkout) or pdem_analysis (installed)
EXIT_BAD_INPUT = 2
NEEDS = ("matplotlib", "scipy")  # pip install pdem[analysis]


def missing_package() -> str | None:
    """The first package of `NEEDS` that is not installed, or None."""
    return next((name for name in NEEDS if find_spec(name) is None), None)


class _Parser(argparse.ArgumentParser):
    """argparse, but usage errors are one line on stderr with status 2."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from . import blast, blast_sensitivity, box_checks, box_thesis_procedure, campaign, error_vs_runtime, grading, \
        oedometer, oedometer_overlap, run_summary, stability, track, validation
    from .stiffness import LOADING_WINDOW, UNLOADING_FRACTION

    parser = _Parser(prog=PROG, description="Analyse pdem HDF5 result files.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    box = sub.add_parser(
        "box", help="box test: loops, settlement per cycle with fits, stiffness per cycle",
        description="Write loops.png, settlement.png, stiffness.png, summary.txt and "
                    "summary.json for a cyclic box test.")
    box.add_argument("results", type=Path, metavar="RUN_DIR|RESULTS.h5",
                     help="a run folder (its results.h5) or a pdem results file")
    box.add_argument("--out", type=Path, metavar="DIR",
                     help="output directory (default: RUN_DIR/analysis, where pdem run's post-processing writes; "
                          "a results file outside a run folder: RESULTS-analysis beside it)")
    box.add_argument("--window", type=float, nargs=2, metavar=("LO", "HI"),
                     default=LOADING_WINDOW,
                     help="loading-stiffness force window, fractions of the branch force "
                          "range (default: %(default)s)")
    box.add_argument("--unload-fraction", type=float, default=UNLOADING_FRACTION,
                     metavar="F", help="part of the force drop used for the unloading "
                                       "stiffness (default: %(default)s)")
    for module in (grading, blast, track, oedometer, oedometer_overlap, run_summary, validation):
        module.add_parser(sub)
    campaign.add_parser(sub)
    blast_sensitivity.add_parser(sub)
    box_checks.add_parser(sub)
    box_thesis_procedure.add_parser(sub)
    error_vs_runtime.add_parser(sub)
    stability.add_parser(sub)
    return parser


def main(argv=None) -> int:
    missing = missing_package()
    if missing:
        return _fail(f"needs the Python package {missing} (pip install 'pdem[analysis]')")
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_BAD_INPUT
    if args.command in ("campaign", "blast-sensitivity", "error-vs-runtime", "stability", "box-checks",
                        "box-thesis-procedure"):
        return _run_campaign(args)
    from . import validation
    from .summary import run_box

    try:
        if hasattr(args, "run"):
            written = args.run(args)
        else:
            written = run_box(results_file(args.results), args.out, tuple(args.window), args.unload_fraction)
    except (ResultFileError, validation.ValidationError) as err:
        return _fail(str(err))
    except (ValueError, OSError) as err:
        inputs = args.results if isinstance(args.results, list) else [args.results]
        return _fail(f"{' '.join(map(str, inputs))}: {_one_line(err)}")
    for path in written:
        print(path)
    return 0


def _run_campaign(args) -> int:
    from . import blast_sensitivity, box_checks, box_thesis_procedure, campaign, error_vs_runtime, stability

    module = {"campaign": campaign, "blast-sensitivity": blast_sensitivity, "error-vs-runtime": error_vs_runtime,
              "stability": stability, "box-checks": box_checks,
              "box-thesis-procedure": box_thesis_procedure}[args.command]
    try:
        written = module.run(args)
    except (campaign.CampaignError, ResultFileError) as err:
        return _fail(str(err))
    except (ValueError, OSError) as err:
        where = (" ".join(map(str, args.dirs)) if hasattr(args, "dirs") else
                 f"{args.calibration} {args.checks}" if hasattr(args, "checks") else
                 f"{args.soft} {args.full}" if hasattr(args, "full") else args.dir)
        return _fail(f"{where}: {_one_line(err)}")
    status = 0
    if args.command == "stability":  # (files, passed): the map's verdict is the exit status
        written, passed = written
        print((Path(written[0])).read_text().splitlines()[0])
        status = 0 if passed else 1
    for path in written:
        print(path)
    return status


def _fail(message: str) -> int:
    print(f"{PROG}: error: {_one_line(message)}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _one_line(message) -> str:
    return " ".join(str(message).split())


if __name__ == "__main__":
    sys.exit(main())
