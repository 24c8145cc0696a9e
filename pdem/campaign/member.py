"""Running one member: ``pdem run`` as a subprocess, its log, run record, lock and signals.

Owns `MemberProcess` (used by the local runner for several members at once, and by
`run_member` for one member of a SLURM array task) and the launch command. The engine is
reached through its command line only:

    python -m pdem run OUT/<member>/scene.toml --out OUT/<member>              (1 rank, local)
    <venv>/bin/mpiexec -n R [launcher_args] python -m pdem run ...              (R ranks; SLURM default)
    srun --ntasks=R --cpus-per-task=T [launcher_args] python -m pdem run ...  (SLURM, launcher = "srun")

with NUMBA_NUM_THREADS = T, OMP_NUM_THREADS = 1. Running it again on the same directory resumes
from its newest checkpoint. The member runs in a session of its own (a Ctrl-C at the terminal
reaches only the runner). Started here (not by srun, which handles signals itself and starts the
tasks elsewhere), it starts with SIGTERM and SIGUSR1 ignored until pdem installs its own
handlers. `stop` sends SIGTERM to its process group, and again every `RESEND_S` seconds until
pdem acknowledges it in the log (`STOP_ACK`) or exits, so a stop that arrives while pdem is still
starting is not lost: pdem then writes a checkpoint and exits with status 3. A member that a stop
killed instead (an MPI rank still starting, or already past its step loop) is recorded as stopped
too: pdem's checkpoints and result files are written so that running it again resumes cleanly.
A member killed by SIGKILL without a stop (``kill -9``, the OOM killer; under mpiexec one of its
ranks: Hydra then exits with status 9) is recorded with exit `EXIT_KILLED` (137), which
`pdem.campaign.record.member_state` counts as stopped: the next run resumes it from its newest
checkpoint.
"""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from ..format.campaign import LOG, SCENE, read_run
from .record import EXIT_KILLED, EXIT_STOPPED, end_attempt, start_attempt, take_lock

RESEND_S = 2.0
STOP_ACK = "stop signal received"  # what pdem logs when it has seen the stop signal
LAUNCHERS = ("local", "mpiexec", "srun")
KILLED_BY_STOP = {signal.SIGTERM, signal.SIGUSR1, 128 + signal.SIGTERM, 128 + signal.SIGUSR1}


def launch_command(launcher, ranks, threads, scene, out, launcher_args=()):
    """The command line that runs ``scene`` into ``out`` on ``ranks`` ranks."""
    py = sys.executable  # the venv's python: its bin/ holds mpiexec
    cmd = [py, "-m", "pdem", "run", str(scene), "--out", str(out)]
    if launcher == "srun":
        return ["srun", f"--ntasks={ranks}", f"--cpus-per-task={threads}", *launcher_args, *cmd]
    if launcher == "mpiexec" or ranks > 1:
        return [str(Path(py).parent / "mpiexec"), "-n", str(ranks), *launcher_args, *cmd]
    return cmd


def member_env(threads):
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    return env


def _ignore_stop_signals():  # in the child, before exec: pdem's own handlers replace these
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.signal(signal.SIGUSR1, signal.SIG_IGN)


