"""The box test (SPEC.md 2.3; thesis ch. 5; Nottingham box test): preparation in stages, then
cyclic loading of the sleeper, on any number of ranks.

A scene file with a ``[box_test]`` table (keys and defaults in `DEFAULTS`, units SI) runs:

1. ``pour``     a seeded loose cloud fills the box (floor = rubber base at z = 0, four steel
                sides) to above ``cut_height``; settle (below).
2. ``refill``   remove the spheres whose top is above ``cut_height`` [m]; place the sleeper (a
                rigid box, z translation only, its bottom at ``cut_height``, centred in x and
                y); pour a second cloud beside it; settle.
3. ``vibrate``  remove the spheres whose top is above ``height``; shake for ``vibration_time``
                [s] with every friction angle times ``vibration_friction_factor`` (thesis 4.2:
                tenfold lower): in the frame of the box, shaking is the pseudo-acceleration
                A·(sin 2πft, cos 2πft, 0) added to gravity, A = ``vibration_acceleration``
                [m/s²], f = ``vibration_frequency`` [Hz]. Friction then restored.
4. ``settle``   settle.
5. ``load``     the sleeper carries a haversine force ``f_min`` ↔ ``f_max`` [N] at
                ``frequency`` [Hz] for ``cycles`` cycles (`pdem.loads.Haversine`, pushing down).

"Settle" runs until Yade's unbalanced-force ratio falls below ``settle_ratio`` (checked every
``check_every`` steps, not before ``settle_min_time`` [s] into the stage) or ``settle_max_time``
[s] has passed (then a warning line is printed and the pipeline goes on). The sleeper takes the
global Cundall damping like every body in Yade's NewtonIntegrator.

Each stage ends with a checkpoint; stage boundaries go through it (every rank reads the merged,
gid-ordered tables back, removes and adds bodies, and builds the next stage's scene with the
contact history carried by key), so a run is bit-identical on any rank count and resumes from
any checkpoint, mid-stage or between stages. Output in the run directory: ``preparation.h5``
(series of every preparation stage), ``results.h5`` (kind "box_test", `analysis.schema`:
series ``sleeper_load``, ``sleeper_force`` [N, ballast reaction, positive up],
``sleeper_settlement`` [m, positive down, zero when cycling starts], and the ``cycles`` table),
``preparation.png``, the analysis of `analysis.box` (``loops.png``, ``settlement.png``,
``stiffness.png``, ``analysis.txt``) and ``summary.txt`` with the timing table.
"""
from math import cos, pi, sin

import numpy as np
from analysis.schema import BOX_TEST_SERIES, PREPARATION_SERIES

from ..config import check_keys, run_settings, scene_from_dict
from ..driver import observables
from ..driver.cycles import CycleRecorder
from ..driver.plain import write_snapshot
from ..driver.plots import plot_energy, save_figure, series_figure
from ..driver.results import series_writer, write_cycles, write_root_attrs
from ..driver.stages import StagedRun, append_bodies, check_no_steps, empty_tables, remove_above
from ..errors import InputError
from ..generators import loose_cloud
from ..loads import Haversine
from ..validate import number

STAGES = ("pour", "refill", "vibrate", "settle", "load")
# [box_test] keys and defaults (SPEC.md 2.3, thesis table 5.1; stiffness is in [materials])
DEFAULTS = {
    "box": [0.7, 0.3, 0.45],           # inner length x, width y, height z [m]
    "ballast_material": "ballast", "wall_material": "steel", "base_material": "rubber",
    "sleeper_material": "steel",
    "radius": 0.01625, "radius_spread": 0.0, "seed": 1,
    "packing_fraction": 0.58,           # settled solid fraction assumed to size the clouds [-]
    "overfill": 1.2,                    # cloud volume / volume to fill [-]
    "cut_height": 0.30,                 # first fill cut = sleeper bottom [m]
    "height": 0.45,                     # final ballast height [m]
    "sleeper_size": [0.25, 0.3, 0.15],  # [m]
    "sleeper_mass": 34.0,               # [kg]
    "settle_ratio": 0.01, "settle_min_time": 0.2, "settle_max_time": 3.0, "check_every": 200,
    "vibration_time": 0.5, "vibration_frequency": 10.0, "vibration_acceleration": 5.0,
    "vibration_friction_factor": 0.1,
    "f_min": 3000.0, "f_max": 40000.0, "frequency": 1.0, "cycles": 10,
}


