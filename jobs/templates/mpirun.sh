#!/usr/bin/env bash
# Run one pdem scene on N MPI ranks of this machine (MPICH from the venv, one numba thread per
# rank unless cores allow more). Re-running the same command resumes from the newest checkpoint.
#   jobs/templates/mpirun.sh SCENE.toml OUTDIR [NP]
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
scene="$1"; out="$2"; np="${3:-2}"
cores=$(nproc)
export NUMBA_NUM_THREADS=$(( cores / np > 0 ? cores / np : 1 ))
exec "$here/.venv/bin/mpiexec" -n "$np" "$here/.venv/bin/python" -m pdem run "$scene" --out "$out"
