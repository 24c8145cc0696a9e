"""The run loop around `Simulation.advance`: progress, stop signals, scheduled checkpoints, resume.

`RunLoop` is what every kind of run (plain, staged) does between steps: progress lines (a rich
progress bar on a terminal, plain lines in a batch log), the stop signal (SIGTERM/SIGUSR1,
polled collectively every 100 steps: then a checkpoint and exit status 3), scheduled checkpoints
(run.checkpoint_every steps, run.checkpoint_every_s wall seconds as measured on rank 0, the
newest run.checkpoint_keep kept) and the checkpoint writer. `resume_point` picks the checkpoint
a run continues from (the newest valid one; a damaged newer one is reported and skipped).
"""
import os
import sys
import time as _time
from pathlib import Path

from ..checks.diagnostics import check_finite
from ..errors import InputError, InstabilityError
from ..format.run import clear_run_info
from ..io.checkpoint import (
    CheckpointError,
    find_resume_checkpoint,
    list_checkpoints,
    write_checkpoint,
)
from ..io.signals import EXIT_CHECKPOINTED_ON_SIGNAL, install_signal_handlers
from . import runlog

_compiled = False  # this process has run a first step (numba's kernels compiled or loaded from the cache)


def log(comm, *args):
    """Print on rank 0."""
    if comm.rank == 0:
        print(*args, flush=True)


class Progress:
    """Progress of a run on rank 0: a rich progress bar when stdout is a terminal (its lines go
    to the run's log.txt, `pdem.driver.runlog`, not its redraws), else a line every ``every``
    steps (batch logs stay plain text)."""

    def __init__(self, comm, every):
        self.every = every
        self.bar = None
        if comm.rank == 0 and every and sys.stdout.isatty():
            from rich.console import Console
            from rich.file_proxy import FileProxy
            from rich.progress import BarColumn, TextColumn, TimeRemainingColumn
            from rich.progress import Progress as RichProgress

            terminal = runlog.terminal() or sys.stdout
            console = Console(file=terminal)
            # printed lines go above the bar: through rich's proxy, and to the log by the Tee
            self.bar = RichProgress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                                    TimeRemainingColumn(), transient=True, console=console,
                                    redirect_stdout=runlog.terminal() is None, redirect_stderr=False)
            self.bar.start()
            runlog.set_terminal(FileProxy(console, terminal))
            self.task = self.bar.add_task("steps", total=None, info="")

    def update(self, k, last_step, line):
        if self.bar is not None:
            self.bar.update(self.task, completed=k, total=last_step, info=line)
            runlog.log_only(line)
        else:
            print(line, flush=True)

    def close(self):
        if self.bar is not None:
            runlog.set_terminal(None)
            self.bar.stop()
            self.bar = None


def eta_text(wall_per_step, steps_left, bounded, later=(), dt=None):
    """"ETA 37 s", "ETA ≤ 37 s" or "ETA ≥ 37 s": the wall seconds left at ``wall_per_step`` [s] for
    ``steps_left`` steps of this stage (at most that many if ``bounded``: it ends on a criterion)
    and for the ``later`` stages, each (simulated seconds [s] or None if unknown, exact) run at
    this Δt ``dt`` [s] and this wall time per step. A stage that may end early adds to the upper
    bound only; an unknown one makes the estimate a lower bound."""
    now = wall_per_step * max(steps_left, 0)
    lo, hi = (0.0 if bounded else now), now
    for seconds, exact in later:
        if seconds is None:
            hi = float("inf")
            continue
        wall = wall_per_step * seconds / max(dt, 1e-300)
        lo += wall if exact else 0.0
        hi += wall
    if hi == float("inf"):
        return f"ETA \u2265 {lo:.0f} s"
    if hi - lo > 0.5:
        return f"ETA \u2264 {hi:.0f} s"
    return f"ETA {hi:.0f} s"


def resume_point(comm, ckdir, fresh):
    """(path or None): the checkpoint to resume from; with ``fresh``, old checkpoints are removed.

    Raises CheckpointError (one line) if the directory holds checkpoints but none is valid."""
    if fresh:
        if comm.rank == 0:
            old = list_checkpoints(ckdir)
            for _, p in old:
                p.unlink(missing_ok=True)
            if old:
                print(f"--fresh: removed {len(old)} old checkpoint(s) from {ckdir}", flush=True)
        comm.barrier()
        return None
    found = find_resume_checkpoint(ckdir, log=lambda m: print(m, flush=True), comm=comm)
    if found is None and list_checkpoints(ckdir):
        names = ", ".join(p.name for _, p in list_checkpoints(ckdir))
        raise CheckpointError(ckdir, f"no valid checkpoint among {names}; "
                                     "start over with --fresh (or restore a good checkpoint)")
    return found


