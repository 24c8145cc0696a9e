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
    [[walls]]      axis ("x"|"y"|"z"), position [m], material, sense (-1|0|1), velocity [m/s],
                   name (for [[loads]])
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
                   ("members"|"grid"|"monte_carlo"), discretization, samples, vel [m/s];
                   or shape = "custom" with members = [[x, y, z, r], ...] [m] (about any origin,
                   touching or overlapping: `pdem.bodies.clump_generators.custom_members`)
    [[bodies]]     a rigid box (sleeper, plate, platen; `pdem.bodies.boxes`): name, center [m],
                   size ([a, b, c] edge lengths [m]), material, mass [kg] or density [kg/m³]
                   (one of them), blocked ("xyzXYZ" letters of blocked DOFs; default "XYZ"),
                   fixed, velocity [m/s], damping (its own Cundall λ_D), inertia [kg·m²]
                   (3 principal moments or a 3×3 tensor; default the solid cuboid), shape ("box")
    [[loads]]      a program on one body (body = NAME) or wall (wall = NAME), at most one each:
                   type and its keys (`pdem.boundaries.loads`), start [s], direction (default
                   [0, 0, -1]): "constant" force [N]; "ramp" f_from, f_to [N], duration [s];
                   "haversine" | "half_sine" f_min, f_max [N], frequency [Hz] or period [s],
                   cycles; "impulse" f0 [N], duration [s]; "displacement" speed [m/s],
                   displacement [m] (then held); "velocity" speed [m/s], duration [s] (optional).
                   Force programs act on bodies; displacement and velocity move a body along
                   its blocked translations, or a wall along its axis.

