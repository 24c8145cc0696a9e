"""Scene files (TOML) → `Scene`, with one-line errors naming the field.

A plain scene file has the tables below (a scene of `pdem.scenes` adds its own table, e.g.
``[box_test]``); any key not listed is an error (so a typo never becomes a silent default).
Values are typed strictly: numbers are numbers (``true`` is not 1), booleans are booleans
(``"false"`` is a string). Units are SI.

    [simulation]   law ("linear"), dt ("auto" or [s]), damping, gravity [m/s²], skin [m],
                   dt_safety, dt_interval, pwave_factor, check_interval, max_overlap_ratio,
                   energy_check, allow_initial_overlap, slab_axis ("x"|"y"|"z"),
                   domain ([[x, y, z], [x, y, z]] [m]: a body outside stops the run)
    [run]          steps, progress_every, output_every, snapshot_every, snapshot_contacts (true:
                   the contact network in the snapshots), checkpoint_every, checkpoint_every_s,
                   checkpoint_keep, kind
    [materials.NAME] density [kg/m³] and the law's keys (linear: young [Pa], poisson [-],
                   friction_angle [rad]; viscous and hertz_mindlin: `pdem.contact.viscous`,
                   `pdem.contact.hertz_mindlin`)
    [[material_pairs]] materials = [NAME, NAME] and values of the law's per-pair keys
                   (hertz_mindlin: restitution, friction, rolling_friction)
    [[walls]]      axis ("x"|"y"|"z"), position [m], material, sense (-1|0|1), velocity [m/s]
    [[facets]]     vertices [[m]×3], material, velocity [m/s]
    [[spheres]]    pos [[m]], radius [m] or [[m]], material, fixed, vel [m/s]
    [deposition]   box_lo, box_hi [m], count, radius [m], radius_spread [-], seed, material,
                   walls_material (optional: adds a floor and four side walls of the box)
    [[clumps]]     grains of one shape (`pdem.bodies.clump_generators`), each turned at random, on a
                   grid in a box: shape ("ellipsoid"|"cylinder"|"cake" with radii [m] =
                   [R_x, R_y, R_z], or "nottingham"|"ballast8"), member_radius [m] (default of
                   the named grains: 3.55 mm, 8.5 mm), member_spacing [m] (of nearest
                   neighbours; default 2 member_radius, less overlaps them), material,
                   box_lo, box_hi [m], count, seed,
                   breakable (bonded members, law "cohesive"), stress_free, mass_model
                   ("members"|"grid"|"monte_carlo"), discretization, samples, vel [m/s]
"""
import tomllib
from dataclasses import fields

from ..errors import InputError
from .generators import loose_cloud
from .scene import Scene
from ..settings import SimulationSettings
from .validate import number

SIMULATION_KEYS = {f.name for f in fields(SimulationSettings)}  # the [simulation] table: the settings
RUN_DEFAULTS = {"steps": 1000, "progress_every": 1000, "output_every": 100, "snapshot_every": 0, "checkpoint_every": 0,
                "checkpoint_every_s": 0.0, "checkpoint_keep": 3, "kind": "scene", "fragments_every": 0,
                "snapshot_contacts": False}
WALL_KEYS = {"axis", "position", "material", "sense", "velocity"}
FACET_KEYS = {"vertices", "material", "velocity"}
SPHERE_KEYS = {"pos", "radius", "material", "fixed", "vel"}
DEPOSITION_KEYS = {"box_lo", "box_hi", "count", "radius", "radius_spread", "seed", "material", "walls_material"}
CLUMP_KEYS = {"shape", "radii", "member_radius", "member_spacing", "material", "box_lo", "box_hi", "count", "seed",
              "breakable", "stress_free", "mass_model", "discretization", "samples", "vel"}
TOP_KEYS = {"simulation", "run", "materials", "material_pairs", "walls", "facets", "spheres", "deposition", "clumps"}
AXES = {"x": 0, "y": 1, "z": 2}


def check_keys(where, table, allowed, required=()):
    """``table`` must be a table with keys from ``allowed`` and every key of ``required``."""
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be a table, got {type(table).__name__}")
    for k in table:
        if k not in allowed:
            raise InputError(f"{where}.{k}: unknown key; allowed: {', '.join(sorted(allowed))}")
    for k in required:
        if k not in table:
            raise InputError(f"{where}.{k}: required key is missing")


