"""A plain run of a scene file: the scene as declared, for run.steps steps, with output.

`run_scene_file(path, out_dir)` runs on every rank. It writes to `out_dir`: ``results.h5``
(`pdem.format.schema`, kind from run.kind: /series of time, energies (kinetic, elastic,
potential, their total), contacts, the largest overlap, unbalanced force, floor force; root
attribute ``external_work``; /fragments every run.fragments_every steps if set,
`pdem.driver.fragments`), ``snapshots.h5``/``.xmf`` if the scene asks, checkpoints in
``checkpoints/`` (`pdem.driver.runloop.RunLoop`; always one at the end) and, when it ends without
a stop, its account ``run_info.json`` (`pdem.format.run`: kind "scene", the final state and the
timing table), from which ``python -m analysis summary`` writes ``results.png`` and
``summary.txt``. Started again on the same directory, a run resumes from the newest valid
checkpoint and appends to its results; ``fresh`` removes the old checkpoints first.
"""
import time as _time
from pathlib import Path

from ..format.schema import RUN_SERIES, fragment_label

from ..version import __version__
from ..build.config import run_settings, scene_from_dict
from ..checks.diagnostics import check_finite
from ..format.run import scene_facts, write_run_info
from ..io.checkpoint import CheckpointError, read_checkpoint
from . import observables
from .fragments import FragmentRecorder
from .snapshots import open_snapshots, write_snapshot
from .results import finite_row, series_writer, write_root_attrs
from .preflight import check_run_length
from .runloop import RunLoop, prepare_output, resume_point


def body_columns(sim):
    """Units of the /series columns of the scene's rigid bodies and moved walls (none without):
    per box ``body_<name>_x|y|z`` (centre [m]), ``body_<name>_force_x|y|z`` (force of the spheres
    on it [N]), ``body_<name>_load`` (its force program's value now, along its direction [N]) or,
    under displacement control, ``body_<name>_displacement`` (the prescribed one [m]); per wall
    with a program ``wall_<name>_position`` [m], ``wall_<name>_force`` (along its axis [N]) and
    ``wall_<name>_displacement`` [m]."""
    cols = {}
    moved = {(t, b) for t, b, _, _ in sim.motions}
    for b, name in enumerate(sim.boxes.names if sim.boxes is not None else []):
        for c in "xyz":
            cols[f"body_{name}_{c}"] = "m"
        for c in "xyz":
            cols[f"body_{name}_force_{c}"] = "N"
        if ("box", b) in moved:
            cols[f"body_{name}_displacement"] = "m"
        elif sim.boxes.loads[b] is not None:
            cols[f"body_{name}_load"] = "N"
    for t, w, _, _ in sim.motions:
        if t == "wall":
            name = sim.walls.names[w]
            cols.update({f"wall_{name}_position": "m", f"wall_{name}_force": "N", f"wall_{name}_displacement": "m"})
    return cols


def body_sample(sim):
    """The values of `body_columns` now (the same bits on every rank: boxes and walls are
    replicated, their forces exact sums; collective)."""
    row = {}
    motion = {(t, b): m for t, b, m, _ in sim.motions}
    boxes = sim.boxes
    for b, name in enumerate(boxes.names if boxes is not None else []):
        for k, c in enumerate("xyz"):
            row[f"body_{name}_{c}"] = float(boxes.center[b, k])
        for k, c in enumerate("xyz"):
            row[f"body_{name}_force_{c}"] = float(boxes.contact_force[b, k])
        if ("box", b) in motion:
            row[f"body_{name}_displacement"] = motion["box", b].value(sim.time)
        elif boxes.loads[b] is not None:
            row[f"body_{name}_load"] = float(boxes.loads[b].value(sim.time))
    if any(t == "wall" for t, _, _, _ in sim.motions):
        wf = observables.wall_forces(sim)
        for t, w, m, _ in sim.motions:
            if t == "wall":
                name, axis = sim.walls.names[w], int(sim.walls.axis[w])
                row.update({f"wall_{name}_position": float(sim.walls.position[w]),
                            f"wall_{name}_force": float(wf[w, axis]), f"wall_{name}_displacement": m.value(sim.time)})
    return row


