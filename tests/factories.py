"""The scenes that several test files build, in one place (scene objects and scene-file text).

- ``BOX_MATERIALS``: the thesis's three materials at the studies' scaled stiffness (ballast E_k
  2.8e6 Pa, steel 10 E_k, rubber 0.1 E_k) as scene-file text (box test, its options, track).
- ``lattice_scene(seed, (nx, ny, nz), ...)``: nx·ny·nz spheres of radius 5 mm × U(0.6, 1.4) on a
  lattice of 16 mm (no initial overlap), jitter ±0.5 mm, optional random velocities along x
  (U(−vx, vx), so bodies cross slab edges), down (U(−vz, 0)) and spins (U(±angvel) about each
  axis), ρ 2700 and E 1e7, ν 0.3, φ 0.5 (or other material keys), damping 0.3, gravity, and
  walls: the floor z = 0, then x = 0, x = Lx, y = 0, y = Ly (one-sided facing inwards with
  ``one_sided``, else two-sided). Returns (scene, material index, (Lx, Ly)).
- ``shuffled_lattice_scene((nx, ny, nz), seed)``: spheres r = 4-5 mm on a jittered lattice of
  10.5 mm (``shuffled_lattice``) in random row order, moving (U(−0.5, 0.5) m/s each way), ρ 2700,
  E 1e7, ν 0.3, φ 0.5, damping 0.3, gravity, between two-sided walls z = 0, x = 0 and x = Lx.
- ``box_scene(n, ...)``: n spheres on a jittered cubic grid (``grid_packing``) in an open box of
  5 walls; ``sphere_mass(r, ρ)`` [kg].
- ``ball_and_steel(...)``: a scene with a ball material (``BALL``) and a ten times stiffer steel
  (``STEEL``), initial overlaps allowed (the box cases start in contact on purpose).
- ``clump_scene()``: rigid 8-sphere clumps and breakable grains thrown sideways in a box long
  along x (the slab axis), so that clumps cross slab edges, straddle them and bonds break.
- ``snapshot_scene()``: the clump scene with one of every other kind of body a snapshot draws:
  a fixed sphere, a facet and a box pushed off its centre so that it turns as it falls
  (``SNAPSHOT_FIXED_GID``: the fixed sphere's gid).
- ``TINY_DEPOSITION``: a tiny plain scene file (50 spheres falling into a box, 400 steps), the
  campaign tests' base scene.
- ``oedometer_ci_doc(**changes)``: jobs/oedometer_ci.toml parsed, with [oedometer] keys replaced;
  ``toml_text(doc)`` writes a parsed scene file back.
"""
import math
import tomllib
from pathlib import Path

import numpy as np

from pdem.bodies.clump_generators import ballast8, grain_cloud, shape_members
from pdem.boundaries.loads import Constant, Haversine
from pdem.build.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
OEDOMETER_CI_JOB = ROOT / "jobs" / "oedometer_ci.toml"

BOX_MATERIALS = """[materials.ballast]
density = 2600.0
young = 2.8e6
poisson = 0.3
friction_angle = 0.5

[materials.steel]
density = 7850.0
young = 2.8e7
poisson = 0.25
friction_angle = 0.5

[materials.rubber]
density = 1000.0
young = 2.8e5
poisson = 0.5
friction_angle = 0.7
"""

# ---------------------------------------------------------------------------- sphere lattices
LATTICE_SPACING = 0.016  # [m]
LATTICE_MATERIAL = {"young": 1e7, "poisson": 0.3, "friction_angle": 0.5}


def lattice_scene(seed, shape, *, vx=0.0, vz=0.0, angvel=0.0, one_sided=False, material=LATTICE_MATERIAL,
                  **scene_kw):
    nx, ny, nz = shape
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * LATTICE_SPACING + rng.uniform(-0.0005, 0.0005, (len(g), 3))
    radius = 0.005 * rng.uniform(0.6, 1.4, len(g))
    vel = np.zeros((len(g), 3))
    if vx:
        vel[:, 0] = rng.uniform(-vx, vx, len(g))
    if vz:
        vel[:, 2] = rng.uniform(-vz, 0.0, len(g))
    spin = rng.uniform(-angvel, angvel, (len(g), 3)) if angvel else None
    settings = {"dt": "auto", "damping": 0.3, "gravity": (0.0, 0.0, -9.81), **scene_kw}
    scene = Scene(**settings)
    m = scene.material(density=2700.0, **material)
    scene.add_spheres(pos, radius, m, vel=vel, angvel=spin)
    lx, ly = nx * LATTICE_SPACING, ny * LATTICE_SPACING
    for axis, position, sense in ((2, 0.0, 1), (0, 0.0, 1), (0, lx, -1), (1, 0.0, 1), (1, ly, -1)):
        scene.add_wall(axis, position, m, sense=sense if one_sided else 0)
    return scene, m, (lx, ly)


