"""Rigid boxes: axis-aligned cuboid bodies (sleeper, loading platen, cover plate), replicated on
every rank (like walls), each one body with its own mass, blocked DOFs and force program.

A box is ``center ± half_extents`` [m] along its own axes; by default its rotations are blocked
and it stays axis-aligned. Spheres touch its faces, edges and corners (`pdem.contact.geometry.
SphereBox`). Every step the simulation sets ``contact_force`` (the total force of the
spheres on each box [N], an exact sum over all ranks, so every rank holds the same bits) and
calls `Boxes.integrate`: per free translation ``a = (F_contact + F_load)/m + g`` (optionally
Cundall-damped per box), ``v += Δt a``, then ``x += Δt v`` for every box (a blocked box moves with
its prescribed velocity), exactly as the sphere leapfrog (`pdem.integrator`). The load is
``program.value(t) · direction`` with t the time at the start of the step (when the contact
forces were computed); direction defaults to −z (a sleeper pushed down).

A box with free rotations (``blocked`` without some of X, Y, Z; e.g. "xyXZ": z translation and
tilting about y, the half model's sleeper) is a rigid body with six degrees of freedom: an
orientation q (w, x, y, z, its principal frame → global), angular momentum L [kg·m²/s] (global),
principal moments I [kg·m²] (a solid cuboid, m(b² + c²)/12 … with a, b, c the edge lengths, or
a given symmetric positive definite tensor in the box's axes, diagonalised once: ``axes`` V, its
principal directions in the box frame). Each step ``contact_torque`` (the moment about the box
centre of the sphere contacts' forces at their contact points [N·m], an exact sum over all ranks
like ``contact_force``) plus the load's moment (the load acts at ``load_point``, box axes [m], or
a program gives its own moment, `Boxes.load_moment`) turns it by Yade's aspherical leapfrog
(`pdem.bodies.clumps.aspherical_rotate`, Cundall-damped by the box's λ_D as the clumps are);
torque and L about blocked global axes are held at zero (exact when the free rotation is about a
principal axis, e.g. one free tilt). Its spheres use the contact kind ``sphere_oriented_box``
(`pdem.contact.geometry.SphereOrientedBox`: the box contact in the box's axes, the box's velocity
at the contact point); axis-aligned boxes keep ``sphere_box``.
Checkpoints carry q, L, ω and R; snapshots draw the box turned (`pdem.driver.snapshots`).
A box with member spheres cannot rotate (refused).

Storage: the rows the contact loop reads (`pdem.contact.geometry.SphereBox`, `SphereOrientedBox`):
``kernel_f`` [n, 21] = centre, half extents, velocity, rotation R box → global (row-major; the
identity for a box that does not rotate), angular velocity ω [rad/s] and ``kernel_i`` [n, 1] =
material; the named attributes are views of them.

A box may instead have a surface of member spheres (``members``: centres relative to its centre
[m], all of ``member_radius`` [m]): the thesis's clump sleeper, 2280 steel spheres of 5 mm fused
into one body that translates along z only (thesis 5.2, fig. 5.6). Such a box has no flat faces:
spheres touch its members (`BoxMembers`, `pdem.contact.geometry.SphereMember`), and the force
of those contacts, summed per box, drives it like the force on a flat box. A clump that never
rotates is exactly a translating box with its members at fixed offsets, so this is Yade's clump
with blocked rotations and x, y translations, without the clump's per-member bookkeeping and
without its slab ownership (boxes are replicated on every rank).

Imports nothing from pdem but errors, loads, state, validate and the clumps' rotation.
"""
from math import sqrt

import numpy as np
from numba import njit

from ..errors import InputError
from ..boundaries.loads import Constant, Haversine, Impulse, Ramp, SleeperLoad
from .clump_properties import qnormalize, quaternion_from_matrix
from .clumps import aspherical_rotate, normalised, rotation_matrix
from .state import DOF_ALL
from ..build.validate import number, vector3

