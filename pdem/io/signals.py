"""Stop requests from the batch system: SIGTERM and SIGUSR1 set a flag, nothing else.

Owns the signal handlers and the exit status of a run that stopped on a signal. The handler only
records the signal (no I/O, no MPI, no exceptions: it may interrupt any line, including a
collective). The step loop polls `stop_requested(comm)` every k steps; it is a collective
(``comm.any_flag``), so all ranks agree on the same step even if the signal reached only some of
them. The run then writes a checkpoint and exits with `EXIT_CHECKPOINTED_ON_SIGNAL`.

Exit statuses of the pdem command line (all of them: pdem.driver.failures): 0 finished, 1
internal error, 2 input error, 3 = `EXIT_CHECKPOINTED_ON_SIGNAL` (stopped on SIGTERM/SIGUSR1 after
writing a checkpoint; the run is not finished and a requeue continues from that checkpoint), 4
instability or runaway, 5 disk full or out of memory. 3 is non-zero on purpose:
SLURM marks the job not-OK, so a chained ``--dependency=afternotok`` continuation starts, and a
campaign runner can tell "resume me" (3) from failures. With sbatch use ``--signal=B:USR1@300``
(signal the batch shell, which forwards it) or ``--signal=USR1@300`` (signal every task).

Signal dispositions are process-wide, so the record of the installed handler is module state;
it is set only by `install_signal_handlers`, never on import. Must not import mpi4py.
"""

from __future__ import annotations

import signal
import threading

from ..errors import EXIT_CHECKPOINTED_ON_SIGNAL
STOP_SIGNALS = (signal.SIGTERM, signal.SIGUSR1)

__all__ = [
    "EXIT_CHECKPOINTED_ON_SIGNAL",
    "STOP_SIGNALS",
    "StopFlag",
    "install_signal_handlers",
    "stop_requested",
]


class StopFlag:
    """Records the first stop signal received; created by `install_signal_handlers`."""

    def __init__(self, signals=STOP_SIGNALS):
        self.signals = tuple(signals)
        self.signum: int | None = None  # first signal received, None if none
        self._previous: dict[int, object] = {}

    @property
    def local(self) -> bool:
        """True if this process received a stop signal."""
        return self.signum is not None

    def _handler(self, signum, frame):  # async-signal context: only set a field
        if self.signum is None:
            self.signum = signum

    def stop_requested(self, comm=None) -> bool:
        """True on every rank if any rank received a stop signal (collective when ``comm`` given)."""
        if comm is None:
            return self.local
        return bool(comm.any_flag(self.local))

    def clear(self) -> None:
        """Forget a received signal (tests; a run that decided to continue)."""
        self.signum = None

    def uninstall(self) -> None:
        """Restore the handlers that were installed before."""
        global _installed
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous.clear()
        if _installed is self:
            _installed = None


_installed: StopFlag | None = None


def install_signal_handlers(signals=STOP_SIGNALS) -> StopFlag:
    """Install flag-setting handlers for ``signals`` (default SIGTERM, SIGUSR1) in this process.

    Call from the main thread (Python delivers signals there), once per run; a second call
    replaces the first. Returns the `StopFlag`; `stop_requested` uses it too.
    """
    global _installed
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError("signal handlers can only be installed from the main thread")
    if _installed is not None:
        _installed.uninstall()
    flag = StopFlag(signals)
    for signum in flag.signals:
        flag._previous[signum] = signal.signal(signum, flag._handler)
    _installed = flag
    return flag


def stop_requested(comm=None) -> bool:
    """True on every rank if any rank got SIGTERM/SIGUSR1 since `install_signal_handlers`.

    Collective when ``comm`` is given (all ranks must call it at the same step). False if no
    handlers are installed.
    """
    local = _installed is not None and _installed.local
    if comm is None:
        return local
    return bool(comm.any_flag(local))
