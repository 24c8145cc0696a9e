# Rigid clumps (O.bodies.appendClumped, discretization=0) with the linear model.
# Run one of the wrappers (each sets CASE and exec's this file):
#   cd tests/validation/yade_reference && yade -n -j1 -x scripts/clump_drop.py
#   clump_drop         3-sphere clump dropped on the wall z=0 (FrictMat, phi 0.5), damping 0
#   clump_drop_damped  the same with NewtonIntegrator damping 0.3 (settles on its 3 members)
#   clump_spin         the same clump, no wall, no gravity, spinning about a non-principal axis (angMom set)
# Ids: drop scenes: wall 0, members 1, 2, 3 (radii 0.01, 0.012, 0.008), clump 4;
#      spin: members 0, 1, 2, clump 3.
import sys, os
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *

DT = 5e-6
# members: offset from the first centre, radius (centres not on a line, so the principal frame is oblique)
MEMBERS = [((0.0, 0.0, 0.0), 0.01), ((0.012, 0.004, 0.0025), 0.012), ((0.003, 0.011, -0.0023), 0.008)]
BASE_DROP = (0.0, 0.0, 0.01035)   # lowest point (member r=0.008) 0.05 mm above the wall
VEL_DROP = (0.3, 0.1, -0.05)
BASE_SPIN = (0.0, 0.0, 0.0)
VEL_SPIN = (0.05, -0.02, 0.01)
ANGMOM_SPIN = (1.2e-4, -0.5e-4, 0.8e-4)   # global angular momentum [kg m^2/s], not along a principal axis

SPIN = CASE == 'clump_spin'
DAMPING = {'clump_drop': 0.0, 'clump_drop_damped': 0.3, 'clump_spin': 0.0}[CASE]
GRAV = (0.0, 0.0, 0.0) if SPIN else GRAVITY
LAST = {'clump_drop': 40000, 'clump_drop_damped': 36000, 'clump_spin': 10000}[CASE]


def build():
    mW = add_material('steelLike', 7850, 2e9, 0.3, 0.5)
    mS = add_material('ballastLike', 2600, 1e8, 0.3, 0.5)
    if not SPIN:
        O.bodies.append(utils.wall(0, axis=2, material=mW))
    base = BASE_SPIN if SPIN else BASE_DROP
    sph = [utils.sphere(tuple(b + o for b, o in zip(base, off)), r, material=mS) for off, r in MEMBERS]
    inputs = [{'id': None, 'centre': [float(b + o) for b, o in zip(base, off)], 'radius': r} for off, r in MEMBERS]
    cid, mids = O.bodies.appendClumped(sph)
    for inp, i in zip(inputs, mids):
        inp['id'] = i
    c = O.bodies[cid]
    vel = VEL_SPIN if SPIN else VEL_DROP
    c.state.vel = vel
    if SPIN:
        c.state.angMom = ANGMOM_SPIN
    # member velocities consistent with the clump (no spin at start); Newton overwrites them anyway
    for i in mids:
        O.bodies[i].state.vel = vel
    setup_engines(DAMPING, DT, gravity=GRAV)
    return cid, mids, inputs


cid, mids, inputs = build()
if SPIN:
    iters = [0, 1, 2, 3, 4, 5, 10] + list(range(100, LAST + 1, 100)) + [1001, 5001, LAST - 1]
    desc = [describe_body(b) for b in O.bodies]
    recs, events = run_and_record(iters, verbose=False)
else:
    # pass 1: find the contact events; pass 2 (same scene, deterministic): record around them
    _, events1 = run_and_record([LAST], verbose=False)
    first_c = min(e['iter'] for e in events1 if e['event'] == 'created')
    first_d = min(e['iter'] for e in events1 if e['event'] == 'deleted')
    two = three = None  # first iteration with two (three) members in contact
    n = 0
    for e in sorted(events1, key=lambda e: e['iter']):
        n += 1 if e['event'] == 'created' else -1
        if n >= 2 and two is None:
            two = e['iter']
        if n >= 3 and three is None:
            three = e['iter']
    iters = set([0, 1, 2, 3, 10, 100] + list(range(1000, LAST + 1, 1000)))
    iters |= set(range(first_c - 3, first_d + 3))            # the whole first impact, every iteration
    iters |= set(range(two - 5, two + 30))                     # first double contact, every iteration
    if three is not None:
        iters |= set(range(three - 2, three + 20))             # first triple contact, every iteration
    # every other event: k-1, k, k+1 (damped: only k after iteration 10000, where it chatters and rocks on 2-3
    # members and events are frequent; keeps the file small)
    dense_until = 10000 if DAMPING > 0 else LAST
    iters |= event_iters([e for e in events1 if e['iter'] <= dense_until], 1, 1, hi=LAST)
    iters |= event_iters([e for e in events1 if e['iter'] > dense_until], 0, 0, hi=LAST)
    reset_scene()
    cid, mids, inputs = build()
    desc = [describe_body(b) for b in O.bodies]
    recs, events = run_and_record(sorted(iters), verbose=False, contact_every=100)
    assert events == events1
    print('first contact', first_c, 'first deletion', first_d, 'first double contact', two, 'triple', three)
print(len(recs), 'records', len(events), 'events')
extra = {'clump': {'id': cid, 'members': mids, 'member_inputs': inputs,
                   'appendClumped': 'O.bodies.appendClumped([utils.sphere(c, r, material=ballastLike) ...]) '
                                    '(discretization=0)',
                   'initial': {'vel': list(VEL_SPIN if SPIN else VEL_DROP),
                               'angMom': list(ANGMOM_SPIN) if SPIN else [0.0, 0.0, 0.0],
                               'member_vel': 'set equal to the clump vel'}}}
# the drop files are written without indentation (size)
write_json(CASE + '.json', CASE, DAMPING, DT, desc, recs, events, extra=extra, compact=not SPIN)
