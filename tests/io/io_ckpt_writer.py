"""Subprocess for test_io_sigkill: write large checkpoints in a loop until killed.

Usage: python io_ckpt_writer.py DIRECTORY N_ROWS. Prints "ready" after the first checkpoint.
The contents of step s are `expected_tables(s, n_rows)`, so the test can check what survived.
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from io_fakecomm import SerialComm  # noqa: E402

from pdem.io.checkpoint import write_checkpoint  # noqa: E402

KEYS = {"particles": ["gid"]}


def expected_tables(step, n):
    gid = np.arange(n, dtype=np.int64)
    return {"particles": {"gid": gid,
                          "pos": np.full((n, 3), float(step)),
                          "vel": np.full((n, 3), -float(step))}}


def main():
    directory, n = Path(sys.argv[1]), int(sys.argv[2])
    step = 1
    while True:
        write_checkpoint(directory, step, expected_tables(step, n), {"step": step, "keys": KEYS},
                         SerialComm(), keep=2)
        if step == 1:
            print("ready", flush=True)
        step += 1


if __name__ == "__main__":
    main()
