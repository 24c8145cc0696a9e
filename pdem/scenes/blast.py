"""The blast layer (SPEC.md 2.5; Szklennik, Biuletyn WAT 65(3), 2016, section 3): a granular layer
in a rigid box, a rigid cover plate on top hit by F(t) = F0 (1 − t/τ), the stress on the fixed
ceiling below it, on any number of ranks.

A scene file with a ``[blast]`` table (keys and defaults in `DEFAULTS`, units SI; the contact law
is ``[simulation] law = "viscous"`` with materials ``grain``, ``plate``, ``wall`` by default, and
``side_material`` for the four side walls: the jobs make them frictionless, the symmetry planes
of a slice of a wide layer) runs:

1. ``pour``     a seeded loose cloud of spheres (diameters ``diameter_min``..``diameter_max``)
                falls into the box (ceiling = floor wall at z = 0, four side walls) and settles
                (optional Cundall damping ``prep_damping``, preparation only; default 0: the
                viscous law alone brings the layer to rest, while Cundall damping together with
                the rolling springs kept a jammed column agitated in tests), not before the top of
                the cloud could have fallen to the floor (sqrt(2 h/g)). With
                ``prep_stiffness_factor`` < 1 the pour runs with the stiffnesses (k_n, k_s, k_θ;
                E) times that factor (a longer Δt); the settle stage makes every contact again
                at the full stiffness.
2. ``settle``   the spheres whose top is above the layer height ``box[2]`` are removed; settle
                again. The layer at the end of this stage is the *prepared layer*: it is also
                written to ``prepared_layer/`` of the run directory.
3. per plate k of ``plates`` (areal masses [kg/m²]), starting again from the prepared layer:
   ``plate_k``  the cover plate (a rigid box spanning the box, z translation only, mass =
                areal mass × box area) is placed on the highest grain and lowered at up to
                ``plate_lowering_speed`` until the grains carry its weight (`PlateLowering`),
                then let go at rest; it settles under its weight (Cundall damping
                ``plate_damping`` on the plate only) until the grains' unbalanced force ratio
                and the plate's (|F_grains + m g|/(m g)) are below ``plate_settle_ratio`` and
                the plate is slower than ``plate_settle_velocity``;
   ``blast_k``  no Cundall damping (only the law's viscous damping, as in the paper); the plate
                carries F(t) = F0 (1 − t/τ) downwards for ``duration`` [s] after the stage starts.

"Prepare once, load many": one run with ``plates = [10780, 2700, 244]`` prepares the layer once
and loads it with each plate in turn; ``prepared_from`` (a run directory or its prepared-layer
file) skips stages 1–2 and starts from another run's prepared layer (the box, diameters and
materials must match); ``plates = []`` prepares a layer and stops. So a seeds × plates campaign is
one run per seed, or one preparation run per seed and one run per (seed, plate) with
``prepared_from``.

Output in the run directory: ``plate_<areal mass>/results.h5`` (kind "blast" of
`pdem.format.schema`: series ``plate_position`` [m], ``plate_velocity`` [m/s], ``ceiling_stress`` σ0
[Pa, compression positive], ``input_force`` [N], time 0 at the start of the impulse; the
``/blast`` group), ``preparation.h5`` and ``preparation.png``, ``analysis/`` (the analysis of
`analysis.blast`: σ0(t), plate motion, impulse I_s and amplification against the paper; with
several plates a comparison) and ``summary.txt`` with the timing table. Each stage ends with a
checkpoint; a run resumes from any of them on any rank count, bit for bit.
"""
import shutil
from math import ceil, pi
from pathlib import Path

import numpy as np

from ..bodies.boxes import blocked_mask
from ..build.config import check_keys, run_settings, scene_from_dict
from ..contact import viscous
from ..driver import observables
from ..driver.snapshots import write_snapshot
from ..driver.results import series_writer, write_root_attrs
from ..driver.stages import (
    Stage,
    StagedRun,
    append_bodies,
    empty_tables,
    in_order,
    remove_above,
    scaled_stiffness,
)
from ..errors import InputError, InstabilityError
from ..format.schema import BLAST_RUN_SERIES, PREPARATION_SERIES, write_blast_parameters
from ..build.generators import loose_cloud
from ..io.checkpoint import (
    CheckpointError,
    list_checkpoints,
    read_checkpoint,
    write_checkpoint,
)
from ..boundaries.loads import Impulse
from ..build.validate import number
from .common.bounds import plausible

