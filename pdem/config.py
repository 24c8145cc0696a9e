"""Scene files (TOML) → `Scene`, with one-line errors naming the field.

A scene file has the tables below; any key not listed is an error (so a typo never becomes a
silent default). Units are SI.

    [simulation]   dt ("auto" or [s]), damping, gravity [m/s²], skin [m], dt_safety, dt_interval,
                   pwave_factor, check_interval, max_overlap_ratio, energy_check,
                   allow_initial_overlap, slab_axis ("x"|"y"|"z")
    [run]          steps, progress_every, output_every, snapshot_every, checkpoint_every,
                   checkpoint_every_s, checkpoint_keep, kind
    [materials.NAME] density [kg/m³], young [Pa], poisson [-], friction_angle [rad]
    [[walls]]      axis ("x"|"y"|"z"), position [m], material, sense (-1|0|1), velocity [m/s]
    [[facets]]     vertices [[m]×3], material, velocity [m/s]
    [[spheres]]    pos [[m]], radius [m] or [[m]], material, fixed, vel [m/s]
    [deposition]   box_lo, box_hi [m], count, radius [m], radius_spread [-], seed, material,
                   walls_material (optional: adds a floor and four side walls of the box)
"""
import tomllib

from .errors import InputError
from .generators import loose_cloud
from .scene import Scene

SIMULATION_KEYS = {"dt", "damping", "gravity", "skin", "dt_safety", "dt_interval", "pwave_factor", "check_interval",
                   "max_overlap_ratio", "energy_check", "allow_initial_overlap", "slab_axis"}
RUN_DEFAULTS = {"steps": 1000, "progress_every": 1000, "output_every": 100, "snapshot_every": 0, "checkpoint_every": 0,
                "checkpoint_every_s": 0.0, "checkpoint_keep": 3, "kind": "scene"}
MATERIAL_KEYS = {"density", "young", "poisson", "friction_angle"}
WALL_KEYS = {"axis", "position", "material", "sense", "velocity"}
FACET_KEYS = {"vertices", "material", "velocity"}
SPHERE_KEYS = {"pos", "radius", "material", "fixed", "vel"}
DEPOSITION_KEYS = {"box_lo", "box_hi", "count", "radius", "radius_spread", "seed", "material", "walls_material"}
TOP_KEYS = {"simulation", "run", "materials", "walls", "facets", "spheres", "deposition", "box_test"}
AXES = {"x": 0, "y": 1, "z": 2}


def _check_keys(where, table, allowed, required=()):
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be a table, got {type(table).__name__}")
    for k in table:
        if k not in allowed:
            raise InputError(f"{where}.{k}: unknown key; allowed: {', '.join(sorted(allowed))}")
    for k in required:
        if k not in table:
            raise InputError(f"{where}.{k}: required key is missing")


def load_toml(path):
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: scene file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None


def run_settings(doc):
    run = dict(RUN_DEFAULTS)
    _check_keys("run", doc.get("run", {}), set(RUN_DEFAULTS))
    run.update(doc.get("run", {}))
    for k in ("steps", "progress_every", "output_every", "snapshot_every", "checkpoint_every", "checkpoint_keep"):
        if not isinstance(run[k], int) or run[k] < 0:
            raise InputError(f"run.{k} = {run[k]!r}: must be an integer >= 0")
    return run


def scene_from_dict(doc):
    """Build a Scene from a parsed scene file (dict)."""
    _check_keys("scene file", doc, TOP_KEYS)
    sim = dict(doc.get("simulation", {}))
    _check_keys("simulation", sim, SIMULATION_KEYS)
    if "slab_axis" in sim:
        if sim["slab_axis"] not in AXES:
            raise InputError(f"simulation.slab_axis = {sim['slab_axis']!r}: must be one of x, y, z")
        sim["slab_axis"] = AXES[sim["slab_axis"]]
    scene = Scene(**sim)
    materials = doc.get("materials", {})
    if not materials:
        raise InputError("materials: the scene file defines no material ([materials.NAME] tables)")
    for name, m in materials.items():
        _check_keys(f"materials.{name}", m, MATERIAL_KEYS, MATERIAL_KEYS)
        scene.material(name=name, **m)
    for k, w in enumerate(doc.get("walls", [])):
        _check_keys(f"walls[{k}]", w, WALL_KEYS, ("axis", "position", "material"))
        scene.add_wall(w["axis"], w["position"], w["material"], sense=w.get("sense", 0),
                       velocity=w.get("velocity", (0.0, 0.0, 0.0)))
    for k, f in enumerate(doc.get("facets", [])):
        _check_keys(f"facets[{k}]", f, FACET_KEYS, ("vertices", "material"))
        scene.add_facet(f["vertices"], f["material"], velocity=f.get("velocity", (0.0, 0.0, 0.0)))
    for k, s in enumerate(doc.get("spheres", [])):
        _check_keys(f"spheres[{k}]", s, SPHERE_KEYS, ("pos", "radius", "material"))
        scene.add_spheres(s["pos"], s["radius"], s["material"], fixed=s.get("fixed", False), vel=s.get("vel"))
    if "deposition" in doc:
        add_deposition(scene, doc["deposition"])
    return scene


def add_deposition(scene, d):
    """A loose seeded cloud in a box; with `walls_material`, the box's floor and four sides."""
    _check_keys("deposition", d, DEPOSITION_KEYS, ("box_lo", "box_hi", "count", "radius", "material"))
    count = d["count"]
    if not isinstance(count, int) or count < 1:
        raise InputError(f"deposition.count = {count!r}: must be an integer >= 1")
    r = d["radius"]
    if not isinstance(r, (int, float)) or not r > 0:
        raise InputError(f"deposition.radius = {r!r}: must be a number > 0 [m]")
    spread = d.get("radius_spread", 0.0)
    if not isinstance(spread, (int, float)) or not 0 <= spread < 1:
        raise InputError(f"deposition.radius_spread = {spread!r}: must be in [0, 1)")
    lo, hi = d["box_lo"], d["box_hi"]
    for name, v in (("box_lo", lo), ("box_hi", hi)):
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) for x in v)):
            raise InputError(f"deposition.{name} = {v!r}: must be [x, y, z] in m")
    if not all(h > l for l, h in zip(lo, hi)):
        raise InputError(f"deposition.box_hi = {hi!r}: must be above box_lo = {lo!r} on every axis")
    pos, radius = loose_cloud(lo, hi, count, r, spread, d.get("seed", 0))
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
    """(Scene, run settings, parsed document) from a scene file."""
    doc = load_toml(path)
    return scene_from_dict(doc), run_settings(doc), doc
