"""The preparation of a ballast bed in stages: pour, cut, place rigid bodies and refill,
vibrate, settle. One implementation for every scene that prepares one (the box test,
`pdem.scenes.box_test`; the oedometer, `pdem.scenes.oedometer`; the track section,
`pdem.scenes.track`): a scene says *where* (the clouds it pours, what it cuts, which rigid
bodies it places, the `Scene` of each stage), this module says *how*, as `Stage` factories
(`pour_stage`, `refill_stage`, `vibrate_stage`, `settle_stage`) that a `PreparedRun` lists
before its own loading stages:

1. ``pour``     the scene's fill (tables → (tables, note)): seeded loose clouds (`add_cloud`)
                fill the scene's mould; settle.
2. ``refill``   the scene's cut (tables → (tables, note)): it cuts the bed (e.g.
                `remove_above` the sleeper bottom), places its rigid bodies (they appear in its
                stage scenes from this stage on) and may pour more clouds beside them; settle.
3. ``vibrate``  the scene's trim: it removes what sticks out of the final shape; then
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
(``at_rest`` of the stage factories), its rigid bodies are at rest, or until ``settle_max_time`` [s]
has passed (then a warning line is printed and the pipeline goes on).

Keys and defaults of the pipeline: `PREPARATION_DEFAULTS` (a scene's table holds them next to
its own keys; `check_preparation` validates them). Records: ``preparation.h5`` (kind
"preparation", `pdem.format.schema.PREPARATION_SERIES`: step, time, stage, spheres, kinetic
energy, unbalanced force, contacts per particle, top of the bed, ``sleeper_z`` = mean centre
height of the scene's rigid bodies [m], 0 before they are placed) and ``preparation.png``; ParaView snapshots every
run.snapshot_every steps and at the end of every stage.

The ballast bodies are spheres (`add_cloud`, radius ``radius`` [m] with ``radius_spread`` [-]),
or clumps of one shape if the scene sets ``c["grain"]`` (`add_grain_cloud`; the box test's
``[box_test.clumps]``, rigid; the track's ``[track.clumps]``, rigid or breakable): the cuts
(`pdem.driver.stages.remove_above` and `remove_where` remove whole clumps), placements and
settling are per body, not per sphere shape.
"""
from math import cos, pi, sin

import numpy as np

from .bounds import PREPARATION_BOUNDS, plausible
from .grains import grain_reach
from ...driver import observables
from ...driver.snapshots import write_snapshot
from ...driver.results import series_writer
from ...driver.stages import Stage, StagedRun, append_bodies, append_tables, clump_tables, keep_tables, \
    next_free_clump
from ...errors import InputError
from ...format.schema import PREPARATION_SERIES
from ...build.generators import loose_cloud
from ...build.validate import number

PREPARATION_STAGES = ("pour", "refill", "vibrate", "settle")  # the usual order
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
    plausible(name, c, PREPARATION_BOUNDS)
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
    """``tables`` with a loose cloud of clumps appended: ``c["grain"]`` = {"members",
    "member_radii", "mass_model", ...} (one grain about its centre; `pdem.scenes.common.grains`),
    rigid, or breakable if its ``breakable`` (bonds as ``contacts/sphere_sphere`` rows), as many as fill ``volume``
    [m³] at the packing fraction times the overfill (by the members' volume), each turned at
    random (`pdem.bodies.clump_generators.grain_cloud`), on a lattice from z0 up; member gids from
    ``first_gid``, clump ids after the tables' largest."""
    from ...bodies.clump_generators import grain_cloud
    from ...build.config import scene_from_dict

    g = c["grain"]
    pos, radius = g["members"], g["member_radii"]
    n = max(int(np.ceil(c["overfill"] * c["packing_fraction"] * volume / np.sum(4.0 / 3.0 * pi * radius**3))), 1)
    reach = grain_reach(g)
    top = lattice_top(lo_xy, hi_xy, z0, n, 2.0 * reach * 1.05)  # grain_cloud's spacing (gap 0.05)
    if top is None:
        raise InputError(f"{where[0]}.clumps: grains of diameter {2 * reach:.4g} m do not fit {where[1]}")
    grains = grain_cloud(pos, radius, (lo_xy[0], lo_xy[1], z0), (hi_xy[0], hi_xy[1], top + 1e-9), n, seed,
                         label=f"{where[0]}.clumps")
    scene = scene_from_dict({k: v for k, v in doc.items() if k in ("simulation", "materials")})
    if g.get("breakable"):  # bonded members (the oedometer's breakable grains), stress free by default
        kind = {"breakable": True, "stress_free": g["stress_free"]}
    else:
        kind = {"mass_model": g["mass_model"], "discretization": g["discretization"], "samples": g["samples"],
                "seed": seed}
    new = clump_tables(scene, grains, c["ballast_material"], first_gid, next_free_clump(tables),
                       label=f"{where[0]}.clumps", **kind)
    return append_tables(tables, new)


