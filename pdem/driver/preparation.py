"""The preparation pipeline of the staged scenes: pour, cut, place rigid bodies and refill,
vibrate, settle. One implementation for every scene that prepares a ballast bed (the box test,
`pdem.scenes.box_test`; the track section, `pdem.scenes.track`): a scene says *where* (the
clouds it pours, what it cuts, which rigid bodies it places), this module says *how*.

Stages (`PREPARATION_STAGES`), then the scene's own loading stages:

1. ``pour``     ``pour(tables)``: seeded loose clouds (`add_cloud`) fill the scene's mould;
                settle.
2. ``refill``   ``refill(tables)``: the scene cuts the bed (e.g. `remove_above` the sleeper
                bottom), places its rigid bodies (they appear in its ``stage_scene`` from this
                stage on) and may pour more clouds beside them; settle.
3. ``vibrate``  ``trim(tables)``: the scene removes what sticks out of the final shape; then
                shake for ``vibration_time`` [s] with every friction angle times
                ``vibration_friction_factor`` (thesis 4.2: tenfold lower; with
                ``vibration_friction_contacts`` = "new" only for the contacts made while
                vibrating, as in Yade, where a contact keeps the tan φ of its creation until it
                opens, on lowering and on restoring alike): in the frame of the
                mould, shaking is the pseudo-acceleration A·(sin 2πft, cos 2πft, 0) added to
                gravity, A = ``vibration_acceleration`` [m/s²], f = ``vibration_frequency``
                [Hz]; rigid bodies feel it too. Friction is then restored.
4. ``settle``   settle.

A scene may order these stages otherwise (the track section compacts its bed before the cut,
as the thesis did: pour, vibrate, settle, refill); what each stage does stays the same.

"Settle" runs until Yade's unbalanced-force ratio falls below ``settle_ratio`` (checked every
``check_every`` steps, not before ``settle_min_time`` [s] into the stage) and, if the scene asks
(`PreparedRun.bodies_settled`), its rigid bodies are at rest, or until ``settle_max_time`` [s]
has passed (then a warning line is printed and the pipeline goes on).

Keys and defaults of the pipeline: `PREPARATION_DEFAULTS` (a scene's table holds them next to
its own keys; `check_preparation` validates them). Records: ``preparation.h5`` (kind
"preparation", `analysis.schema.PREPARATION_SERIES`: step, time, stage, spheres, kinetic
energy, unbalanced force, contacts per particle, top of the bed, ``sleeper_z`` = mean centre
height of the scene's rigid bodies [m], 0 before they are placed) and ``preparation.png``; ParaView snapshots every
run.snapshot_every steps and at the end of every stage.

The ballast bodies are spheres (`add_cloud`, radius ``radius`` [m] with ``radius_spread`` [-]),
or rigid clumps of one shape if the scene sets ``c["grain"]`` (`add_grain_cloud`; the box
test's ``[box_test.clumps]``): the cuts (`pdem.driver.stages.remove_above` removes whole
clumps), placements and settling are per body, not per sphere shape.
"""
from math import cos, pi, sin

import numpy as np

from ..errors import InputError
from ..format.schema import PREPARATION_SERIES
from ..generators import loose_cloud
from ..validate import number
from . import observables
from .plain import write_snapshot
from .results import series_writer
from .stages import StagedRun, append_bodies, append_tables, clump_tables, next_free_clump

PREPARATION_STAGES = ("pour", "refill", "vibrate", "settle")
# keys of the pipeline in a scene's table, with defaults (SI; thesis 4.2 and table 5.1)
PREPARATION_DEFAULTS = {
    "radius": 0.01625, "radius_spread": 0.0, "seed": 1,
    "packing_fraction": 0.58,           # settled solid fraction assumed to size the clouds [-]
    "overfill": 1.2,                    # cloud volume / volume to fill [-]
    "settle_ratio": 0.01, "settle_min_time": 0.2, "settle_max_time": 3.0, "check_every": 200,
    "vibration_time": 0.5, "vibration_frequency": 10.0, "vibration_acceleration": 5.0,
    "vibration_friction_factor": 0.1,
    "vibration_friction_contacts": "all",  # "all": existing contacts too (Ip2 redone); "new": Yade's way
}
FRICTION_CONTACTS = ("all", "new")


