"""Walls: infinite axis-aligned planes (Yade's ``utils.wall``), replicated on every rank.

A wall is the plane ``x[axis] = position`` [m]; ``sense`` 0 means it acts on both sides (the
normal points from the wall to the sphere centre), +1/−1 only towards +axis/−axis. A wall is
fixed but moves with its prescribed velocity [m/s] (``position += velocity[axis]·Δt``; the
tangential components of the velocity drag spheres through friction).
"""
import numpy as np

from .errors import InputError

AXES = {"x": 0, "y": 1, "z": 2}


class Walls:
    def __init__(self):
        self.axis = np.zeros(0, np.int64)
        self.sense = np.zeros(0, np.int64)
        self.position = np.zeros(0)
        self.velocity = np.zeros((0, 3))
        self.material = np.zeros(0, np.int64)
        self.names = []

    def __len__(self):
        return len(self.axis)

    def add(self, axis, position, material, sense=0, velocity=(0.0, 0.0, 0.0), name=""):
        label = name or f"walls[{len(self)}]"
        if isinstance(axis, str):
            if axis not in AXES:
                raise InputError(f"{label}.axis = {axis!r}: must be one of x, y, z")
            axis = AXES[axis]
        if axis not in (0, 1, 2):
            raise InputError(f"{label}.axis = {axis!r}: must be 0, 1, 2 (x, y, z)")
        if sense not in (-1, 0, 1):
            raise InputError(f"{label}.sense = {sense!r}: must be -1, 0 or 1")
        self.axis = np.append(self.axis, axis)
        self.sense = np.append(self.sense, sense)
        self.position = np.append(self.position, float(position))
        self.velocity = np.vstack([self.velocity, np.asarray(velocity, float).reshape(1, 3)])
        self.material = np.append(self.material, material)
        self.names.append(label)
        return len(self) - 1

    def move(self, dt):
        """Advance every wall along its axis with its prescribed velocity (after forces)."""
        for w in range(len(self)):
            self.position[w] += self.velocity[w, self.axis[w]] * dt