def _table_list(where, value):
    if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
        raise InputError(f"{where}: must be an array of tables ([[{where}]]), got {type(value).__name__}")
    return value


def load_toml(path, what="scene file"):
    """The parsed TOML file ``path`` (a ``what``: a scene file, a campaign file); a missing,
    unreadable, binary or malformed file, or a directory, is one InputError line."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: {what} not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a {what}") from None
    except PermissionError:
        raise InputError(f"{path}: cannot read the {what} (permission denied)") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file in UTF-8 (a TOML {what} is)") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None


def run_settings(doc):
    """The [run] table with defaults, checked."""
    run = dict(RUN_DEFAULTS)
    check_keys("run", doc.get("run", {}), set(RUN_DEFAULTS))
    run.update(doc.get("run", {}))
    for k in ("steps", "progress_every", "output_every", "snapshot_every", "checkpoint_every", "checkpoint_keep",
              "fragments_every"):
        run[k] = number(f"run.{k}", run[k], 0, integer=True)
    run["checkpoint_every_s"] = number("run.checkpoint_every_s", run["checkpoint_every_s"], 0.0,
                                       allow="a number of seconds >= 0 (0: off)")
    if not isinstance(run["snapshot_contacts"], bool):
        raise InputError(f"run.snapshot_contacts = {run['snapshot_contacts']!r}: must be true or false")
    if not isinstance(run["kind"], str):
        raise InputError(f"run.kind = {run['kind']!r}: must be a string")
    return run


def scene_from_dict(doc, scene_tables=()):
    """Build a Scene from a parsed plain scene file (dict). ``scene_tables``: the tables of
    registered scenes, only named in the error for an unknown table."""
    check_keys("scene file", doc, TOP_KEYS | set(scene_tables))
    check_keys("simulation", doc.get("simulation", {}), SIMULATION_KEYS)
    sim = dict(doc.get("simulation", {}))
    if "slab_axis" in sim:
        if not isinstance(sim["slab_axis"], str) or sim["slab_axis"] not in AXES:
            raise InputError(f"simulation.slab_axis = {sim['slab_axis']!r}: must be one of x, y, z")
        sim["slab_axis"] = AXES[sim["slab_axis"]]
    if "law" in sim and not isinstance(sim["law"], str):
        raise InputError(f"simulation.law = {sim['law']!r}: must be the name of a contact law")
    if sim.get("dt", "auto") != "auto" and isinstance(sim["dt"], str):
        raise InputError(f"simulation.dt = {sim['dt']!r}: must be 'auto' or a number > 0 [s]")
    scene = Scene(**sim)
    materials = doc.get("materials", {})
    if not isinstance(materials, dict) or not materials:
        raise InputError("materials: the scene file defines no material ([materials.NAME] tables)")
    for name, m in materials.items():
        if not isinstance(m, dict):
            raise InputError(f"materials.{name}: must be a table, got {type(m).__name__}")
        if "density" not in m:
            raise InputError(f"materials.{name}.density: required key is missing")
        scene.material(name=name, **m)
    add_material_pairs(scene, doc)
    for k, w in enumerate(_table_list("walls", doc.get("walls", []))):
        check_keys(f"walls[{k}]", w, WALL_KEYS, ("axis", "position", "material"))
        scene.add_wall(w["axis"], w["position"], w["material"], sense=w.get("sense", 0),
                       velocity=w.get("velocity", (0.0, 0.0, 0.0)))
    for k, f in enumerate(_table_list("facets", doc.get("facets", []))):
        check_keys(f"facets[{k}]", f, FACET_KEYS, ("vertices", "material"))
        scene.add_facet(f["vertices"], f["material"], velocity=f.get("velocity", (0.0, 0.0, 0.0)))
    for k, s in enumerate(_table_list("spheres", doc.get("spheres", []))):
        check_keys(f"spheres[{k}]", s, SPHERE_KEYS, ("pos", "radius", "material"))
        scene.add_spheres(s["pos"], s["radius"], s["material"], fixed=s.get("fixed", False), vel=s.get("vel"))
    if "deposition" in doc:
        add_deposition(scene, doc["deposition"])
    for k, c in enumerate(_table_list("clumps", doc.get("clumps", []))):
        add_clump_cloud(scene, c, f"clumps[{k}]")
    return scene


def add_material_pairs(scene, doc):
    """The [[material_pairs]] tables: per-pair values of the law's PAIR_KEYS."""
    for k, t in enumerate(_table_list("material_pairs", doc.get("material_pairs", []))):
        names = t.get("materials") if isinstance(t, dict) else None
        if not (isinstance(names, list) and len(names) == 2 and all(isinstance(n, str) for n in names)):
            raise InputError(f"material_pairs[{k}].materials = {names!r}: must be two material names")
        scene.material_pair(names[0], names[1], **{key: v for key, v in t.items() if key != "materials"})


