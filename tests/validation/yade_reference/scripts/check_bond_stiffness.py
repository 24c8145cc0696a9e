"""Which evaluation order reproduces Yade's kn, ks and adhesions bit for bit (data/bond_stiffness.json)?
Run with python3 (not inside Yade):  cd tests/validation/yade_reference && python3 scripts/check_bond_stiffness.py
Candidates are tried on the 100 random pairs for CohFrictPhys and FrictPhys; a candidate 'matches' if it gives
Yade's double exactly for every pair."""
import json
import math
import os

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'data')
with open(os.path.join(DATA, 'bond_stiffness.json')) as f:
    d = json.load(f)

KN = {
    'C++ left to right: 2.0*Ea*Da*Eb*Db/(Ea*Da+Eb*Db) = ((((2*Ea)*Da)*Eb)*Db)/((Ea*Da)+(Eb*Db))':
        lambda Ea, Da, Va, Eb, Db, Vb: 2.0 * Ea * Da * Eb * Db / (Ea * Da + Eb * Db),
    'FrictPhys: kna=Ea*Da, knb=Eb*Db, ((2*kna)*knb)/(kna+knb)':
        lambda Ea, Da, Va, Eb, Db, Vb: 2 * (Ea * Da) * (Eb * Db) / ((Ea * Da) + (Eb * Db)),
    '2*(kna*knb)/(kna+knb)':
        lambda Ea, Da, Va, Eb, Db, Vb: 2 * ((Ea * Da) * (Eb * Db)) / ((Ea * Da) + (Eb * Db)),
    '2*kna*knb/(kna+knb) with kna=Da*Ea':
        lambda Ea, Da, Va, Eb, Db, Vb: 2 * (Da * Ea) * (Db * Eb) / ((Da * Ea) + (Db * Eb)),
}
KS = {
    'C++ left to right: 2.0*Ea*Da*Va*Eb*Db*Vb/(Ea*Da*Va+Eb*Db*Vb)':
        lambda Ea, Da, Va, Eb, Db, Vb: 2.0 * Ea * Da * Va * Eb * Db * Vb / (Ea * Da * Va + Eb * Db * Vb),
    'FrictPhys: ksa=(Ea*Da)*Va, ksb=(Eb*Db)*Vb, ((2*ksa)*ksb)/(ksa+ksb)':
        lambda Ea, Da, Va, Eb, Db, Vb: 2 * ((Ea * Da) * Va) * ((Eb * Db) * Vb) / (((Ea * Da) * Va) + ((Eb * Db) * Vb)),
    '2*ksa*ksb/(ksa+ksb), ksa=Ea*(Da*Va)':
        lambda Ea, Da, Va, Eb, Db, Vb: 2 * (Ea * (Da * Va)) * (Eb * (Db * Vb)) / ((Ea * (Da * Va)) + (Eb * (Db * Vb))),
}
ADH = {
    'c*(r*r), r = min(Da,Db) (C++ pow(r,2) folded to r*r by GCC)': lambda c, Da, Db: c * (min(Db, Da) * min(Db, Da)),
    'c*math.pow(r,2) (glibc pow: not always r*r)': lambda c, Da, Db: c * math.pow(min(Db, Da), 2),
    '(c*r)*r': lambda c, Da, Db: (c * min(Da, Db)) * min(Da, Db),
}


def args(p, r):
    a, b = p['a'], p['b']
    return a['young'], r['refR1'], a['poisson'], b['young'], r['refR2'], b['poisson']


for model in ('CohFrictPhys', 'FrictPhys'):
    res = d[model]
    assert all(r['refR1'] == p['a']['radius'] and r['refR2'] == p['b']['radius'] for p, r in zip(d['pairs'], res))
    for name, table in (('kn', KN), ('ks', KS)):
        for cand, f in table.items():
            n = sum(f(*args(p, r)) == r[name] for p, r in zip(d['pairs'], res))
            print('%-12s %-3s %3d/100  %s' % (model, name, n, cand))
    n = sum(math.tan(min(p['a']['frictionAngle'], p['b']['frictionAngle'])) == r['tangensOfFrictionAngle']
            for p, r in zip(d['pairs'], res))
    print('%-12s tan %3d/100  tan(min(phi_a, phi_b))' % (model, n))
res = d['CohFrictPhys']
for name, key in (('normalAdhesion', 'normalCohesion'), ('shearAdhesion', 'shearCohesion')):
    for cand, f in ADH.items():
        n = sum(f(min(p['a'][key], p['b'][key]), r['refR1'], r['refR2']) == r[name] for p, r in zip(d['pairs'], res))
        print('CohFrictPhys %s %3d/100  %s' % (name, n, cand))
n = sum(a['kn'] == b['kn'] for a, b in zip(d['CohFrictPhys'], d['FrictPhys']))
m = sum(a['ks'] == b['ks'] for a, b in zip(d['CohFrictPhys'], d['FrictPhys']))
print('CohFrictPhys kn == FrictPhys kn in %d/100 pairs, ks in %d/100' % (n, m))