# [blast] keys and defaults (SPEC.md 2.5; stiffness and damping are in [materials])
DEFAULTS = {
    "box": [0.3, 0.3, 0.3],            # inner x, y [m] and the layer height z [m]
    "grain_material": "grain", "plate_material": "plate", "wall_material": "wall",
    "side_material": "",               # the four side walls ("": wall_material)
    "diameter_min": 0.009, "diameter_max": 0.010,   # [m], uniform
    "seed": 1,
    "packing_fraction": 0.6,           # solid fraction assumed to size the cloud [-]
    "overfill": 1.1,                   # cloud volume / layer volume [-]
    "prep_damping": 0.0,               # Cundall lambda_D of the preparation stages [-] (see the docstring)
    "prep_stiffness_factor": 1.0,      # pour with the materials' stiffness times this [-]
    "plate_damping": 0.7,              # Cundall lambda_D of the plate (only) while it settles [-]
    "plate_lowering_speed": 0.1,       # the plate is lowered at up to this speed until the grains carry
                                       # its weight, then let go [m/s]; 0: dropped onto the layer
    "settle_ratio": 0.01, "settle_min_time": 0.05, "settle_max_time": 1.0, "check_every": 200,
    "plate_settle_ratio": 0.01, "plate_settle_min_time": 0.02, "plate_settle_max_time": 0.2,
    "plate_settle_velocity": 1e-3,     # and the plate slower than this [m/s]
    "plates": [10780.0],               # areal masses of the cover plates [kg/m^2]; [] prepares only
    "plate_thickness": 0.02,           # [m], geometry only (the mass is areal mass x area)
    "F0": 9.0e6, "tau": 1.0e-4,        # F(t) = F0 (1 - t/tau) [N], [s]
    "duration": 9.0e-3,                # simulated after the impulse starts [s]
    "record_every": 1,                 # steps between rows of the blast record
    "prepared_from": "",               # run directory or prepared-layer file ("": prepare here)
}
PREPARED_DIR = "prepared_layer"
# what must agree between a prepared layer and the run that loads it
PREPARED_KEYS = ("box", "grain_material", "wall_material", "side_material", "diameter_min", "diameter_max", "seed",
                 "packing_fraction", "overfill", "prep_stiffness_factor", "prep_damping", "settle_ratio")


