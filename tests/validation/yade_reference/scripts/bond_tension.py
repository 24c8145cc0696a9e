# Bond scene 'bond_tension' (see bond_cases.py) -> data/bond_tension.json
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/bond_tension.py
import sys, os
CASE = 'bond_tension'
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'bond_cases.py')
exec(compile(open(_f).read(), _f, 'exec'))
