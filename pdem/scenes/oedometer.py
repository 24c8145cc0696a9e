"""The oedometer (SPEC.md 2.2; thesis ch. 4; Nottingham test, Lim 2004): a steel cylinder filled
with ballast (spheres, rigid clumps or breakable clumps), compressed by a platen, on any number
of ranks.

Geometry (axis along z through x = y = 0, units SI): a base plane z = 0, a wall of ``facets``
flat faces (each two triangles) of a cylinder of ``diameter`` [m] up to ``height`` [m], and while
filling a collar of as many faces above it up to the top of the poured cloud (thesis 4.2,
footnote 1). The platen is a rigid box (`pdem.bodies.boxes`, z translation only) of ``platen_thickness``
[m] and ``platen_mass`` [kg] covering the cylinder (a square of side ``diameter``: boxes touch
only spheres, so its corners outside the cylinder touch nothing).

A scene file with an ``[oedometer]`` table (keys and defaults in `DEFAULTS`; the preparation
pipeline's keys in `pdem.scenes.common.preparation.PREPARATION_DEFAULTS`) runs the stages

1. ``pour``     fill: a seeded cloud of grains on a cubic lattice inside the cylinder and collar,
                bottom up until its solid volume is ``overfill`` × ``packing_fraction`` × the
                cylinder's volume; settle under gravity. Breakable grains' bonds are held at
                ``bond_boost`` × their strengths for the first ``bond_boost_time`` [s] of the pour,
                then returned (thesis 4.5: bonds made on overlaps, as Yade makes them with
                ``stress_free = false``, push the members apart and would break; the thesis
                raised the cohesion tenfold for the first steps). A warning line names bonds
                whose push k_n δ exceeds their strength a_N and the boost (`bond_push`).
2. ``refill``   cut: remove every grain of which a sphere reaches above ``height`` (whole
                clumps), remove the collar, place the platen on the cut; settle.
3. ``vibrate``  optional (``vibration_time`` > 0): shake with friction lowered (the pipeline's
                vibration).
4. ``settle``   settle.
5. ``load``     the platen carries F(t) = f_min + (f_max − f_min)(1 − cos 2π t/T)/2 for
                0 ≤ t ≤ T = ``load_time`` [s] (thesis: "a force varying as a sine from 250 N to
                1500 kN and back to 250 N"; `pdem.boundaries.loads.Haversine`, one cycle), pushing down.

Grains: spheres (radius ``radius`` [m], uniform in r (1 ± ``radius_spread``); thesis: Ø32.5 mm,
(0.6–1.4) r) unless the table ``[oedometer.clumps]`` gives a grain (keys of ``[[clumps]]``,
`pdem.build.config`: shape, radii, member_radius, breakable, stress_free, mass_model, discretization,
samples); each copy turned by its own random rotation (seeded). Breakable clumps need law
"cohesive". ``packing_fraction`` is the settled solid fraction of member spheres assumed to size
the cloud.

Output in the run directory: ``preparation.h5`` and ``preparation.png`` (the pipeline),
``results.h5`` (kind "oedometer", `pdem.format.schema.OEDOMETER_SERIES`: ``platen_load`` [N, the
program, down], ``platen_force`` [N, force of the ballast on the platen, up],
``platen_displacement`` [m, down, zero when loading starts], ``max_overlap_ratio`` [-, the largest
overlap over the smaller radius of its pair: how far the load pushes the contacts]; the overlap δ
over the smaller radius r of the contacts in compression by group (`observables.overlap_statistics`),
``<group>_overlap_max`` and ``<group>_overlap_mean`` [-, the largest and the mean δ/r] of ``pair``
(spheres of different grains or fragments, no bond), ``bond`` (intact bonds: members of one grain)
and ``boundary`` (a sphere on the base, the cylinder or the platen), and ``intact_bonds`` [-, bonds
not broken: the breakage between samples]; with breakable clumps
``/fragments`` records "initial" (after the cut and settling), "vibrated" (after vibrating, if
any), "peak" (at F_max) and "unloaded" (at the end), and every ``run.fragments_every`` steps),
the analysis of `analysis.oedometer` in ``analysis/`` (force–displacement PNG, loading and
unloading stiffness, grading curves and breakage indices) and ``summary.txt`` with the timing.
"""
from dataclasses import replace
from math import cos, pi