class MemberProcess:
    """One attempt at one member: `start`, then `poll` until it returns the exit status."""

    def __init__(self, out, entry, launcher="local", launcher_args=()):
        self.dir = (Path(out) / entry["dir"]).resolve()
        self.name = entry["name"]
        self.ranks, self.threads = int(entry["ranks"]), int(entry["threads"])
        self.launcher, self.launcher_args = launcher, tuple(launcher_args)
        self.proc = self.lock = self.log = self.rec = None
        self.t0 = None
        self.stop_sent = None  # time of the last stop signal sent
        self.acked = False     # pdem logged that it saw the stop
        self.log_offset = 0
        self.cpu = None        # CPU time [s] of the finished attempt's process tree

    @property
    def cores(self):
        return self.ranks * self.threads

    def start(self):
        """Start the attempt; False if another process holds the member's lock or finished it."""
        for _ in range(20):  # a status query holds a shared lock for an instant
            self.lock = take_lock(self.dir)
            if self.lock is not None:
                break
            time.sleep(0.05)
        else:
            return False
        done = read_run(self.dir)
        if done and done["attempts"] and done["attempts"][-1].get("end") and done["exit"] == 0:
            self.lock.close()  # another runner finished it since this one looked
            return False
        self.rec = start_attempt(self.dir, self.name, self.ranks, self.threads, self.launcher)
        self.log = open(self.dir / LOG, "a")
        cmd = launch_command(self.launcher, self.ranks, self.threads, self.dir / SCENE, self.dir, self.launcher_args)
        self.log.write("$ " + " ".join(cmd) + "\n")
        self.log.flush()
        self.log_offset = self.log.tell()
        self.t0 = time.perf_counter()
        try:
            self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=self.log, stderr=subprocess.STDOUT,
                                         env=member_env(self.threads), start_new_session=True,
                                         pass_fds=(self.lock.fileno(),),
                                         preexec_fn=None if self.launcher == "srun" else _ignore_stop_signals)
        except OSError as exc:
            self.log.write(f"pdem: error: cannot start {cmd[0]}: {exc}\n")
            self.proc = None
        return True

    def poll(self):
        """None while it runs, else its exit status (recorded in run.json). A stop that was sent
        is sent again every RESEND_S seconds until the member exits."""
        if self.proc is None:
            return self._finish(127)
        rc = self._wait()
        if rc is None:
            if (self.stop_sent is not None and time.monotonic() - self.stop_sent >= RESEND_S
                    and not self._acknowledged()):
                self.stop()
            return None
        if rc < 0:
            self.log.write(f"pdem campaign: the member was killed by signal {-rc}\n")
            rc = 128 - rc
        elif rc == signal.SIGKILL and self._launched_by_mpiexec():
            # mpiexec (Hydra) ends the job with a killed rank's signal number as its status (pdem
            # never exits 9 itself)
            self.log.write("pdem campaign: a rank of the member was killed by signal 9\n")
            rc = EXIT_KILLED
        if self.stop_sent is not None and rc in KILLED_BY_STOP:
            self.log.write(
                f"pdem campaign: exit status {rc} after a stop signal: recorded as stopped ({EXIT_STOPPED}); "
                "running it again resumes from its newest checkpoint\n"
            )
            rc = EXIT_STOPPED
        return self._finish(rc)

    def _wait(self):
        """The exit status (None while it runs); on exit, the CPU time [s] of the member's process
        tree (user + system of it and every descendant it waited for: mpiexec, the ranks)."""
        if self.proc.returncode is not None:
            return self.proc.returncode
        pid, status, usage = os.wait4(self.proc.pid, os.WNOHANG)
        if pid == 0:
            return None
        self.cpu = usage.ru_utime + usage.ru_stime
        self.proc.returncode = os.waitstatus_to_exitcode(status)
        return self.proc.returncode

    def _launched_by_mpiexec(self):
        return self.launcher == "mpiexec" or (self.launcher == "local" and self.ranks > 1)

    def _acknowledged(self):
        if not self.acked:
            with open(self.dir / LOG, errors="replace") as fh:
                fh.seek(self.log_offset)
                self.acked = STOP_ACK in fh.read()
        return self.acked

    def _finish(self, rc):
        wall = time.perf_counter() - self.t0
        self.log.write(f"pdem campaign: exit status {rc} after {wall:.1f} s\n")
        self.log.close()
        end_attempt(self.dir, self.rec, rc, wall, self.cpu)
        self.lock.close()
        self.status, self.wall = rc, wall
        return rc

    def stop(self, signum=signal.SIGTERM):
        """Ask the member to checkpoint and stop (SIGTERM to its process group)."""
        self.stop_sent = time.monotonic()
        if self.proc is not None and self.proc.returncode is None:
            try:
                os.killpg(self.proc.pid, signum)
            except ProcessLookupError:
                pass


def find_entry(man, name_or_index):
    """The manifest entry of a member, by name or by index (an integer, e.g. SLURM_ARRAY_TASK_ID)."""
    from ..errors import InputError

    members = man["members"]
    if str(name_or_index).isdigit() and not any(e["name"] == str(name_or_index) for e in members):
        k = int(name_or_index)
        if not 0 <= k < len(members):
            raise InputError(f"member index {k}: the campaign has members 0..{len(members) - 1}")
        return members[k]
    for e in members:
        if e["name"] == name_or_index:
            return e
    raise InputError(f"member {name_or_index!r}: not in campaign {man['name']!r}")


def run_member(out, entry, launcher="local", launcher_args=(), log=print):
    """Run one member in the foreground (a SLURM array task): forwards SIGTERM, SIGUSR1 and
    SIGINT to it (pdem checkpoints and exits 3); returns its exit status. A member that is
    already done is not run again (status 0)."""
    from .record import member_state

    state, _, _ = member_state(Path(out) / entry["dir"])
    if state == "done":
        log(f"member {entry['name']}: already done; nothing to run")
        return 0
    if state == "running":
        log(f"member {entry['name']}: another process is running it (its .lock is held); not started")
        return 1
    mp = MemberProcess(out, entry, launcher, launcher_args)
    stop = []

    def on_signal(signum, frame):
        stop.append(signum)
        mp.stop(signal.SIGTERM if signum == signal.SIGINT else signum)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGTERM, signal.SIGUSR1, signal.SIGINT)}
    try:
        if not mp.start():
            log(f"member {entry['name']}: another process is running or has finished it; not started")
            return 1
        log(f"member {entry['name']}: running in {mp.dir} ({mp.ranks} rank(s) x {mp.threads} thread(s), "
            f"log {mp.dir / LOG})")
        if stop:
            mp.stop(stop[0] if stop[0] != signal.SIGINT else signal.SIGTERM)
        while (rc := mp.poll()) is None:
            time.sleep(0.2)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    log(f"member {entry['name']}: exit status {rc} after {mp.wall:.1f} s"
        + (" (checkpointed: running it again resumes)" if rc == EXIT_STOPPED else ""))
    return rc