# ---------------------------------------------------------------------------- settings
def box_settings(doc):
    """The [box_test] table with defaults, checked (one-line InputError naming the key)."""
    check_keys("scene file", doc, {"simulation", "run", "materials", "box_test"})
    given = doc["box_test"]
    check_keys("box_test", given, set(DEFAULTS))
    c = {**DEFAULTS, **given}
    for k in ("box", "sleeper_size"):
        v = c[k]
        if not (isinstance(v, list) and len(v) == 3):
            raise InputError(f"box_test.{k} = {v!r}: must be [x, y, z] lengths > 0 [m]")
        c[k] = [number(f"box_test.{k}", x, 0.0, lo_open=True, allow="[x, y, z] lengths > 0 [m]") for x in v]
    for k in ("ballast_material", "wall_material", "base_material", "sleeper_material"):
        if not isinstance(c[k], str) or c[k] not in doc.get("materials", {}):
            raise InputError(f"box_test.{k} = {c[k]!r}: no [materials.{c[k]}] table in the scene file")
    positive = ("radius", "packing_fraction", "overfill", "cut_height", "height", "sleeper_mass", "settle_ratio",
                "settle_max_time", "vibration_frequency", "frequency")
    for k in positive:
        c[k] = number(f"box_test.{k}", c[k], 0.0, lo_open=True)
    for k in ("settle_min_time", "vibration_time", "vibration_acceleration", "f_min", "f_max"):
        c[k] = number(f"box_test.{k}", c[k], 0.0)
    for k in ("seed", "cycles", "check_every"):
        c[k] = number(f"box_test.{k}", c[k], 0 if k == "seed" else 1, integer=True)
    c["radius_spread"] = number("box_test.radius_spread", c["radius_spread"], 0.0, 1.0, hi_open=True,
                                allow="in [0, 1)")
    c["vibration_friction_factor"] = number("box_test.vibration_friction_factor", c["vibration_friction_factor"], 0.0,
                                            1.0, lo_open=True, allow="in (0, 1]")
    if c["f_max"] < c["f_min"]:
        raise InputError(f"box_test.f_max = {c['f_max']!r}: must be >= f_min = {c['f_min']!r} [N]")
    if not c["cut_height"] < c["height"] <= c["box"][2]:
        raise InputError(f"box_test.height = {c['height']!r}: must be above cut_height = {c['cut_height']!r} "
                         f"and at most the box height {c['box'][2]!r} [m]")
    for a, name in ((0, "length"), (1, "width")):
        if c["sleeper_size"][a] > c["box"][a]:
            raise InputError(f"box_test.sleeper_size = {c['sleeper_size']!r}: the sleeper's {name} exceeds the box's")
    if "steps" in doc.get("run", {}):
        raise InputError("run.steps: not used by a box test (its stages end on settle_ratio, vibration_time and "
                         "cycles in [box_test]); remove it")
    return c


# ---------------------------------------------------------------------------- geometry
def sleeper_geometry(c, bottom):
    """(center, half_extents) of the sleeper with its bottom at ``bottom`` [m]."""
    bx, sz = np.asarray(c["box"], float), np.asarray(c["sleeper_size"], float)
    center = np.array([bx[0] / 2, bx[1] / 2, bottom + sz[2] / 2])
    return center, sz / 2


def cloud_count(c, volume):
    """Spheres to fill ``volume`` [m³] at the packing fraction, times the overfill factor."""
    r, s = c["radius"], c["radius_spread"]
    lo, hi = r * (1 - s), r * (1 + s)
    mean_r3 = r**3 if s == 0 else (hi**4 - lo**4) / (4 * (hi - lo))
    return max(int(np.ceil(c["overfill"] * c["packing_fraction"] * volume / (4.0 / 3.0 * pi * mean_r3))), 1)


