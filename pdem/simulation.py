"""The step loop (Yade's engine order) and everything a running simulation owns.

One step: (rebuild neighbours and ghosts if some body moved more than skin/2) → contact forces of
every contact kind the scene has (`Simulation.kinds`: sphere pairs, then walls, facets, boxes;
loops generated from the geometry and the scene's law, `pdem.contact`) → sums per body in a
fixed order (`pdem.contact.forces`; rigid clumps then sum their members', `pdem.bodies.clumps`) → leapfrog
(damped only if the scene asks; clumps by Yade's aspherical integrator, which places their
members) → move walls, facets and boxes → ghost update. Δt is fixed or re-estimated every
`dt_interval` steps (`pdem.timestep`); every `check_interval` steps the state is checked for
blow-up (`pdem.checks.diagnostics`), and every step for runaway bodies and overlaps (`pdem.checks.guard`,
folded into the rebuild test). Global
reductions go through the domain's communicator (exact sums, so they do not depend on the rank
count). Checkpoint tables: `pdem.io.checkpoint_state`.

Read API (owned bodies of this rank; every method is local unless it says collective):
`bodies()`, `body(gid)`, `clumps_table()`, `contacts()`, `wall_index(name)`, `facet_index(name)`,
`box_index(name)`.
"""
import time as _time

import numpy as np

from .io import checkpoint_state
from .checks import diagnostics
from . import integrator, timestep
from .contact import neighbors
from .bodies.clumps import Clumps
from .contact import get_law
from .contact.kinds import box_kinds, make_kinds
from .errors import InputError
from .checks.guard import Guard
from .bodies.state import DOF_ALL, FIELDS

TIMERS = ("neighbours", "contacts", "integration", "communication", "output", "other")


class Timers:
    def __init__(self):
        self.seconds = dict.fromkeys(TIMERS, 0.0)

    def add(self, name, t0):
        t1 = _time.perf_counter()
        self.seconds[name] += t1 - t0
        return t1

    def table(self):
        """LAMMPS-like breakdown of the wall time [s] spent in each part of the loop."""
        total = sum(self.seconds.values())
        lines = ["Section       |  time [s] |  %total", "--------------+-----------+---------"]
        for k, v in self.seconds.items():
            lines.append(f"{k:<14}| {v:9.3f} | {100 * v / total if total else 0:7.2f}")
        return "\n".join(lines)