def remove_where(tables, outside):
    """Drop the spheres for which ``outside(pos, radius)`` (arrays of all spheres) is true, and
    whole clumps (rigid or breakable) of which some member is (with the rigid clumps' rows of
    ``clumps``/``clump_members``); returns (tables, removed spheres)."""
    p = tables["particles"]
    drop = np.asarray(outside(p["pos"], p["radius"]), bool)
    clump = p.get("clump")
    cut = np.zeros(0, np.int64)
    if clump is not None and np.any(clump[drop] >= 0):
        cut = np.unique(clump[drop & (clump >= 0)])
        drop |= np.isin(clump, cut)
    keep = ~drop
    out = dict(tables)
    out["particles"] = {k: v[keep] for k, v in p.items()}
    if "clumps" in tables and len(cut):
        kept = ~np.isin(tables["clumps"]["id"], cut)
        out["clumps"] = {k: v[kept] for k, v in tables["clumps"].items()}
        mk = ~np.isin(tables["clump_members"]["clump"], cut)
        out["clump_members"] = {k: v[mk] for k, v in tables["clump_members"].items()}
    return out, int(drop.sum())


def shaking(c, t):
    """Pseudo-acceleration [m/s²] of the shaken mould at time t since the vibration started."""
    a, w = c["vibration_acceleration"], 2.0 * pi * c["vibration_frequency"]
    return np.array([a * sin(w * t), a * cos(w * t), 0.0])


# ---------------------------------------------------------------------------- the run
def always(sim):
    """Rigid bodies not checked: a settle stage ends on the spheres' ratio alone."""
    return True


class PreparedRun(StagedRun):
    """A `StagedRun` whose first stages prepare a bed (the factories below, in the scene's
    order): ``self.c`` is the scene's table with the pipeline's keys checked. It writes
    ``preparation.h5`` and the snapshots. A scene may add `open_results`/`close_results` (its
    results files) and `bodies_note` (its rigid bodies in the stage-end line)."""

    def open_results(self):
        """Open the scene's own results writers (after preparation.h5)."""

    def close_results(self):
        """Close them."""

    def bodies_note(self, sim):
        """Text appended to the stage-end line about the rigid bodies (e.g. the sleeper bottom)."""
        return ""

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

    def stage_record(self, sim):
        """The summary row's entries of every stage: the rigid bodies' mean centre height."""
        return {"sleeper_z": None if sim.boxes is None else self.sleeper_z(sim)}

    def open_outputs(self):
        self.prep = series_writer(self.out / "preparation.h5", PREPARATION_SERIES, self.comm,
                                  restart_step=self.restart_step)
        self.loop.flush.append(self.prep)
        self.open_results()

    def close_outputs(self):
        self.prep.close()
        self.close_results()

    def prep_sample(self, sim):
        """A row of preparation.h5 in the running stage."""
        e = sim.energy()
        return {"step": sim.step, "time": sim.time, "stage": self.state["stage"],
                "n_spheres": sim.comm.allreduce_sum_int(sim.particles.n_local),
                "kinetic_energy": e["kinetic"] + e["rotational"], "unbalanced_force": observables.unbalanced_force(sim),
                "contacts_per_particle": sim.contacts_per_particle(), "bed_top": observables.bed_top(sim),
                "sleeper_z": self.sleeper_z(sim)}

    def prep_rows(self, sim):
        """The first preparation row (at step 0; later stages start at the step of the row that
        ended the last one) and ``record(sim)``: a row every run.output_every steps and the
        snapshots."""
        every = self.run_cfg["output_every"]
        if sim.step == 0:
            self.prep.append(self.prep_sample(sim))
            if self.snaps is not None:
                self.write_snapshot(sim)

        def record(sim):
            if every and sim.step % every == 0:
                self.prep.append(self.prep_sample(sim))
            self.snapshot(sim)

        return record

    def snapshot(self, sim, stage_end=False):
        """ParaView snapshot every run.snapshot_every steps and at the end of every stage."""
        every = self.run_cfg["snapshot_every"]
        if self.snaps is not None and (sim.step % every == 0) != stage_end:
            self.write_snapshot(sim)

    def write_snapshot(self, sim):
        """One ParaView snapshot (spheres, walls, facets, boxes: `pdem.driver.snapshots`)."""
        write_snapshot(self.snaps, sim)

    def stage_done(self, sim, name):
        """The stage-end line and snapshot (every stage of a prepared run)."""
        top = observables.bed_top(sim)
        self.loop.log(f"stage {name} done at t = {sim.time:.4f} s, step {sim.step}: unbalanced force ratio "
                      f"{observables.unbalanced_force(sim):.3g}, bed top {1e3 * top:.1f} mm" + self.bodies_note(sim))
        self.snapshot(sim, stage_end=True)