def periodic_lattice_scene(seed, shape, *, vx=0.0, vz=0.0, **scene_kw):
    """`lattice_scene`'s bodies with periodic ends along x ([0, nx spacing)) instead of its x end
    walls: a floor and two side walls; the slab axis is x."""
    nx, ny, nz = shape
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * LATTICE_SPACING + rng.uniform(-0.0005, 0.0005, (len(g), 3))
    radius = 0.005 * rng.uniform(0.6, 1.4, len(g))
    vel = np.zeros((len(g), 3))
    vel[:, 0] = rng.uniform(-vx, vx, len(g)) + 0.5 * vx  # a net drift along x: bodies wrap
    if vz:
        vel[:, 2] = rng.uniform(-vz, 0.0, len(g))
    lx, ly = nx * LATTICE_SPACING, ny * LATTICE_SPACING
    settings = {"dt": "auto", "damping": 0.3, "gravity": (0.0, 0.0, -9.81), "slab_axis": 0,
                "periodic": [0.0, lx], **scene_kw}
    scene = Scene(**settings)
    m = scene.material(density=2700.0, **LATTICE_MATERIAL)
    scene.add_spheres(pos, radius, m, vel=vel)
    for axis, position, sense in ((2, 0.0, 1), (1, 0.0, 1), (1, ly, -1)):
        scene.add_wall(axis, position, m, sense=sense)
    return scene, m, (lx, ly)


def box_on_lattice(blocked, load_point=None):
    """A steel box (2 kg) pushed down at 0.2 m/s onto a 20 x 6 x 6 lattice moving along x, loaded by
    two 0–5 N haversine cycles at 20 Hz (at ``load_point`` off its centre [m], if given); the slab
    axis is x. The box moves as ``blocked`` lets it (`pdem.bodies.boxes.blocked_mask`)."""
    nx, ny, nz = 20, 6, 6
    scene, _, (lx, ly) = lattice_scene(7, (nx, ny, nz), vx=0.3, slab_axis=0)
    steel = scene.material(density=7850.0, young=1e8, poisson=0.25, friction_angle=0.5)
    top = nz * LATTICE_SPACING
    arm = {} if load_point is None else {"load_point": (load_point[0] * lx, load_point[1] * ly, 0.0)}
    scene.add_box((0.5 * lx, 0.5 * ly, top + 0.012), (0.4 * lx, 0.4 * ly, 0.01), steel, mass=2.0,
                  blocked=blocked, load=Haversine(0.0, 5.0, 20.0, 2), velocity=(0.0, 0.0, -0.2), **arm)
    return scene


def shuffled_lattice(shape=(8, 5, 6), seed=5, spacing=0.0105):
    """(pos, radius, vel) of a jittered lattice of spheres (r = 4-5 mm, not touching) in a random order, moving."""
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(*(np.arange(k) for k in shape), indexing="ij"), -1).reshape(-1, 3)
    g = g[rng.permutation(len(g))]
    pos = (g + 0.5) * spacing + rng.uniform(-2e-4, 2e-4, (len(g), 3))
    radius = 0.005 * rng.uniform(0.8, 1.0, len(g))
    vel = rng.uniform(-0.5, 0.5, (len(g), 3))
    return pos, radius, vel


def shuffled_lattice_scene(shape=(8, 5, 6), seed=5, **scene_kw):
    spacing = 0.0105
    pos, radius, vel = shuffled_lattice(shape, seed, spacing)
    scene = Scene(dt="auto", damping=0.3, gravity=(0.0, 0.0, -9.81), **scene_kw)
    m = scene.material(density=2700.0, young=1e7, poisson=0.3, friction_angle=0.5)
    scene.add_spheres(pos, radius, m, vel=vel)
    scene.add_wall(2, 0.0, m)
    scene.add_wall(0, 0.0, m)
    scene.add_wall(0, shape[0] * spacing, m)
    return scene


# ---------------------------------------------------------------------------- grid packings in a box
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


