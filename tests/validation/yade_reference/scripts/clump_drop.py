# Clump scene 'clump_drop' (see clump_cases.py) -> data/clump_drop.json
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/clump_drop.py
import sys, os
CASE = 'clump_drop'
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'clump_cases.py')
exec(compile(open(_f).read(), _f, 'exec'))
