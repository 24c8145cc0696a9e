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
                ``frequency`` [Hz] for ``cycles`` cycles (`pdem.boundaries.loads.Haversine`, pushing down).

With ``prep_stiffness_factor`` f < 1 (law linear) stages 1–4 run with every material's young
times f, and a ``stiffen`` stage before ``load`` raises it to the materials' over ``stiffen_time``,
then settles (`pdem.scenes.common.stiffening`, shared with the track). With a
``[box_test.clumps]`` table the ballast is rigid clumps of that grain (`grain_settings`;
`pdem.scenes.common.preparation.add_grain_cloud`).

Options for what the thesis leaves open (``CHOICES``; docs/box_test.md "Options"): ``cut``
("top" | "center"), ``sleeper_placement`` ("cut" | "on_top", `sleeper_on_top`), ``refill``
("beside" | "whole"), ``waveform`` ("haversine" | "half_sine"), ``base`` ("one_sided" |
"two_sided": a catch floor `catch_depth` below holds the spheres that pass, counted by
`base_passed`), ``sleeper_surface`` ("flat" | "spheres": the thesis's clump of 2280 spheres,
`sleeper_members`, with ``sleeper_mass`` = "members" for Yade's 9.37 kg), and the pipeline's
``vibration_friction_contacts`` ("all" | "new", Yade).
Records besides the settlement: the ballast force on the sleeper's bottom face and on its sides
(`face_forces`), per cycle the settlement at the largest force and the largest settlement.

"Settle" runs until Yade's unbalanced-force ratio falls below ``settle_ratio`` (checked every
``check_every`` steps, not before ``settle_min_time`` [s] into the stage) or ``settle_max_time``
[s] has passed (then a warning line is printed and the pipeline goes on). The sleeper takes the
global Cundall damping like every body in Yade's NewtonIntegrator.

