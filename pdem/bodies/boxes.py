"""Rigid boxes: axis-aligned cuboid bodies (sleeper, loading platen, cover plate), replicated on
every rank (like walls), each one body with its own mass, blocked DOFs and force program.

A box is ``center ± half_extents`` [m]; its orientation is fixed (axis-aligned: the rotational
DOFs are always blocked). Spheres touch its faces, edges and corners (`pdem.contact.linear.
sphere_box_forces`). Every step the simulation sets ``contact_force`` (the total force of the
spheres on each box [N], an exact sum over all ranks, so every rank holds the same bits) and
calls `Boxes.integrate`: per free translation ``a = (F_contact + F_load)/m + g`` (optionally
Cundall-damped per box), ``v += Δt a``, then ``x += Δt v`` for every box (a blocked box moves with
its prescribed velocity), exactly as the sphere leapfrog (`pdem.integrator`). The load is
``program.value(t) · direction`` with t the time at the start of the step (when the contact
forces were computed); direction defaults to −z (a sleeper pushed down).

Storage: the rows the contact loop reads (`pdem.contact.geometry.SphereBox`): ``kernel_f``
[n, 9] = centre, half extents, velocity and ``kernel_i`` [n, 1] = material; the named
attributes are views of them.

A box may instead have a surface of member spheres (``members``: centres relative to its centre
[m], all of ``member_radius`` [m]): the thesis's clump sleeper, 2280 steel spheres of 5 mm fused
into one body that translates along z only (thesis 5.2, fig. 5.6). Such a box has no flat faces:
spheres touch its members (`BoxMembers`, `pdem.contact.geometry.SphereMember`), and the force
of those contacts, summed per box, drives it like the force on a flat box. A clump that never
rotates is exactly a translating box with its members at fixed offsets, so this is Yade's clump
with blocked rotations and x, y translations, without the clump's per-member bookkeeping and
without its slab ownership (boxes are replicated on every rank).

Imports nothing from pdem but errors, loads, state and validate.
"""
from math import sqrt

import numpy as np
from numba import njit

from ..errors import InputError
from ..boundaries.loads import Constant, Haversine, Impulse, SleeperLoad
from .state import DOF_ALL
from ..build.validate import number, vector3

DOF_LETTERS = "xyzXYZ"
ROTATIONS = 0b111000


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


def blocked_mask(label, blocked, fixed):
    """Bit mask (bits 0–2 x, y, z; 3–5 rotations) from ``fixed`` or a string of ``xyzXYZ``.

    Rotations are always blocked (orientation fixed); a string that frees one is refused."""
    if fixed:
        return DOF_ALL
    if blocked is None:
        return ROTATIONS
    if not isinstance(blocked, str) or set(blocked) - set(DOF_LETTERS):
        raise InputError(f"{label}.blocked = {blocked!r}: must be a string of letters from 'xyzXYZ'")
    mask = 0
    for c in blocked:
        mask |= 1 << DOF_LETTERS.index(c)
    if mask & ROTATIONS != ROTATIONS:
        raise InputError(f"{label}.blocked = {blocked!r}: boxes do not rotate, so it must contain X, Y and Z "
                         "(e.g. 'xyXYZ' for z translation only)")
    return mask


class Boxes:
    """Structure of arrays over the boxes of a scene (index order = declaration order)."""

    def __init__(self):
        self.kernel_f = np.zeros((0, 9))
        self.kernel_i = np.zeros((0, 1), np.int64)
        self.mass = np.zeros(0)
        self.blocked = np.zeros(0, np.int64)
        self.damping = np.zeros(0)
        self.direction = np.zeros((0, 3))
        self.loads = []
        self.names = []
        # per-step outputs, identical on every rank
        self.contact_force = np.zeros((0, 3))
        self.load_force = np.zeros((0, 3))
        self.members = BoxMembers()

    center = property(lambda self: self.kernel_f[:, 0:3])
    half = property(lambda self: self.kernel_f[:, 3:6])
    velocity = property(lambda self: self.kernel_f[:, 6:9])
    material = property(lambda self: self.kernel_i[:, 0])

    def __len__(self):
        return len(self.mass)

    def search_arrays(self):
        """Arguments of `pdem.contact.neighbors.build_box_candidates` after the particles (boxes with
        member spheres have no flat faces: they are left out)."""
        return self.center, self.half, self.members.count_of(len(self)) == 0

    def smooth_count(self):
        """Number of boxes with flat faces (no member spheres)."""
        return int(np.count_nonzero(self.members.count_of(len(self)) == 0))

    def add(self, center, half_extents, material, mass, *, blocked=None, fixed=False, load=None,
            direction=(0.0, 0.0, -1.0), velocity=(0.0, 0.0, 0.0), damping=0.0, name="", members=None,
            member_radius=None):
        """Validate and append one box; returns its index. ``members`` [k, 3] (centres relative to
        the box centre [m]) with ``member_radius`` [m] give it a surface of spheres of its material
        instead of flat faces."""
        label = f"boxes.{name}" if name else f"boxes[{len(self)}]"
        c = vector3(f"{label}.center", center)
        h = vector3(f"{label}.half_extents", half_extents)
        if not np.all(h > 0.0):
            raise InputError(f"{label}.half_extents = {h.tolist()}: every half extent must be > 0 [m]")
        v = vector3(f"{label}.velocity", velocity)
        m = number(f"{label}.mass", mass, 0.0, lo_open=True, allow="a number > 0 [kg]")
        lam = number(f"{label}.damping", damping, 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)")
        mask = blocked_mask(label, blocked, fixed)
        if load is not None and not isinstance(load, (Constant, Haversine, Impulse, SleeperLoad)):
            raise InputError(
                f"{label}.load = {load!r}: must be None or a pdem.boundaries.loads program (Haversine, Constant, "
                "Impulse, SleeperLoad)"
            )
        d = vector3(f"{label}.direction", direction)
        norm = float(np.sqrt(d @ d))
        if not norm > 0.0:
            raise InputError(f"{label}.direction = {d.tolist()}: must be a non-zero vector")
        self.kernel_f = np.vstack([self.kernel_f, np.concatenate([c, h, v])[None]])
        self.kernel_i = np.vstack([self.kernel_i, np.array([[material]], np.int64)])
        self.mass = np.append(self.mass, m)
        self.blocked = np.append(self.blocked, np.int64(mask))
        self.damping = np.append(self.damping, lam)
        self.direction = np.vstack([self.direction, (d / norm)[None]])
        self.loads.append(load)
        self.names.append(name or str(len(self.names)))
        self.contact_force = np.zeros((len(self), 3))
        self.load_force = np.zeros((len(self), 3))
        if members is not None:
            self.members.add(label, len(self) - 1, members, member_radius, material, h)
            self.place_members()
        return len(self) - 1

    def place_members(self):
        """Member sphere rows at their box's centre and velocity (after the boxes moved)."""
        if len(self.members):
            m = self.members
            m.kernel_f[:, 0:3] = self.center[m.box] + m.offset
            m.kernel_f[:, 3:6] = self.velocity[m.box]

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

    def integrate(self, t, dt, gravity):
        """Leapfrog of every box from ``contact_force`` and the load at t; returns the largest
        displacement [m] of this step (for the neighbour-list rebuild criterion)."""
        self.load_force = self.applied(t)
        moved = leapfrog_boxes(self.kernel_f, self.blocked, self.damping, self.mass, self.contact_force,
                               self.load_force, np.asarray(gravity, np.float64), dt)
        self.place_members()
        return moved

    def spec(self):
        """JSON-able description (initial state as declared)."""
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
