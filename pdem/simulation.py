"""The step loop (Yade's engine order) and everything a running simulation owns.

One step: (rebuild neighbours and ghosts if some body moved more than skin/2) → contact forces
per candidate pair (sphere–sphere, then walls, then facets: only the kinds the scene has) → sums
per body in a fixed order (`pdem.forces`) → leapfrog (damped only if the scene asks) → move
walls and facets → ghost update. Δt is fixed or re-estimated every `dt_interval` steps
(`pdem.timestep`); every `check_interval` steps the state is checked for blow-up (NaN,
overlap beyond a fraction of a radius, growth of the mechanical energy) and the run stops with
`InstabilityError` naming the cause. Global reductions go through the domain's communicator
(exact sums, so they do not depend on the rank count).
"""
import time as _time

import numpy as np

from . import forces, integrator, neighbors, timestep
from .contact import linear
from .contacts import KEY_SHIFT_SPHERE, ContactList, index_pair_keys, sphere_pair_keys
from .errors import InstabilityError

TIMERS = ("neighbours", "contacts", "integration", "communication", "output", "other")


class Timers:
    def __init__(self):
        self.seconds = dict.fromkeys(TIMERS, 0.0)

    def add(self, name, t0):
        t1 = _time.perf_counter()
        self.seconds[name] += t1 - t0
        return t1


