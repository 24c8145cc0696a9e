"""Running a scene file: output, progress, signals, checkpoints, final timing table and plot.

`run_scene_file(path, out_dir)` is what ``python -m pdem run`` calls on every rank. It writes to
`out_dir`: ``results.h5`` (schema pdem-results v1: /series of time, energies, contacts,
unbalanced force, wall forces), ``snapshots.h5``/``.xmf`` if the scene asks, checkpoints in
``checkpoints/`` (run.checkpoint_every steps, run.checkpoint_every_s wall seconds, the newest
run.checkpoint_keep kept, 0 = all; always one at the end), ``results.png`` and ``summary.txt``.
SIGTERM/SIGUSR1 make all ranks agree, write a checkpoint and exit with status 3
(`pdem.io.signals`). Started again on the same directory, a run resumes from the newest valid
checkpoint (a damaged newer one is reported and skipped) and appends to its results; ``--fresh``
removes the old checkpoints and starts over.
"""
import json
import sys
import time as _time
from pathlib import Path

import numpy as np

from . import __version__, observables
from .config import load_toml, run_settings, scene_from_dict
from .io.checkpoint import CheckpointError, find_resume_checkpoint, list_checkpoints, read_checkpoint, write_checkpoint
from .io.signals import EXIT_CHECKPOINTED_ON_SIGNAL, install_signal_handlers
from .io.snapshots import SnapshotWriter
from .io.timeseries import TimeSeriesWriter
from .parallel.comm import configure_threads, get_comm

SERIES = {"step": "-", "time": "s", "dt": "s", "kinetic_energy": "J", "elastic_energy": "J",
          "contacts_per_particle": "-", "unbalanced_force": "-", "bed_top": "m", "floor_force_z": "N"}


def _log(comm, *args):
    if comm.rank == 0:
        print(*args, flush=True)


def sample(sim):
    e = sim.energy()
    wf = observables.wall_forces(sim)
    return {"step": sim.step, "time": sim.time, "dt": sim.dt, "kinetic_energy": e["kinetic"] + e["rotational"],
            "elastic_energy": e["elastic"], "contacts_per_particle": sim.contacts_per_particle(),
            "unbalanced_force": observables.unbalanced_force(sim), "bed_top": observables.bed_top(sim),
            "floor_force_z": float(wf[0, 2]) if len(wf) else 0.0}


def write_root_attrs(path, scene_spec, kind):
    import h5py

    with h5py.File(path, "a") as f:
        f.attrs["scene"] = json.dumps(scene_spec)
        f.attrs["pdem_version"] = __version__
        f.attrs["kind"] = kind


def series_figure(h5_path, rows, cols, size):
    """(series dict, figure, axes) for a plot of the /series of a results file (Agg backend)."""
    import h5py
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with h5py.File(h5_path, "r") as f:
        s = {k: f["series"][k][...] for k in f["series"]}
    fig, ax = plt.subplots(rows, cols, figsize=size, sharex=True)
    return s, fig, ax


def save_figure(fig, png_path):
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(png_path, dpi=110)
    plt.close(fig)


def plot_energy(ax, t, ke):
    """Kinetic energy on a log axis, clipped 12 decades below its maximum (it starts at 0)."""
    ax.semilogy(t, np.maximum(ke, 1e-12 * max(float(ke.max()), 1e-300)))
    ax.set_ylabel("kinetic energy [J]")


def plot_series(results_path, png_path):
    s, fig, ax = series_figure(results_path, 2, 2, (10, 7))
    t = s["time"]
    plot_energy(ax[0, 0], t, s["kinetic_energy"])
    ax[0, 1].plot(t, s["contacts_per_particle"])
    ax[0, 1].set_ylabel("contacts per particle [-]")
    ax[1, 0].semilogy(t, np.maximum(s["unbalanced_force"], 1e-12))
    ax[1, 0].set_ylabel("unbalanced force ratio [-]")
    ax[1, 1].plot(t, s["floor_force_z"])
    ax[1, 1].set_ylabel("force on the floor, z [N]")
    for a in ax[1]:
        a.set_xlabel("time [s]")
    save_figure(fig, png_path)


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

    def log(self, *args):
        _log(self.comm, *args)

    def checkpoint(self, sim, why):
        t0 = _time.perf_counter()
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

    def advance(self, sim, n_steps, on_step=None, until=None, until_every=100, last_step=None):
        """Advance up to ``n_steps`` steps, calling ``on_step(sim)`` after each; stop early when
        ``until(sim)`` (a collective decision) is true, checked every ``until_every`` steps.
        Returns "done", "until" or "signal" (a checkpoint was written, ``status`` is set).
        ``last_step`` (default: the step after n_steps) is the step of the whole run's end, for
        the ETA and to skip a scheduled checkpoint there."""
        run, comm = self.run, self.comm
        step0, wall0 = sim.step, _time.perf_counter()
        last_step = sim.step + n_steps if last_step is None else last_step
        n_total = comm.allreduce_sum_int(sim.particles.n_local)
        for _ in range(max(int(n_steps), 0)):
            sim.advance()
            k = sim.step
            t0 = _time.perf_counter()
            if on_step is not None:
                on_step(sim)
            if run["progress_every"] and k % run["progress_every"] == 0:
                el = _time.perf_counter() - wall0
                done = k - step0
                rate = n_total * done / el if el > 0 else 0.0
                eta = el / max(done, 1) * (last_step - k)
                self.log(f"step {k:>9d}  t = {sim.time:.5e} s  dt = {sim.dt:.3e} s  contacts/particle = "
                         f"{sim.contacts_per_particle():.2f}  {rate / 1e6:.2f} M particle-steps/s  ETA {eta:.0f} s")
            sim.timers.add("output", t0)
            if k % 100 == 0 and self.stop.stop_requested(comm):  # collective: the same step on every rank
                self.log(f"step {k}: stop signal received; writing a checkpoint and stopping "
                         f"(exit status {EXIT_CHECKPOINTED_ON_SIGNAL})")
                self.checkpoint(sim, "stop signal")
                self.status = EXIT_CHECKPOINTED_ON_SIGNAL
                return "signal"
            if until is not None and k % until_every == 0 and until(sim):
                return "until"
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


