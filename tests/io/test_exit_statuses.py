"""One mapping from failures to exit statuses (`pdem.driver.failures.classify`, the constants of
`pdem.errors`), one test per class: every exception class maps to the status documented in
docs/reliability.md (0 done, 1 internal, 2 bad input, 3 signal, 4 instability, 5 write/memory),
directly and through the real command line (tests/tools/inject_fault.py raises each inside a
step of `pdem run`; 1 rank, and 2 ranks with the failure on every rank)."""
import errno
import re
from pathlib import Path

import pytest
from test_failures_cli import pdem_lines, run, scene

from pdem import errors
from pdem.driver.failures import classify
from pdem.errors import InputError, InstabilityError
from pdem.io.checkpoint import CheckpointError, CheckpointWriteError
from pdem.io.signals import EXIT_CHECKPOINTED_ON_SIGNAL
from pdem.io.snapshots import SnapshotError, SnapshotWriteError
from pdem.io.timeseries import ResultsFileError

ROOT = Path(__file__).resolve().parents[2]

# status -> (its constant, the words that open its row of the table in docs/reliability.md)
DOCUMENTED = {0: ("EXIT_DONE", "done"), 1: ("EXIT_INTERNAL_ERROR", "internal error"),
              2: ("EXIT_INPUT_ERROR", "bad input"), 3: ("EXIT_CHECKPOINTED_ON_SIGNAL", "stopped on SIGTERM"),
              4: ("EXIT_INSTABILITY", "unstable"), 5: ("EXIT_SYSTEM_ERROR", "the system failed the run"),
              130: ("EXIT_INTERRUPTED", "interrupted")}

CLASSES = [  # (exception, status, words of its line)
    (InputError("run.steps = -1: must be >= 0"), 2, "error: run.steps = -1"),
    (CheckpointError("ckpt_1.h5", "damaged"), 2, "error: checkpoint ckpt_1.h5: damaged"),
    (ResultsFileError("results.h5", "damaged"), 2, "error: results file results.h5: damaged"),
    (InstabilityError("step 3: body gid 1 ..."), 4, "unstable: step 3"),
    (CheckpointWriteError("ckpt_1.h5", "disk full"), 5, "error: writing checkpoint ckpt_1.h5"),
    (SnapshotWriteError("snapshots.h5", "disk full"), 5, "error: writing snapshots snapshots.h5: disk full"),
    (SnapshotError("snapshots.h5", "gid 3 passed twice"), 1, "internal error: SnapshotError: snapshots.h5"),
    (MemoryError(), 5, "error: out of memory (MemoryError)"),
    (OSError(errno.ENOSPC, "No space left on device", "r.h5"), 5, "no space left on the device writing r.h5"),
    (OSError("Can't write data (file write failed: errno = 28, ...)"), 5, "no space left on the device"),
    (OSError(errno.EIO, "Input/output error", "r.h5"), 5, "error: r.h5: Input/output error"),
    (RuntimeError("a bug"), 1, "internal error: RuntimeError: a bug"),
    (ValueError("a bug"), 1, "internal error: ValueError: a bug"),
    (KeyboardInterrupt(), 130, "interrupted"),
]


def test_the_documented_table_is_the_constants():
    """Each row of the table "Exit statuses" in docs/reliability.md is a constant of pdem.errors
    (and the signal module's status is that constant)."""
    doc = (ROOT / "docs" / "reliability.md").read_text()
    table = doc[doc.index("## Exit statuses"):doc.index("## A failure on any rank")]
    rows = dict(re.findall(r"^\| (\d+) \| ([^|]+) \|", table, flags=re.M))
    assert {int(k) for k in rows} == set(DOCUMENTED)
    for status, (name, words) in DOCUMENTED.items():
        assert getattr(errors, name) == status
        assert rows[str(status)].startswith(words), (status, rows[str(status)])
    assert EXIT_CHECKPOINTED_ON_SIGNAL is errors.EXIT_CHECKPOINTED_ON_SIGNAL


@pytest.mark.parametrize("exc, status, words", CLASSES, ids=lambda x: type(x).__name__ if isinstance(x, BaseException)
                         else None)
def test_every_failure_class_maps_to_its_documented_status(exc, status, words):
    got, line, traceback_wanted = classify(exc)
    assert got == status and status in DOCUMENTED
    assert words in line and "\n" not in line, line
    assert traceback_wanted == (status == errors.EXIT_INTERNAL_ERROR)  # only a bug shows its traceback


@pytest.mark.parametrize("n_ranks", [1, 2])
@pytest.mark.parametrize("kind, status, words", [
    ("none", 0, None),
    ("RuntimeError", 1, "internal error: RuntimeError: injected fault"),
    ("InputError", 2, "error: injected.key = 1"),
    ("CheckpointError", 2, "error: checkpoint ckpt_injected.h5: injected damage"),
    ("ResultsFileError", 2, "error: results file results.h5: injected damage"),
    ("SIGTERM", 3, None),
    ("Instability", 4, "unstable: step 60: injected instability"),
    ("CheckpointWriteError", 5, "error: writing checkpoint ckpt_injected.h5"),
    ("SnapshotWriteError", 5, "error: writing snapshots snapshots.h5"),
    ("MemoryError", 5, "error: out of memory"),
    ("ENOSPC", 5, "no space left on the device writing results.h5"),
    ("KeyboardInterrupt", 130, "interrupted"),
])
def test_every_failure_class_through_the_command_line(tmp_path, n_ranks, kind, status, words):
    """The failure raised inside step 60 on every rank (rank -1): the exit status of its class,
    its line once (none for 0 and 3), a traceback only for an internal error."""
    s = scene(tmp_path)
    rc, out, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path, tool=["-1", "60", kind])
    assert rc == status, (rc, out[-2000:], err[-3000:])
    lines = pdem_lines(err)
    assert (len(lines) == 1 and words in lines[0]) if words else lines == [], err[-3000:]
    assert ("Traceback" in err) == (status == errors.EXIT_INTERNAL_ERROR), err[-3000:]
    if status == EXIT_CHECKPOINTED_ON_SIGNAL:
        assert "stop signal received" in out and list((tmp_path / "out" / "checkpoints").glob("ckpt_*.h5"))
