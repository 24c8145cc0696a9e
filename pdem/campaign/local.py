"""The local runner: the members of a campaign on this machine, several at once within its cores.

Owns `run_local`. Members are started in manifest order while the cores they use (ranks ×
threads each) fit in ``cores``; done members are skipped, stopped ones (exit 3, or interrupted)
resume from their checkpoints, pending ones start, failed ones are skipped unless
``retry_failed``. A member failing never stops the others. SIGTERM or SIGINT to the runner is
forwarded to the running members as SIGTERM (pdem writes a checkpoint and exits 3), no new
member starts, and the runner exits 3 once they have stopped: running the same command again
resumes the campaign. A member killed by SIGKILL (exit 137) does not stop the others either, and
the next run resumes it from its checkpoint; a finished member is never run again.

Exit status: 0 every member done, 3 stopped on a signal, 1 otherwise (a member failed or is
run by another process).
"""
import os
import signal
import time
from pathlib import Path

from ..errors import InputError
from .member import MemberProcess
from .record import EXIT_KILLED, EXIT_STOPPED, member_state


def available_cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def run_local(out, man, cores=None, retry_failed=False, log=print, poll_s=0.2):
    """Run the members of the campaign directory ``out`` (manifest ``man``); returns the exit status."""
    out = Path(out)
    cores = cores or available_cores()
    entries = man["members"]
    for e in entries:
        if e["ranks"] * e["threads"] > cores:
            raise InputError(f"member {e['name']}: {e['ranks']} rank(s) x {e['threads']} thread(s) need more than the "
                             f"{cores} core(s) available; lower campaign.ranks/threads or give --cores")
    todo, skipped = [], {"done": 0, "running": [], "failed": []}
    for e in entries:
        state, _, _ = member_state(out / e["dir"])
        if state == "done":
            skipped["done"] += 1
        elif state == "running":
            skipped["running"].append(e["name"])
        elif state == "failed" and not retry_failed:
            skipped["failed"].append(e["name"])
        else:
            todo.append((e, state))
    log(f"campaign {man['name']}: {len(entries)} members in {out}: {skipped['done']} done, {len(todo)} to run"
        + (f" ({sum(s == 'stopped' for _, s in todo)} resume from a checkpoint)" if todo else "")
        + (f", {len(skipped['failed'])} failed (skipped; --retry-failed runs them again)" if skipped["failed"] else "")
        + (f", {len(skipped['running'])} run by another process" if skipped["running"] else "")
        + f"; {cores} core(s)")
    stop = []
    previous = {s: signal.signal(s, lambda signum, frame: stop.append(signum)) for s in (signal.SIGTERM, signal.SIGINT)}
    running, results, forwarded = [], [], False
    n_total = len(todo)
    try:
        while todo or running:
            if stop and not forwarded:
                log(f"campaign {man['name']}: {signal.Signals(stop[0]).name} received: stopping {len(running)} running "
                    "member(s) (they write a checkpoint); run the same command again to resume")
                for mp in running:
                    mp.stop()
                todo.clear()
                forwarded = True
            used = sum(mp.cores for mp in running)
            while todo and not stop and used + todo[0][0]["ranks"] * todo[0][0]["threads"] <= cores:
                e, state = todo.pop(0)
                mp = MemberProcess(out, e)
                if not mp.start():
                    log(f"{e['name']}: another process is running or has finished it; skipped")
                    skipped["running"].append(e["name"])
                    continue
                running.append(mp)
                used += mp.cores
                log(f"[{n_total - len(todo)}/{n_total}] {e['name']}: {'resumed' if state == 'stopped' else 'started'} "
                    f"({mp.ranks} rank(s) x {mp.threads} thread(s))")
            for mp in list(running):
                rc = mp.poll()
                if rc is None:
                    continue
                running.remove(mp)
                results.append((mp.name, rc))
                what = {0: "done", EXIT_STOPPED: "stopped (checkpointed)",
                        EXIT_KILLED: "killed (SIGKILL; the next run resumes it from its checkpoint)"}.get(rc, "FAILED")
                msg = "" if rc in (0, EXIT_STOPPED, EXIT_KILLED) else ": " + member_state(mp.dir)[2]
                log(f"{mp.name}: {what}, exit {rc}, {mp.wall:.1f} s{msg}")
            if running or todo:
                time.sleep(poll_s)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    states = [member_state(out / e["dir"])[0] for e in entries]
    counts = {s: states.count(s) for s in ("done", "stopped", "failed", "pending", "running")}
    log(f"campaign {man['name']}: " + ", ".join(f"{n} {s}" for s, n in counts.items() if n))
    if stop:
        return EXIT_STOPPED
    return 0 if counts["done"] == len(entries) else 1
