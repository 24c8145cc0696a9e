# Shared helpers for the Yade reference scripts (run inside Yade: yade -n -j1 -x scripts/NAME.py).
# Every script writes ONE JSON file into ../data/ (relative to this scripts/ folder).
# Floats are written by Python's json module, which uses repr() -> 17 significant digits round-trip.
import json
import math
import os
import sys

from yade import O, utils
from yade.config import version
from yade.wrapper import (ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb, Bo1_Wall_Aabb,
                          Bo1_Facet_Aabb, InteractionLoop, Ig2_Sphere_Sphere_ScGeom,
                          Ig2_Wall_Sphere_ScGeom, Ig2_Facet_Sphere_ScGeom,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                          NewtonIntegrator, FrictMat, Sphere, Wall, Facet, Clump, CohFrictMat,
                          CohFrictPhys, Ig2_Sphere_Sphere_ScGeom6D, Ip2_CohFrictMat_CohFrictMat_CohFrictPhys,
                          Law2_ScGeom6D_CohFrictPhys_CohesionMoment)

SCRIPT_DIR = os.path.dirname(os.path.abspath(sys.argv[0]))
DATA_DIR = os.path.join(os.path.dirname(SCRIPT_DIR), 'data')
GRAVITY = (0.0, 0.0, -9.81)

_materials = []  # JSON descriptions, index == Yade material id
_gravity = [GRAVITY]  # gravity of the current scene (set by setup_engines), written by write_json


def v3(v):
    return [float(v[0]), float(v[1]), float(v[2])]


def quat(q):
    # Yade Quaternion: q[0..3] = x, y, z, w (Eigen coefficient order); store both forms explicitly
    return {'w': float(q[3]), 'x': float(q[0]), 'y': float(q[1]), 'z': float(q[2])}


def add_material(label, density, young, poisson, frictionAngle):
    m = FrictMat(density=density, young=young, poisson=poisson, frictionAngle=frictionAngle, label=label)
    mid = O.materials.append(m)
    _materials.append({'id': mid, 'label': label, 'type': 'FrictMat', 'density': float(density),
                       'young': float(young), 'poisson': float(poisson),
                       'frictionAngle': float(frictionAngle)})
    return mid


def add_coh_material(label, density, young, poisson, frictionAngle, normalCohesion, shearCohesion,
                     fragile=True, momentRotationLaw=False, isCohesive=True):
    m = CohFrictMat(density=density, young=young, poisson=poisson, frictionAngle=frictionAngle, label=label,
                    isCohesive=isCohesive, normalCohesion=normalCohesion, shearCohesion=shearCohesion,
                    fragile=fragile, momentRotationLaw=momentRotationLaw)
    mid = O.materials.append(m)
    _materials.append({'id': mid, 'label': label, 'type': 'CohFrictMat', 'density': float(density),
                       'young': float(young), 'poisson': float(poisson),
                       'frictionAngle': float(frictionAngle), 'isCohesive': bool(isCohesive),
                       'normalCohesion': float(normalCohesion), 'shearCohesion': float(shearCohesion),
                       'fragile': bool(fragile), 'momentRotationLaw': bool(momentRotationLaw)})
    return mid


def reset_scene():
    """O.reset() and forget the materials (to rebuild the same scene in a second pass)."""
    O.reset()
    del _materials[:]


def setup_engines(damping, dt, gravity=GRAVITY, cohesive=False, setCohesionNow=True,
                  setCohesionOnNewContacts=False):
    """The linear-model engines (default), or with cohesive=True the cohesive model:
    Ig2_Sphere_Sphere_ScGeom6D, Ip2_CohFrictMat_CohFrictMat_CohFrictPhys, Law2_ScGeom6D_CohFrictPhys_CohesionMoment."""
    if cohesive:
        loop = InteractionLoop(
            [Ig2_Sphere_Sphere_ScGeom6D()],
            [Ip2_CohFrictMat_CohFrictMat_CohFrictPhys(setCohesionNow=setCohesionNow,
                                                      setCohesionOnNewContacts=setCohesionOnNewContacts)],
            [Law2_ScGeom6D_CohFrictPhys_CohesionMoment()])
    else:
        loop = InteractionLoop(
            [Ig2_Sphere_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom()],
            [Ip2_FrictMat_FrictMat_FrictPhys()],
            [Law2_ScGeom_FrictPhys_CundallStrack()])
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb(), Bo1_Facet_Aabb()]),
        loop,
        NewtonIntegrator(damping=damping, gravity=tuple(gravity)),
    ]
    O.dt = dt
    _gravity[0] = tuple(float(g) for g in gravity)


def describe_body(b, extra=None):
    s = b.state
    d = {'id': b.id, 'material': (b.material.id if b.material is not None else None),
         'fixed': bool(s.blockedDOFs == 'xyzXYZ'), 'blockedDOFs': s.blockedDOFs,
         'pos': v3(s.pos), 'ori': quat(s.ori), 'vel': v3(s.vel), 'angVel': v3(s.angVel),
         'mass': float(s.mass), 'inertia': v3(s.inertia)}
    sh = b.shape
    if isinstance(sh, Sphere):
        d['kind'] = 'sphere'
        d['radius'] = float(sh.radius)
    elif isinstance(sh, Wall):
        d['kind'] = 'wall'
        d['axis'] = int(sh.axis)
        d['sense'] = int(sh.sense)
        d['position'] = float(s.pos[sh.axis])
    elif isinstance(sh, Clump):
        d['kind'] = 'clump'
        d['angMom'] = v3(s.angMom)
        d['aspherical'] = bool(b.aspherical)
        # {member id: (relPos, relOri)} as stored by Yade (member pos = clump pos + ori*relPos)
        d['members'] = {str(mid): {'relPos': v3(se3[0]), 'relOri': quat(se3[1])}
                        for mid, se3 in sorted(sh.members.items())}
    elif isinstance(sh, Facet):
        d['kind'] = 'facet'
        d['vertices_relative'] = [v3(v) for v in sh.vertices]
        d['vertices_global'] = [v3(s.pos + s.ori * v) for v in sh.vertices]
        d['normal'] = v3(sh.normal)
    else:
        d['kind'] = type(sh).__name__
    if b.isClumpMember:
        d['clumpId'] = int(b.clumpId)
    if extra:
        d.update(extra)
    return d


