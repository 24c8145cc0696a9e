"""How a run ends when something fails: one line, one exit status, once, and never a hung job.

Owns the mapping of failures to the exit statuses of `pdem run` (`classify`) and the handling of
any exception that reaches the top of a run, on any rank (`run_guarded`):

    0  done                          3  stopped on SIGTERM/SIGUSR1 after a checkpoint
    1  internal error (a bug: the    4  unstable or runaway: the state blew up, a body moved
       line is followed by the          too far in one step, an overlap passed the limit, a
       traceback)                       body left the domain (`InstabilityError`)
    2  bad input: scene file, command line, output directory, a checkpoint or results file
       that cannot be continued from (`InputError`, `CheckpointError`, `ResultsFileError`)
    5  the system failed the run: a write failed (disk full, file system gone), out of memory
       (`MemoryError`, `OSError`, `CheckpointWriteError`, `SnapshotWriteError`)
  130  interrupted (KeyboardInterrupt: SIGINT, Ctrl-C)

The numbers are the constants of `pdem.errors`; `classify` is the one mapping from exceptions
to them (tests/io/test_exit_statuses.py holds one test per class).

Which rank prints: every exception is turned into (status, one line). The failing rank then
asks the others whether they failed too (`Comm.agree_on_failure`, a non-blocking barrier with a
grace time of `GRACE_S`, default 10 s, environment variable PDEM_FAILURE_GRACE_S):

- every rank failed (the same bad input, an instability decided collectively, a failed
  checkpoint write reported on every rank): rank 0 prints each distinct line once and every
  rank returns the highest status: a clean exit, no MPI abort;
- this rank failed alone (others are running or blocked in a collective): it prints its line
  with its rank and ends the whole job with ``MPI_Abort(status)``.

So no failure leaves a job hanging until its wall time, and a 64-rank job prints an error once.
"""
import errno
import os
import sys
import traceback

from ..errors import (
    EXIT_INPUT_ERROR,
    EXIT_INSTABILITY,
    EXIT_INTERNAL_ERROR,
    EXIT_INTERRUPTED,
    EXIT_SYSTEM_ERROR,
    InputError,
    InstabilityError,
)
from ..io.checkpoint import CheckpointError, CheckpointWriteError
from ..io.snapshots import SnapshotWriteError
from ..io.timeseries import ResultsFileError

GRACE_S = 10.0


def grace_seconds():
    """Seconds a failing rank waits for the others to fail too before it aborts the job."""
    try:
        return max(0.0, float(os.environ.get("PDEM_FAILURE_GRACE_S", GRACE_S)))
    except ValueError:
        return GRACE_S


def classify(exc):
    """(status, one line, traceback wanted) of an exception that ended a run."""
    if isinstance(exc, InputError):
        return EXIT_INPUT_ERROR, f"error: {_one_line(exc)}", False
    if isinstance(exc, CheckpointWriteError):
        return EXIT_SYSTEM_ERROR, f"error: writing checkpoint {_one_line(exc)}", False
    if isinstance(exc, SnapshotWriteError):
        return EXIT_SYSTEM_ERROR, f"error: writing snapshots {_one_line(exc)}", False
    if isinstance(exc, CheckpointError):
        return EXIT_INPUT_ERROR, f"error: checkpoint {_one_line(exc)}", False
    if isinstance(exc, ResultsFileError):
        return EXIT_INPUT_ERROR, f"error: results file {_one_line(exc)}", False
    if isinstance(exc, InstabilityError):
        return EXIT_INSTABILITY, f"unstable: {_one_line(exc)}", False
    if isinstance(exc, MemoryError):
        return EXIT_SYSTEM_ERROR, f"error: out of memory ({_one_line(exc) or 'MemoryError'})", False
    if isinstance(exc, OSError):
        return EXIT_SYSTEM_ERROR, f"error: {_os_error(exc)}", False
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED, "interrupted", False
    return EXIT_INTERNAL_ERROR, f"internal error: {type(exc).__name__}: {_one_line(exc)}", True


def _one_line(exc, limit=400):
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _os_error(exc):
    """An OSError (or h5py's, whose errno is buried in the text) as one line."""
    text = _one_line(exc)
    code = exc.errno
    if code is None and "errno = 28" in text:
        code = errno.ENOSPC
    if code == errno.ENOSPC:
        where = f" writing {exc.filename}" if exc.filename else ""
        return f"no space left on the device{where}: free space or choose another --out ({text})"
    if exc.strerror and exc.filename:
        return f"{exc.filename}: {exc.strerror}"
    return f"I/O error: {text}"


def report_failure(comm, exc, grace=None):
    """Print the failure of this rank once for the job and return its exit status; if the other
    ranks did not fail too within the grace time, abort the whole job instead (no return)."""
    status, line, want_tb = classify(exc)
    tb = "".join(traceback.format_exception(exc)) if want_tb else ""
    if comm.size == 1:
        _print(f"pdem: {line}", tb)
        return status
    everyone = comm.agree_on_failure(status, line, grace_seconds() if grace is None else grace)
    if everyone is None:
        _print("", tb)
        comm.abort(f"pdem: {line} (on rank {comm.rank} of {comm.size}; the job is aborted)", status)
        return status  # not reached under MPI
    if comm.rank == 0:
        lines = list(dict.fromkeys(x for _, x in everyone))  # distinct, in rank order
        if len(lines) == 1:
            _print(f"pdem: {lines[0]}", tb)
        else:
            for r, (_, x) in enumerate(everyone):
                if x in lines:
                    _print(f"pdem: {x} (rank {r})", "")
                    lines.remove(x)
            _print("", tb)
    return max(s for s, _ in everyone)


def _print(line, tb):
    sys.stdout.flush()
    if tb:
        sys.stderr.write(tb)
    if line:
        sys.stderr.write(line + "\n")
    sys.stderr.flush()


def run_guarded(comm, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``'s exit status, or the failure's (`report_failure`)."""
    try:
        return fn(*args, **kwargs)
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - every failure ends the job the same way
        return report_failure(comm, exc)
