"""The `pdem` command line: ``python -m pdem run SCENE.toml --out DIR``.

`pdem run` reads the scene file, finds its scene in the registry (`pdem.scenes`; a file without
a scene table is a plain scene, `pdem.driver.plain`) and runs it on this process's ranks. Bad
input prints one line (the field, the value, what is allowed) and exits 2, and so does a
checkpoint that cannot be resumed from (damaged, or written for another scene); a run stopped by
an instability prints the cause and exits 4; a run stopped by SIGTERM/SIGUSR1 after writing a
checkpoint exits 3 (`pdem.io.signals`).
"""
import argparse
import sys

from .errors import EXIT_INPUT_ERROR, EXIT_INSTABILITY, InputError, InstabilityError


def run_file(path, out, steps=None, fresh=False):
    """Run the scene file ``path`` into ``out`` on this process's ranks; returns the exit status."""
    from .config import load_toml
    from .driver.plain import run_scene_file
    from .parallel.comm import configure_threads, get_comm
    from .scenes import find

    comm = get_comm()
    configure_threads(comm)
    doc = load_toml(path)
    name, scene = find(doc)
    if scene is not None:
        return scene.run(path, doc, out, comm, steps=steps, fresh=fresh)
    return run_scene_file(path, doc, out, comm, steps=steps, fresh=fresh)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="pdem", description="pdem: parallel DEM for railway ballast")
    sub = ap.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a scene file (TOML)")
    r.add_argument("scene", help="scene file, e.g. jobs/deposition.toml")
    r.add_argument("--out", default=None, help="output directory (default runs/<scene name>)")
    r.add_argument("--steps", type=int, default=None,
                   help="override run.steps (the total of the run: a resumed run continues up to it); a track "
                        "scene stops with a checkpoint at step N (run again without it to continue)")
    r.add_argument("--fresh", action="store_true",
                   help="ignore and remove the checkpoints in OUT/checkpoints and start from step 0")
    args = ap.parse_args(argv)
    if args.command == "run":
        from pathlib import Path

        out = args.out or str(Path("runs") / Path(args.scene).stem)
        from .io.checkpoint import CheckpointError

        try:
            return run_file(args.scene, out, steps=args.steps, fresh=args.fresh)
        except InputError as exc:
            print(f"pdem: error: {exc}", file=sys.stderr)
            return EXIT_INPUT_ERROR
        except CheckpointError as exc:
            print(f"pdem: error: checkpoint {exc}", file=sys.stderr)
            return EXIT_INPUT_ERROR
        except InstabilityError as exc:
            print(f"pdem: unstable: {exc}", file=sys.stderr)
            return EXIT_INSTABILITY
    return 0


if __name__ == "__main__":
    sys.exit(main())