def grain_shape(c, label):
    """(member pos, member radius) of the grain a [[clumps]] table describes."""
    from ..bodies.clump_generators import (
        BALLAST8_MEMBER_RADIUS, NOTTINGHAM_MEMBER_RADIUS, ballast8, nottingham_grain, shape_members
    )

    shape = c.get("shape")
    if shape == "nottingham":
        return nottingham_grain(c.get("member_radius", NOTTINGHAM_MEMBER_RADIUS), c.get("member_spacing"))
    if shape == "ballast8":
        return ballast8(c.get("member_radius", BALLAST8_MEMBER_RADIUS), c.get("member_spacing"))
    if shape in ("ellipsoid", "cylinder", "cake"):
        for key in ("radii", "member_radius"):
            if key not in c:
                raise InputError(f"{label}.{key}: required key is missing for shape {shape!r}")
        return shape_members(shape, c["member_radius"], c["radii"], c.get("member_spacing"))
    raise InputError(f"{label}.shape = {shape!r}: must be one of ellipsoid, cylinder, cake, nottingham, ballast8")


def add_clump_cloud(scene, c, label="clumps"):
    """``count`` grains of a [[clumps]] table, randomly turned, on a grid in its box."""
    from ..bodies.clump_generators import grain_cloud

    check_keys(label, c, CLUMP_KEYS, ("shape", "material", "box_lo", "box_hi", "count"))
    pos, radius = grain_shape(c, label)
    grains = grain_cloud(pos, radius, c["box_lo"], c["box_hi"], c["count"], c.get("seed", 0), label=label)
    return scene.add_clumps(
        grains,
        c["material"],
        breakable=c.get("breakable", False),
        vel=c.get("vel", (0.0, 0.0, 0.0)),
        stress_free=c.get("stress_free", True),
        mass_model=c.get("mass_model", "members"),
        discretization=c.get("discretization", 0),
        samples=c.get("samples", 0),
        seed=c.get("seed", 0),
        label=label,
    )


def add_deposition(scene, d):
    """A loose seeded cloud in a box; with `walls_material`, the box's floor and four sides."""
    check_keys("deposition", d, DEPOSITION_KEYS, ("box_lo", "box_hi", "count", "radius", "material"))
    count = number("deposition.count", d["count"], 1, integer=True)
    r = number("deposition.radius", d["radius"], 0.0, lo_open=True, allow="a number > 0 [m]")
    spread = number("deposition.radius_spread", d.get("radius_spread", 0.0), 0.0, 1.0, hi_open=True, allow="in [0, 1)")
    seed = number("deposition.seed", d.get("seed", 0), 0, integer=True)
    lo, hi = d["box_lo"], d["box_hi"]
    for name, v in (("box_lo", lo), ("box_hi", hi)):
        if not (isinstance(v, list) and len(v) == 3):
            raise InputError(f"deposition.{name} = {v!r}: must be [x, y, z] in m")
        for x in v:
            number(f"deposition.{name}", x, allow="[x, y, z] numbers in m")
    if not all(h > l for l, h in zip(lo, hi)):
        raise InputError(f"deposition.box_hi = {hi!r}: must be above box_lo = {lo!r} on every axis")
    pos, radius = loose_cloud(lo, hi, count, r, spread, seed)
    scene.add_spheres(pos, radius, d["material"])
    wm = d.get("walls_material")
    if wm is not None:
        scene.add_wall("z", lo[2], wm, sense=1, name="floor")
        scene.add_wall("x", lo[0], wm, sense=1, name="x_min")
        scene.add_wall("x", hi[0], wm, sense=-1, name="x_max")
        scene.add_wall("y", lo[1], wm, sense=1, name="y_min")
        scene.add_wall("y", hi[1], wm, sense=-1, name="y_max")
    return scene


def load_scene(path):
    """(Scene, run settings, parsed document) from a plain scene file."""
    doc = load_toml(path)
    return scene_from_dict(doc), run_settings(doc), doc
