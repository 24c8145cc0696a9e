#!/bin/sh
# Regenerate every JSON in ../data with Yade (Debian package yade 2023.02a), single thread, headless.
set -e
cd "$(dirname "$0")/.."
for s in appendix_a wall_slide wall_slide_damped wall_hop facet_face facet_face_slide facet_edge facet_vertex facet_tilted pack_settle; do
    echo "== $s"
    yade -n -j1 -x scripts/$s.py > /dev/null 2>&1 || { echo "FAILED: $s"; exit 1; }
done
ls -l data
