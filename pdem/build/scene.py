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

from ..bodies.bonds import TOUCH, bonded_rows, check_bond_strengths
from ..bodies.boxes import Boxes
from ..bodies.clump_setup import (check_bond_overlaps, check_tables, mass_settings, member_sets, owner_positions,
                                  per_clump, rigid_rows)
from ..bodies.clumps import Clumps, extent_of
from ..contact import get_law
from ..parallel.serial_domain import SerialDomain
from ..errors import InputError
from ..boundaries.facets import Facets
from ..checks.guard import Guard, check_initial_overlaps
from .materials import MaterialTable
from ..settings import AUTO, simulation_settings
from ..simulation import Simulation
from ..bodies.state import DOF_ALL, FIELDS, Particles, with_defaults
from .validate import boolean, number, numbers, vectors
from ..boundaries.walls import Walls


def sphere_columns(pos, radius, density, first_gid):
    """gid, pos, radius, mass, inertia of spheres at rest (vel, angvel zero) [SI], with Yade's
    mass V·ρ and inertia (2/5)·V·r²·ρ; in no clump (clump -1)."""
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
        "clump": np.full(n, -1, np.int64),
    }


class Scene:
    """Declare a simulation; `build()` turns it into a `Simulation`."""

    def __init__(self, *, dt=AUTO, damping=0.0, gravity=(0.0, 0.0, 0.0), skin=None, dt_safety=0.8, dt_interval=100,
                 pwave_factor=0.5, check_interval=100, max_overlap_ratio=0.5, energy_check=True,
                 allow_initial_overlap=False, slab_axis=0, law="linear", domain=None, periodic=None):
        self.law = get_law(law)
        self.settings = simulation_settings(
            dt=dt, damping=damping, gravity=gravity, skin=skin, dt_safety=dt_safety, dt_interval=dt_interval,
            pwave_factor=pwave_factor, check_interval=check_interval, max_overlap_ratio=max_overlap_ratio,
            energy_check=energy_check, allow_initial_overlap=allow_initial_overlap, slab_axis=slab_axis,
            law=self.law.NAME, domain=domain, periodic=periodic)
        self.materials = MaterialTable(self.law)
        self.walls = Walls()
        self.facets = Facets()
        self.boxes = Boxes()
        self._spheres = []
        self._clumps = []  # (clumps, clump_members) tables of the rigid clumps (pdem.bodies.clumps)
        self._bonds = []  # (gid1, gid2, stress_free) of the bonds of breakable clumps (pdem.bodies.bonds)
        self._clump_ids = []
        self.motions = []  # (target "box"|"wall", index, Motion, unit direction) of displacement control

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
        cols = with_defaults(cols)
        gids = np.asarray(cols["gid"])
        taken = np.concatenate([s["gid"] for s in self._spheres]) if self._spheres else np.zeros(0, np.int64)
        clash = np.intersect1d(gids, taken)
        if len(clash):
            raise InputError(f"spheres.gid: id {int(clash[0])} is already taken")
        self._spheres.append({k: np.asarray(cols[k]).copy() for k in FIELDS})
        return gids

    def empty_like(self):
        """A scene with this one's settings and materials (shared) and no bodies or boundaries."""
        sc = Scene(**self.settings.as_dict())
        sc.materials = self.materials
        return sc

    def body_tables(self):
        """The declared bodies as global tables (`pdem.io.checkpoint_state` layout): ``particles``;
        ``clumps`` and ``clump_members`` if there are rigid clumps; the bonds, made now, as
        ``contacts/sphere_sphere`` rows (key, params, history) if there are any."""
        cols = self.spheres()
        out = {"particles": cols}
        clumps, members = self.clump_tables()
        if clumps is not None:
            out["clumps"], out["clump_members"] = clumps, members
        if self._bonds:
            skin = self.settings.skin if self.settings.skin is not None else 0.25 * float(np.mean(cols["radius"]))
            key, params, history = self._bond_rows(cols, skin)
            out["contacts/sphere_sphere"] = {"key": key, "params": params, "history": history}
        return out

    # ------------------------------------------------------------------ clumps
    def next_clump_id(self):
        """The id the next declared clump gets (one past the largest so far)."""
        used = [max(self._clump_ids)] if self._clump_ids else []
        used += [int(s["clump"].max()) for s in self._spheres if len(s["clump"])]
        return max(used, default=-1) + 1

    def add_clumps(self, members, material, *, breakable=False, vel=(0.0, 0.0, 0.0), angvel=(0.0, 0.0, 0.0),
                   angmom=None, mass_model="members", discretization=0, samples=0, seed=0, stress_free=True,
                   first_gid=None, first_id=None, label="clumps"):
        """Add clumps; returns their ids. ``members``: a list of (member positions [m], member
        radii [m]: one number or one per member), one entry per clump; the members of a clump
        must overlap or touch so as to form one body; ``material`` is the members' material.

        Rigid clumps (`pdem.bodies.clumps`, Yade's clumps): ``vel`` [m/s] and ``angvel`` [rad/s] (one
        triple or one per clump); ``angmom`` [kg·m²/s] sets the angular momentum instead of
        I·ω (then ``angvel`` is only the spin of the first step's damping and contact velocities,
        as when Yade's state.angMom is set); ``mass_model`` "members" (Yade's default: overlaps
        counted twice), "grid" (Yade's discretization, ``discretization`` cells along the
        shortest side) or "monte_carlo" (``samples`` points, ``seed``): `pdem.bodies.clump_properties`.

        ``breakable=True``: the members are free spheres joined by bonds of the scene's law
        (cohesive) between every two members that overlap or touch, made when the scene is
        built, stress free (``stress_free=True``, SPEC 1.2) or loaded by their overlap as Yade
        makes them (False); ``vel`` applies to every member.

        Member gids count up from ``first_gid`` (default: the next free gid), clump by clump;
        clump ids from ``first_id`` (default: the next free clump id)."""
        sets = member_sets(label, members)
        n = len(sets)
        counts = np.array([len(r) for _, r, _ in sets], np.int64)
        mats = _broadcast(f"{label}.material", material, int(counts.sum()))
        m = np.array([self._material_index(f"{label}.material", x) for x in mats], np.int64)
        v = per_clump(f"{label}.vel", vel, n)
        first = self.next_gid() if first_gid is None else number(f"{label}.first_gid", first_gid, 0, integer=True)
        gids = np.arange(first, first + int(counts.sum()), dtype=np.int64)
        c0 = self.next_clump_id() if first_id is None else number(f"{label}.first_id", first_id, 0, integer=True)
        ids = np.arange(c0, c0 + n, dtype=np.int64)
        if set(ids.tolist()) & set(self._clump_ids):
            raise InputError(f"{label}.first_id = {c0}: clump ids from {c0} are already taken")
        if boolean(f"{label}.breakable", breakable):
            w = per_clump(f"{label}.angvel", angvel, n)
            if angmom is not None or np.any(w != 0.0):
                raise InputError(f"{label}.angvel: a breakable clump's members are free spheres; give them vel only")
            boolean(f"{label}.stress_free", stress_free)
            check_bond_overlaps(label, sets, self.settings.max_overlap_ratio)
            mvel, mw = np.repeat(v, counts, axis=0), np.zeros((int(counts.sum()), 3))
        else:
            mass_settings(label, mass_model, discretization, samples)
            w = per_clump(f"{label}.angvel", angvel, n)
            lm = None if angmom is None else per_clump(f"{label}.angmom", angmom, n)
            rho = self.materials.density()[m]
            if mass_model != "members" and len(np.unique(rho)) > 1:
                raise InputError(
                    f"{label}.material: mass_model {mass_model!r} needs one density for all members of a clump"
                )
            clumps, mem, mvel, mw = rigid_rows(sets, rho, ids, gids, v, w, lm, mass_model, discretization, samples,
                                               number(f"{label}.seed", seed, 0, integer=True))
        pos = np.concatenate([p for p, _, _ in sets])
        radius = np.concatenate([r for _, r, _ in sets])
        self.add_spheres(pos, radius, m, vel=mvel, angvel=mw, gid=gids)
        self._spheres[-1]["clump"][:] = np.repeat(ids, counts)
        if breakable:
            at = np.concatenate([[0], np.cumsum(counts)[:-1]])
            g1 = np.concatenate([gids[a + i] for a, (_, _, (i, _)) in zip(at, sets)])
            g2 = np.concatenate([gids[a + j] for a, (_, _, (_, j)) in zip(at, sets)])
            self.add_bonds(np.stack([g1, g2], axis=1), stress_free=stress_free)
        else:
            self._clumps.append((clumps, mem))
        self._clump_ids.extend(int(c) for c in ids)
        return ids

    def add_bonds(self, pairs, *, stress_free=True):
        """Bond pairs of existing spheres, given by gid (``pairs`` [m, 2]); each pair must overlap
        or touch when the scene is built (the bonds are made then, with the scene's law with
        bonds: cohesive). ``stress_free``: as in `add_clumps`."""
        a = np.asarray(pairs)
        if a.ndim != 2 or a.shape[1] != 2 or (a.size and a.dtype.kind not in "iu"):
            raise InputError(f"bonds: must be pairs of sphere gids [[gid1, gid2], ...], got {_short(pairs)}")
        a = a.astype(np.int64)
        if np.any(a[:, 0] == a[:, 1]):
            raise InputError(f"bonds: a sphere cannot be bonded to itself (gid {int(a[a[:, 0] == a[:, 1]][0, 0])})")
        self._bonds.append((a.min(axis=1), a.max(axis=1), boolean("bonds.stress_free", stress_free)))

    def add_clump(self, member_pos, member_radius, material, **kw):
        """Add one rigid clump (see `add_clumps`); returns its id."""
        kw.setdefault("label", f"clumps[{len(self._clump_ids)}]")
        return int(self.add_clumps([(member_pos, member_radius)], material, **kw)[0])

    def add_breakable_clump(self, member_pos, member_radius, material, **kw):
        """Add one breakable clump (bonded spheres, see `add_clumps`); returns its id."""
        kw.setdefault("label", f"clumps[{len(self._clump_ids)}]")
        return int(self.add_clumps([(member_pos, member_radius)], material, breakable=True, **kw)[0])

    def add_clump_tables(self, clumps, members):
        """Add rigid clumps given as tables (``clumps`` and ``clump_members`` of a checkpoint,
        `pdem.io.checkpoint_state`), keeping their ids and state; their member spheres are added
        with `add_sphere_columns`. Used between the stages of a multi-stage scene."""
        clumps = {k: np.asarray(v).copy() for k, v in clumps.items()}
        members = {k: np.asarray(v).copy() for k, v in members.items()}
        if len(clumps["id"]):
            self._clumps.append((clumps, members))
            self._clump_ids.extend(int(c) for c in clumps["id"])

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
                direction=(0.0, 0.0, -1.0), velocity=(0.0, 0.0, 0.0), damping=0.0, name="", members=None,
                member_radius=None, inertia=None, load_point=(0.0, 0.0, 0.0)):
        """Add a rigid box (sleeper, platen): one body of `mass` [kg] spanning
        ``center ± half_extents`` [m]; returns its index.

        `fixed` blocks every DOF (the box still moves with `velocity` [m/s]); `blocked` is a
        string of blocked DOFs from "xyzXYZ" (default "XYZ": free translations, the box stays
        axis-aligned); a box without some of X, Y, Z turns about those global axes (e.g. "xyXZ": z
        and the tilt about y), with principal `inertia` [kg·m²] (default the solid cuboid; 3 moments
        or a symmetric positive definite 3×3 tensor in the box's axes) and its load applied at
        `load_point` (box axes, from the centre [m]): `pdem.bodies.boxes`. `load` is a
        `pdem.boundaries.loads` program (e.g. `Haversine`) whose magnitude [N] pushes along
        `direction` (default −z); `damping` is the box's own Cundall λ_D (default 0: the box is not
        damped). `members` [k, 3] (centres relative to `center`
        [m]) of spheres of `member_radius` [m] of the box's material replace its flat faces: the
        thesis's clump sleeper (`pdem.bodies.boxes.BoxMembers`; such a box cannot rotate)."""
        label = f"boxes.{name}" if name else f"boxes[{len(self.boxes)}]"
        m = self._material_index(f"{label}.material", material)
        return self.boxes.add(center, half_extents, m, mass, blocked=blocked, fixed=fixed, load=load,
                              direction=direction, velocity=velocity, damping=damping, name=name, members=members,
                              member_radius=member_radius, inertia=inertia, load_point=load_point)

    def add_motion(self, target, name, program, direction=(0.0, 0.0, -1.0), *, label="motion"):
        """Displacement or velocity control (`pdem.boundaries.loads.Motion`) of the box or wall
        ``name`` (``target`` "box" or "wall") along ``direction``: each step the body gets the
        velocity that follows the program (`Simulation.apply_motions`). A box must have the
        translations along ``direction`` blocked (the program, not the forces, moves it); a wall
        moves along its own axis only."""
        from ..boundaries.loads import Motion

        if not isinstance(program, Motion):
            raise InputError(f"{label}: must be a pdem.boundaries.loads.Motion, got {type(program).__name__}")
        d = vectors(f"{label}.direction", direction, 1)[0]
        norm = float(np.sqrt(d @ d))
        if not norm > 0.0:
            raise InputError(f"{label}.direction = {d.tolist()}: must be a non-zero vector")
        d = d / norm
        if target == "box":
            b = self.boxes.index(name)
            free = [c for c in range(3) if d[c] != 0.0 and not self.boxes.blocked[b] & (1 << c)]
            if free:
                raise InputError(f"{label}.direction = {d.tolist()}: box {self.boxes.names[b]!r} is free along "
                                 f"{'xyz'[free[0]]}; displacement control needs that translation blocked "
                                 f"(blocked containing {'xyz'[free[0]]!r}, or fixed = true)")
        elif target == "wall":
            if name not in self.walls.names:
                raise InputError(f"{label}.wall = {name!r}: unknown; defined: {', '.join(self.walls.names) or 'none'}")
            b = self.walls.names.index(name)
            axis = int(self.walls.axis[b])
            if any(d[c] != 0.0 for c in range(3) if c != axis):
                raise InputError(f"{label}.direction = {d.tolist()}: wall {name!r} moves along its axis "
                                 f"{'xyz'[axis]} only")
        else:
            raise InputError(f"{label}: target {target!r} must be 'box' or 'wall'")
        self.motions.append((target, b, program, d))
        return len(self.motions) - 1

    # ------------------------------------------------------------------ build
    def spheres(self):
        """All declared spheres as one dict of columns (see `pdem.bodies.state.FIELDS`)."""
        if not self._spheres:
            raise InputError("spheres: the scene has no spheres")
        return {k: np.concatenate([s[k] for s in self._spheres]) for k in FIELDS}

    def spec(self):
        """JSON-able description of the scene (settings, materials, walls, facets, boxes if any; not
        the spheres)."""
        out = {
            "settings": self.settings.as_dict(),
            "materials": self.materials.spec(),
            "walls": [dict(axis=int(a), position=float(p), sense=int(s), velocity=v.tolist(), material=int(m))
                      for a, p, s, v, m in zip(self.walls.axis, self.walls.position, self.walls.sense,
                                               self.walls.velocity, self.walls.material)],
            "facets": [dict(vertices=v.tolist(), velocity=u.tolist(), material=int(m))
                       for v, u, m in zip(self.facets.vertices, self.facets.velocity, self.facets.material)],
        }
        if len(self.boxes):
            out["boxes"] = self.boxes.spec()
        if self.motions:
            out["motions"] = [dict(target=t, index=int(i), direction=d.tolist(), **m.spec())
                              for t, i, m, d in self.motions]
        return out

    def _check_initial_overlaps(self, cols):
        from ..contact.neighbors import build_sphere_pairs

        pos, r, gid, cl = cols["pos"], cols["radius"], cols["gid"], cols["clump"]
        n = len(gid)
        pi_, pj = build_sphere_pairs(pos, r, gid, n, n, 0.0, 2.0 * r.max(), 8 * n + 1000)
        same = (cl[pi_] >= 0) & (cl[pi_] == cl[pj])  # members of one clump overlap by design
        pi_, pj = pi_[~same], pj[~same]
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
        from ..contact.neighbors import build_sphere_pairs

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
        """Create the `Simulation` on ``comm``'s ranks: a pdem communicator or an mpi4py one (e.g.
        ``MPI.COMM_WORLD``); by default `pdem.parallel.get_comm` (every rank of an mpiexec launch,
        else one)."""
        if len(self.materials) == 0:
            raise InputError("materials: the scene defines no material")
        cols = self.spheres()
        clumps, members = self.clump_tables()
        if clumps is not None:
            try:
                check_tables(cols, clumps, members)
            except ValueError as exc:
                raise InputError(f"clumps: {exc}") from None
        if not self.settings.allow_initial_overlap:
            self._check_initial_overlaps(cols)
        else:
            self._check_coincident_centres(cols)
        s = self.settings
        skin = s.skin if s.skin is not None else 0.25 * float(np.mean(cols["radius"]))
        bonds = self._bond_rows(cols, skin) if self._bonds else None
        if s.periodic is not None:
            self._check_periodic(cols, clumps, skin)
        if domain is None:
            from ..parallel.comm import get_comm

            comm = get_comm(comm)
            if s.periodic is not None:  # the slabs closed into a ring, on any rank count
                from ..parallel.periodic_domain import PeriodicSlabDomain

                domain = PeriodicSlabDomain(comm, s.slab_axis, *s.periodic)
                domain.check_rank_count(cols, skin)
            elif comm.size == 1:
                domain = SerialDomain(comm)
            else:
                from ..parallel.slab_domain import SlabDomain

                domain = SlabDomain(comm, axis=s.slab_axis)
                domain.check_rank_count(cols, skin)
        particles = Particles(len(cols["gid"]) if domain.comm.size == 1 else 16)
        rigid = None
        if clumps is None:
            domain.distribute(particles, cols)
        else:
            domain.distribute(particles, cols, owner_positions(cols, clumps, members))
            rigid = Clumps(extent_of(members))
            rigid.set_rows(clumps, members)
            rigid.keep(domain.owns(rigid.pos))
        guard = Guard.for_scene(self.walls, cols["pos"], s.domain)
        sim = Simulation(
            particles=particles,
            materials=self.materials,
            walls=self.walls,
            facets=self.facets,
            boxes=copy.deepcopy(self.boxes),
            settings=s,
            skin=skin,
            domain=domain,
            spec=json.loads(json.dumps(self.spec())),
            guard=guard,
            clumps=rigid,
            bonds=bonds,
            motions=list(self.motions),
        )
        if not s.allow_initial_overlap:
            check_initial_overlaps(sim)
        return sim

    def _check_periodic(self, cols, clumps, skin):
        """One-line InputError for what periodic ends do not support or what contradicts them."""
        s = self.settings
        lo, hi = s.periodic
        a = s.slab_axis
        ax = "xyz"[a]
        head = f"simulation.periodic = [{lo:g}, {hi:g}]"
        halo = 2.0 * float(np.max(cols["radius"])) + float(skin) if len(cols["radius"]) else 0.0
        if not hi - lo > 2.0 * halo:
            raise InputError(f"{head}: the period {hi - lo:.4g} m must be longer than two halos (2 x (2 r_max + skin) "
                             f"= {2.0 * halo:.4g} m) for minimum-image contacts across the ends")
        if clumps is not None or self._bonds:
            raise InputError(f"{head}: clumps (rigid or breakable) are not supported with periodic ends; "
                             "use spheres")
        if getattr(self.law, "CONTACT_POINT_LEVER", False):
            raise InputError(f"{head}: the contact law {self.law.NAME!r} (torque lever from the contact point) is "
                             "not supported with periodic ends; use linear, hertz_mindlin or viscous")
        for k, w_axis in enumerate(self.walls.axis):
            if int(w_axis) == a:
                raise InputError(f"walls[{k}]: a wall perpendicular to {ax} (at {float(self.walls.position[k]):g} m) "
                                 f"and {head} along {ax}: periodic ends have no end walls; remove one of them")

        def crosses(what, k, x0, x1):
            """Boundaries are not imaged: one within a halo of an end must cover the whole period."""
            if (x0 - halo < lo or x1 + halo > hi) and not (x0 <= lo and x1 >= hi):
                raise InputError(f"{what}[{k}]: spans [{x0:g}, {x1:g}] m along {ax}, within a halo ({halo:.4g} m) of "
                                 f"an end of {head} without covering the whole period (not supported: keep it a "
                                 "halo inside or extend it over the period)")

        for k, v in enumerate(self.facets.vertices):
            crosses("facets", k, float(v[:, a].min()), float(v[:, a].max()))
        b = self.boxes
        if len(b):
            reach = np.einsum("bak,bk->ba", np.abs(b.rotation), b.half)  # half extent of the global bounding box
            for k in range(len(b)):
                crosses("boxes", k, float(b.center[k, a] - reach[k, a]), float(b.center[k, a] + reach[k, a]))
        x = np.asarray(cols["pos"])[:, a]
        out = np.flatnonzero((x < lo) | (x >= hi))
        if len(out):
            k = int(out[0])
            raise InputError(f"spheres: gid {int(cols['gid'][k])} at {ax} = {x[k]:g} m lies outside {head} "
                             "(bodies start inside [lo, hi))")
        if not s.allow_initial_overlap:  # the pairs across the ends: the bodies near lo one period up
            near = np.flatnonzero(x - lo <= halo)
            if len(near):
                img = {k: np.concatenate([v, v[near]]) for k, v in cols.items() if k in ("pos", "radius", "gid")}
                img["pos"][len(x):, a] += hi - lo
                img["clump"] = np.full(len(img["gid"]), -1, np.int64)
                self._check_initial_overlaps(img)
        if s.domain is not None and (s.domain[0][a] > lo or s.domain[1][a] < hi):
            raise InputError(f"simulation.domain = {[list(c) for c in s.domain]}: must contain {head} along {ax} "
                             "(bodies wrap at the ends, they never leave)")

    def clump_tables(self):
        """(clumps, clump_members): the declared rigid clumps as global tables, or (None, None)."""
        if not self._clumps:
            return None, None
        clumps = {k: np.concatenate([c[k] for c, _ in self._clumps]) for k in self._clumps[0][0]}
        members = {k: np.concatenate([m[k] for _, m in self._clumps]) for k in self._clumps[0][1]}
        return clumps, members

    def _bond_rows(self, cols, skin):
        """(key, params, history) of the bonds of the breakable clumps, made now."""
        law = self.law
        if not hasattr(law, "bond_rows"):
            raise InputError(f"simulation.law = {law.NAME!r}: breakable clumps need a contact law with bonds "
                             "(law = 'cohesive')")
        props = self.materials.props()
        gid = cols["gid"]
        order = np.argsort(gid, kind="stable")

        def row_of(g):
            return order[np.searchsorted(gid[order], g)]

        parts = []
        for g1, g2, stress_free in self._bonds:
            both = np.concatenate([g1, g2])
            at = np.minimum(np.searchsorted(gid[order], both), len(gid) - 1)
            if np.any(gid[order][at] != both):
                raise InputError(f"bonds: gid {int(both[gid[order][at] != both][0])} is not a sphere of the scene")
            check_bond_strengths(law, props, self.material_names, np.unique(cols["material"][row_of(both)]))
            part = bonded_rows(law, props, cols["pos"], cols["radius"], cols["material"], g1, g2, row_of,
                               stress_free)
            reach = cols["radius"][row_of(g1)] + cols["radius"][row_of(g2)]
            apart = part[3] < -TOUCH * reach
            if np.any(apart):
                k = int(np.flatnonzero(apart)[0])
                raise InputError(f"bonds: spheres gid {int(g1[k])} and {int(g2[k])} are {-part[3][k]:.4g} m apart; "
                                 "a bond needs them to overlap or touch")
            parts.append(part)
        key, params, history = (np.concatenate([p[k] for p in parts]) for k in range(3))
        stretch = law.max_stretch(params, history)
        if len(stretch) and stretch.max() >= skin:
            k = int(np.argmax(stretch))
            raise InputError(
                f"simulation.skin = {skin:.4g} m: the bond between spheres gid {int(key[k] >> 32)} and "
                f"{int(key[k] & 0xFFFFFFFF)} stretches up to {stretch[k]:.4g} m before it breaks, more than "
                "the skin (it would leave the neighbour list); set a larger skin"
            )
        return key, params, history


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
    """float64 [n] from one number or n numbers (each checked as `validate.number` checks one)."""
    a = numbers(label, value)
    if len(a) not in (1, n):
        raise InputError(f"{label} = {_short(value)}: must be one number or {n} numbers, got {len(a)}")
    return np.broadcast_to(a, (n,)).copy()


def _rows3(value, n):
    a = np.asarray(value, dtype=object)
    return np.broadcast_to(value, (n, 3)) if a.shape == (3,) else value


def _short(value, limit=60):
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