class RunLoop:
    """What every kind of run does around `Simulation.advance`: progress lines, the stop signal
    (SIGTERM/SIGUSR1, polled collectively every 100 steps), scheduled checkpoints (every
    run.checkpoint_every steps, every run.checkpoint_every_s wall seconds as measured on rank
    0) and the checkpoint writer itself. ``extra_meta()`` adds the caller's state (e.g. the
    stage of a box test) to every checkpoint; ``flush`` lists writers whose rows must be on disk
    before a checkpoint exists."""

    def __init__(self, comm, out, run, scene_path, scene_text):
        self.comm = comm
        self.out = Path(out)
        self.run = run
        self.scene_path = str(scene_path)
        self.scene_text = scene_text
        self.ckdir = self.out / "checkpoints"
        self.keep = run["checkpoint_keep"] or None  # 0: keep every checkpoint
        self.stop = install_signal_handlers()
        self.wall0 = _time.perf_counter()
        self.last_ckpt_wall = self.wall0
        self.last_ckpt_step = None
        self.status = 0
        self.extra_meta = dict
        self.flush = []
        self.first_step_s = 0.0  # wall time of this process's first step (numba compiling), if it ran here

    def log(self, *args):
        log(self.comm, *args)

    def checkpoint(self, sim, why):
        t0 = _time.perf_counter()
        check_finite(sim)  # a checkpoint never holds a NaN: the run stops naming the body instead
        for w in self.flush:
            w.flush()
        tables, meta = sim.checkpoint_tables()
        meta.update(scene_file=self.scene_text, scene_path=self.scene_path, ranks=self.comm.size,
                    **self.extra_meta())
        written = write_checkpoint(self.ckdir, sim.step, tables, meta, self.comm, keep=self.keep)
        self.last_ckpt_wall = _time.perf_counter()
        self.last_ckpt_step = sim.step
        self.log(f"step {sim.step}: checkpoint {written} ({why}, {self.last_ckpt_wall - t0:.2f} s)")
        sim.timers.add("output", t0)
        return written

    def advance(self, sim, n_steps, on_step=None, until=None, until_every=100, last_step=None, stage=None):
        """Advance up to ``n_steps`` steps, calling ``on_step(sim)`` after each; stop early when
        ``until(sim)`` (a collective decision) is true, checked every ``until_every`` steps.
        Returns "done", "until" or "signal" (a checkpoint was written, ``status`` is set).
        ``last_step`` (default: the step after n_steps) is the step of the whole run's end, for
        the ETA and to skip a scheduled checkpoint there. ``stage`` (a staged run): (label, e.g.
        "stage 2/5 refill", whether it may end before ``last_step``, the later stages as
        `eta_text` takes them) for the progress line's whole-run ETA.

        The first step of a process compiles numba's kernels (or loads them from the cache):
        it is announced before and its wall time printed after, and not counted in the rate."""
        run, comm = self.run, self.comm
        last_step = sim.step + n_steps if last_step is None else last_step
        n_total = comm.allreduce_sum_int(sim.particles.n_local)
        step0, wall0 = sim.step, _time.perf_counter()
        progress = Progress(comm, run["progress_every"])
        try:
            return self._advance(sim, n_steps, on_step, until, until_every, last_step, step0, wall0, n_total, progress,
                                 stage)
        except InstabilityError:
            self._flush_quietly()  # the rows before the stop show how it came (all finite: FiniteSeriesWriter)
            raise
        finally:
            progress.close()

    def _flush_quietly(self):
        for w in self.flush:
            try:
                w.flush()
            except (OSError, RuntimeError):  # the instability is what the run reports
                pass

    def _first_step(self, sim):
        """The first step of this process, announced: numba compiles (or loads) the kernels."""
        global _compiled
        self.log("numba: compiling the kernels (or loading them from the cache); the first step waits for it ...")
        t0 = _time.perf_counter()
        sim.advance()
        _compiled = True
        self.first_step_s = _time.perf_counter() - t0
        self.log(f"numba: the first step took {self.first_step_s:.1f} s (compilation or cache load)")
        return sim.step, _time.perf_counter()

    def _advance(self, sim, n_steps, on_step, until, until_every, last_step, step0, wall0, n_total, progress, stage):
        run, comm = self.run, self.comm
        label, bounded, later = stage if stage is not None else ("", False, ())
        for _ in range(max(int(n_steps), 0)):
            if _compiled:
                sim.advance()
            else:  # the rate and ETA start after it
                step0, wall0 = self._first_step(sim)
            k = sim.step
            t0 = _time.perf_counter()
            if on_step is not None:
                on_step(sim)
            if run["progress_every"] and k % run["progress_every"] == 0:
                el = _time.perf_counter() - wall0
                done = k - step0
                rate = n_total * done / el if el > 0 else 0.0
                eta = eta_text(el / max(done, 1), last_step - k, bounded, later, sim.dt)
                line = (f"{label + '  ' if label else ''}step {k:>9d}  t = {sim.time:.5e} s  dt = {sim.dt:.3e} s  "
                        f"contacts/particle = {sim.contacts_per_particle():.2f}  {rate / 1e6:.2f} M particle-steps/s  "
                        f"{eta}")
                if comm.rank == 0:
                    progress.update(k, last_step, line)
            sim.timers.add("output", t0)
            # the stage's end test before the stop poll: a run stopped at step k resumes at k + 1, so
            # the test of step k must have been made (as in a run that is not stopped)
            if until is not None and k % until_every == 0 and until(sim):
                return "until"
            if k % 100 == 0 and self.stop.stop_requested(comm):  # collective: the same step on every rank
                self.log(f"step {k}: stop signal received; writing a checkpoint and stopping "
                         f"(exit status {EXIT_CHECKPOINTED_ON_SIGNAL})")
                self.checkpoint(sim, "stop signal")
                self.status = EXIT_CHECKPOINTED_ON_SIGNAL
                return "signal"
            why = []
            if run["checkpoint_every"] and k % run["checkpoint_every"] == 0:
                why.append(f"every {run['checkpoint_every']} steps")
            if run["checkpoint_every_s"] and k % 100 == 0:
                # the wall-clock interval as measured on rank 0, so that every rank agrees
                if comm.bcast(_time.perf_counter() - self.last_ckpt_wall >= run["checkpoint_every_s"]
                              if comm.rank == 0 else None):
                    why.append(f"every {run['checkpoint_every_s']:g} s")
            if why and k < last_step:
                self.checkpoint(sim, ", ".join(why))
        return "done"

    def close(self):
        self.stop.uninstall()