# ---------------------------------------------------------------------------- settings
def blast_settings(doc):
    """The [blast] table with defaults, checked (one-line InputError naming the key)."""
    check_keys("scene file", doc, {"simulation", "run", "materials", "blast"})
    given = doc["blast"]
    check_keys("blast", given, set(DEFAULTS))
    c = {**DEFAULTS, **given}
    v = c["box"]
    if not (isinstance(v, list) and len(v) == 3):
        raise InputError(f"blast.box = {v!r}: must be [x, y, layer height] lengths > 0 [m]")
    c["box"] = [number("blast.box", x, 0.0, lo_open=True, allow="[x, y, layer height] lengths > 0 [m]") for x in v]
    materials = doc.get("materials", {})
    if c["side_material"] == "":
        c["side_material"] = c["wall_material"]
    for k in ("grain_material", "plate_material", "wall_material", "side_material"):
        if not isinstance(c[k], str) or c[k] not in materials:
            raise InputError(f"blast.{k} = {c[k]!r}: no [materials.{c[k]}] table in the scene file")
    for k in ("diameter_min", "diameter_max", "packing_fraction", "overfill", "settle_ratio", "settle_max_time",
              "plate_settle_velocity",
              "plate_settle_ratio", "plate_settle_max_time", "plate_thickness", "F0", "tau", "duration"):
        c[k] = number(f"blast.{k}", c[k], 0.0, lo_open=True)
    for k in ("settle_min_time", "plate_settle_min_time", "plate_lowering_speed"):
        c[k] = number(f"blast.{k}", c[k], 0.0)
    c["prep_damping"] = number(
        "blast.prep_damping", c["prep_damping"], 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)"
    )
    c["plate_damping"] = number(
        "blast.plate_damping", c["plate_damping"], 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)"
    )
    c["prep_stiffness_factor"] = number("blast.prep_stiffness_factor", c["prep_stiffness_factor"], 0.0, 1.0,
                                        lo_open=True, allow="in (0, 1]")
    for k in ("seed", "check_every", "record_every"):
        c[k] = number(f"blast.{k}", c[k], 0 if k == "seed" else 1, integer=True)
    if c["diameter_max"] < c["diameter_min"]:
        raise InputError(
            f"blast.diameter_max = {c['diameter_max']!r}: must be >= diameter_min = {c['diameter_min']!r} [m]"
        )
    plates = c["plates"]
    if not isinstance(plates, list):
        raise InputError(f"blast.plates = {plates!r}: must be a list of plate areal masses > 0 [kg/m^2]")
    if not plates and c["prepared_from"]:
        raise InputError("blast.plates = []: a run with prepared_from must load at least one plate "
                         "(plates = [] only prepares a layer)")
    c["plates"] = [
        number("blast.plates", m, 0.0, lo_open=True, allow="plate areal masses > 0 [kg/m^2]") for m in plates
    ]
    if len(set(c["plates"])) != len(c["plates"]):
        raise InputError(f"blast.plates = {plates!r}: each areal mass at most once (one results directory each)")
    if not isinstance(c["prepared_from"], str):
        raise InputError(f"blast.prepared_from = {c['prepared_from']!r}: must be a path (a run directory or its "
                         f"{PREPARED_DIR} checkpoint file) or \"\"")
    if "steps" in doc.get("run", {}):
        raise InputError("run.steps: not used by a blast run (its stages end on settle criteria and blast.duration); "
                         "remove it")
    plausible("blast", c)
    return c


def plate_dir(mass):
    """Results directory of the plate of areal mass ``mass`` [kg/m^2]."""
    return f"plate_{mass:g}"


# ---------------------------------------------------------------------------- geometry
def radius_range(c):
    return 0.5 * c["diameter_min"], 0.5 * c["diameter_max"]


def cloud(c):
    """(pos, radius) of the loose cloud poured in stage 1."""
    lx, ly, h = c["box"]
    r_lo, r_hi = radius_range(c)
    r_mean, spread = 0.5 * (r_lo + r_hi), (r_hi - r_lo) / (r_lo + r_hi)
    mean_r3 = r_mean ** 3 if spread == 0 else (r_hi ** 4 - r_lo ** 4) / (4 * (r_hi - r_lo))
    n = max(ceil(c["overfill"] * c["packing_fraction"] * lx * ly * h / (4.0 / 3.0 * pi * mean_r3)), 1)
    a = 2 * r_hi * 1.05
    per_layer = np.floor(lx / a) * np.floor(ly / a)
    if per_layer < 1:
        raise InputError(f"blast.diameter_max = {c['diameter_max']!r}: the spheres do not fit in the box")
    top = np.ceil(n / per_layer) * a + 1e-9
    return loose_cloud([0.0, 0.0, 0.0], [lx, ly, top], n, r_mean, spread, c["seed"])


def plate_geometry(c, bottom):
    """(centre, half extents) of the cover plate with its bottom at ``bottom`` [m]."""
    lx, ly, _ = c["box"]
    t = c["plate_thickness"]
    return np.array([lx / 2, ly / 2, bottom + t / 2]), np.array([lx / 2, ly / 2, t / 2])


