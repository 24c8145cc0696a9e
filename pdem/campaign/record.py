"""What happened to a member: its run record (run.json), its lock and its state.

Owns the writing of the run record (read by `pdem.format.campaign.read_run`) and the states of
`STATES`. ``run.json`` holds one entry per attempt (``start``, ``end`` (ISO times, ``end`` null
while it runs), ``wall_s``, ``exit``, ``ranks``, ``threads``, ``core_s`` = wall × ranks × threads,
``cpu_s`` = the CPU time its processes used, ``host``, ``launcher``, ``slurm_job``) and the totals
over attempts (``wall_s``, ``core_s``, ``cpu_s``, the last ``exit``), which the error-vs-runtime
report reads as the member's cost. A member being run holds an exclusive `flock` on
``<member>/.lock`` (inherited by its processes), so any process can tell that it is running.

States: done (last exit 0), running (locked), stopped (last exit 3: checkpointed on a signal;
last exit `EXIT_KILLED`, 128 + SIGKILL: killed with ``kill -9`` or by the OOM killer, where no
checkpoint could be written but the earlier ones and the results up to them are whole; or an
attempt with no exit recorded and no process holding its lock: the runner itself was killed;
all of them resume from the newest checkpoint), failed (any other exit; the message is the last
``pdem: error``/``pdem: unstable`` line of its log), pending (never started).
"""
import datetime as _dt
import fcntl
import os
import signal
import socket
from pathlib import Path

from ..errors import EXIT_CHECKPOINTED_ON_SIGNAL, EXIT_DONE
from ..format.campaign import ATTEMPT_MARK, LOCK, LOG, RUN, read_run
from .layout import json_text, write_text_if_changed

STATES = ("done", "running", "stopped", "failed", "pending")
EXIT_STOPPED = EXIT_CHECKPOINTED_ON_SIGNAL
EXIT_KILLED = 128 + signal.SIGKILL  # a member (or one of its ranks) killed by SIGKILL: it resumes


def now():
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def _totals(rec):
    ended = [a for a in rec["attempts"] if a.get("end")]
    rec["wall_s"] = sum(a["wall_s"] for a in ended)
    rec["core_s"] = sum(a["core_s"] for a in ended)
    cpu = [a.get("cpu_s") for a in ended]
    rec["cpu_s"] = sum(cpu) if cpu and None not in cpu else None
    rec["exit"] = rec["attempts"][-1].get("exit") if rec["attempts"] else None
    return rec


def start_attempt(d, name, ranks, threads, launcher):
    """Append a started attempt to run.json and a marker line to the log; returns the record."""
    d = Path(d)
    rec = read_run(d) or {"member": name, "attempts": []}
    job = os.environ.get("SLURM_ARRAY_JOB_ID")
    slurm_job = f"{job}_{os.environ.get('SLURM_ARRAY_TASK_ID')}" if job else os.environ.get("SLURM_JOB_ID")
    rec["attempts"].append({"start": now(), "end": None, "wall_s": None, "exit": None, "ranks": ranks,
                            "threads": threads, "core_s": None, "host": socket.gethostname(), "pid": os.getpid(),
                            "launcher": launcher, "slurm_job": slurm_job})
    write_text_if_changed(d / RUN, json_text(_totals(rec)))
    with open(d / LOG, "a") as fh:
        fh.write(f"{ATTEMPT_MARK} {len(rec['attempts'])} started {rec['attempts'][-1]['start']} on "
                 f"{rec['attempts'][-1]['host']}: {ranks} rank(s) x {threads} thread(s) ===\n")
    return rec


def end_attempt(d, rec, exit_status, wall_s, cpu_s=None):
    """Record the end of the last attempt (exit status, wall time [s], core-seconds allocated and,
    if measured, the CPU seconds used by its processes: on a shared machine the cost that does not
    depend on the load)."""
    a = rec["attempts"][-1]
    a.update(end=now(), exit=int(exit_status), wall_s=round(float(wall_s), 3),
             core_s=round(float(wall_s) * a["ranks"] * a["threads"], 3),
             cpu_s=None if cpu_s is None else round(float(cpu_s), 3))
    write_text_if_changed(Path(d) / RUN, json_text(_totals(rec)))
    return rec


def take_lock(d):
    """An open file holding the exclusive lock of member directory ``d``, or None if another
    process holds it. Keep the file open while the member runs (and let its processes inherit it)."""
    fh = open(Path(d) / LOCK, "a")
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.close()
        return None
    return fh


def is_locked(d):
    """True if some process holds the lock of member directory ``d`` (it is running)."""
    p = Path(d) / LOCK
    if not p.exists():
        return False
    with open(p, "a") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    return False


def failure_message(d):
    """The last ``pdem: error``/``pdem: unstable`` line of the member's last attempt (else the
    last line of its log)."""
    try:
        text = (Path(d) / LOG).read_text(errors="replace")
    except FileNotFoundError:
        return ""
    last = text.rsplit(ATTEMPT_MARK, 1)[-1].splitlines()[1:]
    lines = [x.strip() for x in last if x.strip()]
    tagged = [x for x in lines if x.startswith(("pdem: error", "pdem: unstable"))]
    return tagged[-1] if tagged else (lines[-1] if lines else "")


def member_state(d):
    """(state, record or None, message) of member directory ``d``."""
    d = Path(d)
    rec = read_run(d)
    if is_locked(d):
        return "running", rec, ""
    if rec is None or not rec["attempts"]:
        return "pending", rec, ""
    a = rec["attempts"][-1]
    if a.get("end") is None:
        return "stopped", rec, ("interrupted: no exit status recorded (the runner was killed); runs again from its "
                                "checkpoint")
    if a["exit"] == EXIT_DONE:
        return "done", rec, ""
    if a["exit"] == EXIT_STOPPED:
        return "stopped", rec, "stopped on a signal (exit 3); runs again from its newest checkpoint"
    if a["exit"] == EXIT_KILLED:
        return "stopped", rec, ("killed by SIGKILL (exit 137: kill -9 or out of memory); runs again from its newest "
                                "checkpoint")
    return "failed", rec, failure_message(d) or f"exit status {a['exit']}"