class Simulation:
    """Built by `pdem.build.scene.Scene.build`; run with `run(n_steps)`."""

    def __init__(self, *, particles, materials, walls, facets, boxes, settings, skin, domain, spec, guard=None,
                 clumps=None, bonds=None, motions=None):
        self.settings = settings  # `pdem.settings.SimulationSettings`, as the scene made them
        self.particles = particles
        self.law = get_law(settings.law)
        self.materials = materials
        self.props = materials.props()  # law properties per material (the Ip2 inputs)
        self.walls = walls
        self.facets = facets
        # rigid boxes (pdem.bodies.boxes): replicated, integrated from the exact global sum of their contacts
        self.boxes = boxes if len(boxes) else None
        # the state a stage may change (shaking, settling, a sleeper pressed in): starts as set
        self.gravity = np.asarray(settings.gravity, np.float64)
        self.damping = float(settings.damping)
        self.max_overlap_ratio = settings.max_overlap_ratio
        self.skin = skin  # [m]: the setting, or a quarter of the mean radius
        self.domain = domain
        self.comm = domain.comm
        self.spec = spec
        self.guard = Guard() if guard is None else guard
        self.step = 0
        self.time = 0.0
        self.dt = 0.0
        self.n_rebuilds = 0
        self.boundary_moved = 0.0
        self.timers = Timers()
        self.energy_reference = None
        self.last_dt = None  # Δt of the last step taken (sim.dt may already be the next one's) [s]
        self.kinds = make_kinds(self.law, walls, facets, boxes, periodic=settings.periodic is not None)
        self.box_kinds = box_kinds(self.kinds)  # the kinds whose forces act on the boxes
        # rigid clumps owned here (pdem.bodies.clumps), None in a scene without clumps
        self.clumps = clumps
        if clumps is not None:
            clumps.attach(particles)
        if bonds is not None:  # bonds of breakable clumps (pdem.bodies.bonds): contacts made before the first step
            key, params, history = bonds
            self.kind("sphere_sphere").contacts.add_carried(key, np.ones(len(key), np.int8), params, history)
        # displacement control of boxes and walls (`pdem.boundaries.loads.Motion`, `apply_motions`)
        self.motions = motions or []
        # a box's load and weight do external work; the flag must be the same on every rank
        self.moving_boundaries = bool(self.comm.any_flag(bool(
            (len(walls) and np.any(walls.velocity)) or (len(facets) and np.any(facets.velocity))
            or np.any(particles.vel[: particles.n_local][particles.blocked[: particles.n_local] == DOF_ALL])
            or self.boxes is not None or bool(self.motions))))
        self.rebuild()
        self.update_dt(force=True)

    def kind(self, name):
        """The contact kind called ``name`` ("sphere_sphere", "sphere_wall", ...) or None."""
        for k in self.kinds:
            if k.name == name:
                return k
        return None

    # ------------------------------------------------------------------ neighbours
    def rebuild(self):
        p = self.particles
        t0 = _time.perf_counter()
        self.domain.rebuild(self)
        t0 = self.timers.add("communication", t0)
        r_max = self.comm.allreduce_max(float(p.radius[: p.n_total].max()) if p.n_total else 0.0)
        cell = 2.0 * r_max + self.skin
        # owned rows into cell order (cache locality); rows are storage only, results go by gid
        order = neighbors.cell_order(p.pos, p.n_local, cell, 8 * p.n_local + 1000)
        p.permute_local(order)
        self.domain.renumber_owned(order)
        if self.clumps is not None:
            self.clumps.attach(p)
        for kind in self.kinds:
            kind.rebuild(self, cell)
        p.pos_at_rebuild[: p.n_total] = p.pos[: p.n_total]
        self.boundary_moved = 0.0
        self.n_rebuilds += 1
        self.timers.add("neighbours", t0)

    def _needs_rebuild(self):
        """The rebuild test (some body moved more than skin/2), with the runaway guard's step
        displacement and overlap in the same reduction (`pdem.checks.guard.Guard.check_step`)."""
        p = self.particles
        moved, rate = neighbors.max_motion(p.pos, p.pos_at_rebuild, p.vel, p.radius, p.n_local)
        overlap = max(kind.worst_overlap for kind in self.kinds)
        g = self.comm.allreduce_max(np.array([moved + self.boundary_moved, rate * self.dt, overlap]))
        self.guard.check_step(self, g[1], g[2])
        return g[0] > 0.5 * self.skin

    def update_dt(self, force=False):
        timestep.update_dt(self, force)

    # ------------------------------------------------------------------ one step
    def compute_forces(self):
        for kind in self.kinds:
            kind.compute(self)
        for kind in self.kinds:  # the first (sphere pairs) sets the sums, the others add
            kind.add_forces(self)
        if self.boxes is not None:
            self.boxes.contact_force = self.box_contact_force()
            oriented = self.kind("sphere_oriented_box")
            if oriented is not None:  # boxes with free rotations (pdem.bodies.boxes)
                self.boxes.contact_torque = oriented.torques(self)
        if self.clumps is not None:
            self.clumps.sum_forces(self.particles)

    def box_contact_force(self):
        """[n_boxes, 3] force of the spheres on each rigid box [N] (collective, the same bits on every
        rank): on its flat faces or on its member spheres (a box has one or the other)."""
        total = None
        for kind in self.box_kinds:
            t = kind.totals(self.comm)
            total = t if total is None else total + t
        return total

    def integrate(self):
        p = self.particles
        if self.damping > 0.0:
            integrator.leapfrog_cundall(p.n_local, p.pos, p.vel, p.angvel, p.force, p.torque, p.mass, p.inertia,
                                        p.blocked, self.gravity, self.damping, self.dt)
        else:
            integrator.leapfrog(p.n_local, p.pos, p.vel, p.angvel, p.force, p.torque, p.mass, p.inertia, p.blocked,
                                self.gravity, self.dt)
        if self.clumps is not None:  # moves the clumps and overwrites their members' rows
            self.clumps.integrate(p, self.gravity, self.damping, self.dt)
        if self.motions:
            self.apply_motions()
        if len(self.walls) and self.walls.velocity.any():  # (a wall at rest stays: x + 0·Δt = x)
            before = self.walls.position.copy()
            self.walls.move(self.dt)
            self.boundary_moved += float(np.max(np.abs(self.walls.position - before)))
        if len(self.facets) and np.any(self.facets.velocity):
            self.facets.move(self.dt)
            self.boundary_moved += float(np.max(np.linalg.norm(self.facets.velocity, axis=1))) * self.dt
        if self.boxes is not None:  # after the spheres, from the force summed in compute_forces
            self.boundary_moved += self.boxes.integrate(self.time, self.dt, self.gravity)

    def apply_motions(self):
        """The velocity of this step (t to t + Δt) of every displacement-controlled box and wall:
        (u(t + Δt) − u(t))/Δt along its direction (`pdem.boundaries.loads.Motion`), on its
        controlled components only (a box's blocked translations; a wall's axis)."""
        for target, b, program, d in self.motions:
            v = program.step_velocity(self.time, self.dt)
            rows = self.boxes.velocity if target == "box" else self.walls.velocity
            for c in range(3):
                if d[c] != 0.0:
                    rows[b, c] = v * d[c]

    def advance(self):
        """One time step."""
        timers = self.timers
        t0 = _time.perf_counter()
        if self._needs_rebuild():
            t0 = timers.add("other", t0)
            self.rebuild()
            t0 = _time.perf_counter()
        self.compute_forces()
        t0 = timers.add("contacts", t0)
        self.integrate()
        self.step += 1
        self.time += self.dt
        self.last_dt = self.dt
        t0 = timers.add("integration", t0)
        self.domain.update_ghosts(self.particles)
        t0 = timers.add("communication", t0)
        if self.step % self.settings.check_interval == 0:
            diagnostics.check_stability(self)
        self.update_dt()
        timers.add("other", t0)

    def run(self, n_steps, callback=None, every=0):
        """Advance `n_steps`; call `callback(sim)` every `every` steps (and after the last)."""
        for _ in range(int(n_steps)):
            self.advance()
            if callback is not None and every and self.step % every == 0:
                t0 = _time.perf_counter()
                callback(self)
                self.timers.add("output", t0)
        return self

    # ------------------------------------------------------------------ diagnostics
    def contacts_per_particle(self):
        return diagnostics.contacts_per_particle(self)

    def memory_bytes(self):
        """Bytes held by this rank's per-body arrays, contact rows and incidence lists [B]."""
        p = self.particles
        return p.bytes_per_particle() * p.n_total + sum(k.bytes() for k in self.kinds)

    def energy(self):
        return diagnostics.energy(self)

    def check_stability(self):
        diagnostics.check_stability(self)

    def timing_table(self):
        return self.timers.table()

    # ------------------------------------------------------------------ read API
    def bodies(self):
        """FIELDS columns (plus force and torque of the last step) of this rank's owned bodies,
        sorted by gid: the same rows whatever the rank count or the rebuilds (collect the ranks'
        tables for all bodies)."""
        p = self.particles
        order = np.argsort(p.gid[: p.n_local], kind="stable")
        cols = {k: getattr(p, k)[: p.n_local][order].copy() for k in (*FIELDS, "force", "torque")}
        return cols

    def clumps_table(self):
        """The rigid clumps owned by this rank, sorted by id: ``id``, ``pos`` [m], ``vel`` [m/s],
        ``angvel`` [rad/s], ``angmom`` [kg·m²/s], ``ori`` (w, x, y, z), ``mass`` [kg],
        ``inertia`` (principal) [kg·m²], ``aspherical``, ``force`` and ``torque`` (summed over
        the members in the last step, before damping) [N], [N·m]; empty without clumps."""
        c = self.clumps if self.clumps is not None else Clumps(0.0)
        out, _ = c.table()
        out.update(force=c.force.copy(), torque=c.torque.copy())
        return out

    def body(self, gid):
        """State of the owned body ``gid`` as a dict of values, or None if this rank does not own it."""
        p = self.particles
        rows = np.flatnonzero(p.gid[: p.n_local] == gid)
        if not len(rows):
            return None
        return {k: getattr(p, k)[rows[0]].copy() for k in (*FIELDS, "force", "torque")}

    def contacts(self, kind="sphere_sphere"):
        """Real contacts of one kind held for this rank's owned bodies, sorted by their key:
        ``gid1``/``gid2`` (sphere pairs, gid1 < gid2) or ``gid1``/``index`` (boundaries: the sphere
        and the wall, facet or box index), ``normal_force`` and ``shear_force`` [N] (Yade's
        normalForce and shearForce: the law's normal part kn·pen·n and the stored shear force),
        ``force`` [N] (total force on body 2: the second sphere, or the sphere of a boundary
        contact), ``overlap`` [m], ``normal``, ``kn`` and ``ks`` [N/m], the law's parameters by
        name (``tan_phi`` for the linear law) and ``created`` (the step at which the contact
        was made). Contacts straddling a slab edge appear on both ranks; collect by key."""
        k = self.kind(kind)
        if k is None:
            raise KeyError(f"the scene has no {kind} contacts; it has {', '.join(x.name for x in self.kinds)}")
        c, p, law = k.contacts, self.particles, self.law
        rows = k.owned_rows(p.n_local)
        rows = rows[np.argsort(c.key[rows], kind="stable")]
        params, history, overlap = c.params[rows], c.history[rows], c.overlap[rows]
        normal = history[:, k.normal_column: k.normal_column + 3].copy()
        kn, ks = law.stiffness(params, history, overlap)
        fn, fs = law.contact_forces(params, history, overlap, normal)
        out = {"gid1": p.gid[c.i[rows]].copy(), "overlap": overlap, "normal": normal, "normal_force": fn,
               "shear_force": fs, "kn": np.array(kn, float), "ks": np.array(ks, float),
               "created": params[:, law.N_PARAMS].astype(np.int64)}
        if k.sphere_pair:
            out["gid2"] = p.gid[c.j[rows]].copy()
            out["force"] = -k.row_force(rows)
        else:
            out["index"] = c.j[rows].astype(np.int64)
            out["force"] = k.row_force(rows).copy()
        for name, col in law.PARAM_NAMES.items():
            out.setdefault(name, params[:, col].copy())
        for name, col in getattr(law, "HISTORY_NAMES", {}).items():
            out.setdefault(name, history[:, col].copy())
        return out

    def wall_index(self, name):
        return _index(self.walls.names, name, "wall")

    def facet_index(self, name):
        return _index(self.facets.names, name, "facet")

    def box_index(self, name):
        return _index(self.boxes.names if self.boxes is not None else [], name, "box")

    # ------------------------------------------------------------------ restart, stages
    def checkpoint_tables(self):
        return checkpoint_state.checkpoint_tables(self)

    def restore_checkpoint(self, tables, meta):
        return checkpoint_state.restore_checkpoint(self, tables, meta)

    def load_state(self, tables):
        return checkpoint_state.load_state(self, tables)

    def set_friction_scale(self, factor, existing=True):
        """The law's friction key of every material (and material pair) times ``factor`` [-] (the
        linear law's friction angle, the other laws' μ), for new contacts and, if ``existing``,
        (Ip2 again for the friction) for the existing ones: the vibration stage of the thesis
        (4.2) lowers friction tenfold and restores it with factor 1. ``existing=False`` is what
        Yade does when a material's friction is changed: Ip2 runs once at contact creation, so
        the existing contacts keep their tan φ until they open (YADE_MODEL.md)."""
        law = self.law
        self.props = self.materials.props(scale={law.FRICTION_KEY: factor})
        if not existing:
            return
        p = self.particles
        for kind in self.kinds:
            c = kind.contacts
            if c.n == 0:
                continue
            mi = p.material[c.i[: c.n]]
            mj = p.material[c.j[: c.n]] if kind.boundary is None else kind.boundary.material[c.j[: c.n]]
            law.set_friction(c.n, mi, mj, self.props, c.params)

    def scale_bond_strength(self, factor):
        """The normal and shear strengths (a_N, a_T) of every bond held on this rank times
        ``factor`` [-] (laws with bonds, `pdem.contact.cohesive.scale_bonds`): thesis 4.5 raises
        them tenfold while its grains shed their initial overlaps and then returns them."""
        scale = getattr(self.law, "scale_bonds", None)
        if scale is None:
            raise InputError(f"bond strength scaled by {factor!r}: the law {self.law.NAME!r} has no bonds "
                             "(simulation.law = \"cohesive\" has)")
        for kind in self.kinds:
            if kind.sphere_pair:
                scale(kind.contacts.n, kind.contacts.history, factor)

    def set_stiffness_scale(self, factor, rescale_existing=None):
        """The law's stiffness keys (`STIFFNESS_KEYS`) of every material times ``factor`` [-] for
        new contacts and, with ``rescale_existing``, the stiffness parameters (`STIFFNESS_PARAMS`)
        of the existing contacts times that [-] (their tangential force stays): the stiffening
        stage of the box test (`pdem.scenes.box_test`). Replaces a friction scale."""
        law = self.law
        self.props = self.materials.props(scale={k: factor for k in law.STIFFNESS_KEYS})
        if rescale_existing is None:
            return
        for kind in self.kinds:
            c = kind.contacts
            if c.n:
                c.params[: c.n, law.STIFFNESS_PARAMS] *= rescale_existing


def _index(names, name, what):
    if name not in names:
        raise KeyError(f"no {what} called {name!r}; the scene's {what}s: {', '.join(names) or 'none'}")
    return names.index(name)