Output-only keys (`OUTPUT_ONLY_KEYS`, the [run] intervals of progress, output, snapshots,
checkpoints and fragment records) change what a run writes, never its trajectory: `result_identity`
leaves them out of what a checkpoint or a campaign member is compared on.
"""
import re
import tomllib
from dataclasses import fields

import numpy as np

from ..boundaries.loads import Constant, HalfSine, Haversine, Impulse, Motion, Ramp
from ..errors import InputError
from .generators import loose_cloud
from .scene import Scene
from ..settings import SimulationSettings
from .validate import boolean, number, vector3

SIMULATION_KEYS = {f.name for f in fields(SimulationSettings)}  # the [simulation] table: the settings
RUN_DEFAULTS = {"steps": 1000, "progress_every": 1000, "output_every": 100, "snapshot_every": 0, "checkpoint_every": 0,
                "checkpoint_every_s": 0.0, "checkpoint_keep": 3, "kind": "scene", "fragments_every": 0,
                "snapshot_contacts": False}
WALL_KEYS = {"axis", "position", "material", "sense", "velocity", "name"}
FACET_KEYS = {"vertices", "material", "velocity"}
SPHERE_KEYS = {"pos", "radius", "material", "fixed", "vel"}
DEPOSITION_KEYS = {"box_lo", "box_hi", "count", "radius", "radius_spread", "seed", "material", "walls_material"}
CLUMP_KEYS = {"shape", "radii", "member_radius", "member_spacing", "material", "box_lo", "box_hi", "count", "seed",
              "breakable", "stress_free", "mass_model", "discretization", "samples", "vel", "members"}
BODY_KEYS = {"name", "shape", "center", "size", "material", "mass", "density", "blocked", "fixed", "velocity",
             "damping", "inertia"}
# [[loads]]: the keys of each type (besides body or wall, type, start, direction)
LOAD_TYPES = {"constant": {"force"}, "ramp": {"f_from", "f_to", "duration"},
              "haversine": {"f_min", "f_max", "frequency", "period", "cycles"},
              "half_sine": {"f_min", "f_max", "frequency", "period", "cycles"}, "impulse": {"f0", "duration"},
              "displacement": {"speed", "displacement"}, "velocity": {"speed", "duration"}}
LOAD_REQUIRED = {"constant": ("force",), "ramp": ("f_to", "duration"), "haversine": ("f_max", "cycles"),
                 "half_sine": ("f_max", "cycles"), "impulse": ("f0", "duration"),
                 "displacement": ("speed", "displacement"), "velocity": ("speed",)}
LOAD_COMMON = {"body", "wall", "type", "start", "direction"}
TOP_KEYS = {"simulation", "run", "materials", "material_pairs", "walls", "facets", "spheres", "deposition", "clumps",
            "bodies", "loads"}
# keys that change what a run writes, not what it computes (`result_identity`)
OUTPUT_ONLY_KEYS = ("run.progress_every", "run.output_every", "run.snapshot_every", "run.checkpoint_every",
                    "run.checkpoint_every_s", "run.checkpoint_keep", "run.fragments_every")
AXES = {"x": 0, "y": 1, "z": 2}
NAME = re.compile(r"^[A-Za-z0-9_.-]+$")  # a body's or wall's name (it names /series columns)


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
        name = w.get("name", "")
        if not isinstance(name, str) or not (name == "" or NAME.match(name)) or name in scene.walls.names:
            raise InputError(f"walls[{k}].name = {name!r}: must be letters, digits, _ . - (it names series "
                             "columns), not the name of another wall")
        scene.add_wall(w["axis"], w["position"], w["material"], sense=w.get("sense", 0),
                       velocity=w.get("velocity", (0.0, 0.0, 0.0)), name=name)
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
    add_bodies(scene, doc)
    return scene


def add_bodies(scene, doc):
    """The [[bodies]] (rigid boxes) with their [[loads]], and the [[loads]] on walls."""
    bodies = _table_list("bodies", doc.get("bodies", []))
    loads = _table_list("loads", doc.get("loads", []))
    names = []
    for k, b in enumerate(bodies):
        check_keys(f"bodies[{k}]", b, BODY_KEYS, ("name", "center", "size", "material"))
        name = b["name"]
        if not isinstance(name, str) or not NAME.match(name) or name in names:
            raise InputError(f"bodies[{k}].name = {name!r}: must be letters, digits, _ . - (it names series "
                             "columns), not the name of another body")
        names.append(name)
    wall_names = list(scene.walls.names)
    on_body, on_wall = {}, {}
    for k, ld in enumerate(loads):
        label = f"loads[{k}]"
        if not isinstance(ld, dict):
            raise InputError(f"{label}: must be a table")
        kind = ld.get("type")
        if kind not in LOAD_TYPES:
            raise InputError(f"{label}.type = {kind!r}: must be one of {', '.join(LOAD_TYPES)}")
        check_keys(label, ld, LOAD_COMMON | LOAD_TYPES[kind], ("type",))
        if ("body" in ld) == ("wall" in ld):
            raise InputError(f"{label}: give body = NAME (one of [[bodies]]: {', '.join(names) or 'none'}) or "
                             f"wall = NAME (a named [[walls]]), not {'both' if 'body' in ld else 'neither'}")
        target, table, known = (("body", on_body, names) if "body" in ld else ("wall", on_wall, wall_names))
        name = ld[target]
        if name not in known:
            raise InputError(f"{label}.{target} = {name!r}: unknown; defined: {', '.join(known) or 'none'}")
        if name in table:
            raise InputError(f"{label}.{target} = {name!r}: already loaded by loads[{table[name][0]}] (one program "
                             "per body or wall)")
        if target == "wall" and kind not in ("displacement", "velocity"):
            raise InputError(f"{label}.type = {kind!r}: a wall has no mass; it takes 'displacement' or 'velocity' "
                             "only (a force acts on a [[bodies]] box)")
        table[name] = (k, load_program(label, kind, ld))
    for k, b in enumerate(bodies):
        label = f"bodies.{b['name']}"
        if b.get("shape", "box") != "box":
            raise InputError(f"{label}.shape = {b['shape']!r}: must be 'box' (the one rigid body shape)")
        size = vector3(f"{label}.size", b["size"])
        if not np.all(size > 0.0):
            raise InputError(f"{label}.size = {size.tolist()}: every edge length must be > 0 [m]")
        if ("mass" in b) == ("density" in b):
            raise InputError(f"{label}: give mass [kg] or density [kg/m³], not {'both' if 'mass' in b else 'neither'}")
        mass = (b["mass"] if "mass" in b else
                number(f"{label}.density", b["density"], 0.0, lo_open=True, allow="a number > 0 [kg/m³]")
                * float(np.prod(size)))
        k_load, program = on_body.get(b["name"], (None, None))
        force = program if program is not None and not isinstance(program[0], Motion) else None
        try:
            scene.add_box(b["center"], 0.5 * size, b["material"], mass, blocked=b.get("blocked"),
                          fixed=boolean(f"{label}.fixed", b.get("fixed", False)),
                          load=force[0] if force else None, direction=force[1] if force else (0.0, 0.0, -1.0),
                          velocity=b.get("velocity", (0.0, 0.0, 0.0)), damping=b.get("damping", 0.0),
                          name=b["name"], inertia=b.get("inertia"))
        except InputError as exc:  # the box's checks name it boxes.NAME; the file calls it bodies.NAME
            text = str(exc)
            raise InputError(f"bodies.{text[6:]}" if text.startswith("boxes.") else text) from None
        if program is not None and force is None:
            scene.add_motion("box", b["name"], program[0], program[1], label=f"loads[{k_load}]")
    for name, (k, (motion, direction)) in on_wall.items():
        scene.add_motion("wall", name, motion, direction, label=f"loads[{k}]")


def load_program(label, kind, ld):
    """(program, direction) of a [[loads]] table of type ``kind`` (`pdem.boundaries.loads`)."""
    start = ld.get("start", 0.0)
    direction = vector3(f"{label}.direction", ld.get("direction", (0.0, 0.0, -1.0)))
    missing = [key for key in LOAD_REQUIRED[kind] if key not in ld]
    if missing:
        raise InputError(f"{label}.{missing[0]}: required key is missing for type {kind!r}")
    if kind == "constant":
        return Constant(ld["force"], label=label), direction
    if kind == "ramp":
        return Ramp(ld.get("f_from", 0.0), ld["f_to"], ld["duration"], start=start, label=label), direction
    if kind in ("haversine", "half_sine"):
        if ("frequency" in ld) == ("period" in ld):
            both = "both" if "period" in ld else "neither"
            raise InputError(f"{label}: give frequency [Hz] or period [s], not {both}")
        f = (ld["frequency"] if "frequency" in ld
             else 1.0 / number(f"{label}.period", ld["period"], 0.0, lo_open=True, allow="a time > 0 [s]"))
        cls = Haversine if kind == "haversine" else HalfSine
        return cls(ld.get("f_min", 0.0), ld["f_max"], f, ld["cycles"], start=start, label=label), direction
    if kind == "impulse":
        return Impulse(ld["f0"], ld["duration"], start=start, label=label), direction
    if kind == "displacement":
        return Motion(ld["speed"], ld["displacement"], start=start, label=label), direction
    speed = number(f"{label}.speed", ld["speed"], 0.0, lo_open=True, allow="a speed > 0 [m/s]")
    if "duration" not in ld:
        return Motion(speed, start=start, label=label), direction
    duration = number(f"{label}.duration", ld["duration"], 0.0, lo_open=True, allow="a time > 0 [s]")
    return Motion(speed, speed * duration, start=start, label=label), direction


def result_identity(doc):
    """The scene document without its `OUTPUT_ONLY_KEYS`: two documents with the same identity
    give the same trajectory (a checkpoint of one continues the other; a campaign member is the
    same member)."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in doc.items()}
    for key in OUTPUT_ONLY_KEYS:
        table, leaf = key.split(".")
        if isinstance(out.get(table), dict):
            out[table].pop(leaf, None)
            if not out[table]:
                del out[table]
    return out


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
        BALLAST8_MEMBER_RADIUS, NOTTINGHAM_MEMBER_RADIUS, ballast8, custom_members, nottingham_grain, shape_members
    )

    shape = c.get("shape")
    if shape == "custom":
        extra = [key for key in ("radii", "member_radius", "member_spacing") if key in c]
        if extra:
            raise InputError(f"{label}.{extra[0]}: not a key of shape 'custom' (its members give every sphere)")
        if "members" not in c:
            raise InputError(f"{label}.members: required key is missing for shape 'custom' ([[x, y, z, r], ...] [m])")
        return custom_members(c["members"], label)
    if "members" in c:
        raise InputError(f"{label}.members: only for shape = 'custom' (shape is {shape!r})")
    if shape == "nottingham":
        return nottingham_grain(c.get("member_radius", NOTTINGHAM_MEMBER_RADIUS), c.get("member_spacing"))
    if shape == "ballast8":
        return ballast8(c.get("member_radius", BALLAST8_MEMBER_RADIUS), c.get("member_spacing"))
    if shape in ("ellipsoid", "cylinder", "cake"):
        for key in ("radii", "member_radius"):
            if key not in c:
                raise InputError(f"{label}.{key}: required key is missing for shape {shape!r}")
        return shape_members(shape, c["member_radius"], c["radii"], c.get("member_spacing"))
    raise InputError(f"{label}.shape = {shape!r}: must be one of ellipsoid, cylinder, cake, nottingham, ballast8, "
                     "custom")


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