def prepare_output(comm, out):
    out = Path(out)
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    comm.barrier()
    return out


def run_scene_file(path, out_dir, steps=None, fresh=False):
    """Run the scene file on this process's ranks; returns the exit status.

    A file with a ``[box_test]`` table runs the box test (`pdem.boxtest`). Otherwise ``steps``
    (default run.steps) is the step count of the whole run: if ``out_dir/checkpoints`` holds a
    valid checkpoint (and not ``fresh``), the run resumes from the newest one and continues to
    that step, appending to the time series and snapshots. Checkpoints are written on the
    schedule of `RunLoop`, on SIGTERM/SIGUSR1 (then the exit status is
    EXIT_CHECKPOINTED_ON_SIGNAL) and at the end."""
    comm = get_comm()
    configure_threads(comm)
    doc = load_toml(path)
    if "box_test" in doc:
        from .boxtest import run_box_test

        return run_box_test(path, doc, out_dir, comm, steps=steps, fresh=fresh)
    scene, run = scene_from_dict(doc), run_settings(doc)
    out = prepare_output(comm, out_dir)
    t_start = _time.perf_counter()
    loop = RunLoop(comm, out, run, path, Path(path).read_text())
    resume = resume_point(comm, loop.ckdir, fresh)
    sim = scene.build(comm)
    if resume is not None:
        tables, meta = read_checkpoint(resume)
        try:
            sim.restore_checkpoint(tables, meta)
        except (ValueError, KeyError) as exc:
            raise CheckpointError(resume, f"cannot continue this scene from it: {exc}") from None
        del tables
        loop.log(f"resuming from {resume} at step {sim.step} (t = {sim.time:.6e} s, written by pdem "
                 f"{meta.get('pdem_version')})")
        loop.last_ckpt_step = sim.step
    step0 = sim.step
    n_total = comm.allreduce_sum_int(sim.particles.n_local)
    n_steps = run["steps"] if steps is None else steps
    loop.log(f"pdem {__version__}: {path} on {comm.size} rank(s), {n_total} spheres, {len(sim.walls)} walls, "
             f"{len(sim.facets)} facets, {n_steps} steps, dt = {sim.dt:.3e} s")
    results = out / "results.h5"
    resumed = resume is not None
    series = TimeSeriesWriter(results, SERIES, every=10, comm=comm, append=resumed,
                              restart_step=sim.step if resumed else None)
    loop.flush.append(series)
    if comm.rank == 0:
        write_root_attrs(results, sim.spec, run["kind"])
    snaps = (SnapshotWriter(out, comm=comm, append=resumed, restart_step=sim.step if resumed else None,
                            log=lambda m: print(m, flush=True))
             if run["snapshot_every"] else None)

    def on_step(sim):
        if run["output_every"] and sim.step % run["output_every"] == 0:
            series.append(sample(sim))
        if snaps and sim.step % run["snapshot_every"] == 0:
            write_snapshot(snaps, sim)

    if not resumed:
        series.append(sample(sim))
        if snaps:
            write_snapshot(snaps, sim)
    if sim.step > n_steps:
        loop.log(f"the checkpoint is at step {sim.step}, beyond the {n_steps} steps asked: nothing to run")
    loop.advance(sim, n_steps - sim.step, on_step=on_step, last_step=n_steps)
    if loop.status == 0 and loop.last_ckpt_step != sim.step:
        loop.checkpoint(sim, "end of run")
    series.close()
    loop_s = _time.perf_counter() - loop.wall0
    if comm.rank == 0:
        plot_series(results, out / "results.png")
    last = sample(sim)
    if comm.rank == 0:
        rate = n_total * (sim.step - step0) / loop_s if loop_s > 0 else 0.0
        summary = [f"scene: {path}", f"ranks: {comm.size}", f"spheres: {n_total}", f"steps: {sim.step}",
                   f"simulated time: {sim.time:.6g} s", f"final dt: {sim.dt:.4g} s",
                   f"contacts per particle: {last['contacts_per_particle']:.3f}",
                   f"unbalanced force ratio: {last['unbalanced_force']:.4g}", f"bed top: {last['bed_top']:.5g} m",
                   f"force on floor z: {last['floor_force_z']:.6g} N", f"loop wall time: {loop_s:.2f} s",
                   f"throughput: {rate / 1e6:.3f} M particle-steps/s", "", sim.timing_table()]
        (out / "summary.txt").write_text("\n".join(summary) + "\n")
        print("\n".join(summary[-2 - sim.timing_table().count('\n'):]), flush=True)
        print(f"wrote {results}, {out / 'results.png'}, {out / 'summary.txt'}"
              f"{', snapshots.xmf' if snaps else ''} (total {_time.perf_counter() - t_start:.1f} s)", flush=True)
    loop.close()
    return loop.status


def write_snapshot(snaps, sim):
    p = sim.particles
    nl = p.n_local
    snaps.write(sim.step, sim.time, p.gid[:nl], p.pos[:nl], p.radius[:nl], p.vel[:nl])
