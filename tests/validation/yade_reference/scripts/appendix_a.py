# SPEC 2.1 / thesis appendix A: fixed sphere + falling sphere.  Run: yade -n -j1 -x scripts/appendix_a.py
import sys, os
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
from yref_common import *

DAMPING, DT = 0.1, 2e-6
mA = add_material('fixedMat', 1380, 2.5e9, 0.4, 1.0)
mB = add_material('fallingMat', 7850, 2.1e8, 0.3, 1.0)
O.bodies.append(utils.sphere((0, 0, 0), 0.05, fixed=True, material=mA))
O.bodies.append(utils.sphere((0.01, 0.01, 0.2), 0.03, material=mB))
setup_engines(DAMPING, DT)
desc = [describe_body(b) for b in O.bodies]
iters = [0, 1, 2, 82867, 82868, 82869, 82870, 82871, 82872, 83000, 84000, 86000, 90000, 100000]
recs, events = run_and_record(iters)
write_json('appendix_a.json', 'appendix_a', DAMPING, DT, desc, recs, events)