DOF_LETTERS = "xyzXYZ"
ROTATIONS = 0b111000
ROWS = 21  # kernel_f columns: centre 0, half extents 3, velocity 6, rotation 9 (row-major), ω 18


@njit(cache=True)
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@njit(cache=True)
def leapfrog_boxes(kernel_f, blocked, damping, mass, contact_force, load_force, gravity, dt):
    """The leapfrog of every box (centre ``kernel_f[:, 0:3]``, velocity ``kernel_f[:, 6:9]``):
    per free translation a = (F_contact + F_load)/m + g, Cundall-damped by the box's λ_D,
    v += Δt a; then x += Δt v. Returns the largest displacement of this step [m]."""
    moved = 0.0
    for b in range(mass.shape[0]):
        lam = damping[b]
        for c in range(3):
            if blocked[b] & (1 << c):
                continue
            a = (contact_force[b, c] + load_force[b, c]) / mass[b] + gravity[c]
            if lam > 0.0:
                a *= 1.0 - lam * _sign(a * (kernel_f[b, 6 + c] + 0.5 * dt * a))
            kernel_f[b, 6 + c] += dt * a
        s2 = 0.0
        for c in range(3):
            step = kernel_f[b, 6 + c] * dt
            kernel_f[b, c] += step
            s2 += step * step
        moved = max(moved, sqrt(s2))
    return moved


@njit(cache=True)
def place_member_rows(member_f, member_i, offset, box_f):
    """Member rows at their box's centre plus their offset, with their box's velocity [m, m/s]:
    ``member_f[k, 0:3] = box_f[b, 0:3] + offset[k]``, ``member_f[k, 3:6] = box_f[b, 6:9]`` with
    b = ``member_i[k, 1]`` (`BoxMembers`). One compiled pass: the thesis's sleeper has 2280
    members and this runs every step (numpy's fancy indexing cost 130 µs a step here)."""
    for k in range(member_f.shape[0]):
        b = member_i[k, 1]
        for a in range(3):
            member_f[k, a] = box_f[b, a] + offset[k, a]
            member_f[k, 3 + a] = box_f[b, 6 + a]


def blocked_mask(label, blocked, fixed):
    """Bit mask (bits 0–2 x, y, z; 3–5 rotations) from ``fixed`` or a string of ``xyzXYZ``
    (default: rotations blocked)."""
    if fixed:
        return DOF_ALL
    if blocked is None:
        return ROTATIONS
    if not isinstance(blocked, str) or set(blocked) - set(DOF_LETTERS):
        raise InputError(f"{label}.blocked = {blocked!r}: must be a string of letters from 'xyzXYZ'")
    mask = 0
    for c in blocked:
        mask |= 1 << DOF_LETTERS.index(c)
    return mask


def principal_inertia(label, inertia, mass, half):
    """(principal moments [3] [kg·m²], their directions V [3, 3] (columns, box axes)) from
    ``inertia`` (None: a solid cuboid of ``mass`` and ``half`` extents; 3 moments about the box
    axes; or a 3×3 tensor in the box axes, symmetric positive definite)."""
    if inertia is None:
        a2, b2, c2 = (2.0 * half) ** 2
        return mass / 12.0 * np.array([b2 + c2, a2 + c2, a2 + b2]), np.eye(3)
    bad = (f"{label}.inertia = {inertia!r}: must be 3 principal moments or a 3×3 tensor [kg·m²], symmetric "
           "positive definite")
    try:
        t = np.asarray(inertia, dtype=float)
    except (TypeError, ValueError):
        raise InputError(bad) from None
    if t.shape == (3,):
        t = np.diag(t)
    if t.shape != (3, 3) or not np.all(np.isfinite(t)) or not np.allclose(t, t.T, rtol=0.0,
                                                                           atol=1e-12 * np.abs(t).max()):
        raise InputError(bad)
    t = 0.5 * (t + t.T)  # symmetric to the last bit
    if np.array_equal(t, np.diag(np.diag(t))):
        moments, axes = np.diag(t).copy(), np.eye(3)
    else:
        moments, axes = np.linalg.eigh(t)
        axes[:, 2] *= np.sign(np.linalg.det(axes))  # a rotation (det +1)
    if not np.all(moments > 0.0):
        raise InputError(bad)
    return moments, axes


