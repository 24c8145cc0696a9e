# 40 spheres settling under gravity in an open box of 5 walls (x=0, x=0.1, y=0, y=0.1, z=0).
# Radii uniform in [0.008, 0.012] and a +-2 mm horizontal jitter from numpy seed 1; grid 3x3 per layer
# (x, y in {0.02, 0.05, 0.08}); the bottom of sphere i of layer k is at z = 0.0001 + 0.025 k
# (z_i = 0.0001 + r_i + 0.025 k): the bottom layer lands after ~500 steps; no initial overlaps.
# Spheres get ids 0..39, walls 40..44 (so wall-sphere interactions show the id1 = wall swap).
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/pack_settle.py
import sys, os
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *
import numpy as np

DAMPING, DT, N = 0.3, 1e-5, 40
np.random.seed(1)
radii = np.random.uniform(0.008, 0.012, N)
jitter = np.random.uniform(-0.002, 0.002, (N, 2))
grid = [0.02, 0.05, 0.08]
centres = []
for i in range(N):
    layer, j = divmod(i, 9)
    gx, gy = grid[j % 3], grid[j // 3]
    centres.append((gx + jitter[i, 0], gy + jitter[i, 1], 0.0001 + radii[i] + 0.025 * layer))

mS = add_material('ballastLike', 2600, 1e7, 0.3, 0.5)
mW = add_material('wallMat', 2600, 1e8, 0.3, 0.5)
for c, r in zip(centres, radii):
    O.bodies.append(utils.sphere(tuple(float(x) for x in c), float(r), material=mS))
for pos, ax in [(0.0, 0), (0.1, 0), (0.0, 1), (0.1, 1), (0.0, 2)]:
    O.bodies.append(utils.wall(pos, axis=ax, material=mW))
# sanity: no initial overlaps
for i in range(N):
    for j in range(i + 1, N):
        d = np.linalg.norm(np.array(centres[i]) - np.array(centres[j]))
        assert d > radii[i] + radii[j], (i, j)
setup_engines(DAMPING, DT)
desc = [describe_body(b) for b in O.bodies]
iters = [0, 1, 2, 10, 100] + list(range(250, 5001, 250)) + [7500, 10000, 15000, 20000, 30000, 50000]
recs, events = run_and_record(iters, all_bodies=True)
extra = {'generation': {'numpy_seed': 1, 'radii': [float(r) for r in radii],
                        'centres': [[float(x) for x in c] for c in centres],
                        'recipe': 'np.random.seed(1); radii=np.random.uniform(0.008,0.012,40); '
                                  'jitter=np.random.uniform(-0.002,0.002,(40,2)); sphere i: layer,j=divmod(i,9); '
                                  'x=[0.02,0.05,0.08][j%3]+jitter[i,0]; y=[0.02,0.05,0.08][j//3]+jitter[i,1]; '
                                  'z=0.0001+radii[i]+0.025*layer'}}
write_json('pack_settle.json', 'pack_settle', DAMPING, DT, desc, recs, events, extra=extra)