def stage_scene(doc, c, tables, plate_mass=None, load=None, plate_center=None, lowering=False, stiffness=1.0):
    """The `Scene` of a stage holding the spheres of ``tables``: the file's materials and
    settings (every stiffness times ``stiffness``: ``prep_stiffness_factor`` while pouring), the
    ceiling and four side walls, and (plate and blast stages: ``plate_mass`` [kg/m²] given) the
    cover plate, free in z or (``lowering``) moved at a prescribed velocity (`PlateLowering`).
    With the blast's ``load`` (an impulse stage) nothing is damped."""
    base = {k: v for k, v in doc.items() if k in ("simulation", "materials", "material_pairs")}
    if stiffness != 1.0:
        base["materials"] = scaled_stiffness(base["materials"], stiffness)
    blast = load is not None
    base["simulation"] = {**base.get("simulation", {}), "allow_initial_overlap": True,
                          "damping": 0.0 if blast else c["prep_damping"]}
    scene = scene_from_dict(base)
    lx, ly, _ = c["box"]
    w = c["side_material"]
    scene.add_wall("z", 0.0, c["wall_material"], sense=1, name="ceiling")
    scene.add_wall("x", 0.0, w, sense=1, name="x_min")
    scene.add_wall("x", lx, w, sense=-1, name="x_max")
    scene.add_wall("y", 0.0, w, sense=1, name="y_min")
    scene.add_wall("y", ly, w, sense=-1, name="y_max")
    if plate_mass is not None:
        _, half = plate_geometry(c, 0.0)
        scene.add_box(plate_center, half, c["plate_material"], plate_mass * lx * ly,
                      blocked="xyzXYZ" if lowering else "xyXYZ", load=load,
                      damping=0.0 if blast else c["plate_damping"], name="plate")
    scene.add_sphere_columns(tables["particles"])
    return scene


# ---------------------------------------------------------------------------- the prepared layer
def prepared_file(path):
    """The prepared-layer checkpoint of a run directory, or ``path`` itself if it is a file."""
    path = Path(path)
    if path.is_file():
        return path
    found = list_checkpoints(path / PREPARED_DIR)
    if not found:
        raise InputError(f"blast.prepared_from = {str(path)!r}: no prepared layer there (neither a file nor a run "
                         f"directory with {PREPARED_DIR}/)")
    return found[-1][1]


def read_prepared(path, c, materials):
    """(tables, meta) of a prepared layer; InputError if it was made for another layer."""
    f = prepared_file(path)
    try:
        tables, meta = read_checkpoint(f)
    except CheckpointError as exc:
        raise InputError(f"blast.prepared_from: {exc}") from None
    made = meta.get("blast_prepared")
    if made is None:
        raise InputError(f"blast.prepared_from: {f} is not a prepared blast layer")
    for k in PREPARED_KEYS:
        if made["settings"].get(k) != c[k]:
            raise InputError(f"blast.{k} = {c[k]!r}: the prepared layer {f} was made with {made['settings'].get(k)!r}")
    if made["materials"] != materials:
        raise InputError(f"materials: differ from those the prepared layer {f} was made with")
    return tables, meta


# ---------------------------------------------------------------------------- records
def prep_sample(sim, stage_index):
    e = sim.energy()
    return {
        "step": sim.step,
        "time": sim.time,
        "stage": stage_index,
        "n_spheres": sim.comm.allreduce_sum_int(sim.particles.n_local),
        "kinetic_energy": e["kinetic"] + e["rotational"],
        "unbalanced_force": observables.unbalanced_force(sim),
        "contacts_per_particle": sim.contacts_per_particle(),
        "bed_top": observables.bed_top(sim),
        # the plate's centre height, 0 before the plate is placed (results hold no NaN)
        "sleeper_z": float(sim.boxes.center[0, 2]) if sim.boxes is not None else 0.0,
    }


def blast_sample(sim, t0, load, area):
    """A row of the blast record after a step: time from the start of the impulse ``t0`` at the
    start of the step, when the contact forces (σ0) were computed and the load (F(t)) was taken;
    the plate's position and velocity at the end of the step (one Δt later)."""
    e = sim.energy()
    ceiling = observables.wall_forces(sim)[0]
    bx = sim.boxes
    t = sim.time - sim.dt
    return {"step": sim.step, "time": t - t0, "dt": sim.dt, "plate_position": float(bx.center[0, 2]),
            "plate_velocity": float(bx.velocity[0, 2]), "ceiling_stress": float(-ceiling[2] / area),
            "input_force": float(load.value(t)), "kinetic_energy": e["kinetic"] + e["rotational"]}


