"""Staged runs: a scene as a list of stages, with a checkpoint at every stage end.

A `Stage` is plain data plus actions (as HOOMD-blue's operations list or Yade's ``O.engines``):
its name, the operations that open it on the global tables (``open``: remove bodies above a
height, pour a cloud with new gids, place a rigid body), the `Scene` that holds it (``scene``),
what adjusts the built simulation (``prepare``: e.g. lower the friction), what is recorded after
each step and when it ends (``program``), what happens at its end (``close``) and what its
summary row adds (``record``). A scene subclasses `StagedRun` and lists its stages
(`StagedRun.stage_list`); `StagedRun.run` loops over them. Everything else is here: the output
directory, resume, the record of every finished stage and its checkpoint. The shared
preparation of a ballast bed (pour, refill, vibrate, settle) is `pdem.scenes.common.preparation`.

Stage boundaries go through the checkpoint: at a stage end every rank writes its part, reads the
merged gid-ordered tables back, applies the next stage's operations and builds the next scene
with the contact history carried by key. So a staged run is bit-identical on any rank count and
resumes from any checkpoint, mid-stage or between stages. ``state`` (JSON-able, in every
checkpoint under the scene's name) is where the pipeline is: the stage index, whether its
opening operations were applied, its start time, the next free gid, a summary row per finished
stage and the scene's own entries.

A fresh run may also start from another run's stage-end checkpoint (`StagedRun.start_point`,
e.g. the track section's prepared bed: preparation once, loading many), and a run given
``--steps N`` stops with a checkpoint at step N (a later run without it continues).

Table operations (`empty_tables`, `remove_above`, `append_bodies`, `next_free_gid`,
`next_free_clump`, `clump_tables`, `append_tables`) work on the global tables of
`pdem.io.checkpoint_state` and are pure functions. A stage with clumps declares them in its scene
with `Scene.add_sphere_columns(tables["particles"])` and `Scene.add_clump_tables(tables["clumps"],
tables["clump_members"])`; bonds travel in ``contacts/sphere_sphere``.
"""
import time as _time
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..version import __version__
from ..io.checkpoint_state import restore_clock
from ..build.config import result_identity, run_settings
from ..contact import stiffness_keys
from ..errors import InputError
from ..format.run import scene_facts, write_run_info
from ..io.checkpoint import CheckpointError, read_checkpoint
from ..build.scene import sphere_columns
from ..simulation import Timers
from ..bodies.state import FIELDS
from . import observables
from .preflight import check_run_length
from .snapshots import open_snapshots
from .runloop import RunLoop, prepare_output, resume_point


# ---------------------------------------------------------------------------- table operations
def scaled_stiffness(materials, factor):
    """The scene file's [materials] tables with every stiffness (any law's `STIFFNESS_KEYS`,
    `pdem.contact.stiffness_keys`) times ``factor`` (a preparation at reduced stiffness)."""
    keys = stiffness_keys()
    return {name: {k: v * factor if k in keys else v for k, v in m.items()}
            for name, m in materials.items()}


def empty_tables():
    """Global tables with no bodies."""
    return {"particles": {k: np.zeros((0,) + shape, dtype) for k, (dtype, shape) in FIELDS.items()}}


def remove_above(tables, height):
    """Drop the spheres whose top z + r is above ``height`` [m], and whole clumps (rigid or
    breakable: every sphere with that clump id) of which some member is; returns (tables,
    removed spheres). Rigid clumps leave the ``clumps``/``clump_members`` tables with them."""
    p = tables["particles"]
    above = p["pos"][:, 2] + p["radius"] > height
    clump = p.get("clump")
    cut = np.zeros(0, np.int64)
    if clump is not None:
        cut = np.unique(clump[above & (clump >= 0)])
        above |= np.isin(clump, cut)
    keep = ~above
    out = dict(tables)
    out["particles"] = {k: v[keep] for k, v in p.items()}
    if "clumps" in tables:
        kept = ~np.isin(tables["clumps"]["id"], cut)
        out["clumps"] = {k: v[kept] for k, v in tables["clumps"].items()}
        mk = ~np.isin(tables["clump_members"]["clump"], cut)
        out["clump_members"] = {k: v[mk] for k, v in tables["clump_members"].items()}
    return out, int(above.sum())


def next_free_gid(tables, at_least=0):
    """One past the largest gid of the tables (or ``at_least`` if larger)."""
    gids = tables["particles"]["gid"]
    return max(int(at_least), int(gids.max()) + 1 if len(gids) else 0)


