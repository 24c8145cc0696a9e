#!/bin/sh
# Regenerate every JSON in ../data with Yade (Debian package yade 2023.02a), single thread, headless.
set -e
cd "$(dirname "$0")/.."
for s in appendix_a wall_slide wall_slide_damped wall_hop facet_face facet_face_slide facet_edge facet_vertex facet_tilted pack_settle \
         clump_construction clump_drop clump_drop_damped clump_spin bond_stiffness bond_tension bond_shear bond_dynamic; do
    echo "== $s"
    yade -n -j1 -x scripts/$s.py > /dev/null 2>&1 || { echo "FAILED: $s"; exit 1; }
done
ls -l data
# plain-Python bit-for-bit re-implementations of the clump and bond parts (no Yade needed)
python3 scripts/check_clump_integrator.py && python3 scripts/check_bond_stiffness.py && python3 scripts/check_bond_law.py