def sample(sim):
    e = sim.energy()
    wf = observables.wall_forces(sim)
    return {"step": sim.step, "time": sim.time, "dt": sim.dt, "kinetic_energy": e["kinetic"] + e["rotational"],
            "elastic_energy": e["elastic"], "contacts_per_particle": sim.contacts_per_particle(),
            "unbalanced_force": observables.unbalanced_force(sim), "bed_top": observables.bed_top(sim),
            "floor_force_z": float(wf[0, 2]) if len(wf) else 0.0, "potential_energy": e["potential"],
            "total_energy": e["total"], "max_overlap_ratio": observables.max_overlap_ratio(sim),
            **body_sample(sim)}


def run_scene_file(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run the parsed scene file ``doc`` on ``comm``'s ranks; returns the exit status.

    ``steps`` (default run.steps) is the step count of the whole run: if ``out_dir/checkpoints``
    holds a valid checkpoint (and not ``fresh``), the run resumes from the newest one and
    continues to that step, appending to the time series and snapshots. Checkpoints are written
    on the schedule of `RunLoop`, on SIGTERM/SIGUSR1 (then the exit status is
    EXIT_CHECKPOINTED_ON_SIGNAL) and at the end."""
    scene, run = scene_from_dict(doc), run_settings(doc)
    if steps is None:
        check_run_length(f"run.steps = {run['steps']}", run["steps"])
    out = prepare_output(comm, out_dir, fresh)
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
    series = series_writer(results, {**RUN_SERIES, **body_columns(sim)}, comm,
                           restart_step=sim.step if resumed else None)
    loop.flush.append(series)
    if comm.rank == 0:
        write_root_attrs(results, sim.spec, run["kind"], external_work=sim.moving_boundaries)
    snaps = open_snapshots(out, comm, run, restart_step=sim.step if resumed else None)
    frags = FragmentRecorder(results, comm, every=run["fragments_every"]) if run["fragments_every"] else None

    def on_step(sim):
        if run["output_every"] and sim.step % run["output_every"] == 0:
            series.append(finite_row(sample(sim), sim))
        if snaps and sim.step % run["snapshot_every"] == 0:
            check_finite(sim)
            write_snapshot(snaps, sim)
        if frags is not None:
            frags.on_step(sim)

    if not resumed:
        series.append(sample(sim))
        if snaps:
            write_snapshot(snaps, sim)
        if frags is not None:
            frags.record(sim, fragment_label(sim.step))
    if sim.step > n_steps:
        loop.log(f"the checkpoint is at step {sim.step}, beyond the {n_steps} steps asked: nothing to run")
    loop.advance(sim, n_steps - sim.step, on_step=on_step, last_step=n_steps)
    if loop.status == 0 and loop.last_ckpt_step != sim.step:
        loop.checkpoint(sim, "end of run")
    series.close()
    loop_s = _time.perf_counter() - loop.wall0
    last = sample(sim)
    if comm.rank == 0 and loop.status == 0:
        steps_s = loop_s - loop.first_step_s  # the throughput without numba's compilation
        rate = n_total * (sim.step - step0 - (loop.first_step_s > 0)) / steps_s if steps_s > 0 else 0.0
        about = [f"spheres: {n_total}", f"steps: {sim.step}", f"simulated time: {sim.time:.6g} s",
                 f"final dt: {sim.dt:.4g} s", f"contacts per particle: {last['contacts_per_particle']:.3f}",
                 f"unbalanced force ratio: {last['unbalanced_force']:.4g}", f"bed top: {1e3 * last['bed_top']:.2f} mm",
                 f"force on floor z: {last['floor_force_z']:.6g} N", f"loop wall time: {loop_s:.2f} s",
                 f"throughput: {rate / 1e6:.3f} M particle-steps/s"
                 + (f" (the first step left out: {loop.first_step_s:.1f} s, numba compilation or cache load)"
                    if loop.first_step_s else "")]
        wall_s = _time.perf_counter() - t_start
        write_run_info(out, summary="scene", title="scene", scene_file=str(path), ranks=comm.size, wall_s=wall_s,
                       about=about, stages=[], stage_columns=[], preparation=None, notes=[],
                       timing=sim.timing_table(), pdem_version=__version__, **scene_facts(doc))
        print(f"wrote {results}{', snapshots.xmf' if snaps else ''} (total {wall_s:.1f} s)", flush=True)
    loop.close()
    return loop.status

