#!/bin/sh
# Regenerate all LIGGGHTS reference data (about 25 s), then check them with the
# pure-Python re-implementation.
#   sh tests/validation/liggghts_reference/scripts/run_all.sh
# Needs /usr/bin/liggghts (Debian package liggghts 3.8.0+repack1) and python3 (standard library only).
set -e
S=$(cd "$(dirname "$0")" && pwd)
W=$(mktemp -d "${TMPDIR:-/tmp}/liggghts-ref.XXXXXX")
export OMP_NUM_THREADS=1

mkdir -p "$W/oblique" "$W/oblique_cdt" "$W/wall" "$W/recontact" "$W/pack"
(cd "$W/oblique" && liggghts -in "$S/in.oblique_impact" -var data "$S/oblique_impact.data" -screen none)
(cd "$W/oblique_cdt" && liggghts -in "$S/in.oblique_impact" -var data "$S/oblique_impact.data" \
     -var rollmodel "rolling_friction cdt" -var rmu 0.1 -screen none)
(cd "$W/wall" && liggghts -in "$S/in.wall_impact" -var data "$S/wall_impact.data" -screen none)
(cd "$W/recontact" && liggghts -in "$S/in.recontact" -var data "$S/recontact.data" -screen none)
python3 "$S/pack_generate.py" "$W/pack/pack_settle.data"
cmp "$W/pack/pack_settle.data" "$S/pack_settle.data"
(cd "$W/pack" && liggghts -in "$S/in.pack_settle" -var data "$S/pack_settle.data" -screen none)

cd "$S"
python3 convert.py oblique_impact "$W/oblique"
python3 convert.py oblique_impact "$W/oblique_cdt" --name oblique_impact_cdt --rollmodel "rolling_friction cdt" --rmu 0.1
python3 convert.py wall_impact "$W/wall"
python3 convert.py recontact "$W/recontact"
python3 convert.py pack_settle "$W/pack"
python3 hertz_mindlin_reference.py
python3 pack_sensitivity.py "$W/pack"
echo "scratch directory (dumps, logs): $W"
