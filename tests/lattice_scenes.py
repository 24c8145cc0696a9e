"""The small test packing many tests share: spheres on a jittered lattice in a box of walls.

``lattice_scene(seed, (nx, ny, nz), ...)``: nx·ny·nz spheres of radius 5 mm × U(0.6, 1.4) on a
lattice of 16 mm (no initial overlap), jitter ±0.5 mm, optional random velocities along x
(U(−vx, vx), so bodies cross slab edges) and down (U(−vz, 0)), ρ 2700, E 1e7, ν 0.3, φ 0.5,
damping 0.3, gravity, and walls: the floor z = 0, then x = 0, x = Lx, y = 0, y = Ly (one-sided
facing inwards with ``one_sided``, else two-sided). Returns (scene, material index, (Lx, Ly)).
"""
import numpy as np

from pdem.scene import Scene

SPACING = 0.016


def lattice_scene(seed, shape, *, vx=0.0, vz=0.0, one_sided=False, **scene_kw):
    nx, ny, nz = shape
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * SPACING + rng.uniform(-0.0005, 0.0005, (len(g), 3))
    radius = 0.005 * rng.uniform(0.6, 1.4, len(g))
    vel = np.zeros((len(g), 3))
    if vx:
        vel[:, 0] = rng.uniform(-vx, vx, len(g))
    if vz:
        vel[:, 2] = rng.uniform(-vz, 0.0, len(g))
    settings = {"dt": "auto", "damping": 0.3, "gravity": (0.0, 0.0, -9.81), **scene_kw}
    scene = Scene(**settings)
    m = scene.material(density=2700.0, young=1e7, poisson=0.3, friction_angle=0.5)
    scene.add_spheres(pos, radius, m, vel=vel)
    lx, ly = nx * SPACING, ny * SPACING
    for axis, position, sense in ((2, 0.0, 1), (0, 0.0, 1), (0, lx, -1), (1, 0.0, 1), (1, ly, -1)):
        scene.add_wall(axis, position, m, sense=sense if one_sided else 0)
    return scene, m, (lx, ly)