class PlateLowering:
    """The plate stage's first phase: the plate (blocked in z) is lowered onto the layer at
    v = ``speed`` (1 − F/W) [m/s], F the grains' upward force on it and W its weight, until
    F ≥ (1 − ``tolerance``) W; then it is let go at rest (free in z, Cundall-damped) to settle.
    Dropped from the highest grain instead, a heavy plate lands at ~0.1 m/s and rings on the
    stiff layer for ~0.15 s; lowered, it meets the layer's resistance at a vanishing speed.
    The speed depends on the exact global force sum only, so every rank count gives the same
    bits; the phase is in the run's state (``state["plate_free"]``) and the plate's velocity in
    the checkpoint, so a restart continues it exactly."""

    tolerance = 0.02

    def __init__(self, speed, state):
        self.speed, self.state = speed, state

    def __call__(self, sim):
        """After a step: the prescribed velocity of the next one, or let the plate go."""
        if self.state["plate_free"]:
            return
        bx = sim.boxes
        weight = -bx.mass[0] * sim.gravity[2]
        carried = float(bx.contact_force[0, 2]) / weight
        if carried >= 1.0 - self.tolerance:
            bx.blocked[0] = blocked_mask("plate", "xyXYZ", False)
            bx.velocity[0, 2] = 0.0
            self.state["plate_free"] = True
        else:
            bx.velocity[0, 2] = -self.speed * min(1.0, 1.0 - carried)


def plate_balance(sim):
    """|F_grains,z + m g_z| / (m |g_z|) of the plate [-]: 0 when the layer carries its weight."""
    bx = sim.boxes
    weight = bx.mass[0] * sim.gravity[2]
    return abs(float(bx.contact_force[0, 2]) + weight) / abs(weight)


def check_plate_step(sim, limit):
    """Stop (`InstabilityError`) if the plate moved more than ``limit`` [m] in the last step: it
    would pass through grains before their overlap is checked."""
    v = float(sim.boxes.velocity[0, 2])
    if abs(v) * sim.dt > limit:
        raise InstabilityError(
            f"step {sim.step}: the cover plate moved {abs(v) * sim.dt:.3e} m in one step (velocity {v:.4g} m/s, dt = "
            f"{sim.dt:.3e} s), more than a quarter of the smallest grain radius: the load is too high for the layer's "
            "contact stiffness (or the plate too light); the grains cannot stop it")


# ---------------------------------------------------------------------------- the run
def check(doc):
    """Check a parsed blast scene file without running it (one-line InputError)."""
    c = blast_settings(doc)
    run_settings(doc)
    if doc.get("simulation", {}).get("law") is None:
        raise InputError("simulation.law: required for a blast run (the paper's law is \"viscous\")")
    if c["plates"]:
        center, _ = plate_geometry(c, c["box"][2])
        stage_scene(doc, c, empty_tables(), c["plates"][0], Impulse(c["F0"], c["tau"], label="blast"), center)
    else:
        stage_scene(doc, c, empty_tables(), stiffness=c["prep_stiffness_factor"])
    if c["prepared_from"]:
        read_prepared(c["prepared_from"], c, doc["materials"])