# ---------------------------------------------------------------------------- settings
def check_preparation(name, c):
    """Validate the pipeline's keys of the table ``name`` in place (one-line InputError naming
    ``name.key``); ``c`` holds them with defaults filled in."""
    for k in ("radius", "packing_fraction", "overfill", "settle_ratio", "settle_max_time", "vibration_frequency"):
        c[k] = number(f"{name}.{k}", c[k], 0.0, lo_open=True)
    for k in ("settle_min_time", "vibration_time", "vibration_acceleration"):
        c[k] = number(f"{name}.{k}", c[k], 0.0)
    c["seed"] = number(f"{name}.seed", c["seed"], 0, integer=True)
    c["check_every"] = number(f"{name}.check_every", c["check_every"], 1, integer=True)
    c["radius_spread"] = number(f"{name}.radius_spread", c["radius_spread"], 0.0, 1.0, hi_open=True, allow="in [0, 1)")
    if c["vibration_friction_contacts"] not in FRICTION_CONTACTS:
        raise InputError(f"{name}.vibration_friction_contacts = {c['vibration_friction_contacts']!r}: must be "
                         "'all' (every contact's friction changed) or 'new' (only contacts made afterwards, as Yade)")
    c["vibration_friction_factor"] = number(f"{name}.vibration_friction_factor", c["vibration_friction_factor"], 0.0,
                                            1.0, lo_open=True, allow="in (0, 1]")
    return c


# ---------------------------------------------------------------------------- clouds
def cloud_count(c, volume):
    """Spheres to fill ``volume`` [m³] at the packing fraction, times the overfill factor."""
    r, s = c["radius"], c["radius_spread"]
    lo, hi = r * (1 - s), r * (1 + s)
    mean_r3 = r**3 if s == 0 else (hi**4 - lo**4) / (4 * (hi - lo))
    return max(int(np.ceil(c["overfill"] * c["packing_fraction"] * volume / (4.0 / 3.0 * pi * mean_r3))), 1)


def lattice_top(lo_xy, hi_xy, z0, n, spacing):
    """Top [m] of ``n`` lattice sites of ``spacing`` [m] stacked over the rectangle lo_xy..hi_xy
    from z0 up, or None if not one site fits in a layer."""
    per_layer = np.prod(np.floor((np.asarray(hi_xy) - np.asarray(lo_xy)) / spacing))
    return None if per_layer < 1 else z0 + np.ceil(n / per_layer) * spacing


def cloud(c, lo_xy, hi_xy, z0, volume, seed, where=("cloud", "in its column")):
    """A loose cloud filling ``volume`` over the rectangle lo_xy..hi_xy, from height z0 up.
    ``where`` names the table and the place in the error if the spheres do not fit."""
    n = cloud_count(c, volume)
    top = lattice_top(lo_xy, hi_xy, z0, n, 2 * c["radius"] * (1 + c["radius_spread"]) * 1.05)
    if top is None:
        raise InputError(f"{where[0]}.radius = {c['radius']!r}: spheres do not fit {where[1]}")
    return loose_cloud([lo_xy[0], lo_xy[1], z0], [hi_xy[0], hi_xy[1], top], n, c["radius"], c["radius_spread"], seed)


def add_cloud(tables, doc, c, lo_xy, hi_xy, z0, volume, seed, first_gid, where):
    """``tables`` with a loose cloud of new ballast spheres (gids from ``first_gid``, material
    ``c["ballast_material"]``) appended; rigid clumps instead if ``c["grain"]`` is given
    (`add_grain_cloud`)."""
    if c.get("grain") is not None:
        return add_grain_cloud(tables, doc, c, lo_xy, hi_xy, z0, volume, seed, first_gid, where)
    pos, radius = cloud(c, lo_xy, hi_xy, z0, volume, seed, where)
    return append_bodies(tables, pos, radius, doc["materials"][c["ballast_material"]]["density"],
                         list(doc["materials"]).index(c["ballast_material"]), first_gid)


