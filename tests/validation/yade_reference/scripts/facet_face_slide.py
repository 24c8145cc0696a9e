# Facet scene 'face_slide' (see facet_cases.py) -> data/facet_face_slide.json
# Run (from tests/validation/yade_reference/): yade -n -j1 -x scripts/facet_face_slide.py
import sys, os
CASE = 'facet_face_slide'
_f = os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), 'facet_cases.py')
exec(compile(open(_f).read(), _f, 'exec'))