def cloud(c, lo_xy, hi_xy, z0, volume, seed):
    """A loose cloud filling ``volume`` over the rectangle lo_xy..hi_xy, from height z0 up."""
    n = cloud_count(c, volume)
    r_max = c["radius"] * (1 + c["radius_spread"])
    a = 2 * r_max * 1.05
    per_layer = np.prod(np.floor((np.asarray(hi_xy) - np.asarray(lo_xy)) / a))
    if per_layer < 1:
        raise InputError(f"box_test.radius = {c['radius']!r}: spheres do not fit beside the sleeper")
    top = z0 + np.ceil(n / per_layer) * a
    return loose_cloud([lo_xy[0], lo_xy[1], z0], [hi_xy[0], hi_xy[1], top], n, c["radius"], c["radius_spread"], seed)


# ---------------------------------------------------------------------------- stage scenes
def stage_scene(doc, c, stage, tables, load_start=None, sleeper_center=None):
    """The `Scene` of ``stage`` holding the spheres of ``tables``: materials and settings of
    the file, the box's five walls, the sleeper from stage ``refill`` on (loaded in ``load``)."""
    base = {k: v for k, v in doc.items() if k in ("simulation", "materials")}
    base["simulation"] = {**base.get("simulation", {}), "allow_initial_overlap": True}
    scene = scene_from_dict(base)
    lx, ly, _ = c["box"]
    scene.add_wall("z", 0.0, c["base_material"], sense=1, name="base")
    scene.add_wall("x", 0.0, c["wall_material"], sense=1, name="x_min")
    scene.add_wall("x", lx, c["wall_material"], sense=-1, name="x_max")
    scene.add_wall("y", 0.0, c["wall_material"], sense=1, name="y_min")
    scene.add_wall("y", ly, c["wall_material"], sense=-1, name="y_max")
    if STAGES.index(stage) >= STAGES.index("refill"):
        center, half = sleeper_geometry(c, c["cut_height"])
        if sleeper_center is not None:
            center = np.asarray(sleeper_center, float)
        load = (Haversine(c["f_min"], c["f_max"], c["frequency"], c["cycles"], start=load_start,
                          label="box_test") if stage == "load" else None)
        scene.add_box(center, half, c["sleeper_material"], c["sleeper_mass"], blocked="xyXYZ", load=load,
                      damping=scene.settings["damping"], name="sleeper")
    scene.add_sphere_columns(tables["particles"])
    return scene


def add_cloud(tables, doc, c, lo_xy, hi_xy, z0, volume, seed, first_gid):
    """``tables`` with a loose cloud of new ballast spheres (gids from ``first_gid``) appended."""
    pos, radius = cloud(c, lo_xy, hi_xy, z0, volume, seed)
    return append_bodies(tables, pos, radius, doc["materials"][c["ballast_material"]]["density"],
                         list(doc["materials"]).index(c["ballast_material"]), first_gid)


def shaking(c, t):
    """Pseudo-acceleration [m/s²] of the shaken box at time t since the vibration started."""
    a, w = c["vibration_acceleration"], 2.0 * pi * c["vibration_frequency"]
    return np.array([a * sin(w * t), a * cos(w * t), 0.0])


# ---------------------------------------------------------------------------- records
def prep_sample(sim, stage):
    e = sim.energy()
    return {
        "step": sim.step,
        "time": sim.time,
        "stage": STAGES.index(stage),
        "n_spheres": sim.comm.allreduce_sum_int(sim.particles.n_local),
        "kinetic_energy": e["kinetic"] + e["rotational"],
        "unbalanced_force": observables.unbalanced_force(sim),
        "contacts_per_particle": sim.contacts_per_particle(),
        "bed_top": observables.bed_top(sim),
        "sleeper_z": float(sim.boxes.center[0, 2]) if sim.boxes is not None else float("nan"),
    }


