# Cohesive bonds between two spheres (CohFrictMat, fragile, momentRotationLaw=False) with
# Ig2_Sphere_Sphere_ScGeom6D + Ip2_CohFrictMat_CohFrictMat_CohFrictPhys(setCohesionNow=True) +
# Law2_ScGeom6D_CohFrictPhys_CohesionMoment.  Run one of the wrappers (each sets CASE and exec's this file):
#   cd tests/validation/yade_reference && yade -n -j1 -x scripts/bond_tension.py
#   bond_tension   sphere 0 fixed, sphere 1 blocked and moved away along the centre line at constant velocity
#   bond_shear     sphere 1 blocked and moved perpendicular to the initial centre line (the bond starts compressed)
#   bond_dynamic   both spheres free, no gravity: sphere 1 starts with a velocity away from sphere 0 plus a
#                  tangential part; the bond oscillates and breaks in shear (under tension) after ~2 oscillations
# Sphere 0: r 0.01 at the origin, material A; sphere 1: r 0.0085, material B, at distance r0 + r1 - PEN0 along the
# oblique unit vector E (not a coordinate axis).  The bond is made in iteration 1 (setCohesionNow), so it is
# created with the initial overlap PEN0: Yade's bond is NOT stress-free (unp = 0), the initial overlap pushes.
import sys, os, math
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *

DT = 1e-6
R0, R1 = 0.01, 0.0085
_e = (1.0, 0.3, 0.2)
_n = math.sqrt(_e[0] ** 2 + _e[1] ** 2 + _e[2] ** 2)
E = tuple(x / _n for x in _e)                      # centre line, 0 -> 1
_t = (-0.3, 1.0, 0.0)                              # a direction perpendicular to E
_d = sum(a * b for a, b in zip(_t, E))
_t = tuple(a - _d * b for a, b in zip(_t, E))
_n = math.sqrt(sum(a * a for a in _t))
T = tuple(a / _n for a in _t)                      # unit, perpendicular to E

VN = globals().get('VN', 0.06)   # bond_dynamic: initial velocity of sphere 1 along E and along T
VT = globals().get('VT', 0.45)
CFG = {
    # pen0, velocity of sphere 1 (blocked for tension/shear, initial for dynamic), last iteration, gravity
    'bond_tension': dict(pen0=2e-6, vel=tuple(0.01 * a for a in E), last=1000, blocked=True),
    'bond_shear': dict(pen0=1e-5, vel=tuple(0.05 * a for a in T), last=2500, blocked=True),
    # 0.06 m/s away along E plus 0.45 m/s along T: the shear force reaches its limit (shearAdhesion + Fn tan, with
    # Fn < 0 in tension) after about 2.3 normal oscillation periods (~360 iterations each)
    'bond_dynamic': dict(pen0=2e-6, vel=tuple(VN * a + VT * b for a, b in zip(E, T)), last=1500, blocked=False),
}[CASE]
PEN0 = CFG['pen0']
GRAV = (0.0, 0.0, 0.0)
DAMPING = 0.0


def build():
    # E, nu, r chosen so that Yade's kn and ks differ in the last bit from the FrictPhys evaluation order
    mA = add_coh_material('cohA', 2600, 1.5e8, 0.3, 0.5, normalCohesion=2e5, shearCohesion=3e5)
    mB = add_coh_material('cohB', 2600, 1e8, 0.25, 0.6, normalCohesion=1e5, shearCohesion=1.5e5)
    c1 = tuple((R0 + R1 - PEN0) * a for a in E)
    O.bodies.append(utils.sphere((0.0, 0.0, 0.0), R0, material=mA, fixed=CFG['blocked']))
    O.bodies.append(utils.sphere(c1, R1, material=mB, fixed=CFG['blocked']))
    O.bodies[1].state.vel = CFG['vel']
    setup_engines(DAMPING, DT, gravity=GRAV, cohesive=True, setCohesionNow=True, setCohesionOnNewContacts=False)


def bond_state():
    """(real, cohesionBroken) of the interaction 0-1."""
    i = O.interactions[0, 1] if O.interactions.has(0, 1) else None
    if i is None or not i.isReal:
        return (False, None)
    return (True, bool(i.phys.cohesionBroken))


def run_pass(iters=None, every=None):
    """Step to CFG['last']; log bond events; snapshot after the iterations in iters (or every `every`)."""
    events, recs = [], []
    prev = bond_state()
    if iters is not None and 0 in iters:
        recs.append(snapshot(all_bodies=True))
    while O.iter < CFG['last']:
        O.step()
        cur = bond_state()
        if cur != prev:
            if cur[0] and not prev[0]:
                ev = 'created'
            elif prev[0] and not cur[0]:
                ev = 'deleted'
            else:
                ev = 'cohesion_broken' if cur[1] else 'cohesion_restored'
            events.append({'iter': int(O.iter), 'event': ev, 'id1': 0, 'id2': 1})
            prev = cur
        if iters is not None and O.iter in iters:
            recs.append(snapshot(all_bodies=True))
    return recs, events


build()
_, ev1 = run_pass()
print(CASE, 'events', ev1)
iters = set([0, 1, 2, 3, 4, 5, 10] + list(range(20, CFG['last'] + 1, 20)))
for e in ev1:
    if e['event'] != 'created':
        iters |= set(range(e['iter'] - 20, e['iter'] + 21))
if CASE == 'bond_dynamic':   # the oscillation, every 10 iterations
    iters |= set(range(0, CFG['last'] + 1, 10))
reset_scene()
build()
desc = [describe_body(b) for b in O.bodies]
recs, ev2 = run_pass(sorted(iters))
assert ev1 == ev2
print(len(recs), 'records')
extra = {'bond': {'pen0': PEN0, 'centre_line': list(E), 'tangent': list(T), 'sphere1_vel': list(CFG['vel']),
                  'sphere1_blocked': CFG['blocked'],
                  'engines': 'Ig2_Sphere_Sphere_ScGeom6D(), Ip2_CohFrictMat_CohFrictMat_CohFrictPhys(setCohesionNow=True, '
                             'setCohesionOnNewContacts=False), Law2_ScGeom6D_CohFrictPhys_CohesionMoment() (defaults)',
                  'events': 'interaction_events: created / deleted / cohesion_broken (phys.cohesionBroken became True '
                            'while the interaction stays real), at the O.iter after the step'}}
write_json(CASE + '.json', CASE, DAMPING, DT, desc, recs, ev2, extra=extra)
