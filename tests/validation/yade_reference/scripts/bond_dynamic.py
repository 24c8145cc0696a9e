# Bond scene 'bond_dynamic' (see bond_cases.py) -> data/bond_dynamic.json
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/bond_dynamic.py
import sys, os
CASE = 'bond_dynamic'
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'bond_cases.py')
exec(compile(open(_f).read(), _f, 'exec'))