# ---------------------------------------------------------------------------- the stages
def settle_stage(run, scene, name="settle", open=keep_tables, at_rest=always):
    """A stage ``name`` that opens with ``open`` (tables → (tables, note)) and settles: until the
    unbalanced-force ratio is below ``settle_ratio`` and ``at_rest(sim)`` (the scene's rigid
    bodies), not before ``settle_min_time`` [s], at most ``settle_max_time`` [s]."""
    c = run.c

    def program(sim, sc):
        record = run.prep_rows(sim)
        t0 = run.state["stage_t0"]
        t_end = t0 + c["settle_max_time"]

        def settled(sim):
            return sim.time >= t_end or (sim.time - t0 >= c["settle_min_time"]
                                         and observables.unbalanced_force(sim) < c["settle_ratio"] and at_rest(sim))

        return record, settled, c["check_every"], t_end

    def close(sim):
        ratio = observables.unbalanced_force(sim)
        if ratio >= c["settle_ratio"]:
            run.loop.log(f"warning: stage {name} reached settle_max_time = {c['settle_max_time']} s with unbalanced "
                         f"force ratio {ratio:.3g} >= settle_ratio = {c['settle_ratio']}; going on")
        elif not at_rest(sim):
            run.loop.log(f"warning: stage {name} reached settle_max_time = {c['settle_max_time']} s with the rigid "
                         "bodies not at rest; going on")
        run.stage_done(sim, name)
        run.prep.append(run.prep_sample(sim))

    return Stage(name, scene, program, open=open, close=close, record=run.stage_record,
                 length=(c["settle_max_time"], False))


def pour_stage(run, scene, fill, at_rest=always):
    """``pour``: the scene's first fill (``fill``: tables → (tables, note)), settled."""
    return settle_stage(run, scene, "pour", fill, at_rest)


def refill_stage(run, scene, refill, at_rest=always):
    """``refill``: the scene cuts the bed, places its rigid bodies and pours beside them
    (``refill``: tables → (tables, note)); settled."""
    return settle_stage(run, scene, "refill", refill, at_rest)


def vibrate_stage(run, scene, trim=keep_tables, name="vibrate"):
    """``vibrate`` (or ``name``): ``trim`` (tables → (tables, note)) removes what sticks out; then
    shake for ``vibration_time`` [s] with the friction lowered (none if 0)."""
    c = run.c
    existing = c["vibration_friction_contacts"] == "all"

    def prepare(sim, sc, mid_stage):
        sim.set_friction_scale(c["vibration_friction_factor"], existing=existing)
        sim.gravity = np.asarray(sc.settings.gravity, np.float64) + shaking(c, sim.time - run.state["stage_t0"])
        sim.moving_boundaries = True  # the shaking does external work: no energy-growth check

    def program(sim, sc):
        record = run.prep_rows(sim)
        t0 = run.state["stage_t0"]
        g = np.asarray(sc.settings.gravity, np.float64)
        t_end = t0 + c["vibration_time"]

        def on_step(sim):
            sim.gravity = g + shaking(c, sim.time - t0)
            record(sim)

        return on_step, lambda sim: sim.time >= t_end, 1, t_end

    def close(sim):
        sim.set_friction_scale(1.0, existing=existing)
        run.stage_done(sim, name)
        run.prep.append(run.prep_sample(sim))

    return Stage(name, scene, program, open=trim, prepare=prepare, close=close, record=run.stage_record,
                 max_steps=0 if c["vibration_time"] == 0 else 10**15, length=(c["vibration_time"], True))
