"""SLURM batch scripts, one template for both uses: a single run (``jobs/templates/slurm.sbatch``,
written by `run_script`) and the job array of a campaign (``OUT/campaign.sbatch``, `slurm_script`).

What they share (`_env_lines`, `_run_lines`): the ranks are started by the venv's ``mpiexec`` by
path (MPICH Hydra starts them through the allocation; the campaign's ``launcher = "srun"`` is the
exception a site may choose), NUMBA_NUM_THREADS = the CPUs per task, OMP_NUM_THREADS = 1,
MPLBACKEND = Agg, and NUMBA_CACHE_DIR (unless set) on the shared storage of the runs, in the run
folder's parent: the kernels are compiled once for every node, task and requeue. The run goes
in the background; SLURM sends SIGUSR1 to the batch shell ``signal_lead`` seconds before the wall
time (``--signal=B:USR1@lead``), the shell forwards it (and SIGTERM), pdem writes a checkpoint
and exits 3, and the script requeues its job (``scontrol requeue``), which resumes from that
checkpoint.

Campaign: array task k runs member k of the manifest through ``python -m pdem campaign member OUT
k`` (which skips a member that is done, resumes one that has a checkpoint, records run.json, and
forwards signals to ``pdem run``); ``[slurm]`` time, partition, account, qos and options, per task
``campaign.ranks`` tasks × ``campaign.threads`` CPUs. Members with their own ranks or threads (a
[[case]] that sets them) need a script of their own: `slurm_script` refuses a mix.

``jobs/templates/slurm.sbatch`` is this module's `run_script()` (a test checks that it is current);
write it again with ``python -c "from pdem.campaign.slurm import run_script; print(run_script(), end='')"``.
"""
import shlex
import sys
from pathlib import Path

from ..errors import InputError

SCRIPT = "campaign.sbatch"
CACHE = ".numba_cache"  # in the run folder's parent


def _env_lines(threads, runs_parent):
    """The environment of the ranks: ``threads`` and ``runs_parent`` are bash expressions."""
    return [f"export NUMBA_NUM_THREADS={threads} OMP_NUM_THREADS=1 MPLBACKEND=Agg",
            "# compiled kernels on the runs' shared storage: compiled once for every node, task and requeue",
            f'export NUMBA_CACHE_DIR="${{NUMBA_CACHE_DIR:-{runs_parent}/{CACHE}}}"']


def _run_lines(command, what, job, job_label):
    """Run ``command`` in the background, forward SIGUSR1/SIGTERM, requeue ``job`` on exit 3."""
    return [
        f"{command} &",
        "pid=$!",
        "# SIGUSR1 (the wall time is near) or SIGTERM: pass it on; pdem checkpoints and exits 3",
        "trap 'kill -USR1 $pid 2>/dev/null' USR1",
        "trap 'kill -TERM $pid 2>/dev/null' TERM",
        "wait $pid; status=$?",
        "# a trap ends wait early (status > 128): wait again for the real status (127: it was collected already)",
        'while [ "$status" -gt 128 ]; do wait $pid; s=$?; [ "$s" -eq 127 ] && break; status=$s; done',
        'if [ "$status" -eq 3 ]; then',
        f'  echo "{what} checkpointed on a signal: requeueing {job_label} {job}"',
        f'  scontrol requeue "{job}"',
        "fi",
        'exit "$status"',
        ""]


def _sbatch_lines(job_name, ntasks, cpus, time, signal_lead, output):
    return [f"#SBATCH --job-name={job_name}",
            f"#SBATCH --ntasks={ntasks}",
            f"#SBATCH --cpus-per-task={cpus}",
            f"#SBATCH --time={time}",
            f"#SBATCH --signal=B:USR1@{signal_lead}",
            "#SBATCH --requeue",
            "#SBATCH --open-mode=append",
            f"#SBATCH --output={output}"]