def prepare_output(comm, out, fresh=False):
    """The output directory ``out`` and its checkpoints/ folder, created if missing and checked
    writable by rank 0 (a probe file written and removed in each) before any work; every rank
    raises the same one-line InputError if they cannot be used (bad input found at start, not a
    failed write after the work). The account of an earlier run (run_info.json) is removed; the
    run's log.txt is opened (`pdem.driver.runlog`: truncated if ``fresh``, else appended to)."""
    out = Path(out)
    problem = _unusable_output(out) if comm.rank == 0 else None
    problem = comm.bcast(problem)
    if problem:
        raise InputError(f"--out {out}: {problem}")
    if comm.rank == 0:  # only a run that completes leaves its account
        clear_run_info(out)
        runlog.attach(out, fresh)
    return out


def check_output(comm, out):
    """Like `prepare_output`, but touching nothing (``pdem run --check``): every rank raises the
    same one-line InputError if rank 0 finds that ``out`` or its checkpoints/ folder could not be
    created or written (an existing one not a writable directory; a missing one under no
    writable directory)."""
    out = Path(out)
    problem = _unusable_output(out, _would_be_unwritable) if comm.rank == 0 else None
    problem = comm.bcast(problem)
    if problem:
        raise InputError(f"--out {out}: {problem}")
    return out


def _would_be_unwritable(d):
    """Why the directory ``d`` could not be created or written, or None (nothing is created)."""
    if d.exists():
        if not d.is_dir():
            return "exists and is not a directory"
        return None if os.access(d, os.W_OK | os.X_OK) else "cannot be written (permission denied)"
    parent = d.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f"cannot be created ({parent} is not a directory)"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"cannot be created ({parent} cannot be written)"
    return None


def _unusable_output(out, unwritable=None):
    """Why ``out`` or ``out/checkpoints`` cannot hold a run's output, or None."""
    ckdir = out / "checkpoints"
    for d, what in ((out, ""), (ckdir, f"its checkpoints folder {ckdir} ")):
        problem = (unwritable or _unwritable_directory)(d)
        if problem:
            return what + problem
    return None


def _unwritable_directory(d):
    """Why the directory ``d`` cannot be created or written, or None."""
    if d.exists() and not d.is_dir():
        return "exists and is not a directory"
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / f".pdem-write-test-{os.getpid()}"
        probe.write_bytes(b"pdem")
        probe.unlink()
    except OSError as exc:
        return f"cannot be created or written ({exc.strerror or exc})"
    return None
