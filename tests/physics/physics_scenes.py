"""Small scenes shared by the physics tests (tests/physics)."""
import math

import numpy as np

from pdem import Scene


def sphere_mass(r, rho):
    return rho * (4.0 / 3.0) * math.pi * r ** 3


def grid_packing(n, r_min, r_max, seed, box=None, spacing=1.05):
    """n spheres with radii uniform in [r_min, r_max] on a jittered cubic grid (no initial overlaps).

    Returns (pos, radius, box) with box = (Lx, Ly) of the square base; grid columns fill the base."""
    rng = np.random.default_rng(seed)
    radius = rng.uniform(r_min, r_max, n)
    a = 2.0 * r_max * spacing
    side = int(math.ceil(n ** (1.0 / 3.0))) if box is None else int(box / a)
    idx = np.arange(n)
    ix, iy, iz = idx % side, (idx // side) % side, idx // (side * side)
    jitter = rng.uniform(-0.4, 0.4, (n, 3)) * (a - 2.0 * r_max)
    pos = np.stack([(ix + 0.5) * a, (iy + 0.5) * a, (iz + 0.5) * a], axis=1) + jitter
    return pos, radius, side * a


def box_scene(n, *, seed=1, r_min=0.008, r_max=0.012, young=1e7, wall_young=None, damping=0.3, dt="auto",
              gravity=(0.0, 0.0, -9.81), vel_scale=0.0, friction_angle=0.5, spacing=1.05, **scene_kw):
    """n spheres in an open box of 5 walls (x, y both sides, floor z = 0)."""
    pos, radius, side = grid_packing(n, r_min, r_max, seed, spacing=spacing)
    sc = Scene(dt=dt, damping=damping, gravity=gravity, **scene_kw)
    ball = sc.material(density=2600.0, young=young, poisson=0.3, friction_angle=friction_angle)
    wall = sc.material(density=7850.0, young=wall_young or 10 * young, poisson=0.25, friction_angle=friction_angle)
    rng = np.random.default_rng(seed + 1000)
    vel = rng.uniform(-vel_scale, vel_scale, (n, 3)) if vel_scale else None
    sc.add_spheres(pos, radius, ball, vel=vel)
    for axis in (0, 1):
        sc.add_wall(axis, 0.0, wall)
        sc.add_wall(axis, side, wall)
    sc.add_wall(2, 0.0, wall)
    return sc
