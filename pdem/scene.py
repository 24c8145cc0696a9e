"""Scene: what a simulation declares (materials, bodies, boundaries, loads) and `build()`.

Only what a scene declares is built and run: a scene without walls has no wall contact list and
never compiles the wall kernel, a scene without damping runs the undamped integrator. Every input
is checked here, and bad input raises `InputError` with one line naming the field, the value and
what is allowed.

Example (thesis appendix A, SPEC.md 2.1)::

    scene = Scene(dt=2e-6, damping=0.1, gravity=(0, 0, -9.81))
    pvc = scene.material(density=1380, young=2.5e9, poisson=0.4, friction_angle=1.0)
    steel = scene.material(density=7850, young=2.1e8, poisson=0.3, friction_angle=1.0)
    scene.add_spheres([(0, 0, 0), (.01, .01, .2)], [.05, .03], [pvc, steel], fixed=[True, False])
    sim = scene.build()
    sim.run(82869)
"""
import copy
import json
from math import pi

import numpy as np

from .boxes import Boxes
from .contact import get_law
from .domain import SerialDomain
from .errors import InputError
from .facets import Facets
from .guard import Guard, check_initial_overlaps
from .materials import MaterialTable
from .simulation import Simulation
from .state import DOF_ALL, FIELDS, Particles
from .validate import boolean, number, vectors
from .walls import Walls


def sphere_columns(pos, radius, density, first_gid):
    """gid, pos, radius, mass, inertia of spheres at rest (vel, angvel zero) [SI], with Yade's
    mass V·ρ and inertia (2/5)·V·r²·ρ."""
    # element by element with Python floats, as Yade's utils.sphere does: numpy's power can
    # differ from Python's r**3 in the last bit
    volume = np.array([(4.0 / 3) * pi * float(x) ** 3 for x in radius])
    n = len(radius)
    return {
        "gid": np.arange(first_gid, first_gid + n, dtype=np.int64),
        "pos": np.asarray(pos, np.float64),
        "vel": np.zeros((n, 3)),
        "angvel": np.zeros((n, 3)),
        "radius": np.asarray(radius, np.float64),
        "mass": np.array([v * float(d) for v, d in zip(volume, density)]),
        "inertia": np.array([((2.0 / 5.0) * v * float(x) ** 2) * float(d) for v, x, d in zip(volume, radius, density)]),
    }