def add_grain_cloud(tables, doc, c, lo_xy, hi_xy, z0, volume, seed, first_gid, where):
    """``tables`` with a loose cloud of rigid clumps appended: ``c["grain"]`` = {"members",
    "member_radii", "mass_model", ...} (one grain about its centre), as many as fill ``volume``
    [m³] at the packing fraction times the overfill (by the members' volume), each turned at
    random (`pdem.clump_generators.grain_cloud`), on a lattice from z0 up; member gids from
    ``first_gid``, clump ids after the tables' largest."""
    from ..clump_generators import grain_cloud
    from ..config import scene_from_dict

    g = c["grain"]
    pos, radius = g["members"], g["member_radii"]
    n = max(int(np.ceil(c["overfill"] * c["packing_fraction"] * volume / np.sum(4.0 / 3.0 * pi * radius**3))), 1)
    reach = float(np.max(np.sqrt(np.einsum("ij,ij->i", pos, pos)) + radius))
    top = lattice_top(lo_xy, hi_xy, z0, n, 2.0 * reach * 1.05)  # grain_cloud's spacing (gap 0.05)
    if top is None:
        raise InputError(f"{where[0]}.clumps: grains of diameter {2 * reach:.4g} m do not fit {where[1]}")
    grains = grain_cloud(pos, radius, (lo_xy[0], lo_xy[1], z0), (hi_xy[0], hi_xy[1], top + 1e-9), n, seed,
                         label=f"{where[0]}.clumps")
    scene = scene_from_dict({k: v for k, v in doc.items() if k in ("simulation", "materials")})
    new = clump_tables(scene, grains, c["ballast_material"], first_gid, next_free_clump(tables),
                       mass_model=g["mass_model"], discretization=g["discretization"], samples=g["samples"],
                       seed=seed, label=f"{where[0]}.clumps")
    return append_tables(tables, new)


def remove_where(tables, outside):
    """Drop the spheres for which ``outside(pos, radius)`` (arrays of all spheres) is true;
    returns (tables, removed)."""
    p = tables["particles"]
    keep = ~np.asarray(outside(p["pos"], p["radius"]), bool)
    out = dict(tables)
    out["particles"] = {k: v[keep] for k, v in p.items()}
    return out, int((~keep).sum())


def shaking(c, t):
    """Pseudo-acceleration [m/s²] of the shaken mould at time t since the vibration started."""
    a, w = c["vibration_acceleration"], 2.0 * pi * c["vibration_frequency"]
    return np.array([a * sin(w * t), a * cos(w * t), 0.0])