def load_sample(sim, reference, load=None):
    """A row of the load record; ``reference`` is the sleeper centre where cycling started."""
    e = sim.energy()
    bx = sim.boxes
    d = bx.direction[0]
    return {"step": sim.step, "time": sim.time, "dt": sim.dt,
            "sleeper_load": float(bx.load_force[0] @ d) if load is None else float(load),
            "sleeper_force": float(-(bx.contact_force[0] @ d)),
            "sleeper_settlement": float((bx.center[0] - reference) @ d),
            "kinetic_energy": e["kinetic"] + e["rotational"], "contacts_per_particle": sim.contacts_per_particle()}


def cycle_columns(recorder):
    """The per-cycle table in `analysis.schema` terms (cycle numbered from 1)."""
    t = recorder.table()
    return {"cycle": t["cycle"] + 1.0, "t_start": t["t_start"], "settlement_start": t["settlement_start"],
            "settlement_peak": t["settlement_peak"], "settlement_end": t["settlement_end"],
            "force_peak": t["force_max"], "force_min": t["force_min"], "load_max": t["load_max"],
            "load_min": t["load_min"], "step": np.array([r.get("step", 0) for r in recorder.records], np.float64)}


# ---------------------------------------------------------------------------- the run
def check(doc):
    """Check a parsed box-test scene file without running it (one-line InputError)."""
    box_settings(doc)
    run_settings(doc)
    stage_scene(doc, box_settings(doc), "load", empty_tables(), 0.0, None)


