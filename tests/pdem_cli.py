"""Running ``python -m pdem run`` from a test as a subprocess, on one rank or under the venv's
``mpiexec`` (next to sys.executable), with one numba thread per rank; the ``needs_mpiexec`` skip
marker; a subprocess signalled once it has written what a test waits for."""
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


def signal_when(cmd, condition, signum, **popen_kw):
    """Start ``cmd`` (stdout and stderr as text), send it ``signum`` once ``condition()`` holds, and
    return (exit status, output); fail if it ends before. No wall-clock limit on the wait (a loaded
    machine may compile kernels for minutes): a hang is pytest-timeout's to stop."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **popen_kw)
    try:
        while not condition():
            if proc.poll() is not None:
                pytest.fail(f"ended (exit {proc.returncode}) before it was signalled\n{proc.stdout.read()[-3000:]}")
            time.sleep(0.05)
        proc.send_signal(signum)
        text, _ = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, text
