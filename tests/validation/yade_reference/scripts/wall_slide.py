# Sphere r=0.01 sliding, then rolling, on the wall z=0 (utils.wall(0, axis=2)), damping 0.
# The sphere starts at the static-equilibrium overlap (z = r - m g / kn, about 5.6e-8 m) so that it
# stays on the wall; wall_hop.py is the same with the overlap 1e-5 (z = 0.00999), which makes it hop.
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/wall_slide.py
import sys, os
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *

CASE = globals().get('CASE', 'wall_slide')
DAMPING = globals().get('DAMPING', 0.0)
DT = 1e-6
R = 0.01
LAST = 100000
STEP = globals().get('STEP', 2000)  # recording interval

mW = add_material('steelLike', 7850, 2e9, 0.3, 0.4)
mS = add_material('sphereMat', 2600, 1e8, 0.3, 0.4)
O.bodies.append(utils.wall(0, axis=2, material=mW))
s = O.bodies.append(utils.sphere((0, 0, 0), R, material=mS))
b = O.bodies[s]
if 'Z0' in globals():
    z0 = Z0
else:
    # kn of the wall contact (Ip2 with radius1 = radius2 = R), same evaluation order as Yade
    kna, knb = 2e9 * R, 1e8 * R
    kn = 2 * kna * knb / (kna + knb)
    z0 = R - b.state.mass * 9.81 / kn
b.state.pos = (0.0, 0.0, z0)
b.state.vel = (1.0, 0.3, 0.0)
b.state.angVel = (0.0, 0.0, 5.0)
setup_engines(DAMPING, DT)
desc = [describe_body(bb) for bb in O.bodies]
iters = [0, 1, 2, 3, 10, 100, 1000] + list(range(STEP, LAST + 1, STEP))
recs, events = run_and_record(iters)
write_json(CASE + '.json', CASE, DAMPING, DT, desc, recs, events)
