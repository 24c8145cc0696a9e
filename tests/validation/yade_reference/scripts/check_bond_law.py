"""Re-simulates the bond_* scenes (two spheres, one cohesive interaction) in plain Python and compares every
record with Yade bit for bit.  Run with python3 (not inside Yade):

    cd tests/validation/yade_reference && python3 scripts/check_bond_law.py

Implements, in Yade 2023.02a's evaluation order:
  Ig2_Sphere_Sphere_ScGeom6D (= ScGeom geometry, YADE_MODEL.md 3, avoidGranularRatcheting),
  Ip2_CohFrictMat_CohFrictMat_CohFrictPhys (kn, ks as C++ evaluates 2.0*Ea*Da*Eb*Db/(Ea*Da+Eb*Db) left to right,
      adhesions = min(cohesion) * (r*r), r = min radius, bond only in the creation iteration (setCohesionNow)),
  Law2_ScGeom6D_CohFrictPhys_CohesionMoment (momentRotationLaw False; two variants of the shear cap are tried),
  NewtonIntegrator for spheres (damping 0, spherical rotation).
Prints per case which variant reproduces every record; exits with status 1 if variant A (Yade 2023.02a's law,
YADE_MODEL.md 6) does not.
"""
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from yade_eigen import add, sub, smul, dot, cross, qmul, qnormalize  # noqa: E402

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'data')


def norm(v):
    return math.sqrt(dot(v, v))


class Contact:
    pass


def make_phys(ma, mb, ra, rb, cohesive, frictphys_order=False):
    p = Contact()
    Ea, Eb, Va, Vb, Da, Db = ma['young'], mb['young'], ma['poisson'], mb['poisson'], ra, rb
    if frictphys_order:   # wrong on purpose: the FrictPhys evaluation order (to show the data tells them apart)
        kna, knb = Ea * Da, Eb * Db
        ksa, ksb = kna * Va, knb * Vb
        p.kn = 2 * kna * knb / (kna + knb)
        p.ks = 2 * ksa * ksb / (ksa + ksb)
    else:
        p.kn = 2.0 * Ea * Da * Eb * Db / (Ea * Da + Eb * Db)
        p.ks = 2.0 * Ea * Da * Va * Eb * Db * Vb / (Ea * Da * Va + Eb * Db * Vb) if (Va and Vb) else 0.0
    p.tan = math.tan(min(ma['frictionAngle'], mb['frictionAngle']))
    p.unp = 0.0
    p.fs = [0.0, 0.0, 0.0]
    p.cohesionBroken = True
    p.normalAdhesion = p.shearAdhesion = 0.0
    p.fragile = True
    if cohesive:
        rmin = min(Db, Da)
        p.cohesionBroken = False
        p.normalAdhesion = min(ma['normalCohesion'], mb['normalCohesion']) * (rmin * rmin)
        p.shearAdhesion = min(ma['shearCohesion'], mb['shearCohesion']) * (rmin * rmin)
        p.fragile = ma['fragile'] or mb['fragile']
    p.normalForce = [0.0, 0.0, 0.0]
    return p


def geometry(b1, b2, g_old, dt):
    """Ig2_Sphere_Sphere_ScGeom: returns the new geometry (dict) or None if no contact (not yet real)."""
    r1, r2 = b1['radius'], b2['radius']
    d = sub(b2['pos'], b1['pos'])
    if g_old is None:
        s = 1.0 * (r1 + r2)
        if s * s - dot(d, d) < 0:
            return None
    dist = math.sqrt(dot(d, d))
    n = [d[0] / dist, d[1] / dist, d[2] / dist]
    pen = r1 + r2 - dist
    cp = add(b1['pos'], smul(r1 - 0.5 * pen, n))
    if g_old is None:
        ortho = twist = [0.0, 0.0, 0.0]
    else:
        ortho = cross(g_old['normal'], n)
        angle = dt * 0.5 * dot(g_old['normal'], add(b1['angVel'], b2['angVel']))
        twist = smul(angle, g_old['normal'])
    alpha = (r1 + r2) / (r1 + r2 - pen)
    rv = sub(add(smul(alpha, sub(b2['vel'], b1['vel'])), cross(b2['angVel'], smul(-r2, n))),
             cross(b1['angVel'], smul(r1, n)))
    rv = sub(rv, smul(dot(n, rv), n))
    return {'normal': n, 'pen': pen, 'cp': cp, 'ortho': ortho, 'twist': twist, 'shearInc': smul(dt, rv),
            'r1': r1, 'r2': r2}