Each stage ends with a checkpoint; stage boundaries go through it (every rank reads the merged,
gid-ordered tables back, removes and adds bodies, and builds the next stage's scene with the
contact history carried by key), so a run is bit-identical on any rank count and resumes from
any checkpoint, mid-stage or between stages. Output in the run directory: ``preparation.h5``
(series of every preparation stage), ``results.h5`` (kind "box_test", `pdem.format.schema`:
series ``sleeper_load``, ``sleeper_force`` [N, ballast reaction, positive up],
``sleeper_settlement`` [m, positive down, zero when cycling starts], and the ``cycles`` table),
``preparation.png``, the analysis of `analysis.box` (``loops.png``, ``settlement.png``,
``stiffness.png``, ``analysis.txt``) and ``summary.txt`` with the timing table.
"""
import numpy as np

from ..build.config import check_keys, run_settings, scene_from_dict
from ..checks.diagnostics import kinetic_energy
from ..format.schema import BOX_TEST_SERIES
from ..driver.observables import box_face_forces
from ..driver.results import series_writer, write_cycles, write_root_attrs
from ..driver.stages import Stage, empty_tables, remove_above, scaled_stiffness
from ..errors import InputError
from ..boundaries.loads import HalfSine, Haversine
from ..build.validate import number
from .common.preparation import PREPARATION_DEFAULTS, PreparedRun, add_cloud, check_preparation, \
    pour_stage, refill_stage, remove_where, settle_stage, vibrate_stage
from .common.grains import grain_spec
from .common.sleepers import members_mass, sleeper_members
from .common.stiffening import STIFFEN_DEFAULTS, check_stiffening, stiffen_stage
from .cycles import CycleRecorder

# [box_test] keys and defaults (SPEC.md 2.3, thesis table 5.1; stiffness is in [materials]);
# the preparation pipeline's keys (radius, seed, settle_*, vibration_* ...) are
# `pdem.scenes.common.preparation.PREPARATION_DEFAULTS`
DEFAULTS = {
    "box": [0.7, 0.3, 0.45],           # inner length x, width y, height z [m]
    "ballast_material": "ballast", "wall_material": "steel", "base_material": "rubber",
    "sleeper_material": "steel",
    **PREPARATION_DEFAULTS,
    "cut_height": 0.30,                 # first fill cut = sleeper bottom [m]
    "height": 0.45,                     # final ballast height [m]
    "sleeper_size": [0.25, 0.3, 0.15],  # [m]
    "sleeper_mass": 34.0,               # [kg], or "members": the member spheres' mass (Yade's clump: 9.37 kg)
    "f_min": 3000.0, "f_max": 40000.0, "frequency": 1.0, "cycles": 10,
    # options for what the thesis leaves open or pdem chose differently (docs/box_test.md, "Options")
    "cut": "top",                 # "top": cut the spheres whose top is above a cut; "center": whose centre is (Yade)
    "sleeper_placement": "cut",   # "cut": sleeper bottom at cut_height, overlaps loaded at once (Yade); "on_top":
                                  # lowered onto the spheres the cut leaves (touching, no overlap)
    "refill": "beside",           # "beside": clouds beside the sleeper; "whole": one cloud over the whole box
    "waveform": "haversine",      # "haversine" or "half_sine" (pdem.boundaries.loads)
    "base": "one_sided",          # "one_sided" or "two_sided" (grains may pass through; counted)
    "sleeper_surface": "flat",    # "flat": a smooth rigid box; "spheres": the thesis's clump of 2280 steel spheres
    "sleeper_member_radius": 0.005,  # [m] of the "spheres" surface (`sleeper_members`)
    # preparation at reduced stiffness, then a stiffening stage (law "linear"; docs/box_test.md "Full stiffness";
    # `pdem.scenes.common.stiffening`)
    **STIFFEN_DEFAULTS,
}
CHOICES = {"cut": ("top", "center"), "sleeper_placement": ("cut", "on_top"), "refill": ("beside", "whole"),
           "waveform": ("haversine", "half_sine"), "base": ("one_sided", "two_sided"),
           "sleeper_surface": ("flat", "spheres")}
WAVEFORMS = {"haversine": Haversine, "half_sine": HalfSine}
WHERE = ("box_test", "beside the sleeper")


# ---------------------------------------------------------------------------- settings
def box_settings(doc):
    """The [box_test] table with defaults, checked (one-line InputError naming the key)."""
    check_keys("scene file", doc, {"simulation", "run", "materials", "box_test"})
    given = doc["box_test"]
    check_keys("box_test", given, set(DEFAULTS) | {"clumps"})
    c = {**DEFAULTS, **given}
    for k in ("box", "sleeper_size"):
        v = c[k]
        if not (isinstance(v, list) and len(v) == 3):
            raise InputError(f"box_test.{k} = {v!r}: must be [x, y, z] lengths > 0 [m]")
        c[k] = [number(f"box_test.{k}", x, 0.0, lo_open=True, allow="[x, y, z] lengths > 0 [m]") for x in v]
    for k in ("ballast_material", "wall_material", "base_material", "sleeper_material"):
        if not isinstance(c[k], str) or c[k] not in doc.get("materials", {}):
            raise InputError(f"box_test.{k} = {c[k]!r}: no [materials.{c[k]}] table in the scene file")
    check_preparation("box_test", c)
    for k, allowed in CHOICES.items():
        if c[k] not in allowed:
            raise InputError(f"box_test.{k} = {c[k]!r}: must be one of {', '.join(repr(a) for a in allowed)}")
    limit = doc.get("simulation", {}).get("max_overlap_ratio", 0.5)
    if c["cut"] == "center" and c["sleeper_placement"] == "cut" and limit != 1.0:
        raise InputError(f"box_test.sleeper_placement = 'cut' with cut = 'center': the sleeper starts overlapping "
                         f"spheres by up to their radius (Yade's immediate loading), which the runaway guard stops at "
                         f"simulation.max_overlap_ratio = {limit!r}; set it to 1.0, or sleeper_placement = 'on_top'")
    check_stiffening("box_test", c, doc)
    for k in ("cut_height", "height", "frequency", "sleeper_member_radius"):
        c[k] = number(f"box_test.{k}", c[k], 0.0, lo_open=True)
    c["sleeper_members"] = (sleeper_members(c["sleeper_size"], c["sleeper_member_radius"])
                            if c["sleeper_surface"] == "spheres" else None)
    c["sleeper_mass"] = sleeper_mass(doc, c)
    for k in ("f_min", "f_max"):
        c[k] = number(f"box_test.{k}", c[k], 0.0)
    c["cycles"] = number("box_test.cycles", c["cycles"], 1, integer=True)
    if c["f_max"] < c["f_min"]:
        raise InputError(f"box_test.f_max = {c['f_max']!r}: must be >= f_min = {c['f_min']!r} [N]")
    if not c["cut_height"] < c["height"] <= c["box"][2]:
        raise InputError(f"box_test.height = {c['height']!r}: must be above cut_height = {c['cut_height']!r} "
                         f"and at most the box height {c['box'][2]!r} [m]")
    for a, name in ((0, "length"), (1, "width")):
        if c["sleeper_size"][a] > c["box"][a]:
            raise InputError(f"box_test.sleeper_size = {c['sleeper_size']!r}: the sleeper's {name} exceeds the box's")
    c["grain"] = grain_settings(doc, c)
    if "steps" in doc.get("run", {}):
        raise InputError("run.steps: not used by a box test (its stages end on settle_ratio, vibration_time and "
                         "cycles in [box_test]); remove it")
    return c


def grain_settings(doc, c):
    """None for sphere ballast, else the grain of ``[box_test.clumps]`` (rigid clumps: ``shape``
    and its keys as a ``[[clumps]]`` table, ``mass_model``; `pdem.scenes.common.grains.grain_spec`):
    {"members", "member_radii", "mass_model", "discretization", "samples", ...}."""
    if "clumps" not in c:
        return None
    g = grain_spec(doc, c["clumps"], "box_test.clumps", breakable=False)
    if c["cut"] == "center":
        raise InputError("box_test.cut = 'center': cuts spheres, which would split the clumps of [box_test.clumps]; "
                         "use cut = 'top' (whole clumps with a member above the cut are removed)")
    return g


def sleeper_mass(doc, c):
    """The sleeper's mass [kg]: ``sleeper_mass``, or with "members" (``sleeper_surface`` = "spheres")
    the mass of its member spheres of the sleeper material's density, as Yade sums a clump's."""
    m = c["sleeper_mass"]
    if m == "members":
        if c["sleeper_surface"] != "spheres":
            raise InputError("box_test.sleeper_mass = 'members': needs sleeper_surface = 'spheres' (a flat sleeper "
                             "has no members); give a mass in kg")
        r = c["sleeper_member_radius"]
        density = float(doc["materials"][c["sleeper_material"]]["density"])
        return members_mass(c["sleeper_members"], r, density)
    return number("box_test.sleeper_mass", m, 0.0, lo_open=True, allow="a number > 0 [kg] or 'members'")


# ---------------------------------------------------------------------------- geometry
def sleeper_geometry(c, bottom):
    """(center, half_extents) of the sleeper with its bottom at ``bottom`` [m]."""
    bx, sz = np.asarray(c["box"], float), np.asarray(c["sleeper_size"], float)
    center = np.array([bx[0] / 2, bx[1] / 2, bottom + sz[2] / 2])
    return center, sz / 2


def sleeper_on_top(c, tables):
    """Bottom height [m] of the sleeper lowered onto the spheres of ``tables``: the lowest at which
    its bottom face touches but overlaps none of them (a sphere at horizontal distance d < r from
    the footprint holds it at z + sqrt(r² − d²)); 0 if none lies under it."""
    center, half = sleeper_geometry(c, 0.0)
    p = tables["particles"]
    pos, r = p["pos"], p["radius"]
    dx = np.maximum(np.abs(pos[:, 0] - center[0]) - half[0], 0.0)
    dy = np.maximum(np.abs(pos[:, 1] - center[1]) - half[1], 0.0)
    d2 = dx * dx + dy * dy
    under = d2 < r * r
    return float(np.max(pos[under, 2] + np.sqrt(r[under] ** 2 - d2[under]), initial=0.0))


def cut(c, tables, height):
    """(tables, removed): the spheres above ``height`` [m] removed, by their top (``cut`` = "top",
    `remove_above`) or by their centre (``cut`` = "center", as a Yade script that deletes the
    bodies with pos z > height)."""
    if c["cut"] == "center":
        return remove_where(tables, lambda pos, radius: pos[:, 2] > height)
    return remove_above(tables, height)


def catch_depth(c):
    """Depth [m] below the base of the floor that catches the spheres passing a two-sided base
    (4 largest radii: a sphere resting on it is clear of the base)."""
    return 4.0 * c["radius"] * (1.0 + c["radius_spread"])


# ---------------------------------------------------------------------------- stage scenes
def stage_scene(doc, c, tables, sleeper=True, load_start=None, sleeper_center=None, stiffness=1.0):
    """The `Scene` of a stage holding the spheres of ``tables``: materials and settings of the
    file, the box's five walls, the sleeper if ``sleeper`` (from stage ``refill`` on; loaded
    from ``load_start`` [s] if given: stage ``load``). With ``base`` = "two_sided" the base acts
    on both sides (Yade's wall sense 0) and a sixth wall ``catch`` at `catch_depth` below it
    holds the spheres that passed through. Every material's stiffness times ``stiffness``
    (``prep_stiffness_factor`` before ``load``)."""
    base = {k: v for k, v in doc.items() if k in ("simulation", "materials")}
    if stiffness != 1.0:
        base["materials"] = scaled_stiffness(base["materials"], stiffness)
    base["simulation"] = {**base.get("simulation", {}), "allow_initial_overlap": True}
    scene = scene_from_dict(base)
    lx, ly, _ = c["box"]
    two_sided = c["base"] == "two_sided"
    scene.add_wall("z", 0.0, c["base_material"], sense=0 if two_sided else 1, name="base")
    scene.add_wall("x", 0.0, c["wall_material"], sense=1, name="x_min")
    scene.add_wall("x", lx, c["wall_material"], sense=-1, name="x_max")
    scene.add_wall("y", 0.0, c["wall_material"], sense=1, name="y_min")
    scene.add_wall("y", ly, c["wall_material"], sense=-1, name="y_max")
    if two_sided:
        scene.add_wall("z", -catch_depth(c), c["wall_material"], sense=1, name="catch")
    if sleeper:
        center, half = sleeper_geometry(c, c["cut_height"])
        if sleeper_center is not None:
            center = np.asarray(sleeper_center, float)
        load = (WAVEFORMS[c["waveform"]](c["f_min"], c["f_max"], c["frequency"], c["cycles"], start=load_start,
                                         label="box_test") if load_start is not None else None)
        scene.add_box(center, half, c["sleeper_material"], c["sleeper_mass"], blocked="xyXYZ", load=load,
                      damping=scene.settings.damping, name="sleeper", members=c["sleeper_members"],
                      member_radius=c["sleeper_member_radius"])
    scene.add_sphere_columns(tables["particles"])
    if "clumps" in tables:
        scene.add_clump_tables(tables["clumps"], tables["clump_members"])
    return scene


# ---------------------------------------------------------------------------- records
def face_forces(sim):
    """{"force_bottom", "force_side"}: the ballast force on the sleeper's bottom face and on its
    sides (friction) [N, along the load direction, positive against it] (collective)."""
    d = sim.boxes.direction[0]
    bottom, side = box_face_forces(sim, 0)
    return {"force_bottom": float(-(bottom @ d)), "force_side": float(-(side @ d))}


def base_passed(sim):
    """Spheres whose centre is below the base plane z = 0 (passed through a two-sided base)."""
    p = sim.particles
    return sim.comm.allreduce_sum_int(int(np.count_nonzero(p.pos[: p.n_local, 2] < 0.0)))


def load_sample(sim, reference, load=None):
    """A row of the load record; ``reference`` is the sleeper centre where cycling started."""
    bx = sim.boxes
    d = bx.direction[0]
    faces = face_forces(sim)
    return {"step": sim.step, "time": sim.time, "dt": sim.dt,
            "sleeper_load": float(bx.load_force[0] @ d) if load is None else float(load),
            "sleeper_force": float(-(bx.contact_force[0] @ d)),
            "sleeper_force_bottom": faces["force_bottom"], "sleeper_force_side": faces["force_side"],
            "base_passed": float(base_passed(sim)),
            "sleeper_settlement": float((bx.center[0] - reference) @ d),
            "kinetic_energy": kinetic_energy(sim), "contacts_per_particle": sim.contacts_per_particle()}


CYCLE_EXTRA = ("settlement_at_force_max", "settlement_max", "force_bottom_peak", "force_side_peak", "base_passed_end")


def cycle_columns(recorder):
    """The per-cycle table in `pdem.format.schema` terms (cycle numbered from 1)."""
    t = recorder.table()
    return {"cycle": t["cycle"] + 1.0, "t_start": t["t_start"], "settlement_start": t["settlement_start"],
            "settlement_peak": t["settlement_peak"], "settlement_end": t["settlement_end"],
            "force_peak": t["force_max"], "force_min": t["force_min"], "load_max": t["load_max"],
            "load_min": t["load_min"], "step": np.array([r.get("step", 0) for r in recorder.records], np.float64),
            **{k: t.get(k, np.full(len(t["cycle"]), np.nan)) for k in CYCLE_EXTRA}}


# ---------------------------------------------------------------------------- the run
def check(doc):
    """Check a parsed box-test scene file without running it (one-line InputError)."""
    box_settings(doc)
    run_settings(doc)
    stage_scene(doc, box_settings(doc), empty_tables(), load_start=0.0)


def run(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run (or resume) the box test of a parsed scene file; returns the exit status."""
    run = BoxTestRun(path, doc, out_dir, comm, fresh)
    if steps is not None:  # stop with a checkpoint at this step of the run (continue without --steps)
        run.stop_step = number("--steps", steps, 0, integer=True)
    return run.run()


class BoxTestRun(PreparedRun):
    """One box test on this process's ranks: the preparation stages
    (`pdem.scenes.common.preparation`) in the box, then (after ``stiffen`` if the preparation
    was soft) the cyclic load stage, its records (results.h5 with the cycles) and the finishing
    analysis. The scene's ``state`` adds the load start and the cycle recorder."""

    NAME = "box_test"

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.c = box_settings(doc)
        self.recorder = None
        super().__init__(path, doc, out_dir, comm, fresh)

    def stage_list(self):
        soft = self.c["prep_stiffness_factor"] != 1.0
        stages = [pour_stage(self, lambda tables: self.stage_scene(tables, sleeper=False), self.pour),
                  refill_stage(self, self.stage_scene, self.refill),
                  vibrate_stage(self, self.stage_scene, self.trim),
                  settle_stage(self, self.stage_scene).then(close=None if soft else self.first_load_row)]
        if soft:
            stages.append(stiffen_stage(self, self.stage_scene, after=self.first_load_row))
        stages.append(Stage("load", lambda tables: self.stage_scene(tables, loaded=True), self.load_program,
                            open=self.open_load, close=lambda sim: self.stage_done(sim, "load"),
                            record=self.stage_record, length=(self.c["cycles"] / self.c["frequency"], False)))
        if self.c["base"] == "two_sided":
            stages = [stage.then(prepare=self.open_base) for stage in stages]
        return stages

    def initial_state(self):
        return {"load_start": None, "recorder": None, "stiffness_scale": self.c["prep_stiffness_factor"]}

    def checkpoint_state(self):
        return {**self.state, "recorder": self.recorder.state() if self.recorder else None}

    def open_results(self):
        restart, comm = self.restart_step, self.comm
        self.results = self.out / "results.h5"
        # written every 500 rows, at every checkpoint and at a stop (the loop flushes it): rows after
        # the last checkpoint are made again by a resumed run
        self.series = series_writer(self.results, BOX_TEST_SERIES, comm, restart_step=restart, every=500)
        self.loop.flush.append(self.series)
        if comm.rank == 0:
            doc = self.doc
            write_root_attrs(self.results, {k: doc[k] for k in ("simulation", "materials", "box_test") if k in doc},
                             "box_test")

    def close_results(self):
        self.series.close()

    def stage_scene(self, tables, sleeper=True, loaded=False):
        """`stage_scene` of the run: the sleeper where the tables (or the refill) put it; before
        ``load`` at the preparation's stiffness."""
        center = tables["boxes"]["center"][0] if "boxes" in tables else None
        if center is None and self.state.get("sleeper_bottom") is not None:
            center = sleeper_geometry(self.c, self.state["sleeper_bottom"])[0]
        return stage_scene(self.doc, self.c, tables, sleeper, self.state["load_start"] if loaded else None, center,
                           1.0 if loaded else self.c["prep_stiffness_factor"])

    def open_base(self, sim, scene, mid_stage):
        """A two-sided base: a sphere may pass it, so no domain check there, and a sphere on the
        plane overlaps it by its radius (ratio 1)."""
        sim.guard.wall_side[sim.wall_index("base")] = 0
        sim.max_overlap_ratio = max(sim.max_overlap_ratio, 1.0)

    def bodies_note(self, sim):
        if sim.boxes is None:
            return ""
        z = sim.boxes.center[0, 2]
        return f", sleeper centre z {1e3 * z:.1f} mm (bottom {1e3 * (z - sim.boxes.half[0, 2]):.1f} mm)"

    # ------------------------------------------------------------------ preparation in the box
    def pour(self, tables):
        c = self.c
        lx, ly, _ = c["box"]
        tables = add_cloud(empty_tables(), self.doc, c, (0.0, 0.0), (lx, ly), 0.0, lx * ly * c["cut_height"], c["seed"],
                           0, WHERE)
        return tables, f"poured {len(tables['particles']['gid'])} spheres"

    def refill(self, tables):
        c, doc = self.c, self.doc
        lx, ly, _ = c["box"]
        h1, h2 = c["cut_height"], c["height"]
        tables, removed = cut(c, tables, h1)
        bottom = sleeper_on_top(c, tables) if c["sleeper_placement"] == "on_top" else h1
        self.state["sleeper_bottom"] = bottom
        center, half = sleeper_geometry(c, bottom)
        x0, x1 = center[0] - half[0], center[0] + half[0]
        gid = self.state["next_gid"]
        n0 = len(tables["particles"]["gid"])
        if c["refill"] == "whole":  # one cloud over the whole box, from the sleeper's top up
            tables = add_cloud(tables, doc, c, (0.0, 0.0), (lx, ly), center[2] + half[2], lx * ly * (h2 - h1),
                               c["seed"] + 1000, gid, ("box_test", "in the box"))
            where = "over the whole box"
        else:
            for k, (a, b) in enumerate(((0.0, x0), (x1, lx))):
                if b - a <= 0:
                    continue
                tables = add_cloud(tables, doc, c, (a, 0.0), (b, ly), h1, (b - a) * ly * (h2 - h1),
                                   c["seed"] + 1000 + k, gid, WHERE)
                gid = int(tables["particles"]["gid"].max()) + 1
            where = "beside it"
        surface = "" if c["sleeper_members"] is None else f", {len(c['sleeper_members'])} member spheres"
        return tables, (f"removed {removed} spheres above {h1} m, placed the sleeper (bottom {bottom:.4f} m, "
                        f"{c['sleeper_mass']:.4g} kg{surface}), poured {len(tables['particles']['gid']) - n0} spheres "
                        f"{where}")

    def trim(self, tables):
        h2 = self.c["height"]
        tables, removed = cut(self.c, tables, h2)
        return tables, f"removed {removed} spheres above {h2} m"

    # ------------------------------------------------------------------ cyclic loading
    def open_load(self, tables):
        self.state["load_start"] = float(self.meta["time"]) if self.meta else 0.0
        return tables, ""

    def first_load_row(self, sim):
        """The first row of the load record: the sleeper where cycling starts."""
        self.series.append(load_sample(sim, sim.boxes.center[0], load=self.c["f_min"]))

    def load_program(self, sim, scene):
        c, state, run = self.c, self.state, self.run_cfg
        self.recorder = rec = CycleRecorder(scene.boxes.loads[0])
        if state["recorder"] is not None:
            rec.restore(state["recorder"])
        else:
            rec.reference = sim.boxes.center[0].copy()

        def on_step(sim):
            done = rec.sample_box(sim, 0, split=face_forces(sim) if rec.at_peak(sim.time) else None)
            if done is not None:
                done["step"] = sim.step
                done["base_passed_end"] = float(base_passed(sim))
                write_cycles(self.results, cycle_columns(rec), self.comm)
                self.loop.log(f"cycle {done['cycle'] + 1}/{c['cycles']}: settlement start "
                              f"{1e3 * done['settlement_start']:.3f} mm, peak {1e3 * done['settlement_peak']:.3f} mm, "
                              f"end {1e3 * done['settlement_end']:.3f} mm; ballast force {done['force_min']:.1f} .. "
                              f"{done['force_max']:.1f} N")
            if run["output_every"] and sim.step % run["output_every"] == 0:
                self.series.append(load_sample(sim, rec.reference))
            self.snapshot(sim)

        return (
            on_step,
            lambda sim: len(rec.records) >= c["cycles"],
            1,
            state["load_start"] + c["cycles"] / c["frequency"],
        )

    def finish(self, sim, wall_s):
        c = self.c
        super().finish(sim, wall_s, summary="box_test", title="box test", about=[],
                       stage_columns=[("sleeper_z", "sleeper centre z [m]", ".4f")],
                       preparation={"stages": list(self.STAGES), "body": "sleeper centre"},
                       notes=[f"cycles {c['f_min']:g} <-> {c['f_max']:g} N at {c['frequency']:g} Hz"])
