# Same scene as wall_slide.py with damping 0.2 -> data/wall_slide_damped.json.
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/wall_slide_damped.py
import sys, os
CASE, DAMPING = 'wall_slide_damped', 0.2
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'wall_slide.py')
exec(compile(open(_f).read(), _f, 'exec'))