class Simulation:
    """Built by `pdem.scene.Scene.build`; run with `run(n_steps)`."""

    def __init__(self, *, particles, materials, walls, facets, gravity, damping, dt, dt_safety, dt_interval,
                 pwave_factor, skin, check_interval, max_overlap_ratio, energy_check, domain, spec, boxes=None):
        self.particles = particles
        self.materials = materials
        self.young, self.poisson, self.friction, self.density = materials.arrays()
        self.walls = walls
        self.facets = facets
        self.gravity = np.asarray(gravity, np.float64)
        self.damping = float(damping)
        self.fixed_dt = dt
        self.dt_safety = dt_safety
        self.dt_interval = dt_interval
        self.pwave_factor = pwave_factor
        self.skin = skin
        self.check_interval = check_interval
        self.max_overlap_ratio = max_overlap_ratio
        self.energy_check = energy_check
        self.domain = domain
        self.comm = domain.comm
        self.spec = spec
        self.law = linear
        self.step = 0
        self.time = 0.0
        self.dt = 0.0
        self.n_rebuilds = 0
        self.boundary_moved = 0.0
        self.timers = Timers()
        self.energy_reference = None
        self.ss = ContactList(linear.N_PARAMS, linear.HISTORY_WIDTH)
        self.sw = ContactList(linear.N_PARAMS, linear.HISTORY_WIDTH) if len(walls) else None
        self.sf = ContactList(linear.N_PARAMS, linear.HISTORY_WIDTH) if len(facets) else None
        # rigid boxes (pdem.boxes): replicated, integrated from the exact global sum of their contacts
        self.boxes = boxes if boxes is not None and len(boxes) else None
        self.sb = ContactList(linear.N_PARAMS, linear.HISTORY_WIDTH) if self.boxes is not None else None
        # a box's load and weight do external work; the flag must be the same on every rank
        self.moving_boundaries = bool(self.comm.any_flag(bool(
            (len(walls) and np.any(walls.velocity)) or (len(facets) and np.any(facets.velocity))
            or np.any(particles.vel[: particles.n_local][particles.blocked[: particles.n_local] == 63])
            or self.boxes is not None)))
        self._empty_ptr = np.zeros(1, np.int64)
        self.rebuild()
        self.update_dt(force=True)

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
        pi, pj = neighbors.build_sphere_pairs(p.pos, p.radius, p.gid, p.n_local, p.n_total, self.skin, cell,
                                              8 * p.n_total + 1000)
        self.ss.replace(pi, pj, sphere_pair_keys(pi, pj, p.gid), key_shift=KEY_SHIFT_SPHERE)
        self.inc_ptr, self.inc_pair, self.inc_first = neighbors.build_incidence(p.n_local, self.ss.n, self.ss.i, self.ss.j, p.gid)
        if self.sw is not None:
            self.w_ptr, ps, pw = neighbors.build_wall_candidates(p.pos, p.radius, p.n_local, self.skin,
                                                                 self.walls.axis, self.walls.position)
            self.sw.replace(ps, pw, index_pair_keys(ps, pw, p.gid))
        if self.sf is not None:
            self.f_ptr, ps, pf = neighbors.build_facet_candidates(p.pos, p.radius, p.n_local, self.skin,
                                                                  self.facets.geom, self.facets.vertices)
            self.sf.replace(ps, pf, index_pair_keys(ps, pf, p.gid))
        if self.sb is not None:
            self.b_ptr, ps, pb = neighbors.build_box_candidates(p.pos, p.radius, p.n_local, self.skin,
                                                                self.boxes.center, self.boxes.half)
            self.sb.replace(ps, pb, index_pair_keys(ps, pb, p.gid))
        p.pos_at_rebuild[: p.n_total] = p.pos[: p.n_total]
        self.boundary_moved = 0.0
        self.n_rebuilds += 1
        self.timers.add("neighbours", t0)

    def _needs_rebuild(self):
        p = self.particles
        moved = neighbors.max_displacement(p.pos, p.pos_at_rebuild, p.n_local) + self.boundary_moved
        return self.comm.allreduce_max(moved) > 0.5 * self.skin

    # ------------------------------------------------------------------ time step
    def update_dt(self, force=False):
        if self.fixed_dt is not None:
            self.dt = self.fixed_dt
            return
        if not force and self.step % self.dt_interval:
            return
        p = self.particles
        k_dt = timestep.stiffness_dt(p.n_local, p.mass, p.inertia, p.blocked, p.radius, self.inc_ptr, self.inc_pair,
                                     self.inc_first, self.ss.i, self.ss.j, self.ss.state, self.ss.params, self.ss.history,
                                     *self._list_args(self.sw, "w_ptr"), *self._list_args(self.sf, "f_ptr"),
                                     *self._list_args(self.sb, "b_ptr"))
        if self.boxes is not None:  # the box's own mass–spring step, from the global sum of its contacts
            k_dt = min(k_dt, timestep.box_dt(self.boxes.mass, self.boxes.blocked, self.box_stiffness()))
        k_dt = self.comm.allreduce_min(k_dt)
        pw = self.comm.allreduce_min(timestep.pwave_dt(p.n_local, p.radius, p.mass, p.material, self.young))
        # never above the P-wave step itself: a body whose few contacts allow a long step can
        # gain many more within dt_interval steps (a sphere landing on a bed)
        self.dt = min(self.dt_safety * k_dt, pw) if np.isfinite(k_dt) else self.pwave_factor * pw

    def box_stiffness(self):
        """[n_boxes] Σ (k_n + k_s) over each box's real contacts, summed exactly over all ranks [N/m]."""
        nb = len(self.boxes)
        rows = self.sb.real_rows()
        vals = np.zeros((len(rows), nb))
        vals[np.arange(len(rows)), self.sb.j[rows]] = self.sb.params[rows, 0] + self.sb.params[rows, 1]
        return np.asarray(self.comm.exact_sum_rows(vals), np.float64).reshape(nb)

    def _list_args(self, cl, ptr_name):
        if cl is None:
            z = np.zeros((0, linear.N_PARAMS))
            return (np.zeros(self.particles.n_local + 1, np.int64), np.zeros(0, np.int8), z, np.zeros((0, linear.HISTORY_WIDTH)))
        return getattr(self, ptr_name), cl.state, cl.params, cl.history

    # ------------------------------------------------------------------ one step
    def compute_forces(self):
        p = self.particles
        y, nu, phi = self.young, self.poisson, self.friction
        ss = self.ss
        linear.sphere_sphere_forces(ss.n, ss.i, ss.j, ss.state, ss.params, ss.history, ss.force, ss.torque_i, ss.torque_j,
                                    ss.overlap, p.pos, p.vel, p.angvel, p.radius, p.material, y, nu, phi, self.dt)
        if self.sw is not None:
            w, sw = self.walls, self.sw
            linear.sphere_wall_forces(sw.n, sw.i, sw.j, sw.state, sw.params, sw.history, sw.force, sw.torque_i,
                                      sw.torque_j, sw.overlap, p.pos, p.vel, p.angvel, p.radius, p.material, y, nu, phi,
                                      w.axis, w.sense, w.position, w.velocity, w.material, self.dt)
        if self.sf is not None:
            f, sf = self.facets, self.sf
            linear.sphere_facet_forces(sf.n, sf.i, sf.j, sf.state, sf.params, sf.history, sf.force, sf.torque_i,
                                       sf.torque_j, sf.overlap, p.pos, p.vel, p.angvel, p.radius, p.material, y, nu, phi,
                                       f.geom, f.velocity, f.material, self.dt)
        if self.sb is not None:
            bx, sb = self.boxes, self.sb
            linear.sphere_box_forces(sb.n, sb.i, sb.j, sb.state, sb.params, sb.history, sb.force, sb.torque_i,
                                     sb.torque_j, sb.overlap, p.pos, p.vel, p.angvel, p.radius, p.material, y, nu, phi,
                                     bx.center, bx.half, bx.velocity, bx.material, self.dt)
        forces.sum_sphere_pairs(p.n_local, self.inc_ptr, self.inc_pair, self.inc_first, ss.force, ss.torque_i,
                                ss.torque_j, p.force, p.torque)
        if self.sw is not None:
            forces.add_sphere_contacts(p.n_local, self.w_ptr, self.sw.force, self.sw.torque_i, p.force, p.torque)
        if self.sf is not None:
            forces.add_sphere_contacts(p.n_local, self.f_ptr, self.sf.force, self.sf.torque_i, p.force, p.torque)
        if self.sb is not None:
            forces.add_sphere_contacts(p.n_local, self.b_ptr, self.sb.force, self.sb.torque_i, p.force, p.torque)
            self.boxes.contact_force = self.box_contact_forces()

    def box_contact_forces(self):
        """[n_boxes, 3] total force of the spheres on each box [N]: exact sum over the contact rows
        of all ranks (each contact is held by the owner of its sphere), so every rank gets the
        same bits whatever the rank count."""
        nb = len(self.boxes)
        rows = self.sb.real_rows()
        vals = np.zeros((len(rows), 3 * nb))
        cols = 3 * self.sb.j[rows][:, None] + np.arange(3)[None, :]
        vals[np.arange(len(rows))[:, None], cols] = -self.sb.force[rows]
        return np.asarray(self.comm.exact_sum_rows(vals), np.float64).reshape(nb, 3)

    def integrate(self):
        p = self.particles
        if self.damping > 0.0:
            integrator.leapfrog_cundall(p.n_local, p.pos, p.vel, p.angvel, p.force, p.torque, p.mass, p.inertia,
                                        p.blocked, self.gravity, self.damping, self.dt)
        else:
            integrator.leapfrog(p.n_local, p.pos, p.vel, p.angvel, p.force, p.torque, p.mass, p.inertia, p.blocked,
                                self.gravity, self.dt)
        if len(self.walls):
            before = self.walls.position.copy()
            self.walls.move(self.dt)
            self.boundary_moved += float(np.max(np.abs(self.walls.position - before)))
        if len(self.facets) and np.any(self.facets.velocity):
            self.facets.move(self.dt)
            self.boundary_moved += float(np.max(np.linalg.norm(self.facets.velocity, axis=1))) * self.dt
        if self.boxes is not None:  # after the spheres, from the force summed in compute_forces
            self.boundary_moved += self.boxes.integrate(self.time, self.dt, self.gravity)

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
        t0 = timers.add("integration", t0)
        self.domain.update_ghosts(self.particles)
        t0 = timers.add("communication", t0)
        if self.step % self.check_interval == 0:
            self.check_stability()
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
        """Real contacts per owned body (sphere pairs counted for both bodies, walls/facets once)."""
        p = self.particles
        n = 0.0
        for cl in (self.ss, self.sw, self.sf, self.sb):
            if cl is None:
                continue
            rows = cl.real_rows()
            if cl is self.ss:
                n += np.count_nonzero(cl.i[rows] < p.n_local) + np.count_nonzero(cl.j[rows] < p.n_local)
            else:
                n += len(rows)
        n_tot = self.comm.allreduce_sum_int(int(n))
        bodies = self.comm.allreduce_sum_int(p.n_local)
        return n_tot / max(bodies, 1)

    def energy(self):
        """Mechanical energy [J] of the owned free bodies and the contacts, as exact global sums:
        kinetic (translation, rotation), gravitational potential −m g·x, elastic ½k_n δ² + ½|F_s|²/k_s."""
        p = self.particles
        nl = p.n_local
        free = p.blocked[:nl] != 63
        m = p.mass[:nl][free]
        v = p.vel[:nl][free]
        w = p.angvel[:nl][free]
        ke = 0.5 * m * np.einsum("ij,ij->i", v, v)
        kr = 0.5 * p.inertia[:nl][free] * np.einsum("ij,ij->i", w, w)
        # potential energy at the positions the overlaps were computed from (start of the step)
        x_start = p.pos[:nl][free] - v * self.dt
        pe = -m * (x_start @ self.gravity)
        el = []
        for cl in (self.ss, self.sw, self.sf, self.sb):
            if cl is None:
                continue
            rows = cl.real_rows()
            if cl is self.ss:
                rows = rows[cl.i[rows] < nl]
            kn, ks = cl.params[rows, 0], cl.params[rows, 1]
            fs2 = np.einsum("ij,ij->i", cl.history[rows, :3], cl.history[rows, :3])
            shear = np.divide(fs2, ks, out=np.zeros_like(fs2), where=ks > 0)
            el.append(0.5 * kn * cl.overlap[rows] ** 2 + 0.5 * shear)
        el = np.concatenate(el) if el else np.zeros(0)
        s = self.comm.exact_sum
        out = {"kinetic": s(ke), "rotational": s(kr), "potential": s(pe), "elastic": s(el)}
        out["total"] = out["kinetic"] + out["rotational"] + out["potential"] + out["elastic"]
        return out

    def max_overlap_ratio_now(self):
        """Largest overlap divided by the smaller radius of the pair, with the pair's gids."""
        p = self.particles
        worst = (0.0, -1, -1)
        for cl, kind in ((self.ss, "sphere"), (self.sw, "wall"), (self.sf, "facet"), (self.sb, "box")):
            if cl is None or cl.n == 0:
                continue
            ov = cl.overlap[: cl.n]
            if kind == "sphere":
                rmin = np.minimum(p.radius[cl.i[: cl.n]], p.radius[cl.j[: cl.n]])
            else:
                rmin = p.radius[cl.i[: cl.n]]
            ratio = ov / rmin
            k = int(np.argmax(ratio))
            if ratio[k] > worst[0]:
                other = int(p.gid[cl.j[k]]) if kind == "sphere" else f"{kind} {int(cl.j[k])}"
                worst = (float(ratio[k]), int(p.gid[cl.i[k]]), other)
        return worst

    def check_stability(self):
        """Stop with a message naming the cause if the state is not finite, an overlap exceeds
        `max_overlap_ratio` of the smaller radius, or the mechanical energy grew (no external work)."""
        p = self.particles
        nl = p.n_local
        bad = ~np.isfinite(p.pos[:nl]).all(axis=1) | ~np.isfinite(p.vel[:nl]).all(axis=1)
        first_bad = int(p.gid[:nl][bad].min()) if bad.any() else -1
        any_bad = self.comm.any_flag(bool(bad.any()))
        if any_bad:
            gid = int(-self.comm.allreduce_max(-first_bad if first_bad >= 0 else -2**62))
            raise InstabilityError(
                f"step {self.step}: non-finite position or velocity of body gid {gid} (dt = {self.dt:.3e} s): "
                "the time step is too large for the stiffness, or an input is not finite")
        ratio, gi, other = self.max_overlap_ratio_now()
        worst = self.comm.allreduce_max(ratio)
        if worst > self.max_overlap_ratio:
            where = f" between body gid {gi} and {other}" if ratio == worst else ""
            raise InstabilityError(
                f"step {self.step}: overlap {worst:.3g} of the smaller radius{where} exceeds max_overlap_ratio = "
                f"{self.max_overlap_ratio} (dt = {self.dt:.3e} s): time step too large or load too high for the stiffness")
        if self.energy_check and not self.moving_boundaries:
            e = self.energy()
            scale = e["kinetic"] + e["rotational"] + e["elastic"]
            if self.energy_reference is None:
                self.energy_reference = [e["total"], scale]
                return
            ref = self.energy_reference
            growth = e["total"] - ref[0]
            tolerance = 0.5 * ref[1] + 1e-9 * (abs(ref[0]) + abs(e["potential"]))
            if growth > tolerance:
                raise InstabilityError(
                    f"step {self.step}: mechanical energy grew by {growth:.3e} J without external work "
                    f"(kinetic+elastic {scale:.3e} J, before {ref[1]:.3e} J; dt = {self.dt:.3e} s): numerical "
                    "instability, the time step exceeds the critical value for the contact stiffness")
            ref[0] = min(ref[0], e["total"])  # dissipation lowers the reference, nothing raises it
            ref[1] = max(ref[1], scale)

    def timing_table(self):
        """LAMMPS-like breakdown of the wall time [s] spent in each part of the loop."""
        total = sum(self.timers.seconds.values())
        lines = ["Section       |  time [s] |  %total", "--------------+-----------+---------"]
        for k, v in self.timers.seconds.items():
            lines.append(f"{k:<14}| {v:9.3f} | {100 * v / total if total else 0:7.2f}")
        return "\n".join(lines)

    # ------------------------------------------------------------------ checkpoints (restart)
    # Tables for `pdem.io.checkpoint.write_checkpoint` and their inverse. Everything a step reads
    # that is not rebuilt from these is either derived (neighbour lists, ghosts, incidence) or a
    # per-step output (forces, overlaps), so a restored run continues bit for bit on any number
    # of ranks (tests/io/test_restart.py, tests/mpi/test_restart_mpi.py).
    CHECKPOINT_CONTACTS = (("ss", "contacts/sphere_sphere"), ("sw", "contacts/sphere_wall"),
                           ("sf", "contacts/sphere_facet"), ("sb", "contacts/sphere_box"))

    def checkpoint_tables(self):
        """(tables, meta) of this rank for `write_checkpoint` (collective writer; every rank calls).

        Tables: ``particles`` (FIELDS of the owned bodies, key gid), ``contacts/<kind>`` (real
        contacts only: key, params, history; a pair that straddles a slab edge is held, bit for
        bit identical, by both ranks and the writer keeps one copy), ``walls`` (index, position,
        velocity) and ``facets`` (index, geom, vertices, velocity), replicated on every rank.
        Meta: step, time, dt, the energy-check reference and the other scalars of the loop, the
        scene spec and the pdem version."""
        from . import __version__

        p = self.particles
        tables = {"particles": p.columns()}
        keys = {"particles": ["gid"]}
        for attr, name in self.CHECKPOINT_CONTACTS:
            cl = getattr(self, attr)
            if cl is None:
                continue
            rows = cl.real_rows()
            tables[name] = {"key": cl.key[rows].copy(), "params": cl.params[rows].copy(),
                            "history": cl.history[rows].copy()}
            keys[name] = ["key"]
        if len(self.walls):
            tables["walls"] = {"index": np.arange(len(self.walls), dtype=np.int64),
                               "position": self.walls.position.copy(), "velocity": self.walls.velocity.copy()}
            keys["walls"] = ["index"]
        if len(self.facets):
            tables["facets"] = {"index": np.arange(len(self.facets), dtype=np.int64), "geom": self.facets.geom.copy(),
                                "vertices": self.facets.vertices.copy(), "velocity": self.facets.velocity.copy()}
            keys["facets"] = ["index"]
        boxes = self.boxes
        if boxes is not None:  # rigid boxes (pdem.boxes): the state their step evolves
            tables["boxes"] = {"index": np.arange(len(boxes), dtype=np.int64), "center": boxes.center.copy(),
                               "velocity": boxes.velocity.copy()}
            keys["boxes"] = ["index"]
        meta = {
            "step": int(self.step),
            "time": float(self.time),
            "dt": float(self.dt),
            "n_rebuilds": int(self.n_rebuilds),
            "energy_reference": None if self.energy_reference is None else [float(x) for x in self.energy_reference],
            "moving_boundaries": self.moving_boundaries,
            "n_bodies": int(self.comm.allreduce_sum_int(p.n_local)),
            "scene": self.spec,
            "pdem_version": __version__,
            "keys": keys,
        }
        return tables, meta

    def restore_checkpoint(self, tables, meta):
        """Continue from a checkpoint (`read_checkpoint`'s tables and meta) on this communicator.

        Call on every rank right after `Scene.build` of the same scene (any rank count): the
        bodies are replaced by the checkpointed ones (distributed like at build), walls and
        facets get their position/geometry and velocity back, the real contacts are injected as
        carried rows and picked up by key at a neighbour rebuild, and step, time, Δt, the
        energy-check reference and the rebuild count are restored. Raises ValueError with one
        line if the checkpoint does not fit this simulation."""
        if meta.get("scene") != self.spec:
            raise ValueError("the checkpoint was written for a different scene (settings, materials, walls or "
                             "facets differ from the scene file)")
        cols = tables["particles"]
        if len(cols["gid"]) != int(meta.get("n_bodies", len(cols["gid"]))):
            raise ValueError(f"table particles has {len(cols['gid'])} bodies, meta says {meta.get('n_bodies')}")
        for name, n in (("walls", len(self.walls)), ("facets", len(self.facets)),
                        ("boxes", len(self.boxes) if self.boxes is not None else 0)):
            if n and (name not in tables or len(tables[name]["index"]) != n):
                raise ValueError(f"table {name}: expected {n} rows (the scene's {name})")
        for attr, name in self.CHECKPOINT_CONTACTS:
            if getattr(self, attr) is not None and name not in tables:
                raise ValueError(f"table {name} missing (the scene has contacts of that kind)")
        self.moving_boundaries = bool(meta.get("moving_boundaries", self.moving_boundaries))
        self.load_state(tables)
        self.n_rebuilds = int(meta.get("n_rebuilds", self.n_rebuilds))
        self.step = int(meta["step"])
        self.time = float(meta["time"])
        self.dt = float(meta["dt"])
        ref = meta.get("energy_reference")
        self.energy_reference = None if ref is None else [float(x) for x in ref]
        return self

    def load_state(self, tables):
        """Replace the bodies by ``tables["particles"]`` (FIELDS columns, any order; distributed
        like at build) and give back the contact history of ``tables["contacts/<kind>"]`` (rows
        whose bodies are gone are dropped at the next rebuild); walls, facets and boxes get their
        state back when their table is present. Every rank passes the same tables. Used by
        `restore_checkpoint` and by multi-stage scenes (`pdem.boxtest`) between stages."""
        from .state import FIELDS

        cols = tables["particles"]
        missing = [k for k in FIELDS if k not in cols]
        if missing:
            raise ValueError(f"table particles lacks column(s) {', '.join(missing)}")
        p = self.particles
        p.n_ghost = 0
        p.n_local = 0
        cols = {k: np.asarray(cols[k]) for k in FIELDS}
        if hasattr(self.domain, "distribute"):
            self.domain.distribute(p, cols)
        else:
            p.append_local(cols)
        if len(self.walls) and "walls" in tables:
            self.walls.position[:] = tables["walls"]["position"]
            self.walls.velocity[:] = tables["walls"]["velocity"]
        if len(self.facets) and "facets" in tables:
            f = tables["facets"]
            self.facets.geom[:] = f["geom"]
            self.facets.vertices[:] = f["vertices"]
            self.facets.velocity[:] = f["velocity"]
        if self.boxes is not None and "boxes" in tables:
            self.boxes.center[:] = tables["boxes"]["center"]
            self.boxes.velocity[:] = tables["boxes"]["velocity"]
        # contacts: every rank gets every row; `replace` at the rebuild keeps the keys it needs
        for attr, name in self.CHECKPOINT_CONTACTS:
            cl = getattr(self, attr)
            if cl is None or name not in tables:
                continue
            t = tables[name]
            key = np.asarray(t["key"], np.int64)
            cl.n = 0  # candidate rows of the build-time rebuild: no contacts yet (no force computed)
            cl.add_carried(key, np.ones(len(key), np.int8), np.asarray(t["params"], np.float64),
                           np.asarray(t["history"], np.float64))
        self.rebuild()
        return self

    def set_friction_scale(self, factor):
        """Friction angles of every material times ``factor`` [-], for new contacts and (Ip2 again
        for tan φ) for the existing ones: the vibration stage of the thesis (4.2) lowers friction
        tenfold and restores it with factor 1."""
        base = self.materials.arrays()[2]
        self.friction = base * float(factor)
        p = self.particles
        for cl, other in ((self.ss, None), (self.sw, self.walls), (self.sf, self.facets), (self.sb, self.boxes)):
            if cl is None or cl.n == 0:
                continue
            n = cl.n
            mi = p.material[cl.i[:n]]
            mj = p.material[cl.j[:n]] if other is None else other.material[cl.j[:n]]
            linear.set_friction(n, mi, mj, self.friction, cl.params)