@njit(cache=True)
def rotate_boxes(kernel_f, blocked, damping, ori, angmom, inertia, axes, torque, dt):
    """Turn every box with a free rotation: torque (about free global axes) into L and q by
    `aspherical_rotate`, q normalised, ω (zero about blocked axes) and R = R(q) Vᵀ into the box's
    row. Returns the largest displacement of a box point by this step's turn, |ω| Δt |h| [m]."""
    turned = 0.0
    for b in range(blocked.shape[0]):
        if blocked[b] & ROTATIONS == ROTATIONS:
            continue
        tx = 0.0 if blocked[b] & 8 else torque[b, 0]
        ty = 0.0 if blocked[b] & 16 else torque[b, 1]
        tz = 0.0 if blocked[b] & 32 else torque[b, 2]
        qw, qx, qy, qz, ox, oy, oz = aspherical_rotate(ori[b, 0], ori[b, 1], ori[b, 2], ori[b, 3], angmom[b], tx, ty,
                                                       tz, kernel_f[b, 18:21], inertia[b], damping[b], dt)
        qw, qx, qy, qz = normalised(qw, qx, qy, qz)
        ori[b, 0] = qw
        ori[b, 1] = qx
        ori[b, 2] = qy
        ori[b, 3] = qz
        w = (ox, oy, oz)
        for k in range(3):
            kernel_f[b, 18 + k] = 0.0 if blocked[b] & (8 << k) else w[k]
        rp = rotation_matrix(qw, qx, qy, qz)
        for a in range(3):
            for k in range(3):
                kernel_f[b, 9 + 3 * a + k] = (rp[3 * a] * axes[b, k, 0] + rp[3 * a + 1] * axes[b, k, 1]
                                              + rp[3 * a + 2] * axes[b, k, 2])
        w2 = kernel_f[b, 18] ** 2 + kernel_f[b, 19] ** 2 + kernel_f[b, 20] ** 2
        h2 = kernel_f[b, 3] ** 2 + kernel_f[b, 4] ** 2 + kernel_f[b, 5] ** 2
        turned = max(turned, sqrt(w2 * h2) * dt)
    return turned