def snapshot(all_bodies=False):
    bodies = {}
    for b in O.bodies:
        if b is None:
            continue
        if (not all_bodies) and b.state.blockedDOFs == 'xyzXYZ':
            continue
        s = b.state
        bodies[str(b.id)] = {'pos': v3(s.pos), 'vel': v3(s.vel), 'angVel': v3(s.angVel),
                             'ori': quat(s.ori),
                             # accumulators of the last step (ForceResetter clears them at the next one)
                             'force': v3(O.forces.f(b.id)), 'torque': v3(O.forces.t(b.id))}
        if b.isClump:
            bodies[str(b.id)].update({'angMom': v3(s.angMom), 'mass': float(s.mass), 'inertia': v3(s.inertia)})
    inters = []
    for i in O.interactions:
        if not i.isReal:
            continue
        g, p = i.geom, i.phys
        inters.append({
            'id1': i.id1, 'id2': i.id2,
            'iterMadeReal': int(i.iterMadeReal),
            'normalForce': v3(p.normalForce), 'shearForce': v3(p.shearForce),
            'penetrationDepth': float(g.penetrationDepth), 'normal': v3(g.normal),
            'contactPoint': v3(g.contactPoint), 'shearInc': v3(g.shearInc),
            'radius1': float(g.refR1), 'radius2': float(g.refR2),
            'kn': float(p.kn), 'ks': float(p.ks),
            'tangensOfFrictionAngle': float(p.tangensOfFrictionAngle),
        })
        if isinstance(p, CohFrictPhys):
            inters[-1].update({'normalAdhesion': float(p.normalAdhesion), 'shearAdhesion': float(p.shearAdhesion),
                               'cohesionBroken': bool(p.cohesionBroken), 'unp': float(p.unp),
                               'unpMax': float(p.unpMax), 'fragile': bool(p.fragile),
                               'initCohesion': bool(p.initCohesion),
                               'momentRotationLaw': bool(p.momentRotationLaw)})
    return {'iter': int(O.iter), 'time': float(O.time), 'bodies': bodies, 'interactions': inters}


def _real_pairs():
    return {(i.id1, i.id2): int(i.iterMadeReal) for i in O.interactions if i.isReal}


def run_and_record(iters, all_bodies=False, verbose=True, contact_every=None):
    """Advance one iteration at a time (O.step(), same engines as O.run) and snapshot after each
    iteration listed in iters (the value of O.iter after the step).  Also log every change of the set
    of real interactions: returns (records, events); an event {'iter': k, 'event': 'created'|'deleted',
    'id1', 'id2'} means the interaction is real after iteration k and was not after k-1 (or the
    reverse).  With contact_every=m, a snapshot is also taken after every iteration k with
    k % m == 0 at which at least one interaction is real (dense sampling of short impacts)."""
    records, events = [], []
    targets = sorted(set(iters))
    prev = _real_pairs()
    for k in targets:
        assert k >= O.iter
        while O.iter < k:
            O.step()
            cur = _real_pairs()
            if contact_every and cur and O.iter % contact_every == 0 and O.iter != k:
                records.append(snapshot(all_bodies))
            if cur.keys() != prev.keys():
                for p in sorted(cur.keys() - prev.keys()):
                    events.append({'iter': int(O.iter), 'event': 'created', 'id1': p[0], 'id2': p[1],
                                   'iterMadeReal': cur[p]})
                for p in sorted(prev.keys() - cur.keys()):
                    events.append({'iter': int(O.iter), 'event': 'deleted', 'id1': p[0], 'id2': p[1]})
            prev = cur
        assert O.iter == k, (O.iter, k)
        rec = snapshot(all_bodies)
        records.append(rec)
        if verbose:
            print('iter %d: %d real interactions' % (k, len(rec['interactions'])))
    if verbose:
        print('%d interaction events' % len(events))
    return records, events


def write_json(name, case, damping, dt, bodies_desc, records, events=None, extra=None, compact=False):
    out = {'case': case, 'yade_version': version, 'dt': float(dt), 'damping': float(damping),
           'gravity': list(_gravity[0]), 'engines': [e.__class__.__name__ for e in O.engines],
           'materials': _materials, 'bodies': bodies_desc, 'records': records,
           'interaction_events': events if events is not None else []}
    if extra:
        out.update(extra)
    os.makedirs(DATA_DIR, exist_ok=True)
    path = os.path.join(DATA_DIR, name)
    with open(path, 'w') as f:
        if compact:   # same content, no indentation (large files)
            json.dump(out, f, separators=(',', ':'))
        else:
            json.dump(out, f, indent=1)
    print('wrote', path)


def event_iters(events, before, after, lo=0, hi=None):
    """Iterations k-before .. k+after around every interaction event k (clipped to [lo, hi])."""
    out = set()
    for e in events:
        for k in range(e['iter'] - before, e['iter'] + after + 1):
            if k >= lo and (hi is None or k <= hi):
                out.add(k)
    return out