def law2(g, p, squared_cap):
    """Law2_ScGeom6D_CohFrictPhys_CohesionMoment (momentRotationLaw False).  Returns the force on body 1,
    or None if the interaction is deleted."""
    Fn = p.kn * (g['pen'] - p.unp)
    if p.fragile and -Fn > p.normalAdhesion:
        return None                                            # tensile break (or a broken bond in tension)
    if -Fn > p.normalAdhesion:                                 # non-fragile: normal plasticity (not used here)
        Fn = -p.normalAdhesion
        p.unp = g['pen'] + p.normalAdhesion / p.kn
    p.normalForce = smul(Fn, g['normal'])
    fs = p.fs
    fs = sub(fs, cross(fs, g['ortho']))                        # ScGeom::rotate
    fs = sub(fs, cross(fs, g['twist']))
    fs = sub(fs, smul(p.ks, g['shearInc']))
    maxFs = p.shearAdhesion + Fn * p.tan                       # cohesionDisablesFriction = False
    maxFs = max(0.0, maxFs)
    if squared_cap:                                            # variant B: compare squares, ratio sqrt(max2/Fs2)
        Fs2, max2 = dot(fs, fs), maxFs * maxFs
        if Fs2 > max2:
            if p.fragile and not p.cohesionBroken:
                p.cohesionBroken = True
                p.normalAdhesion = p.shearAdhesion = 0.0
                maxFs = max(0.0, Fn * p.tan)
                max2 = maxFs * maxFs
            fs = smul(math.sqrt(max2 / Fs2), fs)
            if Fn < 0:
                p.normalForce = [0.0, 0.0, 0.0]
    else:                                                      # variant A: Fs = |fs|, fs *= maxFs/Fs
        Fs = norm(fs)
        if Fs > maxFs:
            if p.fragile and not p.cohesionBroken:
                p.cohesionBroken = True
                p.normalAdhesion = p.shearAdhesion = 0.0
                maxFs = max(0.0, Fn * p.tan)
            fs = smul(maxFs / Fs, fs)
            if Fn < 0:
                p.normalForce = [0.0, 0.0, 0.0]
    p.fs = fs
    return sub(smul(-1.0, p.normalForce), fs)                  # -normalForce - shearForce


def newton(b, f, t, dt, grav):
    if b['blockedDOFs'] != 'xyzXYZ':
        acc = [f[i] / b['mass'] + grav[i] for i in range(3)]
        b['vel'] = add(b['vel'], smul(dt, acc))
        aa = [t[i] / b['inertia'][i] for i in range(3)]
        b['angVel'] = add(b['angVel'], smul(dt, aa))
    b['pos'] = add(b['pos'], [b['vel'][0] * dt, b['vel'][1] * dt, b['vel'][2] * dt])
    w = b['angVel']
    a2 = dot(w, w)
    if a2 != 0:
        a = math.sqrt(a2)
        ax = [w[0] / a, w[1] / a, w[2] / a]
        ha = 0.5 * (a * dt)
        s = math.sin(ha)
        q = (math.cos(ha), s * ax[0], s * ax[1], s * ax[2])
        b['ori'] = qmul(q, b['ori'])
    b['ori'] = qnormalize(b['ori'])