def run_script():
    """The text of ``jobs/templates/slurm.sbatch``: one ``pdem run`` of SCENE into OUT."""
    lines = ["#!/usr/bin/env bash",
             "# SLURM batch script for one pdem run (written by pdem/campaign/slurm.py, which writes campaigns'",
             "# job arrays from the same template). Submit from the repository root:",
             "#   sbatch --export=ALL,SCENE=jobs/deposition.toml,OUT=runs/dep jobs/templates/slurm.sbatch",
             "# The ranks are started by the venv's mpiexec (PDEM_PYTHON, default .venv/bin/python, and the",
             "# mpiexec beside it). SLURM sends SIGUSR1 300 s before the wall time; pdem then writes a checkpoint",
             "# and exits with status 3, and this script requeues itself so the next allocation resumes from it.",
             "# 8 ranks suit jobs/deposition.toml (it takes at most 12: each slab along the slab axis must",
             "# be one halo, 2 r_max + skin, thick; pdem names the largest usable count if there are too many).",
             "# Larger scenes take more: override with sbatch --ntasks=N.",
             *_sbatch_lines("pdem", 8, 1, "24:00:00", 300, "%x-%j.out"),
             "set -uo pipefail",
             ': "${SCENE:?set SCENE=path/to/scene.toml}" "${OUT:?set OUT=runs/name}"',
             'PYTHON="${PDEM_PYTHON:-$PWD/.venv/bin/python}"',
             *_env_lines("${SLURM_CPUS_PER_TASK:-1}", '$(dirname "$OUT")'),
             *_run_lines('"$(dirname "$PYTHON")/mpiexec" -n "$SLURM_NTASKS" '
                         '"$PYTHON" -m pdem run "$SCENE" --out "$OUT"', "pdem", "$SLURM_JOB_ID", "job")]
    return "\n".join(lines)


def slurm_script(camp, man, out):
    """The text of the job-array script for the campaign directory ``out`` (absolute paths)."""
    out = Path(out).resolve()
    members = man["members"]
    sizes = {(e["ranks"], e["threads"]) for e in members}
    if len(sizes) > 1:
        raise InputError(f"{camp.path.name}: members ask for different ranks x threads {sorted(sizes)}; one job array "
                         "has one size: split the campaign by size")
    ranks, threads = sizes.pop()
    s = camp.slurm
    n = len(members)
    array = f"0-{n - 1}" + (f"%{s['max_running']}" if s["max_running"] else "")
    lines = ["#!/usr/bin/env bash",
             f"# SLURM job array of campaign {camp.name}: {n} members, one per array task (written by",
             f"# pdem campaign slurm {camp.path}). Submit with:  sbatch {out / SCRIPT}",
             "# At the wall time pdem checkpoints (SIGUSR1 to this shell, forwarded) and exits 3; the task then",
             "# requeues itself and resumes from the checkpoint. Finished members are skipped when a task runs again.",
             f"#SBATCH --array={array}",
             *_sbatch_lines(s["job_name"] or "pdem-" + camp.name, ranks, threads, s["time"], s["signal_lead"],
                            f"{out / 'slurm'}/%A_%a.out")]
    for k in ("partition", "account", "qos"):
        if s[k]:
            lines.append(f"#SBATCH --{k}={s[k]}")
    for opt in s["options"]:
        lines.append(f"#SBATCH {opt if opt.startswith('-') else '--' + opt}")
    q = shlex.quote
    launcher_args = "".join(f" --launcher-arg={q(a)}" for a in s["launcher_args"])
    lines += [
        "set -uo pipefail",
        f"PYTHON={q(sys.executable)}",
        f"CAMPAIGN_DIR={q(str(out))}",
        "MEMBERS=(" + " ".join(q(e["name"]) for e in members) + ")",
        'task="${SLURM_ARRAY_TASK_ID:?not a SLURM array task (submit with sbatch)}"',
        'if [ "$task" -ge "${#MEMBERS[@]}" ]; then',
        '  echo "array task $task: the campaign has ${#MEMBERS[@]} members" >&2; exit 2',
        "fi",
        'member="${MEMBERS[$task]}"',
        *_env_lines(threads, "$CAMPAIGN_DIR"),
        'echo "array task ${SLURM_ARRAY_JOB_ID:-?}_$task: member $member on $(hostname) at $(date -Is)"',
        *_run_lines(f'"$PYTHON" -m pdem campaign member "$CAMPAIGN_DIR" "$member" --launcher {s["launcher"]}'
                    f'{launcher_args}', "member $member", "${SLURM_ARRAY_JOB_ID}_$task", "array task")]
    return "\n".join(lines)