def set_path(doc, path, value):
    """Set the dotted ``path`` in the nested ``doc`` (tables created as needed; an integer
    segment indexes an array of tables). Returns the paths of the tables it created (not in
    the base scene). Raises InputError naming the path."""
    parts = path.split(".")
    if any(p == "" for p in parts):
        raise InputError(f"{path}: not a dotted key (an empty part)")
    node, created = doc, []
    for i, p in enumerate(parts):
        last = i == len(parts) - 1
        where = ".".join(parts[:i + 1])
        if isinstance(node, list):
            if not p.lstrip("-").isdigit() or not -len(node) <= int(p) < len(node):
                raise InputError(f"{path}: {'.'.join(parts[:i])} is an array of {len(node)}; "
                                 f"{p!r} is not an index of it")
            if last:
                node[int(p)] = value
            else:
                node = node[int(p)]
        elif isinstance(node, dict):
            if last:
                node[p] = value
            else:
                if p not in node:
                    node[p] = {}
                    created.append(where)
                node = node[p]
        else:
            raise InputError(f"{path}: {'.'.join(parts[:i])} is a value, not a table, in the base scene")
        if not last and not isinstance(node, (dict, list)):
            raise InputError(f"{path}: {where} is a value ({node!r}), not a table, in the base scene")
    return created