def run(d, squared_cap, frictphys_order=False):
    mats = {m['id']: m for m in d['materials']}
    bodies = []
    for bd in sorted(d['bodies'], key=lambda b: b['id']):
        bodies.append({'pos': list(bd['pos']), 'vel': list(bd['vel']), 'angVel': list(bd['angVel']),
                       'ori': (bd['ori']['w'], bd['ori']['x'], bd['ori']['y'], bd['ori']['z']),
                       'mass': bd['mass'], 'inertia': bd['inertia'], 'radius': bd['radius'],
                       'blockedDOFs': bd['blockedDOFs'], 'material': mats[bd['material']]})
    dt, grav = d['dt'], d['gravity']
    recs = {r['iter']: r for r in d['records']}
    last = d['records'][-1]['iter']
    g = p = None
    made = None
    bad = []
    events = []
    for it in range(0, last + 1):
        if it > 0:
            b1, b2 = bodies
            f1 = t1 = f2 = t2 = [0.0, 0.0, 0.0]
            gn = geometry(b1, b2, g, dt)
            if gn is not None:
                if g is None:                                  # new interaction: phys once, bonded in iteration 1 only
                    p = make_phys(b1['material'], b2['material'], b1['radius'], b2['radius'], cohesive=(it == 1),
                                   frictphys_order=frictphys_order)
                    made = it - 1
                    events.append((it, 'created'))
                broken_before = p.cohesionBroken
                f = law2(gn, p, squared_cap)
                if f is None:
                    g = p = None
                    events.append((it, 'deleted'))
                else:
                    g = gn
                    if p.cohesionBroken and not broken_before:
                        events.append((it, 'cohesion_broken'))
                    f1, f2 = f, smul(-1.0, f)
                    t1 = cross(sub(gn['cp'], b1['pos']), f)
                    t2 = smul(-1.0, cross(sub(gn['cp'], b2['pos']), f))
            for b, ff, tt in ((b1, f1, t1), (b2, f2, t2)):
                b['force'], b['torque'] = ff, tt
                newton(b, ff, tt, dt, grav)
        if it in recs and it > 0:
            r = recs[it]
            for i, b in enumerate(bodies):
                rb = r['bodies'][str(i)]
                for k in ('pos', 'vel', 'angVel', 'force', 'torque'):
                    if list(b[k]) != rb[k]:
                        bad.append((it, 'body %d %s' % (i, k), b[k], rb[k]))
                if list(b['ori']) != [rb['ori'][c] for c in 'wxyz']:
                    bad.append((it, 'body %d ori' % i, b['ori'], rb['ori']))
            want = r['interactions']
            if (g is None) != (len(want) == 0):
                bad.append((it, 'interaction real', g is not None, len(want)))
            elif g is not None:
                I = want[0]
                got = {'normalForce': p.normalForce, 'shearForce': p.fs, 'penetrationDepth': g['pen'],
                       'normal': g['normal'], 'contactPoint': g['cp'], 'shearInc': g['shearInc'], 'kn': p.kn,
                       'ks': p.ks, 'tangensOfFrictionAngle': p.tan, 'normalAdhesion': p.normalAdhesion,
                       'shearAdhesion': p.shearAdhesion, 'cohesionBroken': p.cohesionBroken, 'unp': p.unp,
                       'iterMadeReal': made}
                for k, v in got.items():
                    if (list(v) if isinstance(v, list) else v) != I[k]:
                        bad.append((it, k, v, I[k]))
    want_ev = [(e['iter'], e['event']) for e in d['interaction_events']]
    if events != want_ev:
        bad.append(('events', events, want_ev))
    return bad, events


status = 0
for case in ('bond_tension', 'bond_shear', 'bond_dynamic'):
    with open(os.path.join(DATA, case + '.json')) as fh:
        d = json.load(fh)
    res = {}
    for name, sq, fo in (('A: |Fs| > maxFs, Fs *= maxFs/|Fs|', False, False),
                         ('B: |Fs|^2 > maxFs^2, Fs *= sqrt(maxFs^2/|Fs|^2)', True, False),
                         ('A with kn, ks in the FrictPhys order', False, True)):
        bad, events = run(d, sq, fo)
        res[name] = bad
        print('%-13s %-50s %s' % (case, name, 'all %d records bit-identical, events %s' % (len(d['records']), events)
                                  if not bad else '%d differences, first: %s' % (len(bad), bad[0])))
    if res['A: |Fs| > maxFs, Fs *= maxFs/|Fs|']:
        status = 1
sys.exit(status)
