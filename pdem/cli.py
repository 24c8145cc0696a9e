"""The `pdem` command line: ``python -m pdem run SCENE.toml --out DIR``, ``python -m pdem campaign ...``
(`pdem.campaign`).

`pdem run` reads the scene file, finds its scene in the registry (`pdem.scenes`; a file without
a scene table is a plain scene, `pdem.driver.plain`) and runs it on this process's ranks. Any
failure on any rank ends the whole job with one line, printed once, and an exit status
(`pdem.driver.failures`): 0 done, 1 internal error, 2 bad input (scene file, command line,
output directory, a checkpoint or results file that cannot be continued from), 3 stopped by
SIGTERM/SIGUSR1 after writing a checkpoint (`pdem.io.signals`), 4 unstable or runaway, 5 a
write failed (disk full) or memory ran out.

``pdem run SCENE --check`` does every check a run does at its start (`check_file`) and prints one
line ``ok ...`` without running or writing anything.

Rank 0 writes what it prints, from the start of the run to the end of its post-processing, also
to ``OUT/log.txt`` (`pdem.driver.runlog`; appended to when a run resumes).

After a successful run, rank 0 launches the post-processing the run declared in its files (a
staged scene's run_info.json, `pdem.format.run`): ``python -m analysis summary OUT`` (in this
process), which writes summary.txt, preparation.png and analysis/. Its exit status is printed;
the run's stays. Without the optional packages it needs (``pip install pdem[analysis]``:
matplotlib, scipy), it is skipped with a one-line note.

The analysis package is the source folder ``analysis/`` in a checkout and ``pdem_analysis`` in an
installed wheel (pyproject.toml); `analysis_package` names the one present.
"""
import argparse
import os
import sys
from importlib import import_module
from importlib.util import find_spec

from .errors import EXIT_INPUT_ERROR
from .version import __version__

# environment variables through which launchers give a process its rank (to print usage errors,
# found before MPI is set up, on one rank only)
_RANK_VARS = ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "MV2_COMM_WORLD_RANK", "SLURM_PROCID")


def run_file(path, out, steps=None, fresh=False, comm=None, sets=()):
    """Run the scene file ``path`` into ``out`` on this process's ranks; returns the exit status
    (exceptions propagate: `pdem.driver.failures.run_guarded` turns them into statuses). First
    of all, the ranks agree on their input (`pdem.driver.preflight.agree_on_input`, the ``sets``
    included). ``sets``: ``KEY=VALUE`` texts (`pdem.build.config.apply_sets`); the scene they
    make is written to ``out/scene_set.toml`` and run from there (its text is the run's scene)."""
    from .build.config import load_toml
    from .driver.plain import run_scene_file
    from .parallel.comm import get_comm
    from .scenes import find
    from .build.validate import number
    from .driver.preflight import agree_on_input, check_run_length

    comm = get_comm(comm)
    sets = list(sets or ())
    agree_on_input(comm, path, {"out": str(out), "steps": steps, "fresh": bool(fresh), "set": sets})
    if steps is not None:
        steps = number("--steps", steps, 0, integer=True, allow="an integer >= 0 (the total steps of the run)")
        check_run_length(f"--steps = {steps}", steps)
    doc = load_toml(path)
    if sets:
        path, doc = write_set_scene(comm, path, doc, sets, out)
    _, scene = find(doc)
    if scene is not None:
        return scene.run(path, doc, out, comm, steps=steps, fresh=fresh)
    return run_scene_file(path, doc, out, comm, steps=steps, fresh=fresh)


def check_file(path, out, steps=None, comm=None, sets=()):
    """``pdem run SCENE --check``: load and check everything a run checks at its start, without
    stepping or writing: the ranks' agreement on their input, the scene file (its scene's own
    tables, run settings, materials; a plain scene is built, so its initial overlaps and the rank
    count are checked too), the run's length and whether ``out`` could hold the output. Rank 0
    prints one line ``ok ...``; returns 0 (a problem raises, as a run would at its start).
    ``sets``: ``KEY=VALUE`` texts applied as a run applies them (nothing written)."""
    from .build.config import apply_sets, load_toml, run_settings, scene_from_dict
    from .build.validate import number
    from .driver.preflight import agree_on_input, check_run_length
    from .driver.runloop import check_output
    from .parallel.comm import get_comm
    from .scenes import SCENES, check, find

    comm, sets = get_comm(comm), list(sets or ())
    agree_on_input(comm, path, {"out": str(out), "steps": steps, "fresh": False, "check": True, "set": sets})
    if steps is not None:
        steps = number("--steps", steps, 0, integer=True, allow="an integer >= 0 (the total steps of the run)")
        check_run_length(f"--steps = {steps}", steps)
    doc = load_toml(path)
    if sets:
        doc = apply_sets(doc, sets, check)
    name, scene = find(doc)
    if scene is not None:
        scene.check(doc)
        what = f"[{name}] scene"
    else:
        sc, run = scene_from_dict(doc, scene_tables=tuple(SCENES)), run_settings(doc)
        if steps is None:
            check_run_length(f"run.steps = {run['steps']}", run["steps"])
        sim = sc.build(comm)
        n = comm.allreduce_sum_int(sim.particles.n_local)
        what = f"plain scene, {n} spheres, {steps if steps is not None else run['steps']} steps, dt = {sim.dt:.3e} s"
    check_output(comm, out)
    if comm.rank == 0:
        print(f"ok {path}: {what}, output folder {out} usable, on {comm.size} rank(s) (checked, not run)", flush=True)
    return 0


