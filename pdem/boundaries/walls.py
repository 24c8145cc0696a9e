"""Walls: infinite axis-aligned planes (Yade's ``utils.wall``), replicated on every rank.

A wall is the plane ``x[axis] = position`` [m]; ``sense`` 0 means it acts on both sides (the
normal points from the wall to the sphere centre), +1/−1 only towards +axis/−axis. A wall is
fixed but moves with its prescribed velocity [m/s] (``position += velocity[axis]·Δt``; the
tangential components of the velocity drag spheres through friction).

Storage: the rows the contact loop reads (`pdem.contact.geometry.SphereWall`): ``kernel_f``
[n, 4] = position, velocity and ``kernel_i`` [n, 3] = axis, sense, material; the named
attributes are views of them.
"""
import numpy as np

from ..errors import InputError

AXES = {"x": 0, "y": 1, "z": 2}


class Walls:
    def __init__(self):
        self.kernel_f = np.zeros((0, 4))
        self.kernel_i = np.zeros((0, 3), np.int64)
        self.names = []

    position = property(lambda self: self.kernel_f[:, 0])
    velocity = property(lambda self: self.kernel_f[:, 1:4])
    axis = property(lambda self: self.kernel_i[:, 0])
    sense = property(lambda self: self.kernel_i[:, 1])
    material = property(lambda self: self.kernel_i[:, 2])

    def __len__(self):
        return len(self.kernel_i)

    def add(self, axis, position, material, sense=0, velocity=(0.0, 0.0, 0.0), name=""):
        label = f"walls.{name}" if name else f"walls[{len(self)}]"
        if isinstance(axis, str):
            if axis not in AXES:
                raise InputError(f"{label}.axis = {axis!r}: must be one of x, y, z")
            axis = AXES[axis]
        if axis not in (0, 1, 2) or isinstance(axis, (bool, np.bool_)):
            raise InputError(f"{label}.axis = {axis!r}: must be 0, 1, 2 (x, y, z)")
        if sense not in (-1, 0, 1) or isinstance(sense, (bool, np.bool_)):
            raise InputError(f"{label}.sense = {sense!r}: must be -1, 0 or 1")
        row = np.concatenate([[float(position)], np.asarray(velocity, float).reshape(3)])
        self.kernel_f = np.vstack([self.kernel_f, row[None]])
        self.kernel_i = np.vstack([self.kernel_i, np.array([[axis, sense, material]], np.int64)])
        self.names.append(name or str(len(self.names)))
        return len(self) - 1

    def search_arrays(self):
        """Arguments of `pdem.contact.neighbors.build_wall_candidates` after the particles."""
        return self.axis, self.position

    def move(self, dt):
        """Advance every wall along its axis with its prescribed velocity (after forces)."""
        for w in range(len(self)):
            self.kernel_f[w, 0] += self.kernel_f[w, 1 + self.kernel_i[w, 0]] * dt