class Scene:
    """Declare a simulation; `build()` turns it into a `Simulation`."""

    def __init__(self, *, dt="auto", damping=0.0, gravity=(0.0, 0.0, 0.0), skin=None, dt_safety=0.8, dt_interval=100,
                 pwave_factor=0.5, check_interval=100, max_overlap_ratio=0.5, energy_check=True,
                 allow_initial_overlap=False, slab_axis=0, law="linear", domain=None):
        self.law = get_law(law)
        if dt is not None and dt != "auto":
            dt = number("dt", dt, 0.0, lo_open=True, allow="'auto' or a number > 0 [s]")
        self.settings = {
            "dt": dt,
            "damping": number("damping", damping, 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)"),
            "gravity": vectors("gravity", gravity, 1)[0].tolist(),
            "skin": None if skin is None else number("skin", skin, 0.0, lo_open=True, allow="a length > 0 [m]"),
            "dt_safety": number("dt_safety", dt_safety, 0.0, 1.0, lo_open=True, allow="in (0, 1]"),
            "dt_interval": number("dt_interval", dt_interval, 1, integer=True, allow="an integer >= 1 [steps]"),
            "pwave_factor": number("pwave_factor", pwave_factor, 0.0, 1.0, lo_open=True, allow="in (0, 1]"),
            "check_interval": number(
                "check_interval", check_interval, 1, integer=True, allow="an integer >= 1 [steps]"
            ),
            "max_overlap_ratio": number(
                "max_overlap_ratio", max_overlap_ratio, 0.0, 1.0, lo_open=True, allow="in (0, 1]"
            ),
            "energy_check": boolean("energy_check", energy_check),
            "allow_initial_overlap": boolean("allow_initial_overlap", allow_initial_overlap),
            "slab_axis": slab_axis,
            "law": self.law.NAME,
        }
        if domain is not None:  # only when declared: the spec (and checkpoints) of other scenes stay as they were
            box = vectors("domain", domain, 2)
            if not np.all(box[1] > box[0]):
                raise InputError(
                    f"domain = {box.tolist()}: must be [[x, y, z] low, [x, y, z] high] with low < high [m]"
                )
            self.settings["domain"] = box.tolist()
        if slab_axis not in (0, 1, 2) or isinstance(slab_axis, bool):
            raise InputError(f"slab_axis = {slab_axis!r}: must be 0, 1 or 2 (x, y, z)")
        self.materials = MaterialTable(self.law)
        self.walls = Walls()
        self.facets = Facets()
        self.boxes = Boxes()
        self._spheres = []

    @property
    def material_names(self):
        return self.materials.names

    # ------------------------------------------------------------------ declarations
    def material(self, *, density, name="", **properties):
        """Add a material; returns its index. ``density`` [kg/m³] and the keys of the scene's law
        (linear: ``young`` [Pa], ``poisson`` [-], ``friction_angle`` [rad])."""
        return self.materials.add(name, density, properties)

    def material_pair(self, a, b, **values):
        """Set the law's per-pair keys (``law.PAIR_KEYS``, e.g. Hertz–Mindlin's ``restitution``
        and ``friction``) for the pair of materials a, b (names or indices)."""
        ia = self._material_index("material_pairs.materials[0]", a)
        ib = self._material_index("material_pairs.materials[1]", b)
        self.materials.set_pair(
            ia, ib, values, label=f"material_pairs.{self.material_names[ia]}-{self.material_names[ib]}"
        )

    def _material_index(self, label, m):
        if isinstance(m, str):
            if m not in self.material_names:
                raise InputError(
                    f"{label} = {m!r}: unknown material; defined: {', '.join(self.material_names) or 'none'}"
                )
            return self.material_names.index(m)
        if not (isinstance(m, (int, np.integer)) and 0 <= m < len(self.materials)):
            raise InputError(f"{label} = {m!r}: not a material index (0..{len(self.materials) - 1})")
        return int(m)

    def add_spheres(self, pos, radius, material, *, fixed=False, vel=None, angvel=None, blocked=None, first_gid=None,
                    gid=None, mass=None, inertia=None):
        """Add spheres; returns their global ids. pos [m], radius [m], vel [m/s], angvel [rad/s].

        `fixed` blocks every DOF (the body still moves with `vel`); `blocked` is a per-body string
        of blocked DOFs from "xyzXYZ" (lowercase translations, uppercase rotations). Global ids
        count up from `first_gid` (default: one past the largest so far), or are given per
        sphere in `gid`. `mass` [kg] and `inertia` [kg·m²] replace Yade's V·ρ and (2/5)V·r²·ρ
        (e.g. to match another code's values to the last bit)."""
        pos = vectors("spheres.pos", pos)
        n = len(pos)
        r = _per_body("spheres.radius", radius, n)
        if not np.all(np.isfinite(r) & (r > 0)):
            k = int(np.flatnonzero(~(np.isfinite(r) & (r > 0)))[0])
            raise InputError(f"spheres.radius[{k}] = {r[k]!r}: must be a finite number > 0 [m]")
        mats = _broadcast("spheres.material", material, n)
        mat = np.array([self._material_index(f"spheres.material[{k}]", m) for k, m in enumerate(mats)], np.int64)
        fixed = _broadcast("spheres.fixed", fixed, n)
        for k, f in enumerate(fixed):
            boolean(f"spheres.fixed[{k}]", f)
        mask = np.where(fixed.astype(bool), DOF_ALL, 0).astype(np.int64)
        if blocked is not None:
            for k, b in enumerate(_broadcast("spheres.blocked", blocked, n)):
                if not isinstance(b, str) or set(b) - set("xyzXYZ"):
                    raise InputError(f"spheres.blocked[{k}] = {b!r}: must be a string of letters from 'xyzXYZ'")
                for c in b:
                    mask[k] |= 1 << "xyzXYZ".index(c)
        vel = np.zeros((n, 3)) if vel is None else vectors("spheres.vel", _rows3(vel, n), n)
        angvel = np.zeros((n, 3)) if angvel is None else vectors("spheres.angvel", _rows3(angvel, n), n)
        rho = self.materials.density()[mat]
        if gid is not None:
            gids = np.asarray(gid)
            if gids.shape != (n,) or gids.dtype.kind not in "iu" or (n and gids.min() < 0) or len(np.unique(gids)) != n:
                raise InputError(f"spheres.gid: must be {n} distinct integers >= 0, got {_short(gid)}")
            first = 0
        else:
            first = self.next_gid() if first_gid is None else number("spheres.first_gid", first_gid, 0, integer=True)
        cols = sphere_columns(pos, r, rho, first)
        if gid is not None:
            cols["gid"] = gids.astype(np.int64)
        for key, value in (("mass", mass), ("inertia", inertia)):
            if value is not None:
                v = _per_body(f"spheres.{key}", value, n)
                if not np.all(np.isfinite(v) & (v > 0)):
                    raise InputError(f"spheres.{key}: every value must be a finite number > 0")
                cols[key] = v
        cols.update(vel=vel, angvel=angvel, material=mat, blocked=mask)
        self.add_sphere_columns(cols)
        return cols["gid"]

    def next_gid(self):
        """The global id the next added sphere gets (one past the largest so far)."""
        return max((int(s["gid"].max()) + 1 for s in self._spheres if len(s["gid"])), default=0)

    def add_sphere_columns(self, cols):
        """Add bodies given as FIELDS columns (e.g. a checkpoint's ``particles`` table), keeping
        their global ids and state; used between the stages of a multi-stage scene."""
        gids = np.asarray(cols["gid"])
        taken = np.concatenate([s["gid"] for s in self._spheres]) if self._spheres else np.zeros(0, np.int64)
        clash = np.intersect1d(gids, taken)
        if len(clash):
            raise InputError(f"spheres.gid: id {int(clash[0])} is already taken")
        self._spheres.append({k: np.asarray(cols[k]).copy() for k in FIELDS})
        return gids

    def add_wall(self, axis, position, material, *, sense=0, velocity=(0.0, 0.0, 0.0), name=""):
        """Add an infinite axis-aligned plane x[axis] = position [m] (Yade's utils.wall)."""
        label = f"walls.{name}" if name else f"walls[{len(self.walls)}]"
        m = self._material_index(f"{label}.material", material)
        return self.walls.add(axis, number(f"{label}.position", position), m, sense,
                              vectors(f"{label}.velocity", velocity, 1)[0], name)

    def add_facet(self, vertices=None, material=0, *, center=None, local=None, velocity=(0.0, 0.0, 0.0), name=""):
        """Add a triangle from three global `vertices` [m], or from a `center` [m] and three
        vertices `local` to it; optionally translating with `velocity` [m/s]. `name` finds it
        again (`Simulation.facet_index`)."""
        label = f"facets.{name}" if name else f"facets[{len(self.facets)}]"
        m = self._material_index(f"{label}.material", material)
        if (vertices is None) == (center is None or local is None):
            raise InputError(f"{label}: give either vertices or center and local")
        if vertices is None:
            vertices = vectors(f"{label}.center", center, 1) + vectors(f"{label}.local", local, 3)
        return self.facets.add(vertices, m, vectors(f"{label}.velocity", velocity, 1)[0], name=name)

    def add_box(self, center, half_extents, material, mass, *, blocked=None, fixed=False, load=None,
                direction=(0.0, 0.0, -1.0), velocity=(0.0, 0.0, 0.0), damping=0.0, name=""):
        """Add a rigid axis-aligned box (sleeper, platen): one body of `mass` [kg] spanning
        ``center ± half_extents`` [m]; returns its index.

        `fixed` blocks every DOF (the box still moves with `velocity` [m/s]); `blocked` is a
        string of blocked DOFs from "xyzXYZ" and must contain XYZ (boxes do not rotate; default
        "XYZ": free translations). `load` is a `pdem.loads` program (e.g. `Haversine`) whose
        magnitude [N] pushes along `direction` (default −z); `damping` is the box's own Cundall
        λ_D (default 0: the box is not damped)."""
        label = f"boxes.{name}" if name else f"boxes[{len(self.boxes)}]"
        m = self._material_index(f"{label}.material", material)
        return self.boxes.add(center, half_extents, m, mass, blocked=blocked, fixed=fixed, load=load,
                              direction=direction, velocity=velocity, damping=damping, name=name)

    # ------------------------------------------------------------------ build
    def spheres(self):
        """All declared spheres as one dict of columns (see `pdem.state.FIELDS`)."""
        if not self._spheres:
            raise InputError("spheres: the scene has no spheres")
        return {k: np.concatenate([s[k] for s in self._spheres]) for k in FIELDS}

    def spec(self):
        """JSON-able description of the scene (settings, materials, walls, facets, boxes if any; not
        the spheres)."""
        out = {
            "settings": self.settings,
            "materials": self.materials.spec(),
            "walls": [dict(axis=int(a), position=float(p), sense=int(s), velocity=v.tolist(), material=int(m))
                      for a, p, s, v, m in zip(self.walls.axis, self.walls.position, self.walls.sense,
                                               self.walls.velocity, self.walls.material)],
            "facets": [dict(vertices=v.tolist(), velocity=u.tolist(), material=int(m))
                       for v, u, m in zip(self.facets.vertices, self.facets.velocity, self.facets.material)],
        }
        if len(self.boxes):
            out["boxes"] = self.boxes.spec()
        return out

    def _check_initial_overlaps(self, cols):
        from .neighbors import build_sphere_pairs

        pos, r, gid = cols["pos"], cols["radius"], cols["gid"]
        n = len(gid)
        pi_, pj = build_sphere_pairs(pos, r, gid, n, n, 0.0, 2.0 * r.max(), 8 * n + 1000)
        if len(pi_):
            d = np.linalg.norm(pos[pj] - pos[pi_], axis=1)
            over = r[pi_] + r[pj] - d
            k = int(np.argmax(over))
            if over[k] > 0:
                raise InputError(
                    f"spheres: bodies gid {gid[pi_[k]]} and {gid[pj[k]]} overlap by {over[k]:.3e} m at the start; "
                    "move them apart or set allow_initial_overlap = true"
                )

    def _check_coincident_centres(self, cols):
        """Overlaps allowed, but two spheres on one centre have no contact normal (0/0): refused."""
        from .neighbors import build_sphere_pairs

        pos, r, gid = cols["pos"], cols["radius"], cols["gid"]
        n = len(gid)
        if n < 2:
            return
        pi_, pj = build_sphere_pairs(pos, r, gid, n, n, 0.0, 2.0 * r.max(), 8 * n + 1000)
        same = np.flatnonzero(np.all(pos[pi_] == pos[pj], axis=1))
        if len(same):
            k = int(same[0])
            raise InputError(f"spheres: bodies gid {gid[pi_[k]]} and {gid[pj[k]]} have the same centre "
                             f"{pos[pi_[k]].tolist()} m (a repeated row?): no contact normal exists between them")

    def build(self, comm=None, domain=None):
        """Create the `Simulation` (on `comm`'s ranks; default one rank)."""
        if len(self.materials) == 0:
            raise InputError("materials: the scene defines no material")
        cols = self.spheres()
        if not self.settings["allow_initial_overlap"]:
            self._check_initial_overlaps(cols)
        else:
            self._check_coincident_centres(cols)
        s = self.settings
        skin = s["skin"] if s["skin"] is not None else 0.25 * float(np.mean(cols["radius"]))
        if domain is None:
            if comm is None:
                from .parallel.comm import SerialComm

                comm = SerialComm()
            if comm.size == 1:
                domain = SerialDomain(comm)
            else:
                from .parallel.slab_domain import SlabDomain

                domain = SlabDomain(comm, axis=s["slab_axis"])
                domain.check_rank_count(cols, skin)
        particles = Particles(len(cols["gid"]) if domain.comm.size == 1 else 16)
        domain.distribute(particles, cols)
        guard = Guard.for_scene(self.walls, cols["pos"], s.get("domain"))
        sim = Simulation(
            particles=particles,
            law=self.law,
            materials=self.materials,
            walls=self.walls,
            facets=self.facets,
            boxes=copy.deepcopy(self.boxes),
            gravity=s["gravity"],
            damping=s["damping"],
            dt=None if s["dt"] in ("auto", None) else s["dt"],
            dt_safety=s["dt_safety"],
            dt_interval=s["dt_interval"],
            pwave_factor=s["pwave_factor"],
            skin=skin,
            check_interval=s["check_interval"],
            max_overlap_ratio=s["max_overlap_ratio"],
            energy_check=s["energy_check"],
            domain=domain,
            spec=json.loads(json.dumps(self.spec())),
            guard=guard,
        )
        if not s["allow_initial_overlap"]:
            check_initial_overlaps(sim)
        return sim


def _broadcast(label, value, n):
    """An object array [n] from one value or a list of n values."""
    items = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    if len(items) not in (1, n):
        raise InputError(f"{label}: one value or one per sphere ({n}), got {len(items)}")
    out = np.empty(n, dtype=object)
    for k in range(n):
        out[k] = items[0] if len(items) == 1 else items[k]
    return out


def _per_body(label, value, n):
    """float64 [n] from one number or n numbers."""
    try:
        if isinstance(value, (str, bool)):
            raise ValueError
        a = np.asarray(value, dtype=np.float64)
        return np.broadcast_to(a, (n,)).copy()
    except (TypeError, ValueError):
        raise InputError(f"{label} = {_short(value)}: must be one number or {n} numbers") from None


def _rows3(value, n):
    a = np.asarray(value, dtype=object)
    return np.broadcast_to(value, (n, 3)) if a.shape == (3,) else value


def _short(value, limit=60):
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
