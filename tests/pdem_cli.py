"""Running ``python -m pdem run`` from a test as a subprocess, on one rank or under the venv's
``mpiexec`` (next to sys.executable), with one numba thread per rank."""
import os
import subprocess
import sys
from pathlib import Path

MPIEXEC = Path(sys.executable).parent / "mpiexec"


def pdem_cmd(n_ranks, scene, out, *extra):
    cmd = [sys.executable, "-m", "pdem", "run", str(scene), "--out", str(out), *extra]
    return ([str(MPIEXEC), "-n", str(n_ranks)] + cmd) if n_ranks > 1 else cmd


def run_pdem(n_ranks, scene, out, *extra, expect=0):
    """Run and assert the exit status; returns the CompletedProcess (stdout, stderr as text)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    r = subprocess.run(pdem_cmd(n_ranks, scene, out, *extra), capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == expect, f"exit {r.returncode}, expected {expect}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r
