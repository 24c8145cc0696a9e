"""Re-implements Yade's clump construction and clump NewtonIntegrator step in plain Python (yade_eigen.py)
and compares with the reference data bit for bit.  Run with python3 (not inside Yade):

    cd tests/validation/yade_reference && python3 scripts/check_clump_integrator.py

1. Construction (data/clump_construction.json and the clump of every clump_* scene): mass, centre, principal
   moments, orientation quaternion, relPos, relOri from the member centres/radii/density.
2. One step: for every pair of consecutive records (k, k+1) of clump_drop, clump_drop_damped and clump_spin,
   the clump state of record k plus the member force/torque accumulators of record k+1 must give Yade's clump
   force/torque accumulators, pos, vel, ori, angVel, angMom and the members' pos, ori, vel, angVel of k+1.
3. Whole run: clump_spin (no contacts, no gravity) integrated from the initial state over all its iterations,
   compared with every record.
Prints a summary and exits with status 1 if anything is not bit-identical.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import yade_eigen as ye  # noqa: E402

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'data')
failures = []


def q_of(d):
    return (d['w'], d['x'], d['y'], d['z'])


def load(name):
    with open(os.path.join(DATA, name + '.json')) as f:
        return json.load(f)


def check(what, got, want):
    if isinstance(want, dict):
        want = q_of(want)
    if list(got) != list(want):
        failures.append((what, got, want))
        return False
    return True


# ------------------------------------------------------------------ 1. construction
def check_construction(rec, density, label):
    members = [(inp['centre'], inp['radius'], density) for inp in rec['member_inputs']]
    p = ye.clump_properties(members, rec.get('discretization', 0))
    ok = True
    ok &= check(label + ' mass', [p['mass']], [rec['mass']])
    ok &= check(label + ' pos', p['pos'], rec['pos'])
    ok &= check(label + ' inertia', p['inertia'], rec['inertia'])
    ok &= check(label + ' ori', p['ori'], rec['ori'])
    for mid, rp, ro in zip(rec['memberIds'], p['relPos'], p['relOri']):
        ok &= check(label + ' relPos %d' % mid, rp, rec['members'][str(mid)]['relPos'])
        ok &= check(label + ' relOri %d' % mid, ro, rec['members'][str(mid)]['relOri'])
    return ok, p


cons = load('clump_construction')
dens = cons['materials'][0]['density']
n_ok = n_flip = n_wneg = 0
for i, rec in enumerate(cons['random']):
    ok, p = check_construction(rec, dens, 'random %d' % i)
    n_ok += ok
    n_flip += p['det_flipped']
    n_wneg += rec['ori']['w'] < 0
print('construction, 100 random clumps (discretization 0): %d bit-identical; %d had det(eigenvectors) = -1 '
      '(third column negated); %d have w < 0' % (n_ok, n_flip, n_wneg))
n_ok = 0
for i, rec in enumerate(cons['pow2']):
    ok, p = check_construction(rec, dens, 'pow2 %d' % i)
    n_ok += ok
print('construction, 30 clumps with a radius where math.pow(r,2) != r*r: %d bit-identical (with r*r)' % n_ok)
for rec in cons['drop']:
    ok, p = check_construction(rec, dens, 'drop d=%d' % rec['discretization'])
    print('construction, drop clump, discretization %2d: %s (mass %r, inertia %r, intersecting=%s)'
          % (rec['discretization'], 'bit-identical' if ok else 'DIFFERS', rec['mass'], rec['inertia'],
             p['intersecting']))

# ------------------------------------------------------------------ 2./3. integrator
def scene_parts(d):
    bodies = {b['id']: b for b in d['bodies']}
    c = [b for b in d['bodies'] if b['kind'] == 'clump'][0]
    mids = sorted(int(i) for i in c['members'])
    rel_pos = [c['members'][str(i)]['relPos'] for i in mids]
    rel_ori = [q_of(c['members'][str(i)]['relOri']) for i in mids]
    return bodies, c, mids, rel_pos, rel_ori


def clump_state(bs, c):
    return {'pos': bs['pos'], 'vel': bs['vel'], 'ori': q_of(bs['ori']), 'angVel': bs['angVel'],
            'angMom': bs['angMom'], 'mass': c['mass'], 'inertia': c['inertia']}


def compare_step(label, new, F, T, mp, mo, mv, mw, rec1, cid, mids):
    b1 = rec1['bodies']
    c1 = b1[str(cid)]
    ok = True
    ok &= check(label + ' clump force', F, c1['force'])
    ok &= check(label + ' clump torque', T, c1['torque'])
    for f in ('pos', 'vel', 'angVel', 'angMom'):
        ok &= check(label + ' clump ' + f, new[f], c1[f])
    ok &= check(label + ' clump ori', new['ori'], c1['ori'])
    for i, mid in enumerate(mids):
        m1 = b1[str(mid)]
        ok &= check(label + ' member %d pos' % mid, mp[i], m1['pos'])
        ok &= check(label + ' member %d ori' % mid, mo[i], m1['ori'])
        ok &= check(label + ' member %d vel' % mid, mv[i], m1['vel'])
        ok &= check(label + ' member %d angVel' % mid, mw[i], m1['angVel'])
    return ok


for case in ('clump_drop', 'clump_drop_damped', 'clump_spin'):
    d = load(case)
    bodies, c, mids, rel_pos, rel_ori = scene_parts(d)
    cid = c['id']
    # the scene's own clump against the construction re-implementation
    inp = d['clump']['member_inputs']
    rec = {'member_inputs': inp, 'memberIds': mids, 'mass': c['mass'], 'pos': c['pos'], 'inertia': c['inertia'],
           'ori': c['ori'], 'members': c['members']}
    ok_c, _ = check_construction(rec, d['materials'][1]['density'], case + ' construction')
    recs = {r['iter']: r for r in d['records']}
    pairs = sorted(k for k in recs if k + 1 in recs)
    n_ok = n_contact = n_multi = 0
    for k in pairs:
        r0, r1 = recs[k], recs[k + 1]
        b0 = r0['bodies']
        st = clump_state(b0[str(cid)], c)
        mf = [r1['bodies'][str(i)]['force'] for i in mids]
        mt = [r1['bodies'][str(i)]['torque'] for i in mids]
        mp0 = [b0[str(i)]['pos'] for i in mids]
        out = ye.clump_step(st, mf, mt, mp0, rel_pos, rel_ori, d['dt'], d['damping'], d['gravity'])
        ok = compare_step('%s %d->%d' % (case, k, k + 1), *out, r1, cid, mids)
        n_ok += ok
        nc = len(r1['interactions'])
        n_contact += ok and nc > 0
        n_multi += ok and nc > 1
    print('%s: construction %s; one-step check on %d record pairs: %d bit-identical (%d with contacts, '
          '%d with >= 2 members in contact)' % (case, 'bit-identical' if ok_c else 'DIFFERS', len(pairs), n_ok,
                                                 n_contact, n_multi))
    if case == 'clump_spin':
        b0 = d['records'][0]['bodies']
        assert d['records'][0]['iter'] == 0
        st = clump_state(b0[str(cid)], c)
        mp = [b0[str(i)]['pos'] for i in mids]
        zero = [[0.0, 0.0, 0.0]] * len(mids)
        last = d['records'][-1]['iter']
        n_rec = n_rec_ok = 0
        for k in range(1, last + 1):
            st, F, T, mp, mo, mv, mw = ye.clump_step(st, zero, zero, mp, rel_pos, rel_ori, d['dt'], d['damping'],
                                                     d['gravity'])
            if k in recs:
                n_rec += 1
                n_rec_ok += compare_step('clump_spin run %d' % k, st, F, T, mp, mo, mv, mw, recs[k], cid, mids)
        print('clump_spin: whole run of %d steps from the initial state: %d of %d records bit-identical'
              % (last, n_rec_ok, n_rec))

if failures:
    print('%d differences, first ones:' % len(failures))
    for f in failures[:10]:
        print('  ', f)
    sys.exit(1)
print('ALL BIT-IDENTICAL')
