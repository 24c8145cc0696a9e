#!/usr/bin/env bash
# The large track section (jobs/track_large.toml) on N ranks of this machine with mpirun (pdem
# writes the analysis into OUTDIR/analysis at the end). Re-running the same command resumes.
#   jobs/track_large.sh [NP] [OUTDIR]        (defaults: 2 ranks, runs/track_large)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
np="${1:-2}"; out="${2:-runs/track_large}"
"$here/jobs/templates/mpirun.sh" "$here/jobs/track_large.toml" "$out" "$np"