def deepcopy_doc(x):
    if isinstance(x, dict):
        return {k: deepcopy_doc(v) for k, v in x.items()}
    if isinstance(x, list):
        return [deepcopy_doc(v) for v in x]
    return x


def parse_set(text):
    """(dotted key, value) of one ``--set KEY=VALUE``: VALUE is a TOML value (3, 2.5e7, true,
    [0.0, 0.0, -9.81], "text"); a bare word that is not one (``--set simulation.slab_axis=y``) is a
    string. One-line InputError for a malformed argument."""
    if not isinstance(text, str) or "=" not in text:
        raise InputError(f"--set {text!r}: must be KEY=VALUE (a dotted scene key, e.g. run.steps=2000)")
    key, raw = (part.strip() for part in text.split("=", 1))
    if not key or any(p == "" for p in key.split(".")):
        raise InputError(f"--set {text!r}: {key!r} is not a dotted scene key (e.g. materials.ballast.young)")
    try:
        return key, tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        if raw and all(ch.isalnum() or ch in "_-." for ch in raw):
            return key, raw
        raise InputError(f"--set {text!r}: {raw!r} is not a TOML value (numbers, true/false, [lists], "
                         "quoted strings)") from None


def apply_sets(doc, sets, check):
    """A copy of the scene document ``doc`` with the ``--set KEY=VALUE`` texts ``sets`` applied
    (in order; a later one wins), checked by ``check(doc)`` (the scene registry's validation):
    the document as given must pass it, and a key that is not a key of that scene, or a value it
    refuses, is one InputError line naming the --set."""
    check(doc)
    out = deepcopy_doc(doc)
    for text in sets:
        key, value = parse_set(text)
        try:
            set_path(out, key, value)
        except InputError as exc:
            raise InputError(f"--set {text}: {exc}") from None
        try:
            check(out)
        except InputError as exc:
            raise InputError(f"--set {text}: {exc}") from None
    return out


def load_scene(path):
    """(Scene, run settings, parsed document) from a plain scene file."""
    doc = load_toml(path)
    return scene_from_dict(doc), run_settings(doc), doc
