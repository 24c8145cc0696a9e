"""``pdem run`` with a fault injected on one rank: for the tests of how failures end a job.

    python tests/tools/inject_fault.py RANK STEP KIND -- run SCENE --out DIR ...

On rank RANK (of the MPI job, or 0 serially), when the step counter reaches STEP, KIND is raised
from inside the step (``Simulation.advance``), while the other ranks go on into the next
collective and wait there: RuntimeError, MemoryError, OSError, ENOSPC (OSError with errno 28),
Instability (an `InstabilityError` on that rank only), InputError, CheckpointError,
CheckpointWriteError, ResultsFileError, KeyboardInterrupt; or SIGTERM (sent to the process
itself: the run stops at the next poll with a checkpoint), none (no fault). RANK -1: on every rank. Everything
else is the real ``pdem`` command line (`pdem.cli.main`), so the exit status and the messages
are those a user gets.
"""
import errno
import os
import signal
import sys

from pdem import cli
from pdem.errors import InputError, InstabilityError
from pdem.io.checkpoint import CheckpointError, CheckpointWriteError
from pdem.io.timeseries import ResultsFileError
from pdem.parallel.comm import get_comm
from pdem.simulation import Simulation


def main():
    rank, step, kind = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    argv = sys.argv[sys.argv.index("--") + 1:]
    faults = {"RuntimeError": lambda: RuntimeError("injected fault"),
              "MemoryError": lambda: MemoryError("injected: cannot allocate 8 GiB"),
              "OSError": lambda: OSError(errno.EIO, "injected I/O error", "somewhere.h5"),
              "ENOSPC": lambda: OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "results.h5"),
              "Instability": lambda: InstabilityError(f"step {step}: injected instability"),
              "InputError": lambda: InputError("injected.key = 1: must be injected"),
              "CheckpointError": lambda: CheckpointError("ckpt_injected.h5", "injected damage"),
              "CheckpointWriteError": lambda: CheckpointWriteError("ckpt_injected.h5", "injected write failure"),
              "ResultsFileError": lambda: ResultsFileError("results.h5", "injected damage"),
              "KeyboardInterrupt": KeyboardInterrupt}
    advance = Simulation.advance

    def faulty_advance(sim):
        if sim.step == step and rank in (sim.comm.rank, -1):
            if kind == "SIGTERM":
                os.kill(os.getpid(), signal.SIGTERM)
            elif kind != "none":
                raise faults[kind]()
        return advance(sim)

    Simulation.advance = faulty_advance
    get_comm()  # MPI up before the run, as in `python -m pdem`
    return cli.main(argv)


if __name__ == "__main__":
    sys.exit(main())
