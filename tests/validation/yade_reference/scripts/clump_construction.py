# Clump construction only (no time steps): what O.bodies.appendClumped computes.
#  * 'drop': the 3-member clump of clump_cases.py (at its clump_drop position) with discretization 0 (default:
#    member volumes and inertias simply summed, overlaps counted twice) and with discretization 5, 10, 20
#    (Yade's grid integration over the union of the spheres, overlaps counted once).
#  * 'pow2': 30 two-sphere clumps whose first radius r has math.pow(r, 2) != r*r (glibc's pow is not always
#    correctly rounded): they show that Yade's (2/5.)*m*pow(r,2) is evaluated with r*r (GCC folds pow(x,2)).
#  * 'random': 100 clumps of 2-6 non-fixed spheres (random.Random(3): centres uniform in [-0.02,0.02]^3, radii uniform
#    in [0.005,0.015], density 2600), discretization 0. About half of them have an eigenvector matrix with
#    determinant -1 (see NOTES.md, "Facts for the implementer").
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/clump_construction.py
import sys, os, random, math
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *
from yref_common import _materials

MEMBERS = [((0.0, 0.0, 0.0), 0.01), ((0.012, 0.004, 0.0025), 0.012), ((0.003, 0.011, -0.0023), 0.008)]
BASE = (0.0, 0.0, 0.01035)


def clump_record(cid, mids, inputs, discretization):
    c = O.bodies[cid]
    s = c.state
    rec = {'discretization': discretization, 'clumpId': cid, 'memberIds': list(mids),
           'member_inputs': inputs,
           'mass': float(s.mass), 'pos': v3(s.pos), 'ori': quat(s.ori), 'inertia': v3(s.inertia),
           'aspherical': bool(c.aspherical),
           'members': {str(i): {'relPos': v3(se3[0]), 'relOri': quat(se3[1])}
                       for i, se3 in sorted(c.shape.members.items())},
           # the members' own bodies after clumping (pos/ori/mass/inertia are left as utils.sphere made them)
           'member_bodies': {str(i): {'pos': v3(O.bodies[i].state.pos), 'ori': quat(O.bodies[i].state.ori),
                                      'mass': float(O.bodies[i].state.mass),
                                      'inertia': v3(O.bodies[i].state.inertia)} for i in mids}}
    return rec


drop = []
for disc in (0, 5, 10, 20):
    reset_scene()
    mS = add_material('ballastLike', 2600, 1e8, 0.3, 0.5)
    inputs = [{'centre': [float(b + o) for b, o in zip(BASE, off)], 'radius': r} for off, r in MEMBERS]
    sph = [utils.sphere(tuple(i['centre']), i['radius'], material=mS) for i in inputs]
    cid, mids = O.bodies.appendClumped(sph, discretization=disc)
    drop.append(clump_record(cid, mids, inputs, disc))
    print('discretization', disc, drop[-1]['mass'], drop[-1]['inertia'])

reset_scene()
mS = add_material('ballastLike', 2600, 1e8, 0.3, 0.5)
rng = random.Random(3)   # private generator: utils.sphere draws random colours from the global one
rand = []
for k in range(100):
    n = rng.randint(2, 6)
    inputs = []
    for i in range(n):
        c = [rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02)]
        inputs.append({'centre': c, 'radius': rng.uniform(0.005, 0.015)})
    sph = [utils.sphere(tuple(i['centre']), i['radius'], material=mS) for i in inputs]
    cid, mids = O.bodies.appendClumped(sph)
    rand.append(clump_record(cid, mids, inputs, 0))

reset_scene()
mS = add_material('ballastLike', 2600, 1e8, 0.3, 0.5)
rng = random.Random(1)
xs = [rng.uniform(0.001, 0.02) for _ in range(100000)]
bad = [x for x in xs if math.pow(x, 2) != x * x][:30]
pow2 = []
for k, r in enumerate(bad):
    inputs = [{'centre': [0.001 * k, 0.0, 0.0], 'radius': r}, {'centre': [0.001 * k + 0.013, 0.004, 0.002], 'radius': 0.006}]
    sph = [utils.sphere(tuple(i['centre']), i['radius'], material=mS) for i in inputs]
    cid, mids = O.bodies.appendClumped(sph)
    pow2.append(clump_record(cid, mids, inputs, 0))

out = {'case': 'clump_construction', 'yade_version': version, 'materials': _materials,
       'note': 'utils.sphere(centre, radius, material=ballastLike) for every member, then '
               'O.bodies.appendClumped(spheres, discretization=d); ori as {w,x,y,z}; relPos/relOri from '
               'O.bodies[clumpId].shape.members (member pos = clump pos + ori*relPos, member ori = ori*relOri)',
       'drop': drop, 'random': rand, 'pow2': pow2}
path = os.path.join(DATA_DIR, 'clump_construction.json')
with open(path, 'w') as f:
    json.dump(out, f, indent=1)
print('wrote', path)
