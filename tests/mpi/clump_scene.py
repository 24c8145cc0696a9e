"""The clump scene of the MPI tests (rank invariance, restart): rigid 8-sphere clumps and
breakable grains thrown sideways in a box long along x (the slab axis), so that clumps cross
slab edges, straddle them (members on both sides) and bonds break."""
import numpy as np

from pdem.clump_generators import ballast8, grain_cloud, shape_members
from pdem.scene import Scene

LX, LY = 0.40, 0.06


def make_scene(n_rigid=60, n_breakable=6):
    rng = np.random.default_rng(11)
    sc = Scene(dt="auto", damping=0.2, gravity=(0.0, 0.0, -9.81), law="cohesive", slab_axis=0, dt_interval=50,
               check_interval=40)
    sc.material(name="grain", density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5, normal_cohesion=6e4,
                shear_cohesion=6e4)
    sc.material(name="wall", density=7850.0, young=1e8, poisson=0.25, friction_angle=0.4, normal_cohesion=0.0,
                shear_cohesion=0.0)
    p, r = ballast8(0.005)
    grains = grain_cloud(p, r, (0.0, 0.0, 0.0), (LX, LY, 0.09), n_rigid, seed=5)
    vel = np.stack([rng.uniform(-0.8, 0.8, n_rigid), np.zeros(n_rigid), rng.uniform(-0.6, 0.0, n_rigid)], axis=1)
    sc.add_clumps(grains, "grain", vel=vel, angvel=rng.uniform(-20.0, 20.0, (n_rigid, 3)))
    p, r = shape_members("ellipsoid", 0.004, (0.022, 0.02, 0.018))
    grains = grain_cloud(p, r, (0.0, 0.0, 0.09), (LX, LY, 0.20), n_breakable, seed=6)
    vel = np.stack([rng.uniform(-1.0, 1.0, n_breakable), np.zeros(n_breakable), rng.uniform(-1.5, -0.5, n_breakable)],
                   axis=1)
    sc.add_clumps(grains, "grain", breakable=True, vel=vel)
    sc.add_wall("z", 0.0, "wall", sense=1)
    sc.add_wall("x", 0.0, "wall", sense=1)
    sc.add_wall("x", LX, "wall", sense=-1)
    sc.add_wall("y", 0.0, "wall", sense=1)
    sc.add_wall("y", LY, "wall", sense=-1)
    return sc
