#!/usr/bin/env bash
# The full box test (jobs/box_test_full.toml) on N ranks of this machine with mpirun (pdem
# writes the analysis into OUTDIR/analysis at the end). Re-running the same command resumes.
#   jobs/box_test_full.sh [NP] [OUTDIR]        (defaults: 8 ranks, runs/box_test_full)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
np="${1:-8}"; out="${2:-runs/box_test_full}"
"$here/jobs/templates/mpirun.sh" "$here/jobs/box_test_full.toml" "$out" "$np"