def run(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run (or resume) the box test of a parsed scene file; returns the exit status."""
    check_no_steps(steps)
    return BoxTestRun(path, doc, out_dir, comm, fresh).run()


class BoxTestRun(StagedRun):
    """One box test on this process's ranks (`pdem.driver.stages.StagedRun`): the stages, their
    records (preparation.h5, results.h5 with the cycles) and the finishing analysis. The scene's
    ``state`` adds the load start and the cycle recorder."""

    NAME = "box_test"
    STAGES = STAGES

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.c = box_settings(doc)
        self.recorder = None
        super().__init__(path, doc, out_dir, comm, fresh)

    def initial_state(self):
        return {"load_start": None, "recorder": None}

    def checkpoint_state(self):
        return {**self.state, "recorder": self.recorder.state() if self.recorder else None}

    def open_outputs(self):
        restart, comm = self.restart_step, self.comm
        self.results = self.out / "results.h5"
        self.prep = series_writer(self.out / "preparation.h5", PREPARATION_SERIES, comm, restart_step=restart)
        self.series = series_writer(self.results, BOX_TEST_SERIES, comm, restart_step=restart)
        self.loop.flush += [self.prep, self.series]
        if comm.rank == 0:
            doc = self.doc
            write_root_attrs(self.results, {k: doc[k] for k in ("simulation", "materials", "box_test") if k in doc},
                             "box_test")

    def close_outputs(self):
        self.prep.close()
        self.series.close()

    def open_stage(self, stage, tables):
        c, doc, state = self.c, self.doc, self.state
        lx, ly, _ = c["box"]
        h1, h2 = c["cut_height"], c["height"]
        if stage == "pour":
            tables = add_cloud(empty_tables(), doc, c, (0.0, 0.0), (lx, ly), 0.0, lx * ly * h1, c["seed"], 0)
            return tables, f"poured {len(tables['particles']['gid'])} spheres"
        if stage == "refill":
            tables, removed = remove_above(tables, h1)
            center, half = sleeper_geometry(c, h1)
            x0, x1 = center[0] - half[0], center[0] + half[0]
            gid = state["next_gid"]
            n0 = len(tables["particles"]["gid"])
            for k, (a, b) in enumerate(((0.0, x0), (x1, lx))):
                if b - a <= 0:
                    continue
                tables = add_cloud(
                    tables, doc, c, (a, 0.0), (b, ly), h1, (b - a) * ly * (h2 - h1), c["seed"] + 1000 + k, gid
                )
                gid = int(tables["particles"]["gid"].max()) + 1
            return tables, (f"removed {removed} spheres above {h1} m, placed the sleeper, poured "
                            f"{len(tables['particles']['gid']) - n0} spheres beside it")
        if stage == "vibrate":
            tables, removed = remove_above(tables, h2)
            return tables, f"removed {removed} spheres above {h2} m"
        if stage == "load":
            state["load_start"] = float(self.meta["time"]) if self.meta else 0.0
        return tables, ""

    def stage_scene(self, stage, tables):
        center = tables["boxes"]["center"][0] if "boxes" in tables else None
        return stage_scene(self.doc, self.c, stage, tables, self.state["load_start"], center)

    def prepare(self, stage, sim, scene, mid_stage):
        if stage == "vibrate":
            c = self.c
            sim.set_friction_scale(c["vibration_friction_factor"])
            sim.gravity = np.asarray(scene.settings["gravity"], np.float64) + shaking(
                c, sim.time - self.state["stage_t0"]
            )

    def max_steps(self, stage):
        return 0 if stage == "vibrate" and self.c["vibration_time"] == 0 else 10**15

    def program(self, stage, sim, scene):
        c, state, run = self.c, self.state, self.run_cfg
        t0 = state["stage_t0"]
        if stage == "load":
            self.recorder = rec = CycleRecorder(scene.boxes.loads[0])
            if state["recorder"] is not None:
                rec.restore(state["recorder"])
            else:
                rec.reference = sim.boxes.center[0].copy()

            def on_step(sim):
                done = rec.sample_box(sim, 0)
                if done is not None:
                    done["step"] = sim.step
                    write_cycles(self.results, cycle_columns(rec), self.comm)
                    self.loop.log(
                        f"cycle {done['cycle'] + 1}/{c['cycles']}: settlement start "
                        f"{1e3 * done['settlement_start']:.3f} mm, peak {1e3 * done['settlement_peak']:.3f} mm, "
                        f"end {1e3 * done['settlement_end']:.3f} mm; ballast force {done['force_min']:.1f} .. "
                        f"{done['force_max']:.1f} N"
                    )
                if run["output_every"] and sim.step % run["output_every"] == 0:
                    self.series.append(load_sample(sim, rec.reference))
                self.snapshot(sim)

            return (
                on_step,
                lambda sim: len(rec.records) >= c["cycles"],
                1,
                state["load_start"] + c["cycles"] / c["frequency"],
            )
        if sim.step == 0:  # later stages start at the step of the row that ended the last one
            self.prep.append(prep_sample(sim, stage))
            if self.snaps is not None:
                write_snapshot(self.snaps, sim)
        g = np.asarray(scene.settings["gravity"], np.float64)

        def on_step(sim):
            if stage == "vibrate":
                sim.gravity = g + shaking(c, sim.time - t0)
            if run["output_every"] and sim.step % run["output_every"] == 0:
                self.prep.append(prep_sample(sim, stage))
            self.snapshot(sim)

        if stage == "vibrate":
            t_end = t0 + c["vibration_time"]
            return on_step, lambda sim: sim.time >= t_end, 1, t_end
        t_end = t0 + c["settle_max_time"]

        def settled(sim):
            return sim.time >= t_end or (sim.time - t0 >= c["settle_min_time"]
                                         and observables.unbalanced_force(sim) < c["settle_ratio"])

        return on_step, settled, c["check_every"], t_end

    def snapshot(self, sim, stage_end=False):
        """ParaView snapshot every run.snapshot_every steps and at the end of every stage."""
        every = self.run_cfg["snapshot_every"]
        if self.snaps is not None and (sim.step % every == 0) != stage_end:
            write_snapshot(self.snaps, sim)

    def close_stage(self, stage, sim):
        c, log = self.c, self.loop.log
        ratio = observables.unbalanced_force(sim)
        if stage in ("pour", "refill", "settle") and ratio >= c["settle_ratio"]:
            log(f"warning: stage {stage} reached settle_max_time = {c['settle_max_time']} s with unbalanced force "
                f"ratio {ratio:.3g} >= settle_ratio = {c['settle_ratio']}; going on")
        if stage == "vibrate":
            sim.set_friction_scale(1.0)
        top = observables.bed_top(sim)
        sleeper = sim.boxes.center[0, 2] if sim.boxes is not None else None
        log(
            f"stage {stage} done at t = {sim.time:.4f} s, step {sim.step}: unbalanced force ratio {ratio:.3g}, "
            f"bed top {top:.4f} m"
            + ("" if sleeper is None else f", sleeper bottom {sleeper - sim.boxes.half[0, 2]:.4f} m")
        )
        self.snapshot(sim, stage_end=True)
        if stage != "load":
            self.prep.append(prep_sample(sim, stage))
        if stage == "settle":  # the first row of the load record: the sleeper where cycling starts
            self.series.append(load_sample(sim, sim.boxes.center[0], load=c["f_min"]))

    def stage_record(self, stage, sim):
        return {"sleeper_z": None if sim.boxes is None else float(sim.boxes.center[0, 2])}

    def finish(self, sim, wall_s):
        finish(self.out, self.results, sim, self.state, self.c, self.path, self.comm.size, wall_s)


def plot_preparation(h5_path, png_path):
    """Bed top, sleeper bottom, kinetic energy and unbalanced force over the preparation."""
    s, fig, ax = series_figure(h5_path, 3, 1, (8, 8))
    t = s["time"]
    ax[0].plot(t, s["bed_top"], label="top of the ballast")
    ax[0].plot(t, s["sleeper_z"], label="sleeper centre")
    ax[0].set_ylabel("height [m]")
    ax[0].legend()
    plot_energy(ax[1], t, s["kinetic_energy"])
    ax[2].semilogy(t, np.maximum(s["unbalanced_force"], 1e-6))
    ax[2].set_ylabel("unbalanced force ratio [-]")
    ax[2].set_xlabel("time [s]")
    for k in range(1, len(STAGES)):
        starts = t[s["stage"] == k]
        if len(starts):
            for a in ax:
                a.axvline(starts[0], color="0.7", lw=0.8)
            ax[0].text(starts[0], ax[0].get_ylim()[1], STAGES[k], fontsize=8, va="top")
    save_figure(fig, png_path)


def finish(out, results, sim, state, c, path, ranks, wall_s):
    """Rank 0 at the end: plots, the analysis of the cycles and summary.txt (with timing): the
    scene's finishing step calls the analysis entry point `analysis.__main__.main`."""
    from analysis.__main__ import main as analysis_main

    plot_preparation(out / "preparation.h5", out / "preparation.png")
    status = analysis_main(["box", str(results), "--out", str(out / "analysis")])
    lines = [f"box test: {path}", f"ranks: {ranks}", f"wall time: {wall_s:.1f} s", "",
             "stage     t_end [s]    steps  spheres  unbalanced  bed top [m]  sleeper z [m]  wall [s]"]
    for r in state["stages"]:
        z = f"{r['sleeper_z']:.4f}" if r["sleeper_z"] is not None else "-"
        lines.append(
            f"{r['stage']:<8} {r['t_end']:9.4f} {r['step_end']:8d} {r['spheres']:8d} {r['unbalanced_force']:11.3g} "
            f"{r['bed_top']:12.4f} {z:>14} {r['wall_s']:9.1f}"
        )
    lines += ["", f"cycles {c['f_min']:g} <-> {c['f_max']:g} N at {c['frequency']:g} Hz",
              "cycle  settlement start/peak/end [mm]     ballast force min/max [N]"]
    import h5py

    with h5py.File(results, "r") as f:
        cyc = {k: f["cycles"][k][...] for k in f["cycles"]} if "cycles" in f else None
    if cyc is not None:
        for k in range(len(cyc["cycle"])):
            lines.append(
                f"{int(cyc['cycle'][k]):5d}  {1e3 * cyc['settlement_start'][k]:9.3f} "
                f"{1e3 * cyc['settlement_peak'][k]:9.3f} "
                f"{1e3 * cyc['settlement_end'][k]:9.3f}   {cyc['force_min'][k]:10.1f} {cyc['force_peak'][k]:10.1f}"
            )
    lines += ["", sim.timing_table()]
    (out / "summary.txt").write_text("\n".join(lines) + "\n")
    print("\n".join(lines), flush=True)
    print(f"wrote {results}, {out / 'preparation.h5'}, {out / 'preparation.png'}, {out / 'summary.txt'} and "
          f"{out / 'analysis'}/ (analysis exit status {status})", flush=True)