# ---------------------------------------------------------------------------- the run
class PreparedRun(StagedRun):
    """A `StagedRun` whose first stages are `PREPARATION_STAGES` (in the scene's order);
    ``STAGES`` = those + the scene's loading stages. ``self.c`` is the scene's table with the pipeline's keys checked.

    The scene implements `pour`, `refill`, `trim` (table operations of the preparation),
    `stage_scene`, and for its loading stages `open_load_stage`, `load_program`; optionally
    `open_results`/`close_results` (its results files), `after_stage` (records at a stage end),
    `bodies_note` (its rigid bodies in the stage-end line) and `finish`."""

    # ------------------------------------------------------------------ scene hooks
    def pour(self, tables):
        """(tables, note): the first fill."""
        raise NotImplementedError

    def refill(self, tables):
        """(tables, note): cut, place the rigid bodies, pour beside them."""
        raise NotImplementedError

    def trim(self, tables):
        """(tables, note): remove what sticks out before vibrating."""
        return tables, ""

    def open_load_stage(self, stage, tables):
        return tables, ""

    def load_program(self, stage, sim, scene):
        """`StagedRun.program` of a loading stage."""
        raise NotImplementedError

    def open_results(self):
        """Open the scene's own results writers (after preparation.h5)."""

    def close_results(self):
        """Close them."""

    def after_stage(self, stage, sim):
        """Records of the scene at the end of ``stage`` (after the preparation row)."""

    def bodies_note(self, sim):
        """Text appended to the stage-end line about the rigid bodies (e.g. the sleeper bottom)."""
        return ""

    def after_snapshot(self, sim):
        """Written with every snapshot of the spheres (e.g. the rigid bodies)."""

    def bodies_settled(self, sim):
        """Whether the scene's rigid bodies are at rest too (a settle stage ends only then);
        default: not checked (the box test ends its stages on the spheres' ratio alone)."""
        return True

    def sleeper_z(self, sim):
        """Mean centre height of the rigid bodies [m] (0 before they are placed: the results hold no
        NaN, `pdem.driver.results.finite_row`)."""
        bx = sim.boxes
        if bx is None:
            return 0.0
        z = 0.0
        for k in range(len(bx)):
            z += float(bx.center[k, 2])
        return z / len(bx)

    # ------------------------------------------------------------------ StagedRun hooks
    def open_outputs(self):
        self.prep = series_writer(self.out / "preparation.h5", PREPARATION_SERIES, self.comm,
                                  restart_step=self.restart_step)
        self.loop.flush.append(self.prep)
        self.open_results()

    def close_outputs(self):
        self.prep.close()
        self.close_results()

    def open_stage(self, stage, tables):
        if stage == "pour":
            return self.pour(tables)
        if stage == "refill":
            return self.refill(tables)
        if stage == "vibrate":
            return self.trim(tables)
        if stage == "settle":
            return tables, ""
        return self.open_load_stage(stage, tables)

    def prepare(self, stage, sim, scene, mid_stage):
        if stage == "vibrate":
            c = self.c
            sim.set_friction_scale(c["vibration_friction_factor"], existing=c["vibration_friction_contacts"] == "all")
            g = np.asarray(scene.settings["gravity"], np.float64)
            sim.gravity = g + shaking(c, sim.time - self.state["stage_t0"])
            sim.moving_boundaries = True  # the shaking does external work: no energy-growth check

    def max_steps(self, stage):
        return 0 if stage == "vibrate" and self.c["vibration_time"] == 0 else 10**15

    def prep_sample(self, sim, stage):
        e = sim.energy()
        return {"step": sim.step, "time": sim.time, "stage": self.STAGES.index(stage),
                "n_spheres": sim.comm.allreduce_sum_int(sim.particles.n_local),
                "kinetic_energy": e["kinetic"] + e["rotational"], "unbalanced_force": observables.unbalanced_force(sim),
                "contacts_per_particle": sim.contacts_per_particle(), "bed_top": observables.bed_top(sim),
                "sleeper_z": self.sleeper_z(sim)}

    def program(self, stage, sim, scene):
        if stage not in PREPARATION_STAGES:
            return self.load_program(stage, sim, scene)
        c, state, run = self.c, self.state, self.run_cfg
        t0 = state["stage_t0"]
        if sim.step == 0:  # later stages start at the step of the row that ended the last one
            self.prep.append(self.prep_sample(sim, stage))
            if self.snaps is not None:
                self.write_snapshot(sim)
        g = np.asarray(scene.settings["gravity"], np.float64)

        def on_step(sim):
            if stage == "vibrate":
                sim.gravity = g + shaking(c, sim.time - t0)
            if run["output_every"] and sim.step % run["output_every"] == 0:
                self.prep.append(self.prep_sample(sim, stage))
            self.snapshot(sim)

        if stage == "vibrate":
            t_end = t0 + c["vibration_time"]
            return on_step, lambda sim: sim.time >= t_end, 1, t_end
        t_end = t0 + c["settle_max_time"]

        def settled(sim):
            return sim.time >= t_end or (sim.time - t0 >= c["settle_min_time"]
                                         and observables.unbalanced_force(sim) < c["settle_ratio"]
                                         and self.bodies_settled(sim))

        return on_step, settled, c["check_every"], t_end

    def snapshot(self, sim, stage_end=False):
        """ParaView snapshot every run.snapshot_every steps and at the end of every stage."""
        every = self.run_cfg["snapshot_every"]
        if self.snaps is not None and (sim.step % every == 0) != stage_end:
            self.write_snapshot(sim)

    def write_snapshot(self, sim):
        """One ParaView snapshot of the spheres (and what `after_snapshot` adds)."""
        write_snapshot(self.snaps, sim)
        self.after_snapshot(sim)

    def close_stage(self, stage, sim):
        c, log = self.c, self.loop.log
        ratio = observables.unbalanced_force(sim)
        if stage in ("pour", "refill", "settle") and ratio >= c["settle_ratio"]:
            log(f"warning: stage {stage} reached settle_max_time = {c['settle_max_time']} s with unbalanced force "
                f"ratio {ratio:.3g} >= settle_ratio = {c['settle_ratio']}; going on")
        elif stage in ("pour", "refill", "settle") and not self.bodies_settled(sim):
            log(f"warning: stage {stage} reached settle_max_time = {c['settle_max_time']} s with the rigid bodies "
                "not at rest; going on")
        if stage == "vibrate":
            sim.set_friction_scale(1.0, existing=c["vibration_friction_contacts"] == "all")
        top = observables.bed_top(sim)
        log(f"stage {stage} done at t = {sim.time:.4f} s, step {sim.step}: unbalanced force ratio {ratio:.3g}, "
            f"bed top {top:.4f} m" + self.bodies_note(sim))
        self.snapshot(sim, stage_end=True)
        if stage in PREPARATION_STAGES:
            self.prep.append(self.prep_sample(sim, stage))
        self.after_stage(stage, sim)

    def stage_record(self, stage, sim):
        return {"sleeper_z": None if sim.boxes is None else self.sleeper_z(sim)}