SET_SCENE = "scene_set.toml"  # the scene a run with --set runs, in its output directory


def write_set_scene(comm, path, doc, sets, out):
    """(path of ``out``/scene_set.toml, its document): ``doc`` with ``sets`` applied, written by
    rank 0 (atomically; every rank reads it after a broadcast)."""
    from .build.config import apply_sets
    from .campaign.tomlw import dumps
    from .driver.runloop import prepare_output
    from .io.atomic import atomic_write_text
    from .scenes import check

    doc = apply_sets(doc, sets, check)
    target = prepare_output(comm, out) / SET_SCENE
    if comm.rank == 0:
        header = (f"the scene run by pdem run {path} " + " ".join(f"--set {s}" for s in sets)
                  + "\n(written by pdem run; the run's scene file)")
        atomic_write_text(target, dumps(doc, header=header))
    comm.bcast(None)  # the file exists before any rank reads it
    return str(target), doc


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        """Usage errors on rank 0 only (every rank parses the same command line), exit 2."""
        if all(os.environ.get(v, "0") == "0" for v in _RANK_VARS):
            self.print_usage(sys.stderr)
            sys.stderr.write(f"pdem: error: {message}\n")
        sys.exit(EXIT_INPUT_ERROR)


def build_parser():
    """The parser of ``pdem`` (``campaign`` has its own: `pdem.campaign.cli`)."""
    ap = _Parser(prog="pdem", description="pdem: parallel DEM for railway ballast")
    ap.add_argument("--version", action="version", version=f"pdem {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("run", help="run a scene file (TOML)")
    r.add_argument("scene", help="scene file, e.g. jobs/deposition.toml")
    r.add_argument("--out", default=None, help="output directory (default runs/<scene name>)")
    r.add_argument("--steps", type=int, default=None,
                   help="override run.steps (the total of the run: a resumed run continues up to it); a track "
                        "scene stops with a checkpoint at step N (run again without it to continue)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="sets",
                   help="set a scene key (dotted, e.g. materials.ballast.young=2.8e7; a TOML value); repeatable; "
                        "the scene run is written to OUT/scene_set.toml")
    r.add_argument("--fresh", action="store_true",
                   help="ignore and remove the checkpoints in OUT/checkpoints and start from step 0")
    r.add_argument("--check", action="store_true",
                   help="check the scene file, the run's length and OUT as a run would at its start, without running "
                        "or writing anything; prints one line 'ok ...' (exit 0) or the error (exit 2)")
    sub.add_parser("campaign", help="campaigns of runs: expand, run, slurm, status (docs/campaigns.md)", add_help=False)
    return ap


def main(argv=None):
    ap = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["campaign"]:  # its own parser (pdem.campaign.cli)
        from .campaign import main as campaign_main

        return campaign_main(argv[1:])
    args = ap.parse_args(argv)
    if args.command == "run":
        from pathlib import Path

        from .driver.failures import run_guarded
        from .parallel.comm import LaunchError, configure_threads, get_comm

        try:
            comm = get_comm()
        except LaunchError as exc:  # N copies of this process: one line, from the launcher's rank 0
            if all(os.environ.get(v, "0") == "0" for v in _RANK_VARS):
                sys.stderr.write(f"pdem: {exc}\n")
            return EXIT_INPUT_ERROR
        out = args.out or str(Path("runs") / Path(args.scene).stem)

        from .driver import runlog

        def run():
            configure_threads(comm)
            if args.check:
                return check_file(args.scene, out, steps=args.steps, comm=comm, sets=args.sets)
            return run_file(args.scene, out, steps=args.steps, fresh=args.fresh, comm=comm, sets=args.sets)

        if comm.rank == 0 and not args.check:  # --check writes nothing
            runlog.start(argv)  # OUT/log.txt: what rank 0 prints, from here to the post-processing
        try:
            status = run_guarded(comm, run)
            if status == 0 and comm.rank == 0 and not args.check:
                post_process(out)
        finally:
            runlog.stop()
        return status
    return 0


def post_process(out):
    """The post-processing the run in ``out`` declared (none for a plain scene or a stopped run).
    Skipped for want of a package: a one-line note, then the run's timing table (which the
    summary would have shown)."""
    from .format.run import read_run_info

    info = read_run_info(out)
    if info is None:
        return
    package = analysis_package()
    command = f"python -m {package} summary {out}"
    try:
        analysis = import_module(f"{package}.__main__")
        missing = analysis.missing_package()
        if missing is None:
            status = analysis.main(["summary", str(out)])
    except ModuleNotFoundError as exc:
        if exc.name is None or exc.name.split(".")[0] in ("pdem", package):
            raise
        missing = exc.name.split(".")[0]
    if missing is not None:
        print(f"post-processing skipped: {command} needs the Python package {missing} "
              "(pip install pdem[analysis]); the run itself is complete", flush=True)
        if info.get("timing"):
            print(f"\n{info['timing']}", flush=True)
        return
    print(f"post-processing: {command}: exit status {status}", flush=True)


def analysis_package():
    """``pdem_analysis`` (installed from the wheel) or ``analysis`` (a source checkout)."""
    return "pdem_analysis" if find_spec("pdem_analysis") is not None else "analysis"


if __name__ == "__main__":
    sys.exit(main())
