# Same scene as wall_slide.py (damping 0) but starting at z = 0.00999 (overlap 1e-5, ~180x the static
# one): the sphere is thrown up, loses contact and lands again several times (interaction deleted and
# re-created) -> data/wall_hop.json (recorded every 500 iterations).
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/wall_hop.py
import sys, os
CASE, DAMPING, Z0, STEP = 'wall_hop', 0.0, 0.00999, 500
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'wall_slide.py')
exec(compile(open(_f).read(), _f, 'exec'))
