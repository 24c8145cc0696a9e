# Clump scene 'clump_drop_damped' (see clump_cases.py) -> data/clump_drop_damped.json
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/clump_drop_damped.py
import sys, os
CASE = 'clump_drop_damped'
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'clump_cases.py')
exec(compile(open(_f).read(), _f, 'exec'))
