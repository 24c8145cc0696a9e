"""Stand-ins for pdem.parallel.comm in the pdem.io tests (no MPI).

`SerialComm` is the one-rank version. `run_ranks(n, fn)` runs ``fn(comm)`` on n threads whose
comms behave like n MPI ranks for the collectives pdem.io uses (gather_rows, bcast, barrier,
allreduce_max, any_flag); a rank that fails aborts the barrier so the others fail instead of hanging.
"""

from __future__ import annotations

import threading

import numpy as np


class SerialComm:
    rank, size = 0, 1

    def gather_rows(self, array):
        return np.asarray(array)

    def bcast(self, obj):
        return obj

    def barrier(self):
        pass

    def allreduce_max(self, value):
        return value

    def any_flag(self, flag):
        return bool(flag)


class _Shared:
    def __init__(self, size):
        self.barrier = threading.Barrier(size)
        self.slots = [None] * size


class ThreadComm:
    def __init__(self, shared, rank, size):
        self._s, self.rank, self.size = shared, rank, size

    def _exchange(self, value):
        """All-gather of Python objects: every rank gets the list in rank order."""
        self._s.slots[self.rank] = value
        self._s.barrier.wait()
        out = list(self._s.slots)
        self._s.barrier.wait()
        return out

    def gather_rows(self, array):
        parts = self._exchange(np.asarray(array))
        return np.concatenate(parts, axis=0) if self.rank == 0 else None

    def bcast(self, obj):
        return self._exchange(obj)[0]

    def barrier(self):
        self._exchange(None)

    def allreduce_max(self, value):
        return max(self._exchange(value))

    def any_flag(self, flag):
        return any(self._exchange(bool(flag)))


def run_ranks(size, fn):
    """Run ``fn(comm)`` on ``size`` fake ranks; return the results, or raise each rank's error."""
    shared = _Shared(size)
    results, errors = [None] * size, [None] * size

    def body(rank):
        try:
            results[rank] = fn(ThreadComm(shared, rank, size))
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            errors[rank] = exc
            failed.set()

    failed = threading.Event()
    threads = [threading.Thread(target=body, args=(r,), daemon=True) for r in range(size)]
    for t in threads:
        t.start()
    # A rank that raised leaves the others waiting in a collective (as under MPI): they finish on
    # their own (they may raise the same error) unless every rank still running waits in the
    # barrier, which can then never fill: break it. No clock: a hang is pytest-timeout's to stop.
    while any(t.is_alive() for t in threads):
        alive = sum(t.is_alive() for t in threads)
        if failed.wait(0.01) and shared.barrier.n_waiting == alive:
            shared.barrier.abort()
    for t in threads:
        t.join()
    return results, errors