import numpy as np

from ..bodies.bonds import touching_pairs
from ..build.config import check_keys, run_settings, scene_from_dict
from ..driver import observables
from ..driver.fragments import FragmentRecorder
from ..driver.results import series_writer, write_root_attrs
from ..driver.stages import Stage, append_bodies, append_tables, check_no_steps, clump_tables, empty_tables, \
    next_free_clump, remove_above
from ..errors import InputError
from ..format.schema import OEDOMETER_SERIES
from ..build.generators import sphere_radii
from ..boundaries.loads import Haversine
from ..build.validate import number
from .common.bounds import plausible
from .common.grains import grain_reach, grain_spec as common_grain_spec
from .common.preparation import PREPARATION_DEFAULTS, PREPARATION_STAGES, PreparedRun, check_preparation, \
    pour_stage, refill_stage, settle_stage, vibrate_stage

STAGES = PREPARATION_STAGES + ("load",)
# [oedometer] keys and defaults (SPEC.md 2.2, thesis tables 4.1, 4.8, 4.15; stiffness in [materials])
DEFAULTS = {
    "diameter": 0.30, "height": 0.15, "facets": 24,
    "ballast_material": "ballast", "wall_material": "steel", "platen_material": "steel",
    **PREPARATION_DEFAULTS,
    "radius_spread": 0.4,               # thesis: radii uniform in (0.6–1.4) r
    "vibration_time": 0.0,              # optional vibration (thesis: vibrated and not vibrated samples)
    "platen_thickness": 0.02,           # [m]
    "platen_mass": 11.1,                # [kg] (a steel disc Ø300 × 20 mm)
    "f_min": 250.0, "f_max": 1.5e6,     # [N]
    "load_time": 0.2,                   # duration of the 250 N → F_max → 250 N program [s]
    "lattice_gap": 0.05,                # gap between neighbouring grains of the poured lattice [-]
    "bond_boost": 1.0,                  # bond strengths × this from the start of the pour ... [-]
    "bond_boost_time": 0.0,             # ... for this long [s], then returned (thesis 4.5: tenfold)
}
TOP = {"simulation", "run", "materials", "oedometer"}


# ---------------------------------------------------------------------------- settings
def settings(doc):
    """The [oedometer] table with defaults, checked (one-line InputError naming the key)."""
    check_keys("scene file", doc, TOP)
    given = doc["oedometer"]
    check_keys("oedometer", given, set(DEFAULTS) | {"clumps"})
    c = {**DEFAULTS, **given}
    for k in ("ballast_material", "wall_material", "platen_material"):
        if not isinstance(c[k], str) or c[k] not in doc.get("materials", {}):
            raise InputError(f"oedometer.{k} = {c[k]!r}: no [materials.{c[k]}] table in the scene file")
    check_preparation("oedometer", c)
    for k in ("diameter", "height", "platen_thickness", "platen_mass", "load_time"):
        c[k] = number(f"oedometer.{k}", c[k], 0.0, lo_open=True, allow="a number > 0")
    c["facets"] = number("oedometer.facets", c["facets"], 6, integer=True, allow="an integer >= 6")
    c["lattice_gap"] = number("oedometer.lattice_gap", c["lattice_gap"], 0.0, allow="a number >= 0 [-]")
    for k in ("f_min", "f_max"):
        c[k] = number(f"oedometer.{k}", c[k], 0.0, allow="a force >= 0 [N]")
    if c["f_max"] < c["f_min"]:
        raise InputError(f"oedometer.f_max = {c['f_max']!r}: must be >= f_min = {c['f_min']!r} [N]")
    if "steps" in doc.get("run", {}):
        raise InputError("run.steps: not used by an oedometer (its stages end on settle_ratio, vibration_time and "
                         "load_time in [oedometer]); remove it")
    c["grain"] = grain_spec(doc, c)
    check_bond_boost(c)
    plausible("oedometer", c)
    return c