class Boxes:
    """Structure of arrays over the boxes of a scene (index order = declaration order)."""

    def __init__(self):
        self.kernel_f = np.zeros((0, ROWS))
        self.kernel_i = np.zeros((0, 1), np.int64)
        self.mass = np.zeros(0)
        self.blocked = np.zeros(0, np.int64)
        self.damping = np.zeros(0)
        self.direction = np.zeros((0, 3))
        self.loads = []
        self.names = []
        # rotation (boxes with free rotations; module docstring)
        self.ori = np.zeros((0, 4))
        self.angmom = np.zeros((0, 3))
        self.inertia = np.zeros((0, 3))
        self.axes = np.zeros((0, 3, 3))
        self.load_point = np.zeros((0, 3))
        # per-step outputs, identical on every rank
        self.contact_force = np.zeros((0, 3))
        self.contact_torque = np.zeros((0, 3))
        self.load_force = np.zeros((0, 3))
        self.load_torque = np.zeros((0, 3))  # the loads' moment of the last step (rotating boxes)
        self.members = BoxMembers()

    center = property(lambda self: self.kernel_f[:, 0:3])
    half = property(lambda self: self.kernel_f[:, 3:6])
    velocity = property(lambda self: self.kernel_f[:, 6:9])
    material = property(lambda self: self.kernel_i[:, 0])
    rotation = property(lambda self: self.kernel_f[:, 9:18].reshape(-1, 3, 3))
    angvel = property(lambda self: self.kernel_f[:, 18:21])
    rotating = property(lambda self: (self.blocked & ROTATIONS) != ROTATIONS)

    def __len__(self):
        return len(self.mass)

    def search_arrays(self):
        """Arguments of `pdem.contact.neighbors.build_box_candidates` after the particles for the
        axis-aligned boxes (boxes with member spheres have no flat faces, rotating boxes are
        `oriented_search_arrays`': both are left out)."""
        return self.center, self.half, (self.members.count_of(len(self)) == 0) & ~self.rotating

    def oriented_search_arrays(self):
        """The same for the boxes with free rotations, each by its global bounding box (half
        extents Σ_k |R_ak| h_k)."""
        return self.center, np.einsum("bak,bk->ba", np.abs(self.rotation), self.half), self.rotating

    def smooth_count(self):
        """Number of axis-aligned boxes with flat faces (no member spheres, no free rotation)."""
        return int(np.count_nonzero(self.search_arrays()[2]))

    def oriented_count(self):
        """Number of boxes with free rotations."""
        return int(np.count_nonzero(self.rotating))

    def add(self, center, half_extents, material, mass, *, blocked=None, fixed=False, load=None,
            direction=(0.0, 0.0, -1.0), velocity=(0.0, 0.0, 0.0), damping=0.0, name="", members=None,
            member_radius=None, inertia=None, load_point=(0.0, 0.0, 0.0)):
        """Validate and append one box; returns its index. ``members`` [k, 3] (centres relative to
        the box centre [m]) with ``member_radius`` [m] give it a surface of spheres of its material
        instead of flat faces. ``inertia`` and ``load_point`` matter for a box with free rotations
        (module docstring)."""
        label = f"boxes.{name}" if name else f"boxes[{len(self)}]"
        c = vector3(f"{label}.center", center)
        h = vector3(f"{label}.half_extents", half_extents)
        if not np.all(h > 0.0):
            raise InputError(f"{label}.half_extents = {h.tolist()}: every half extent must be > 0 [m]")
        v = vector3(f"{label}.velocity", velocity)
        m = number(f"{label}.mass", mass, 0.0, lo_open=True, allow="a number > 0 [kg]")
        lam = number(f"{label}.damping", damping, 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)")
        mask = blocked_mask(label, blocked, fixed)
        if members is not None and mask & ROTATIONS != ROTATIONS:
            raise InputError(f"{label}.blocked = {blocked!r}: a box with member spheres does not rotate, so it must "
                             "contain X, Y and Z (e.g. 'xyXYZ' for z translation only)")
        moments, axes = principal_inertia(label, inertia, m, h)
        arm = vector3(f"{label}.load_point", load_point)
        if load is not None and not isinstance(load, (Constant, Haversine, Impulse, Ramp, SleeperLoad)):
            raise InputError(
                f"{label}.load = {load!r}: must be None or a pdem.boundaries.loads program (Haversine, Constant, "
                "Impulse, Ramp, SleeperLoad)"
            )
        d = vector3(f"{label}.direction", direction)
        norm = float(np.sqrt(d @ d))
        if not norm > 0.0:
            raise InputError(f"{label}.direction = {d.tolist()}: must be a non-zero vector")
        self.kernel_f = np.vstack([self.kernel_f, np.concatenate([c, h, v, np.eye(3).ravel(), np.zeros(3)])[None]])
        self.kernel_i = np.vstack([self.kernel_i, np.array([[material]], np.int64)])
        self.mass = np.append(self.mass, m)
        self.blocked = np.append(self.blocked, np.int64(mask))
        self.damping = np.append(self.damping, lam)
        self.direction = np.vstack([self.direction, (d / norm)[None]])
        self.loads.append(load)
        self.names.append(name or str(len(self.names)))
        self.ori = np.vstack([self.ori, np.array(qnormalize(quaternion_from_matrix(axes)))[None]])
        self.angmom = np.vstack([self.angmom, np.zeros((1, 3))])
        self.inertia = np.vstack([self.inertia, moments[None]])
        self.axes = np.concatenate([self.axes, axes[None]])
        self.load_point = np.vstack([self.load_point, arm[None]])
        self.contact_force = np.zeros((len(self), 3))
        self.contact_torque = np.zeros((len(self), 3))
        self.load_force = np.zeros((len(self), 3))
        self.load_torque = np.zeros((len(self), 3))
        if members is not None:
            self.members.add(label, len(self) - 1, members, member_radius, material, h)
            self.place_members()
        return len(self) - 1

    def place_members(self):
        """Member sphere rows at their box's centre and velocity (after the boxes moved)."""
        if len(self.members):
            m = self.members
            place_member_rows(m.kernel_f, m.kernel_i, m.offset, self.kernel_f)

    def index(self, name_or_index):
        """Index of a box from its name or index."""
        if isinstance(name_or_index, str):
            if name_or_index not in self.names:
                raise InputError(f"box {name_or_index!r}: unknown; defined: {', '.join(self.names) or 'none'}")
            return self.names.index(name_or_index)
        return int(name_or_index)

    def applied(self, t):
        """[n, 3] applied load [N] at time t."""
        out = np.zeros((len(self), 3))
        for b, load in enumerate(self.loads):
            if load is not None:
                out[b] = load.value(t) * self.direction[b]
        return out

    def load_moment(self, t):
        """[n, 3] moment of the loads at t about the box centres [N·m] (global axes): the load at
        ``load_point``, or, for a program with ``moment(t)`` that answers (not None), that moment
        (e.g. the rails' pads at their seats, `pdem.boundaries.rail_beam.SleeperRails.moment`)."""
        out = np.cross(np.einsum("bak,bk->ba", self.rotation, self.load_point), self.load_force)
        for b, load in enumerate(self.loads):
            own = getattr(load, "moment", None)
            moment = None if own is None else own(t)
            if moment is not None:
                out[b] = moment
        return out

    def integrate(self, t, dt, gravity):
        """Leapfrog of every box from ``contact_force`` and the load at t; returns the largest
        displacement [m] of this step (for the neighbour-list rebuild criterion)."""
        self.load_force = self.applied(t)
        moved = leapfrog_boxes(self.kernel_f, self.blocked, self.damping, self.mass, self.contact_force,
                               self.load_force, np.asarray(gravity, np.float64), dt)
        if self.oriented_count():
            self.load_torque = self.load_moment(t)
            torque = self.contact_torque + self.load_torque
            moved += rotate_boxes(self.kernel_f, self.blocked, self.damping, self.ori, self.angmom, self.inertia,
                                  self.axes, torque, dt)
        self.place_members()
        return moved

    def load_step(self, dt):
        """([n, 6] load, [n, 6] displacement) of the last step of length ``dt`` [s], per box: the
        load [N] and its moment [N·m] at the start of the step (global axes; the moment on a
        rotating box only), and the step's displacement Δt v [m] and turn Δt ω [rad]; blocked
        components 0. Their products summed give the loads' work (`pdem.scenes.track_record`)."""
        free = ((self.blocked[:, None] >> np.arange(6)) & 1) == 0
        free[:, 3:] &= self.rotating[:, None]
        load = np.where(free, np.concatenate([self.load_force, self.load_torque], axis=1), 0.0)
        return load, np.where(free, dt * np.concatenate([self.velocity, self.angvel], axis=1), 0.0)

    def energy(self, gravity, dt):
        """Mechanical energy [J] of the boxes at the positions of the last force computation,
        as `pdem.checks.diagnostics.energy` takes the spheres': kinetic ½ m v_{n−½}·v_{n+½} =
        ½ m v² − (Δt/2) m a·v (a = (F_contact + F_load)/m + g: exact without damping), potential
        −m g·(x − Δt v), and ½ ω·L of the rotating boxes (not synchronised); summed in index
        order (replicated: the same on every rank). ``dt`` [s]: the last step's."""
        g = np.asarray(gravity, float)
        e = 0.0
        for b in range(len(self)):
            m, v = float(self.mass[b]), self.velocity[b]
            a = np.where((self.blocked[b] >> np.arange(3)) & 1, 0.0,
                         (self.contact_force[b] + self.load_force[b]) / m + g)
            e += 0.5 * m * float(v @ v) - 0.5 * dt * m * float(a @ v) - m * float((self.center[b] - dt * v) @ g)
            if self.rotating[b]:
                e += 0.5 * float(self.angvel[b] @ self.angmom[b])
        return e

    def spec(self):
        """JSON-able description (initial state as declared)."""
        out = self._translation_spec()
        for b in np.flatnonzero(self.rotating):
            out[b].update(inertia=self.inertia[b].tolist(), axes=self.axes[b].tolist(),
                          load_point=self.load_point[b].tolist())
        return out

    def _translation_spec(self):
        return [
            dict(
                name=n,
                center=c.tolist(),
                half_extents=h.tolist(),
                velocity=v.tolist(),
                mass=float(m),
                material=int(mt),
                blocked=int(bl),
                damping=float(lam),
                direction=d.tolist(),
                load=None if ld is None else ld.spec(),
                **({"members": int(k), "member_radius": float(self.members.radius[self.members.box == b][0])}
                   if k else {}),
            )
            for b, (n, c, h, v, m, mt, bl, lam, d, ld, k) in enumerate(zip(
                self.names,
                self.center,
                self.half,
                self.velocity,
                self.mass,
                self.material,
                self.blocked,
                self.damping,
                self.direction,
                self.loads,
                self.members.count_of(len(self)),
            ))
        ]


