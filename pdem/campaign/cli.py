"""``pdem campaign COMMAND``: check, expand, run, slurm, status, member.

Bad input (campaign file, base scene, a member's key, a directory holding another campaign)
prints one line ``pdem: error: ...`` and exits 2. ``run`` exits 0 when every member is done, 3
when stopped on SIGTERM/SIGINT (run it again to resume), 1 otherwise; ``member`` exits with the
member's status (0, 2, 3, 4).
"""
import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

from ..errors import EXIT_INPUT_ERROR, InputError
from .layout import read_manifest, write_campaign, write_text_if_changed
from .spec import load_campaign


def _parser():
    ap = argparse.ArgumentParser(prog="pdem campaign", description="campaigns: many runs of one base scene "
                                 "(seeds, parameter grids, cases); see docs/campaigns.md")
    sub = ap.add_subparsers(dest="command", required=True)

    def add(name, help, file_help="campaign file (TOML)"):
        p = sub.add_parser(name, help=help)
        p.add_argument("file", help=file_help)
        p.add_argument("--out", default=None, help="campaign directory (default: [campaign] out, else runs/<name>)")
        return p

    add("check", "check the campaign file, its base scene, every member's scene and the campaign directory, "
                 "writing nothing: one line 'ok ...' (exit 0) or the error (exit 2)")
    add("expand", "write the member directories and the manifest (idempotent)")
    r = add("run", "expand, then run the members here, several at once within the cores")
    r.add_argument("--cores", type=int, default=None, help="cores to use (default [local] cores, else all)")
    r.add_argument("--retry-failed", action="store_true", help="run failed members again too")
    s = add("slurm", "expand, then write OUT/campaign.sbatch (a SLURM job array)")
    s.add_argument("--submit", action="store_true", help="also submit it with sbatch")
    st = add("status", "list members: done / running / stopped / failed / pending",
             file_help="campaign file, or a campaign directory")
    st.add_argument("--json", action="store_true", help="print JSON instead of a table")
    m = sub.add_parser("member", help="run one member in the foreground (what a SLURM array task does)")
    m.add_argument("dir", help="campaign directory")
    m.add_argument("member", help="member name or index in the manifest (SLURM_ARRAY_TASK_ID)")
    m.add_argument("--launcher", choices=("local", "srun", "mpiexec"), default="local")
    m.add_argument("--launcher-arg", action="append", default=[], help="extra argument of the launcher (repeat)")
    return ap


def _campaign(args):
    camp = load_campaign(args.file, out=args.out)
    return camp, write_campaign(camp)


def main(argv=None):
    args = _parser().parse_args(argv)
    try:
        return _dispatch(args)
    except InputError as exc:
        print(f"pdem: error: {' '.join(str(exc).split())}", file=sys.stderr, flush=True)
        return EXIT_INPUT_ERROR


def _dispatch(args):
    if args.command == "member":
        from .member import find_entry, run_member

        man = read_manifest(args.dir)
        return run_member(args.dir, find_entry(man, args.member), args.launcher, args.launcher_arg,
                          log=lambda m: print(m, flush=True))
    if args.command == "status":
        from .status import format_status, status_rows

        p = Path(args.file)
        if p.is_dir():
            out, man = p, read_manifest(p)
        else:
            camp = load_campaign(p, out=args.out)
            out = Path(camp.out)
            if (out / "campaign.json").exists():
                man = read_manifest(out)
                if man["name"] != camp.name:
                    raise InputError(f"{out}: holds the members of campaign {man['name']!r}, not of {camp.name!r}")
            else:
                from .layout import manifest

                man = manifest(camp)
        rows = status_rows(out, man)
        print(json.dumps(rows, indent=1) if args.json else format_status(out, man, rows), flush=True)
        return 0
    if args.command == "check":
        from .layout import plan_campaign

        camp = load_campaign(args.file, out=args.out)
        plan_campaign(camp)
        print(f"ok {args.file}: campaign {camp.name}, {len(camp.members)} members checked, directory {camp.out} "
              "usable (nothing written)", flush=True)
        return 0
    camp, man = _campaign(args)
    out = Path(camp.out)
    if args.command == "expand":
        print(f"campaign {camp.name}: {len(man['members'])} members in {out}", flush=True)
        for e in man["members"]:
            print(f"  {e['name']}: " + ", ".join(f"{k} = {v!r}" for k, v in e["params"].items()), flush=True)
        return 0
    if args.command == "run":
        from .local import run_local

        if args.cores is not None and args.cores < 1:
            raise InputError(f"--cores = {args.cores}: must be >= 1")
        return run_local(out, man, cores=args.cores or camp.cores, retry_failed=args.retry_failed,
                         log=lambda m: print(m, flush=True))
    if args.command == "slurm":
        from .slurm import SCRIPT, slurm_script

        text = slurm_script(camp, man, out)
        (out / "slurm").mkdir(exist_ok=True)
        path = out / SCRIPT
        write_text_if_changed(path, text)
        path.chmod(0o755)
        print(f"wrote {path} ({len(man['members'])} array tasks); submit with: sbatch {path}", flush=True)
        if args.submit:
            if shutil.which("sbatch") is None:
                raise InputError("--submit: sbatch not found on PATH")
            r = subprocess.run(["sbatch", str(path)], capture_output=True, text=True)
            print((r.stdout + r.stderr).strip(), flush=True)
            return 0 if r.returncode == 0 else 1
        return 0
    return 0