def run(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run (or resume) the blast layer of a parsed scene file; returns the exit status."""
    check(doc)
    run = BlastRun(path, doc, out_dir, comm, fresh)
    if steps is not None:  # stop with a checkpoint at this step of the run (continue without --steps)
        run.stop_step = number("--steps", steps, 0, integer=True)
    return run.run()


class BlastRun(StagedRun):
    """One blast run (`pdem.driver.stages.StagedRun`): the preparation, then plate and blast
    stages per plate, each plate from the prepared layer. ``state`` adds the prepared-layer
    file and the start of the current impulse."""

    NAME = "blast"

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.c = blast_settings(doc)
        self.writer = None
        super().__init__(path, doc, out_dir, comm, fresh)

    def initial_state(self):
        return {"prepared": self.c["prepared_from"] and str(prepared_file(self.c["prepared_from"])), "blast_t0": None,
                "plates": []}

    def open_outputs(self):
        self.prep = series_writer(self.out / "preparation.h5", PREPARATION_SERIES, self.comm,
                                  restart_step=self.restart_step)
        self.loop.flush.append(self.prep)

    def close_outputs(self):
        self.prep.close()
        if self.writer is not None:
            self.writer.close()

    # ------------------------------------------------------------------ the stages
    def stage_list(self):
        """pour, settle (unless ``prepared_from``), then per plate ``plate_k`` (placed on the
        prepared layer and settled) and ``blast_k`` (the impulse)."""
        c = self.c
        prep = [] if c["prepared_from"] else [
            Stage("pour", self.pour_scene, self.settle_program(wait_fall=True), open=self.pour,
                  close=self.settle_close("pour"), record=self.stage_record),
            Stage("settle", self.prep_scene, self.settle_program(), open=self.cut,
                  close=in_order(self.settle_close("settle"), self.write_prepared), record=self.stage_record)]
        return prep + [stage for k, mass in enumerate(c["plates"]) for stage in (
            Stage(f"plate_{k}", self.plate_scene(mass), self.settle_program(plate=True), open=self.place_plate(mass),
                  close=self.settle_close(f"plate_{k}", plate=True), record=self.stage_record),
            Stage(f"blast_{k}", self.blast_scene(mass), self.blast_program(mass), open=self.open_blast,
                  close=self.blast_close(f"blast_{k}", mass), record=self.stage_record))]

    def pour(self, tables):
        c, state = self.c, self.state
        pos, radius = cloud(c)
        g = float(np.linalg.norm(self.doc.get("simulation", {}).get("gravity", [0.0, 0.0, 0.0])))
        top = float(np.max(pos[:, 2] + radius))
        state["pour_min_time"] = float(np.sqrt(2.0 * top / g)) if g > 0 else 0.0
        grain = c["grain_material"]
        tables = append_bodies(empty_tables(), pos, radius, self.doc["materials"][grain]["density"],
                               list(self.doc["materials"]).index(grain), 0)
        return tables, f"poured {len(radius)} spheres"

    def cut(self, tables):
        c = self.c
        tables, removed = remove_above(tables, c["box"][2])
        if c["prep_stiffness_factor"] != 1.0:  # the soft pour's contacts are made again at full stiffness
            tables = {k: v for k, v in tables.items() if not k.startswith("contacts/")}
        return tables, f"removed {removed} spheres above {c['box'][2]} m"

    def place_plate(self, mass):
        """The plate stage's opening: the prepared layer, the plate of ``mass`` [kg/m²] on its
        highest grain."""
        def place(tables):
            c, state = self.c, self.state
            tables, meta = read_prepared(state["prepared"], c, self.doc["materials"])
            tables = {k: v for k, v in tables.items() if k != "boxes"}
            self.restart_clock(meta)
            p = tables["particles"]
            top = float(np.max(p["pos"][:, 2] + p["radius"]))
            state["plate_center"] = plate_geometry(c, top)[0].tolist()
            state["plate_free"] = not c["plate_lowering_speed"]
            return tables, (
                f"from the prepared layer {state['prepared']}: placed the plate of {mass:g} "
                f"kg/m^2 on the highest grain (z = {top:.4f} m)"
            )
        return place

    def open_blast(self, tables):
        self.state["blast_t0"] = float(self.meta["time"]) if self.meta else 0.0
        return tables, ""

    def restart_clock(self, prepared):
        """Every plate starts from the prepared layer's time and from a step congruent to its
        step modulo every schedule that acts on the state (Δt updates, stage checks, records), so
        a plate's record is the same bits whichever plates ran before it and whether the layer
        was prepared in this run or another (``prepared_from``); steps still only grow (the
        checkpoint names)."""
        sim_doc = self.doc.get("simulation", {})
        run = self.run_cfg
        period = 1
        for k in (sim_doc.get("dt_interval", 100), sim_doc.get("check_interval", 100), self.c["check_every"],
                  self.c["record_every"], run["output_every"], run["snapshot_every"], run["checkpoint_every"]):
            period = int(np.lcm(period, int(k) if k else 1))
        now = int(self.meta["step"]) if self.meta else 0
        step = int(prepared["step"])
        step += -(-(now - step) // period) * period if now > step else 0
        if self.meta is None:
            self.meta = {"n_rebuilds": 0}
        self.meta.update(step=step, time=float(prepared["time"]))

    def pour_scene(self, tables):
        return stage_scene(self.doc, self.c, tables, stiffness=self.c["prep_stiffness_factor"])

    def prep_scene(self, tables):
        return stage_scene(self.doc, self.c, tables)

    def plate_center(self, tables):
        return tables["boxes"]["center"][0] if "boxes" in tables else np.asarray(self.state["plate_center"])

    def plate_scene(self, mass):
        def scene(tables):
            return stage_scene(self.doc, self.c, tables, mass, None, self.plate_center(tables),
                               not self.state["plate_free"])
        return scene

    def blast_scene(self, mass):
        def scene(tables):
            load = Impulse(self.c["F0"], self.c["tau"], start=self.state["blast_t0"], label="blast")
            return stage_scene(self.doc, self.c, tables, mass, load, self.plate_center(tables))
        return scene

    def settle_program(self, plate=False, wait_fall=False):
        """Settle until the unbalanced-force ratio is small (and, ``plate``, the plate lowered,
        let go and at rest), not before the stage's minimum time (``wait_fall``: nor before the
        top of the cloud could have fallen to the floor), at most its maximum time."""
        def program(sim, scene):
            c, state, run = self.c, self.state, self.run_cfg
            t0 = state["stage_t0"]
            k = state["stage"]
            if sim.time == t0:
                self.prep.append(prep_sample(sim, k))
                if self.snaps is not None:
                    write_snapshot(self.snaps, sim)

            lower = PlateLowering(c["plate_lowering_speed"], state) if plate else None

            def on_step(sim):
                if lower is not None:
                    lower(sim)
                if run["output_every"] and sim.step % run["output_every"] == 0:
                    self.prep.append(prep_sample(sim, k))
                self.snapshot(sim)

            ratio = c["plate_settle_ratio" if plate else "settle_ratio"]
            t_min = c["plate_settle_min_time" if plate else "settle_min_time"]
            if wait_fall:
                t_min = max(t_min, state.get("pour_min_time", 0.0))
            t_end = t0 + c["plate_settle_max_time" if plate else "settle_max_time"]

            def settled(sim):
                if sim.time >= t_end:
                    return True
                if sim.time - t0 < t_min or observables.unbalanced_force(sim) >= ratio:
                    return False
                return not plate or (
                    state["plate_free"] and plate_balance(sim) < ratio
                    and abs(sim.boxes.velocity[0, 2]) < c["plate_settle_velocity"]
                )

            return on_step, settled, c["check_every"], t_end

        return program

    def blast_program(self, mass):
        """The impulse on the ceiling with the plate of ``mass`` [kg/m²]: its record in
        plate_<mass>/results.h5 for ``duration`` [s]."""
        def program(sim, scene):
            c, state = self.c, self.state
            t0 = state["blast_t0"]
            load = scene.boxes.loads[0]
            area = c["box"][0] * c["box"][1]
            results = self.out / plate_dir(mass) / "results.h5"
            fresh = sim.time == t0
            if self.comm.rank == 0 and fresh:
                results.parent.mkdir(parents=True, exist_ok=True)
                results.unlink(missing_ok=True)
            self.comm.barrier()
            self.writer = series_writer(results, BLAST_RUN_SERIES, self.comm, restart_step=None if fresh else sim.step)
            self.loop.flush.append(self.writer)
            if self.comm.rank == 0:
                write_root_attrs(results, {k: self.doc[k] for k in ("simulation", "materials", "blast")
                                           if k in self.doc}, "blast")
                write_blast_parameters(results, plate_areal_mass=mass, ceiling_area=area, F0=c["F0"], tau=c["tau"])
            if fresh:
                self.log_time_step(sim, mass)
            every = c["record_every"]
            t_end = t0 + c["duration"]
            limit = 0.25 * radius_range(c)[0]
            step0 = sim.step if fresh else None

            def on_step(sim):
                check_plate_step(sim, limit)
                if sim.step % every == 0 or sim.step - 1 == step0:  # the first row: the static state at t = 0
                    self.writer.append(blast_sample(sim, t0, load, area))
                self.snapshot(sim)

            return on_step, lambda sim: sim.time - sim.dt >= t_end * (1 - 1e-12), 1, t_end

        return program

    def log_time_step(self, sim, mass):
        """Δt of pdem against the paper's eq. 10 estimate (smallest mass, largest stiffness)."""
        if sim.law is not viscous:
            return
        p = sim.particles
        m_min = sim.comm.allreduce_min(float(p.mass[: p.n_local].min()) if p.n_local else np.inf)
        kn = np.concatenate([k.contacts.params[k.contacts.real_rows(), 0] for k in sim.kinds])
        eta = float(np.max(sim.materials.column("damping_ratio")))
        k_max = sim.comm.allreduce_max(float(kn.max()) if len(kn) else 0.0)
        if k_max > 0:
            self.loop.log(
                f"plate {mass:g} kg/m^2: dt = {sim.dt:.3e} s (automatic); the paper's eq. 10 with the smallest "
                f"mass {m_min:.3e} kg, the largest k_n {k_max:.3e} N/m, eta = {eta:g}: "
                f"{viscous.critical_step(k_max, m_min, eta):.3e} s"
            )

    def snapshot(self, sim, stage_end=False):
        every = self.run_cfg["snapshot_every"]
        if self.snaps is not None and (sim.step % every == 0) != stage_end:
            write_snapshot(self.snaps, sim)

    def stage_done(self, sim, name):
        """The stage-end line and snapshot."""
        top = observables.bed_top(sim)
        z = None if sim.boxes is None else sim.boxes.center[0, 2]
        plate = ("" if z is None else
                 f", plate centre z {1e3 * z:.2f} mm (bottom {1e3 * (z - sim.boxes.half[0, 2]):.2f} mm)")
        self.loop.log(
            f"stage {name} done at t = {sim.time:.5f} s, step {sim.step}: unbalanced force ratio "
            f"{observables.unbalanced_force(sim):.3g}, layer top {1e3 * top:.2f} mm{plate}"
        )
        self.snapshot(sim, stage_end=True)

    def settle_close(self, name, plate=False):
        """A settling stage's end: a warning if it did not settle, its last preparation row."""
        def close(sim):
            c = self.c
            ratio = observables.unbalanced_force(sim)
            want = c["plate_settle_ratio" if plate else "settle_ratio"]
            if ratio >= want or (plate and plate_balance(sim) >= want):
                self.loop.log(f"warning: stage {name} reached its maximum time with unbalanced force ratio "
                              f"{ratio:.3g} >= {want}; going on")
            self.prep.append(prep_sample(sim, self.state["stage"]))
            self.stage_done(sim, name)
        return close

    def blast_close(self, name, mass):
        """A blast stage's end: its record closed."""
        def close(sim):
            self.stage_done(sim, name)
            self.writer.close()
            self.loop.flush.remove(self.writer)
            self.writer = None
            self.state["plates"].append(mass)
        return close

    def write_prepared(self, sim):
        """The prepared layer: a checkpoint of the end of stage settle in prepared_layer/, with
        what it was made from (for ``prepared_from``)."""
        tables, meta = sim.checkpoint_tables()
        meta["blast_prepared"] = {"settings": {k: self.c[k] for k in PREPARED_KEYS},
                                  "materials": self.doc["materials"], "scene_file": self.scene_text}
        folder = self.out / PREPARED_DIR
        if self.comm.rank == 0 and folder.exists():
            shutil.rmtree(folder)
        self.comm.barrier()
        written = write_checkpoint(folder, sim.step, tables, meta, self.comm, keep=None)
        self.state["prepared"] = str(written)
        self.loop.log(f"prepared layer: {written}")

    def stage_record(self, sim):
        return {"plate_z": None if sim.boxes is None else float(sim.boxes.center[0, 2])}

    def finish(self, sim, wall_s):
        c = self.c
        super().finish(sim, wall_s, summary="blast", title="blast layer",
                       about=[f"prepared layer: {self.state['prepared']}"],
                       stage_columns=[("plate_z", "plate centre z [m]", ".5f")],
                       preparation={"stages": list(self.STAGES), "body": "plate centre"},
                       notes=[f"impulse F0 = {c['F0']:g} N over tau = {c['tau']:g} s, {c['duration'] * 1e3:g} ms "
                              "recorded"],
                       plates=[(m, plate_dir(m)) for m in c["plates"]])