class BoxMembers:
    """The member spheres of every box that has them, as the boundary rows of the contact kind
    ``sphere_member`` (`pdem.contact.geometry.SphereMember`): ``kernel_f`` [k, 7] = centre [m],
    velocity [m/s] (those of its box, `Boxes.place_members`) and radius [m]; ``kernel_i`` [k, 2]
    = material and box index; ``offset`` [k, 3] the centre relative to the box's [m]. Members
    of one box are consecutive, in declaration order."""

    def __init__(self):
        self.kernel_f = np.zeros((0, 7))
        self.kernel_i = np.zeros((0, 2), np.int64)
        self.offset = np.zeros((0, 3))

    material = property(lambda self: self.kernel_i[:, 0])
    box = property(lambda self: self.kernel_i[:, 1])
    radius = property(lambda self: self.kernel_f[:, 6])

    def __len__(self):
        return len(self.offset)

    @property
    def names(self):
        return [f"member {k} of box {b}" for k, b in enumerate(self.box)]

    def count_of(self, n_boxes):
        """[n_boxes] number of members of each box."""
        return np.bincount(self.box, minlength=n_boxes)[:n_boxes]

    def search_arrays(self):
        """Arguments of `pdem.contact.neighbors.build_member_candidates` after the particles."""
        return self.kernel_f[:, 0:3], self.radius

    def add(self, label, box, offsets, radius, material, half):
        """Append the members of box ``box`` (index); ``half`` its half extents [m]."""
        off = np.asarray(offsets, dtype=float)
        if off.ndim != 2 or off.shape[1] != 3 or len(off) < 1 or not np.all(np.isfinite(off)):
            raise InputError(f"{label}.members: must be a non-empty [k, 3] array of finite centres [m] "
                             f"relative to the box centre, got shape {off.shape}")
        r = number(f"{label}.member_radius", radius, 0.0, lo_open=True, allow="a number > 0 [m]")
        if np.any(np.abs(off) + r > half * (1.0 + 1e-9)):
            raise InputError(f"{label}.members: every member sphere must lie inside the box's extents "
                             f"(|offset| + member_radius <= half_extents = {half.tolist()})")
        rows = np.zeros((len(off), 7))
        rows[:, 6] = r
        ints = np.column_stack([np.full(len(off), material, np.int64), np.full(len(off), box, np.int64)])
        self.kernel_f = np.vstack([self.kernel_f, rows])
        self.kernel_i = np.vstack([self.kernel_i, ints])
        self.offset = np.vstack([self.offset, off])
