# kn, ks (and adhesions) of Ip2_CohFrictMat_CohFrictMat_CohFrictPhys vs Ip2_FrictMat_FrictMat_FrictPhys for the same
# 100 random sphere pairs (radii, young, poisson, frictionAngle, cohesions per sphere; random.Random(7)).
# Each pair slightly overlaps (1e-3 of the smaller radius), the pairs are 1 m apart; one O.step() per model.
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/bond_stiffness.py
import sys, os, random, math
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *
from yref_common import _materials

rng = random.Random(7)   # private generator (utils.sphere draws colours from the global one)
pairs = []
for k in range(100):
    p = {}
    for s in ('a', 'b'):
        p[s] = {'radius': rng.uniform(0.002, 0.02), 'young': 10 ** rng.uniform(6, 11),
                'poisson': rng.uniform(0.05, 0.5), 'frictionAngle': rng.uniform(0.1, 0.8),
                'normalCohesion': 10 ** rng.uniform(4, 8), 'shearCohesion': 10 ** rng.uniform(4, 8),
                'density': 2600.0}
    pairs.append(p)

results = {}
for model in ('CohFrictPhys', 'FrictPhys'):
    reset_scene()
    ids = []
    for k, p in enumerate(pairs):
        ra, rb = p['a']['radius'], p['b']['radius']
        ca = (float(k), 0.0, 0.0)
        cb = (float(k) + (ra + rb - 1e-3 * min(ra, rb)), 0.0, 0.0)
        mats = []
        for s in ('a', 'b'):
            q = p[s]
            if model == 'CohFrictPhys':
                mats.append(add_coh_material('%d%s' % (k, s), q['density'], q['young'], q['poisson'], q['frictionAngle'],
                                             q['normalCohesion'], q['shearCohesion']))
            else:
                mats.append(add_material('%d%s' % (k, s), q['density'], q['young'], q['poisson'], q['frictionAngle']))
        ia = O.bodies.append(utils.sphere(ca, ra, material=mats[0], fixed=True))
        ib = O.bodies.append(utils.sphere(cb, rb, material=mats[1], fixed=True))
        ids.append((ia, ib))
    setup_engines(0.0, 1e-6, cohesive=(model == 'CohFrictPhys'), setCohesionNow=True)
    O.step()
    out = []
    for ia, ib in ids:
        i = O.interactions[ia, ib]
        g, ph = i.geom, i.phys
        r = {'id1': i.id1, 'id2': i.id2, 'refR1': float(g.refR1), 'refR2': float(g.refR2), 'kn': float(ph.kn), 'ks': float(ph.ks),
             'tangensOfFrictionAngle': float(ph.tangensOfFrictionAngle)}
        if model == 'CohFrictPhys':
            r.update({'normalAdhesion': float(ph.normalAdhesion), 'shearAdhesion': float(ph.shearAdhesion)})
        out.append(r)
    results[model] = out

data = {'case': 'bond_stiffness', 'yade_version': version, 'pairs': pairs,
        'note': 'sphere a = material "<k>a" (id1), sphere b = "<k>b" (id2); CohFrictPhys run with '
                'Ig2_Sphere_Sphere_ScGeom6D + Ip2_CohFrictMat_CohFrictMat_CohFrictPhys(setCohesionNow=True), '
                'FrictPhys run with Ig2_Sphere_Sphere_ScGeom + Ip2_FrictMat_FrictMat_FrictPhys',
        'CohFrictPhys': results['CohFrictPhys'], 'FrictPhys': results['FrictPhys']}
path = os.path.join(DATA_DIR, 'bond_stiffness.json')
with open(path, 'w') as f:
    json.dump(data, f, indent=1)
print('wrote', path)