def check_bond_boost(c):
    """bond_boost > 0 [-] (not 1 only for breakable grains) held for bond_boost_time > 0 [s]."""
    c["bond_boost"] = number("oedometer.bond_boost", c["bond_boost"], 0.0, lo_open=True, allow="a factor > 0 [-]")
    c["bond_boost_time"] = number("oedometer.bond_boost_time", c["bond_boost_time"], 0.0,
                                  allow="a time >= 0 [s]")
    if c["bond_boost"] == 1.0:
        return
    if c["grain"] is None or not c["grain"]["breakable"]:
        raise InputError(f"oedometer.bond_boost = {c['bond_boost']!r}: scales bonds, which only breakable grains "
                         "have ([oedometer.clumps] breakable = true); remove it or set it to 1")
    if c["bond_boost_time"] <= 0.0:
        raise InputError(f"oedometer.bond_boost_time = {c['bond_boost_time']!r}: must be > 0 [s] with "
                         f"bond_boost = {c['bond_boost']!r} (how long the pour holds the bonds scaled)")


def grain_spec(doc, c):
    """None for spheres, else the checked [oedometer.clumps] table with (members, radii, breakable)."""
    if "clumps" not in c:
        return None
    return common_grain_spec(doc, c["clumps"], "oedometer.clumps")


def bond_push(doc, c):
    """Largest k_n δ / a_N [-] over a grain's bonds made on their overlap δ as Yade makes them
    (``stress_free = false``): released, such a bond swings to a pull of about that much and
    breaks above 1 (thesis 4.5); 0 for stress-free bonds or unbreakable grains."""
    g = c["grain"]
    if g is None or not g["breakable"] or g["stress_free"]:
        return 0.0
    scene = base_scene(doc)
    pos, r = g["members"], g["member_radii"]
    i, j = touching_pairs("oedometer.clumps", pos, r)
    pen = r[i] + r[j] - np.linalg.norm(pos[j] - pos[i], axis=1)
    mat = np.full(len(i), scene.material_names.index(c["ballast_material"]))
    params, history = scene.law.bond_rows(scene.materials.props(), mat, mat, r[i], r[j], pen, False)
    kn, a_n = params[:, scene.law.PARAM_NAMES["kn"]], history[:, scene.law.HISTORY_NAMES["normal_adhesion"]]
    return float(np.max(kn * pen / a_n))


def intact_members(c):
    """Spheres of one intact grain (1 for spheres)."""
    return 1 if c["grain"] is None else len(c["grain"]["member_radii"])


# ---------------------------------------------------------------------------- geometry
def ring_facets(radius, n, z0, z1):
    """2n triangles [2n, 3, 3] of the n flat faces of a cylinder (polygon of vertices at
    ``radius`` [m], axis z) between z0 and z1 [m]."""
    a = 2.0 * pi * np.arange(n + 1) / n
    x, y = radius * np.cos(a), radius * np.sin(a)
    tri = []
    for k in range(n):
        p00, p10 = (x[k], y[k], z0), (x[k + 1], y[k + 1], z0)
        p01, p11 = (x[k], y[k], z1), (x[k + 1], y[k + 1], z1)
        tri += [(p00, p10, p11), (p00, p11, p01)]
    return np.array(tri, np.float64)


def inner_radius(c):
    """Distance [m] from the axis to the flat faces of the wall."""
    return 0.5 * c["diameter"] * cos(pi / c["facets"])