# ---------------------------------------------------------------------------- a ball and a steel body
BALL = {"density": 2600.0, "young": 1e8, "poisson": 0.3, "friction_angle": 0.5}
STEEL = {"density": 7850.0, "young": 1e9, "poisson": 0.25, "friction_angle": 0.5}


def ball_and_steel(dt=1e-6, damping=0.0, gravity=0.0, **scene_kw):
    """(scene, ball material, steel material); gravity [m/s²] downwards."""
    scene_kw.setdefault("allow_initial_overlap", True)
    sc = Scene(dt=dt, damping=damping, gravity=(0.0, 0.0, -gravity), **scene_kw)
    return sc, sc.material(**BALL), sc.material(**STEEL)


# ---------------------------------------------------------------------------- clumps
CLUMP_BOX = (0.40, 0.06)  # (Lx, Ly) [m]


def clump_scene(n_rigid=60, n_breakable=6):
    lx, ly = CLUMP_BOX
    rng = np.random.default_rng(11)
    sc = Scene(dt="auto", damping=0.2, gravity=(0.0, 0.0, -9.81), law="cohesive", slab_axis=0, dt_interval=50,
               check_interval=40)
    sc.material(name="grain", density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5, normal_cohesion=6e4,
                shear_cohesion=6e4)
    sc.material(name="wall", density=7850.0, young=1e8, poisson=0.25, friction_angle=0.4, normal_cohesion=0.0,
                shear_cohesion=0.0)
    p, r = ballast8(0.005)
    grains = grain_cloud(p, r, (0.0, 0.0, 0.0), (lx, ly, 0.09), n_rigid, seed=5)
    vel = np.stack([rng.uniform(-0.8, 0.8, n_rigid), np.zeros(n_rigid), rng.uniform(-0.6, 0.0, n_rigid)], axis=1)
    sc.add_clumps(grains, "grain", vel=vel, angvel=rng.uniform(-20.0, 20.0, (n_rigid, 3)))
    p, r = shape_members("ellipsoid", 0.004, (0.022, 0.02, 0.018))
    grains = grain_cloud(p, r, (0.0, 0.0, 0.09), (lx, ly, 0.20), n_breakable, seed=6)
    vel = np.stack([rng.uniform(-1.0, 1.0, n_breakable), np.zeros(n_breakable), rng.uniform(-1.5, -0.5, n_breakable)],
                   axis=1)
    sc.add_clumps(grains, "grain", breakable=True, vel=vel)
    sc.add_wall("z", 0.0, "wall", sense=1)
    sc.add_wall("x", 0.0, "wall", sense=1)
    sc.add_wall("x", lx, "wall", sense=-1)
    sc.add_wall("y", 0.0, "wall", sense=1)
    sc.add_wall("y", ly, "wall", sense=-1)
    return sc


SNAPSHOT_FIXED_GID = 10_000


def snapshot_scene():
    lx, ly = CLUMP_BOX
    sc = clump_scene()
    sc.add_spheres([(0.05, 0.5 * ly, 0.24)], 0.006, "wall", fixed=True, first_gid=SNAPSHOT_FIXED_GID)
    sc.add_facet([(0.0, 0.0, 0.30), (0.12, 0.0, 0.30), (0.0, ly, 0.32)], "wall")
    sc.add_box((0.3, 0.5 * ly, 0.25), (0.05, 0.02, 0.01), "wall", mass=0.5, blocked="xyXZ",
               load=Constant(2.0), load_point=(0.04, 0.0, 0.0))
    return sc


# ---------------------------------------------------------------------------- scene files
TINY_DEPOSITION = """
[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]

[run]
steps = 400
progress_every = 100
output_every = 20
checkpoint_keep = 2
kind = "deposition"

[materials.ballast]
density = 2600.0
young = 1.0e7
poisson = 0.3
friction_angle = 0.5

[deposition]
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.2, 0.1, 0.3]
count = 50
radius = 0.01
radius_spread = 0.3
seed = 3
material = "ballast"
walls_material = "ballast"
"""


def oedometer_ci_doc(**oedometer):
    """The parsed CI oedometer job with ``oedometer`` keys replaced."""
    doc = tomllib.loads(OEDOMETER_CI_JOB.read_text())
    doc["oedometer"].update(oedometer)
    return doc


def toml_text(doc):
    """TOML text of a parsed scene file (tables of scalars, lists and subtables)."""
    from pdem.campaign.tomlw import dumps

    return dumps(doc)
