"""The SLURM job-array script of a campaign: one member per array task, requeued at the wall time.

Owns `slurm_script`. The script (``OUT/campaign.sbatch``) asks for ``[slurm]`` time, partition,
account, qos and options, and per task ``campaign.ranks`` tasks × ``campaign.threads`` CPUs.
Array task k runs member k of the manifest through ``python -m pdem campaign member OUT k``
(which skips a member that is done, resumes one that has a checkpoint, records run.json, and
forwards signals to ``pdem run``). SLURM sends SIGUSR1 to the batch shell ``signal_lead``
seconds before the wall time (``--signal=B:USR1@lead``); the shell forwards it, pdem writes a
checkpoint and exits 3, and the script requeues its own array task (``scontrol requeue
<array job>_<task>``), which resumes from that checkpoint. Members with their own ranks or
threads (a [[case]] that sets them) need a script of their own: `slurm_script` refuses a mix.
"""
import shlex
import sys
from pathlib import Path

from ..errors import InputError

SCRIPT = "campaign.sbatch"


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
             f"#SBATCH --job-name={s['job_name'] or 'pdem-' + camp.name}",
             f"#SBATCH --array={array}",
             f"#SBATCH --ntasks={ranks}",
             f"#SBATCH --cpus-per-task={threads}",
             f"#SBATCH --time={s['time']}",
             f"#SBATCH --signal=B:USR1@{s['signal_lead']}",
             "#SBATCH --requeue",
             "#SBATCH --open-mode=append",
             f"#SBATCH --output={out / 'slurm'}/%A_%a.out"]
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
        f"export NUMBA_NUM_THREADS={threads} OMP_NUM_THREADS=1 MPLBACKEND=Agg",
        'echo "array task ${SLURM_ARRAY_JOB_ID:-?}_$task: member $member on $(hostname) at $(date -Is)"',
        f'"$PYTHON" -m pdem campaign member "$CAMPAIGN_DIR" "$member" --launcher {s["launcher"]}{launcher_args} &',
        "pid=$!",
        "# SIGUSR1 (the wall time is near) or SIGTERM: pass it on; pdem checkpoints and exits 3",
        "trap 'kill -USR1 $pid 2>/dev/null' USR1",
        "trap 'kill -TERM $pid 2>/dev/null' TERM",
        "wait $pid; status=$?",
        "# a trap ends wait early (status > 128): wait again for the real status (127: it was collected already)",
        'while [ "$status" -gt 128 ]; do wait $pid; s=$?; [ "$s" -eq 127 ] && break; status=$s; done',
        'if [ "$status" -eq 3 ]; then',
        '  echo "member $member checkpointed on a signal: requeueing array task ${SLURM_ARRAY_JOB_ID}_$task"',
        '  scontrol requeue "${SLURM_ARRAY_JOB_ID}_$task"',
        "fi",
        'exit "$status"',
        ""]
    return "\n".join(lines)
