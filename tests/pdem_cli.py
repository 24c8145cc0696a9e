"""Running ``python -m pdem run`` from a test as a subprocess, on one rank or under the venv's
``mpiexec`` (next to sys.executable), with one numba thread per rank; the ``needs_mpiexec`` skip
marker; waiting for what a running subprocess writes."""
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

MPIEXEC = Path(sys.executable).parent / "mpiexec"
needs_mpiexec = pytest.mark.skipif(not MPIEXEC.exists(),
                                   reason="multi-rank test: no mpiexec next to the Python executable")


def pdem_cmd(n_ranks, scene, out, *extra):
    cmd = [sys.executable, "-m", "pdem", "run", str(scene), "--out", str(out), *extra]
    return ([str(MPIEXEC), "-n", str(n_ranks)] + cmd) if n_ranks > 1 else cmd


def run_pdem(n_ranks, scene, out, *extra, expect=0):
    """Run and assert the exit status; returns the CompletedProcess (stdout, stderr as text)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    r = subprocess.run(pdem_cmd(n_ranks, scene, out, *extra), capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == expect, f"exit {r.returncode}, expected {expect}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


def wait_until(condition, proc, poll=0.05):
    """Poll ``condition()`` until it holds while ``proc`` runs; fail if proc ends first. No wall-clock
    limit (a loaded machine may compile kernels for minutes): a hang is pytest-timeout's to stop."""
    while not condition():
        if proc.poll() is not None:
            output = proc.stdout.read() if proc.stdout else ""
            pytest.fail(f"the process ended (exit {proc.returncode}) before the awaited state\n{output[-3000:]}")
        time.sleep(poll)
