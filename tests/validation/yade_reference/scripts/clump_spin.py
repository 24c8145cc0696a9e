# Clump scene 'clump_spin' (see clump_cases.py) -> data/clump_spin.json
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/clump_spin.py
import sys, os
CASE = 'clump_spin'
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'clump_cases.py')
exec(compile(open(_f).read(), _f, 'exec'))