def lattice_sites(c, reach, z0, count_volume, body_volume, clear=None):
    """Centres [n, 3] of a cubic lattice (spacing 2·reach·(1 + gap)) inside the cylinder (each
    ``clear`` [m], default ``reach``, from the wall) from z0 up, bottom up and in a fixed order
    within a layer, as many as give a solid volume of ``count_volume`` [m³] at ``body_volume`` each."""
    a = 2.0 * reach * (1.0 + c["lattice_gap"])
    rin = inner_radius(c) - (reach if clear is None else clear)
    if rin < 0:
        raise InputError(f"oedometer.diameter = {c['diameter']!r}: grains of diameter {2 * reach:.4g} m do not fit")
    k = np.arange(-int(rin // a) - 1, int(rin // a) + 2)
    gx, gy = np.meshgrid(k * a, k * a, indexing="ij")
    inside = gx**2 + gy**2 <= rin**2
    xy = np.stack([gx[inside], gy[inside]], axis=1)
    n = max(int(np.ceil(count_volume / body_volume)), 1)
    layers = int(np.ceil(n / len(xy)))
    z = z0 + reach * (1.0 + c["lattice_gap"]) + a * np.arange(layers)
    sites = np.concatenate([np.column_stack([xy, np.full(len(xy), zz)]) for zz in z])
    return sites[:n]


def fill_volume(c):
    """Solid volume [m³] the poured cloud holds: overfill × packing fraction × cylinder."""
    return c["overfill"] * c["packing_fraction"] * pi * inner_radius(c) ** 2 * c["height"]


def sphere_fill(c, seed):
    """(pos, radius) of the poured spheres: lattice sites, each sphere moved off its site
    horizontally at random within the disc inscribed in its cell (spheres exactly above each
    other would fall into frictionless columns)."""
    r, s = c["radius"], c["radius_spread"]
    mean_r3 = r**3 if s == 0 else ((r * (1 + s)) ** 4 - (r * (1 - s)) ** 4) / (4 * 2 * r * s)
    half = r * (1 + s) * (1.0 + c["lattice_gap"])  # half the lattice spacing
    sites = lattice_sites(c, r * (1 + s), 0.0, fill_volume(c), 4.0 / 3.0 * pi * mean_r3, clear=half)
    rng = np.random.default_rng(seed)
    sites = sites[np.lexsort((rng.random(len(sites)), sites[:, 2]))]
    radius = sphere_radii(len(sites), r, s, seed + 1)
    room = half - radius
    phi, rho = 2.0 * pi * rng.random(len(sites)), np.sqrt(rng.random(len(sites))) * room
    sites[:, 0] += rho * np.cos(phi)
    sites[:, 1] += rho * np.sin(phi)
    return sites, radius


def grain_fill(c, seed):
    """[(member pos, member radius)] of the poured grains, each turned at random."""
    from ..bodies.clump_generators import random_rotations

    g = c["grain"]
    pos, radius = g["members"], g["member_radii"]
    sites = lattice_sites(c, grain_reach(g), 0.0, fill_volume(c), float(np.sum(4.0 / 3.0 * pi * radius**3)))
    rot = random_rotations(len(sites), np.random.default_rng(seed))
    return [(s + pos @ m.T, radius.copy()) for s, m in zip(sites, rot)]


def clump_options(c):
    """`Scene.add_clumps` options of the grains."""
    g = c["grain"]
    kw = {"breakable": g["breakable"], "mass_model": g.get("mass_model", "members"),
          "discretization": g.get("discretization", 0), "samples": g.get("samples", 0), "seed": c["seed"],
          "label": "oedometer.clumps"}
    if g["breakable"]:
        kw["stress_free"] = g["stress_free"]
    return kw


def platen_center(c, bottom):
    return np.array([0.0, 0.0, bottom + 0.5 * c["platen_thickness"]])


# ---------------------------------------------------------------------------- stage scenes
def base_scene(doc):
    base = {k: v for k, v in doc.items() if k in ("simulation", "materials")}
    base["simulation"] = {**base.get("simulation", {}), "allow_initial_overlap": True}
    return scene_from_dict(base)


def stage_scene(doc, c, tables, collar_top=None, platen=True, load_start=None, platen_z=None):
    """The `Scene` of a stage holding the bodies of ``tables``: the base, the wall (and the
    collar up to ``collar_top`` [m] if given: while pouring), the platen if ``platen`` (from
    ``refill`` on; loaded from ``load_start`` [s] if given: stage ``load``)."""
    scene = base_scene(doc)
    wm = c["wall_material"]
    scene.add_wall("z", 0.0, wm, sense=1, name="base")
    for k, tri in enumerate(ring_facets(0.5 * c["diameter"], c["facets"], 0.0, c["height"])):
        scene.add_facet(tri, wm, name=f"wall_{k}")
    if collar_top is not None and collar_top > c["height"]:
        for k, tri in enumerate(ring_facets(0.5 * c["diameter"], c["facets"], c["height"], collar_top)):
            scene.add_facet(tri, wm, name=f"collar_{k}")
    if platen:
        center = platen_center(c, c["height"]) if platen_z is None else np.array([0.0, 0.0, platen_z])
        load = (Haversine(c["f_min"], c["f_max"], 1.0 / c["load_time"], 1, start=load_start, label="oedometer")
                if load_start is not None else None)
        r = 0.5 * c["diameter"]
        scene.add_box(center, (r, r, 0.5 * c["platen_thickness"]), c["platen_material"], c["platen_mass"],
                      blocked="xyXYZ", load=load, damping=scene.settings.damping, name="platen")
    scene.add_sphere_columns(tables["particles"])
    if "clumps" in tables:
        scene.add_clump_tables(tables["clumps"], tables["clump_members"])
    return scene


# ---------------------------------------------------------------------------- records
def load_sample(sim, reference, load=None):
    """A row of the load record; ``reference`` is the platen centre height where loading started."""
    e = sim.energy()
    bx = sim.boxes
    return {"step": sim.step, "time": sim.time, "dt": sim.dt,
            "platen_load": float(-bx.load_force[0, 2]) if load is None else float(load),
            "platen_force": float(bx.contact_force[0, 2]),
            "platen_displacement": float(reference - bx.center[0, 2]),
            "kinetic_energy": e["kinetic"] + e["rotational"], "contacts_per_particle": sim.contacts_per_particle(),
            "max_overlap_ratio": observables.max_overlap_ratio(sim), **observables.overlap_statistics(sim)}


# ---------------------------------------------------------------------------- the run
def check(doc):
    """Check a parsed oedometer scene file without running it (one-line InputError)."""
    c = settings(doc)
    run_settings(doc)
    if c["grain"] is None:  # the grains fit the cylinder
        sphere_fill(c, c["seed"])
    else:  # and make clumps (mass model, bonds)
        clump_tables(base_scene(doc), grain_fill(c, c["seed"])[:1], c["ballast_material"], 0, 0, **clump_options(c))
    stage_scene(doc, c, empty_tables(), load_start=0.0)


def run(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run (or resume) the oedometer of a parsed scene file; returns the exit status."""
    check_no_steps(steps)
    return OedometerRun(path, doc, out_dir, comm, fresh).run()


class OedometerRun(PreparedRun):
    """One oedometer test on this process's ranks: the preparation stages in the cylinder, the
    load stage, its records (results.h5, fragments) and the finishing analysis."""

    NAME = "oedometer"

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.c = settings(doc)
        super().__init__(path, doc, out_dir, comm, fresh)

    def stage_list(self):
        vibrated = "vibrated" if self.c["vibration_time"] > 0 else None
        pour = pour_stage(self, self.pour_scene, self.pour, at_rest=self.poured)
        return [replace(pour, program=self.boosted(pour.program)).then(prepare=self.boost_bonds,
                                                                         close=self.end_bond_boost),
                refill_stage(self, self.stage_scene, self.refill).then(close=self.fragments_at("initial")),
                vibrate_stage(self, self.stage_scene).then(close=self.fragments_at(vibrated)),
                settle_stage(self, self.stage_scene).then(close=self.first_load_row),
                Stage("load", self.load_scene, self.load_program, open=self.open_load, close=self.close_load,
                      record=self.stage_record)]

    def initial_state(self):
        return {"load_start": None, "reference": None, "peak_recorded": False, "collar_top": None,
                "bond_boost_on": False}

    @property
    def breakable(self):
        g = self.c["grain"]
        return g is not None and g["breakable"]

    def open_results(self):
        restart, comm = self.restart_step, self.comm
        self.results = self.out / "results.h5"
        self.series = series_writer(self.results, OEDOMETER_SERIES, comm, restart_step=restart)
        self.loop.flush.append(self.series)
        if comm.rank == 0:
            doc = self.doc
            write_root_attrs(self.results, {k: doc[k] for k in ("simulation", "materials", "oedometer") if k in doc},
                             "oedometer")
        self.fragments = (FragmentRecorder(self.results, comm, every=self.run_cfg["fragments_every"])
                          if self.breakable else None)

    def close_results(self):
        self.series.close()

    # ------------------------------------------------------------------ preparation
    def pour(self, tables):
        tables, note = self.pour_grains()
        push = bond_push(self.doc, self.c)
        if push > max(1.0, self.c["bond_boost"]):
            self.loop.log(f"warning: the grains' bonds are made on overlaps that push with up to {push:.3g} a_N "
                          "(oedometer.clumps.stress_free = false); released they swing to about that pull and break "
                          "unless oedometer.bond_boost holds them (thesis 4.5: tenfold)")
        p = tables["particles"]
        self.state["collar_top"] = 1.05 * float(np.max(p["pos"][:, 2] + p["radius"]))
        return tables, note + f", collar up to {self.state['collar_top']:.4f} m"

    def pour_grains(self):
        c, doc = self.c, self.doc
        mat = c["ballast_material"]
        if c["grain"] is None:
            pos, radius = sphere_fill(c, c["seed"])
            tables = append_bodies(empty_tables(), pos, radius, doc["materials"][mat]["density"],
                                   list(doc["materials"]).index(mat), 0)
            return tables, f"poured {len(radius)} spheres"
        g = c["grain"]
        grains = grain_fill(c, c["seed"])
        new = clump_tables(base_scene(doc), grains, mat, 0, next_free_clump(empty_tables()), **clump_options(c))
        tables = append_tables(empty_tables(), new)
        kind = "breakable" if g["breakable"] else "rigid"
        return tables, f"poured {len(grains)} {kind} clumps of {len(g['member_radii'])} spheres"

    def boost_bonds(self, sim, scene, mid_stage):
        """At the start of the pour: bond strengths times ``bond_boost`` (thesis 4.5)."""
        c = self.c
        if not mid_stage and c["bond_boost"] != 1.0:
            sim.scale_bond_strength(c["bond_boost"])
            self.state["bond_boost_on"] = True
            self.loop.log(f"bond strengths x {c['bond_boost']:g} until t = {c['bond_boost_time']:g} s "
                          "(oedometer.bond_boost)")

    def end_bond_boost(self, sim):
        """Return the bonds to their strength (thesis 4.5: "which we then return to its value")."""
        if self.state["bond_boost_on"]:
            sim.scale_bond_strength(1.0 / self.c["bond_boost"])
            self.state["bond_boost_on"] = False
            self.loop.log(f"bond strengths returned at t = {sim.time:.4g} s, step {sim.step}")

    def boosted(self, program):
        """The pour's ``program`` that returns the bonds to their strength ``bond_boost_time``
        [s] into the stage."""
        def boosted_program(sim, scene):
            on_step, until, every, t_end = program(sim, scene)
            if not self.state["bond_boost_on"]:
                return on_step, until, every, t_end
            t_back = self.state["stage_t0"] + self.c["bond_boost_time"]

            def boosted_step(sim):
                if self.state["bond_boost_on"] and sim.time >= t_back:
                    self.end_bond_boost(sim)
                on_step(sim)

            return boosted_step, until, every, t_end

        return boosted_program

    def refill(self, tables):
        h = self.c["height"]
        tables, removed = remove_above(tables, h)
        tables.pop("facets", None)  # the collar goes: the wall's facets (the first ones) are fixed, built anew
        return tables, f"removed {removed} spheres above {h} m (whole grains), removed the collar, placed the platen"

    def pour_scene(self, tables):
        return stage_scene(self.doc, self.c, tables, collar_top=self.state["collar_top"], platen=False)

    def stage_scene(self, tables):
        z = float(tables["boxes"]["center"][0][2]) if "boxes" in tables else None
        return stage_scene(self.doc, self.c, tables, platen_z=z)

    def load_scene(self, tables):
        z = float(tables["boxes"]["center"][0][2]) if "boxes" in tables else None
        return stage_scene(self.doc, self.c, tables, load_start=self.state["load_start"], platen_z=z)

    def poured(self, sim):
        """The pour ends only after 1.5 × the time a grain needs to fall from the top of the
        collar, sqrt(2 h/((1 − λ_D) g)) (Cundall damping slows a free fall): before, a few hard
        impacts make the unbalanced-force ratio small while most grains are still in the air."""
        g = float(np.linalg.norm(sim.gravity)) * (1.0 - float(sim.damping))
        return g <= 0.0 or sim.time - self.state["stage_t0"] >= 1.5 * (2.0 * self.state["collar_top"] / g) ** 0.5

    def bodies_note(self, sim):
        if sim.boxes is None:
            return ""
        z = sim.boxes.center[0, 2]
        return f", platen centre z {1e3 * z:.1f} mm (bottom {1e3 * (z - sim.boxes.half[0, 2]):.1f} mm)"

    def fragments_at(self, label):
        """A stage's closing action: the fragment record ``label`` (breakable grains; none if
        ``label`` is None)."""
        def record(sim):
            if self.fragments is not None and label:
                self.fragments.record(sim, label)
        return record

    def first_load_row(self, sim):
        """The first row of the load record: the platen where loading starts."""
        self.state["reference"] = float(sim.boxes.center[0, 2])
        self.series.append(load_sample(sim, self.state["reference"], load=self.c["f_min"]))

    # ------------------------------------------------------------------ loading
    def open_load(self, tables):
        self.state["load_start"] = float(self.meta["time"]) if self.meta else 0.0
        return tables, ""

    def close_load(self, sim):
        self.stage_done(sim, "load")
        self.fragments_at("unloaded")(sim)
        every = self.run_cfg["output_every"]
        if not (every and sim.step % every == 0):  # the last row: the end of unloading
            self.series.append(load_sample(sim, self.state["reference"]))

    def load_program(self, sim, scene):
        c, state, run = self.c, self.state, self.run_cfg
        t_peak = state["load_start"] + 0.5 * c["load_time"]
        t_end = state["load_start"] + c["load_time"]
        frag = self.fragments

        def on_step(sim):
            if frag is not None:
                frag.on_step(sim)
                if not state["peak_recorded"] and sim.time >= t_peak:
                    frag.record(sim, "peak")
                    state["peak_recorded"] = True
            if run["output_every"] and sim.step % run["output_every"] == 0:
                self.series.append(load_sample(sim, state["reference"]))
            self.snapshot(sim)

        return on_step, lambda sim: sim.time >= t_end, 1, t_end

    def finish(self, sim, wall_s):
        super().finish(sim, wall_s, summary="oedometer", title="oedometer", about=[],
                       stage_columns=[("sleeper_z", "platen centre z [m]", ".4f")],
                       preparation={"stages": list(STAGES), "body": "platen centre"}, notes=[],
                       intact_members=intact_members(self.c))