def next_free_clump(tables, at_least=0):
    """One past the largest clump id of the tables' spheres (or ``at_least`` if larger)."""
    clump = tables["particles"].get("clump", np.zeros(0, np.int64))
    return max(int(at_least), int(clump.max()) + 1 if len(clump) else 0)


def clump_tables(scene, grains, material, first_gid, first_clump, **kw):
    """The tables of new clumps (`Scene.add_clumps` ``grains``, ``material`` and ``kw``:
    breakable, stress_free, vel, mass_model ...) with member gids from ``first_gid`` and clump
    ids from ``first_clump``: ``particles``, and for rigid clumps ``clumps`` and
    ``clump_members``, for breakable ones the bonds as ``contacts/sphere_sphere`` rows.
    ``scene`` is a `Scene` with the run's law and materials (its bodies are ignored; it is left
    unchanged)."""
    sc = scene.empty_like()
    sc.add_clumps(grains, material, first_gid=first_gid, first_id=first_clump, **kw)
    return sc.body_tables()


def append_tables(tables, new):
    """``tables`` with the rows of ``new`` (e.g. `clump_tables`) appended, table by table."""
    out = dict(tables)
    for name, cols in new.items():
        if name not in out:
            out[name] = {k: np.asarray(v).copy() for k, v in cols.items()}
        else:
            out[name] = {k: np.concatenate([np.asarray(out[name][k]), np.asarray(cols[k])]) for k in out[name]}
    return out


def append_bodies(tables, pos, radius, density, material, first_gid):
    """``tables`` with new spheres at rest appended (gids from ``first_gid``; Yade's mass and
    inertia from ``density`` [kg/m³]; ``material`` the material index)."""
    new = sphere_columns(pos, radius, np.full(len(radius), float(density)), first_gid)
    new["material"] = np.full(len(radius), int(material), np.int64)
    new["blocked"] = np.zeros(len(radius), np.int64)
    out = dict(tables)
    old = tables["particles"]
    out["particles"] = {k: np.concatenate([old[k], new[k]]) for k in old}
    return out


# ---------------------------------------------------------------------------- a stage
def keep_tables(tables):
    """The default opening of a stage: the tables as they are, no note."""
    return tables, ""


def nothing(*args):
    """The default action: none."""


def no_record(sim):
    """The default extra entries of a stage's summary row: none."""
    return {}


def in_order(first, then):
    """An action that runs ``first`` and then ``then`` with the same arguments."""
    def both(*args):
        first(*args)
        then(*args)
    return both


@dataclass(frozen=True)
class Stage:
    """One stage of a staged run. ``name`` is its summary and log name (unique in a run);
    the actions, all called on every rank:

    - ``scene(tables) -> Scene``: the scene holding the bodies of the global ``tables``;
    - ``program(sim, scene) -> (on_step, until, until_every, t_end)``: what is done after each
      step, when the stage ends (``until(sim)``, a collective decision checked every
      ``until_every`` steps) and its expected end time [s] (for the ETA only);
    - ``open(tables) -> (tables, note)``: operations on the global tables that open it (not
      repeated when a checkpoint resumes inside it); ``note`` goes into the log line;
    - ``prepare(sim, scene, mid_stage)``: adjust the built simulation before it runs;
    - ``max_steps``: at most this many steps (default: until ``until``);
    - ``close(sim)``: what is done at its end, before its checkpoint;
    - ``record(sim) -> dict``: extra entries of its summary row (JSON-able);
    - ``saved(path)``: what is done with its stage-end checkpoint file (collective);
    - ``length``: (simulated seconds [s], exact) if known before the stage opens: exact (it ends
      then) or at most that (it ends earlier on a criterion); None (default) if unknown. For the
      whole-run ETA of the progress lines only.
    """

    name: str
    scene: Callable
    program: Callable
    open: Callable = keep_tables
    prepare: Callable = nothing
    max_steps: int = 10**15
    close: Callable = nothing
    record: Callable = no_record
    saved: Callable = nothing
    length: tuple = None

    def then(self, prepare=None, close=None):
        """This stage with ``prepare`` and/or ``close`` run after its own."""
        return replace(self, prepare=self.prepare if prepare is None else in_order(self.prepare, prepare),
                       close=self.close if close is None else in_order(self.close, close))


