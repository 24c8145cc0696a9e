"""A writer killed with SIGKILL in the middle of a checkpoint leaves the previous one usable."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from io_ckpt_writer import expected_tables
from io_fakecomm import SerialComm

from pdem.io.checkpoint import (
    find_resume_checkpoint,
    list_checkpoints,
    read_checkpoint,
    write_checkpoint,
)

WRITER = Path(__file__).with_name("io_ckpt_writer.py")
N_ROWS = 400_000  # about 22 MB per checkpoint: a write takes long enough to be caught in it
MID_WRITE_BYTES = 4_000_000
MAX_STEPS = 100  # checkpoints the writer may finish before one is caught in progress


def step_of(path):
    return int(path.name.split("_")[1].split(".")[0])


def kill_during_write(directory):
    """Start the writer, SIGKILL it while it writes datasets; return the temp file and exit code.

    The kill comes once the temp file holds part of the data (a few MB), not just its header. The
    watch ends on a count of checkpoints, not on the clock (a loaded machine writes slowly).
    """
    proc = subprocess.Popen([sys.executable, str(WRITER), str(directory), str(N_ROWS)],
                            stdout=subprocess.PIPE)
    try:
        assert proc.stdout.readline().strip() == b"ready"
        while max(map(step_of, directory.glob("ckpt_*.h5*")), default=0) <= MAX_STEPS:
            for tmp in directory.glob("ckpt_*.h5.tmp"):
                try:
                    if tmp.stat().st_size > MID_WRITE_BYTES:
                        os.kill(proc.pid, signal.SIGKILL)
                        proc.wait(10)
                        return tmp, proc.returncode
                except FileNotFoundError:
                    pass  # renamed between glob and stat: wait for the next write
            time.sleep(0.001)
        pytest.fail("the writer never had a checkpoint in progress")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()


def test_sigkill_mid_write_keeps_previous_checkpoint(tmp_path):
    for attempt in range(5):
        directory = tmp_path / f"attempt{attempt}"
        tmp, returncode = kill_during_write(directory)
        assert returncode == -signal.SIGKILL
        if tmp.exists():  # killed before the rename: a true mid-write kill
            break
    else:
        pytest.fail("could not kill the writer before its rename in 5 attempts")

    found = list_checkpoints(directory)
    last_step, last_path = found[-1]
    assert tmp.name == f"ckpt_{last_step + 1:012d}.h5.tmp"  # the one being written
    lines = []
    assert find_resume_checkpoint(directory, log=lines.append) == last_path
    assert lines == []
    tables, meta = read_checkpoint(last_path)
    assert meta["step"] == last_step
    for col, expected in expected_tables(last_step, N_ROWS)["particles"].items():
        np.testing.assert_array_equal(tables["particles"][col], expected)

    # the resumed run's next checkpoint replaces the leftover temp file
    small = expected_tables(last_step + 1, 10)
    write_checkpoint(directory, last_step + 1, small, {"keys": {"particles": ["gid"]}}, SerialComm(), keep=2)
    assert not tmp.exists()
    assert find_resume_checkpoint(directory) == directory / f"ckpt_{last_step + 1:012d}.h5"