# ---------------------------------------------------------------------------- the staged run
def same_results(old_text, new_text):
    """True if the scene texts ``old_text`` (a checkpoint's) and ``new_text`` give the same
    trajectory: equal, or equal but for output-only keys (`pdem.build.config.result_identity`)."""
    if old_text == new_text:
        return True
    if not isinstance(old_text, str):
        return False
    try:
        return result_identity(tomllib.loads(old_text)) == result_identity(tomllib.loads(new_text))
    except (TypeError, tomllib.TOMLDecodeError):
        return False


class StagedRun:
    """A run in stages on this process's ranks. Subclasses set ``NAME`` (the scene's table name,
    also the checkpoint meta key) and list their stages (`stage_list`); ``STAGES`` holds their
    names. The run-level hooks below have defaults."""

    NAME = "staged"

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.run_cfg = run_settings(doc)
        self.path, self.doc, self.comm = path, doc, comm
        self.stages = self.stage_list()
        self.STAGES = tuple(stage.name for stage in self.stages)
        self.t_start = _time.perf_counter()
        self.out = prepare_output(comm, out_dir, fresh)
        self.scene_text = Path(path).read_text()
        self.loop = RunLoop(comm, self.out, self.run_cfg, path, self.scene_text)
        self.state = {"stage": 0, "started": False, "stage_t0": 0.0, "next_gid": 0, "stages": [],
                      **self.initial_state()}
        self.tables, self.meta = empty_tables(), None
        self.stop_step = None  # `pdem run --steps N`: stop with a checkpoint at step N of the run
        self.stopped = False
        resume = resume_point(comm, self.loop.ckdir, fresh)
        if resume is None:
            start = self.start_point()
            if start is not None:  # a fresh run from another run's stage-end checkpoint
                self.tables, self.meta, self.state = start
        else:
            self.tables, self.meta = read_checkpoint(resume)
            if not same_results(self.meta.get("scene_file"), self.scene_text) or self.NAME not in self.meta:
                raise CheckpointError(
                    resume, "cannot continue this scene from it: it was written for another scene file"
                )
            self.state = self.meta[self.NAME]
            k = self.state["stage"]
            self.loop.log(f"resuming from {resume} at step {self.meta['step']} (stage "
                          f"{self.STAGES[k] if k < len(self.STAGES) else 'none left'}, t = {self.meta['time']:.6e} s, "
                          f"written by pdem {self.meta.get('pdem_version')})")
            self.loop.last_ckpt_step = int(self.meta["step"])
        self.restart_step = int(self.meta["step"]) if resume is not None else None
        self.snaps = open_snapshots(self.out, comm, self.run_cfg, restart_step=self.restart_step)
        self.timers = Timers()  # one timing table for the whole run
        self.loop.extra_meta = lambda: {self.NAME: self.checkpoint_state()}
        self.open_outputs()

    # ------------------------------------------------------------------ hooks
    def stage_list(self):
        """The run's `Stage` objects in order (called once, before the run's state exists: their
        actions read it when called)."""
        raise NotImplementedError

    def start_point(self):
        """(tables, meta, state) a fresh run starts from instead of stage 0, or None (default):
        e.g. a prepared bed, the checkpoint of another run at the end of its preparation."""
        return None

    def initial_state(self):
        """The scene's own entries of ``state`` at the start."""
        return {}

    def checkpoint_state(self):
        """``state`` as written into a checkpoint (a scene may add live objects' state)."""
        return dict(self.state)

    def open_outputs(self):
        """Open the scene's writers (append after a restart: ``self.restart_step``)."""

    def close_outputs(self):
        """Flush and close them."""

    def collect(self, sim):
        """Every rank at the end of a run that was not stopped by a signal (collectives allowed):
        what `finish` or `report_stop` needs from all ranks."""

    def report_stop(self, sim, wall_s):
        """Rank 0 after a run stopped by ``--steps``: this invocation's timing table (rank 0's)."""
        print(sim.timing_table(), flush=True)

    def finish(self, sim, wall_s, **facts):
        """Rank 0 at the end of the last stage: the run's account for its post-processing
        (run_info.json, `pdem.format.run`; ``facts`` are the scene's entries)."""
        write_run_info(self.out, scene_file=str(self.path), ranks=self.comm.size, wall_s=wall_s,
                       stages=self.state["stages"], timing=sim.timing_table(), pdem_version=__version__,
                       **scene_facts(self.doc), **facts)

    # ------------------------------------------------------------------ the loop
    def run(self):
        """Run (or resume) the remaining stages; returns the exit status."""
        self.loop.log(f"pdem {__version__}: {self.NAME} {self.path} on {self.comm.size} rank(s); stages "
                      f"{', '.join(self.STAGES)}")
        sim = None
        while self.state["stage"] < len(self.stages):
            stage = self.stages[self.state["stage"]]
            wall0 = _time.perf_counter()
            sim, scene = self.build_stage(stage)
            on_step, until, every, t_end = stage.program(sim, scene)
            eta_step = sim.step + int(max(t_end - sim.time, 0.0) / max(sim.dt, 1e-300))
            n_steps = stage.max_steps
            if self.stop_step is not None:
                n_steps = min(n_steps, max(self.stop_step - sim.step, 0))
            check_run_length(f"stage {stage.name}: its end at t = {t_end:.6g} s at dt = {sim.dt:.4g} s",
                             min(eta_step - sim.step, n_steps))
            k, n = self.state["stage"], len(self.stages)
            later = [s.length or (None, False) for s in self.stages[k + 1:]]
            bounded = until is not None and not (stage.length and stage.length[1])
            outcome = self.loop.advance(sim, n_steps, on_step=on_step, until=until, until_every=every,
                                        last_step=eta_step, stage=(f"stage {k + 1}/{n} {stage.name}", bounded, later))
            if outcome == "signal":
                break
            if outcome == "done" and self.stop_step is not None and sim.step >= self.stop_step:
                self.loop.checkpoint(sim, f"--steps {self.stop_step} reached")
                self.loop.log(f"stopped at step {sim.step} (--steps {self.stop_step}) in stage {stage.name}; run "
                              "again without --steps to continue")
                self.stopped = True
                break
            self.end_stage(stage, sim, wall0)
        self.close_outputs()
        wall_s = _time.perf_counter() - self.t_start
        if sim is not None and self.loop.status == 0:
            self.collect(sim)
        if self.stopped:
            if self.comm.rank == 0:
                self.report_stop(sim, wall_s)
        elif sim is None:
            self.loop.log(f"the run in {self.out} is complete (its newest checkpoint is after the last stage); nothing "
                          "to run (--fresh starts over)")
        elif self.loop.status == 0 and self.comm.rank == 0:
            self.finish(sim, wall_s)
        self.loop.close()
        return self.loop.status

    def build_stage(self, stage):
        """The simulation of ``stage`` from the global tables (opening operations applied unless
        the stage was already running in the checkpoint)."""
        state, meta = self.state, self.meta
        mid_stage = state["started"]
        note = ""
        if not mid_stage:
            self.tables, note = stage.open(self.tables)
            meta = self.meta  # an opening may set the clock (pdem.scenes.blast: every plate from the prepared layer)
            state["next_gid"] = next_free_gid(self.tables, state["next_gid"])
            state.update(started=True, stage_t0=float(meta["time"]) if meta else 0.0)
        tables = self.tables
        scene = stage.scene(tables)
        sim = scene.build(self.comm)
        sim.timers = self.timers
        sim.load_state(tables)
        self.tables = None
        restore_clock(sim, meta, continuing=mid_stage)  # mid-stage: the checkpoint's Δt and energy reference
        stage.prepare(sim, scene, mid_stage)
        n_total = self.comm.allreduce_sum_int(sim.particles.n_local)
        self.loop.log(f"stage {stage.name}{' (resumed)' if mid_stage else ''}: {n_total} spheres, t = "
                      f"{sim.time:.4f} s, dt = {sim.dt:.3e} s{'; ' + note if note else ''}")
        return sim, scene

    def end_stage(self, stage, sim, wall0):
        """Record the stage, close it, write its checkpoint and read it back for the next stage."""
        state = self.state
        stage.close(sim)
        row = {"stage": stage.name, "t_start": state["stage_t0"], "t_end": sim.time, "step_end": sim.step,
               "spheres": self.comm.allreduce_sum_int(sim.particles.n_local),
               "unbalanced_force": observables.unbalanced_force(sim), "bed_top": observables.bed_top(sim),
               "wall_s": _time.perf_counter() - wall0, **stage.record(sim)}
        state["stages"].append(row)
        state.update(stage=state["stage"] + 1, started=False)
        written = self.loop.checkpoint(sim, f"end of stage {stage.name}")
        stage.saved(written)
        if state["stage"] < len(self.stages):
            self.tables, self.meta = read_checkpoint(written)
        return written


def check_no_steps(steps):
    """A staged run ends its stages on its own criteria: refuse ``--steps``."""
    if steps is not None:
        raise InputError(f"--steps = {steps}: not used by a staged scene (its stages end on their own criteria)")
