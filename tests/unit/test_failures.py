"""How failures end a run (`pdem.driver.failures`), and refusals that must come before any work:
the exit status and the one line of every kind of failure, on one rank (SerialComm); the
multi-rank paths are tests/mpi/test_comm.py and tests/io/test_failures_cli.py."""
import errno

import numpy as np
import pytest

from pdem.driver.failures import classify, report_failure, run_guarded
from pdem.errors import InputError, InstabilityError
from pdem.build.generators import loose_cloud
from pdem.io.checkpoint import CheckpointError, CheckpointWriteError
from pdem.io.timeseries import ResultsFileError
from pdem.parallel.comm import SerialComm
from pdem.parallel.slabs import ghost_destinations, max_slabs, uniform_edges


@pytest.mark.parametrize(
    "exc, status, start",
    [
        (InputError("dt = True: must be a number"), 2, "error: dt = True"),
        (CheckpointError("/x/ckpt_1.h5", "damaged"), 2, "error: checkpoint ckpt_1.h5: damaged"),
        (CheckpointWriteError("/x/ckpt_1.h5", "[Errno 28] No space"), 5, "error: writing checkpoint ckpt_1.h5"),
        (ResultsFileError("/x/results.h5", "damaged"), 2, "error: results file results.h5: damaged"),
        (InstabilityError("step 3: overlap"), 4, "unstable: step 3: overlap"),
        (MemoryError(), 5, "error: out of memory"),
        (
            OSError(errno.ENOSPC, "No space left on device", "/x/results.h5"),
            5,
            "error: no space left on the device writing /x/results.h5",
        ),
        (
            OSError("Unable to synchronously write data (file write failed: errno = 28, error message = 'No space')"),
            5,
            "error: no space left",
        ),
        (OSError(errno.EACCES, "Permission denied", "/x"), 5, "error: /x: Permission denied"),
        (RuntimeError("a bug\nover two lines"), 1, "internal error: RuntimeError: a bug over two lines"),
    ],
)
def test_classify(exc, status, start):
    s, line, tb = classify(exc)
    assert s == status and line.startswith(start) and "\n" not in line, line
    assert tb == (status == 1)


def test_report_once_serial(capsys):
    def boom():
        raise InputError("walls[0].axis = 'w': must be one of x, y, z")

    assert run_guarded(SerialComm(), boom) == 2
    assert capsys.readouterr().err == "pdem: error: walls[0].axis = 'w': must be one of x, y, z\n"
    assert report_failure(SerialComm(), ValueError("oops")) == 1
    err = capsys.readouterr().err
    assert "ValueError: oops" in err  # a bug: its traceback, then the line
    assert err.splitlines()[-1] == "pdem: internal error: ValueError: oops"


def test_max_slabs_matches_ghost_destinations():
    """The rank limit named before any work is exactly where the ghost layer would refuse."""
    for span, halo in ((0.66, 0.0366), (0.084, 0.0225), (1.0, 0.2), (0.1, 0.5)):
        most = max_slabs(0.0, span, halo)
        ghost_destinations(np.zeros(1), uniform_edges(0.0, span, most), halo)
        if most > 2 or span / halo >= 2:
            with pytest.raises(ValueError):
                ghost_destinations(np.zeros(1), uniform_edges(0.0, span, most + 1), halo)


def test_huge_cloud_refused_before_allocation():
    """10^12 spheres would be 8 TB of radii: refused at once, not after a MemoryError."""
    with pytest.raises(InputError, match="do not fit"):  # not MemoryError
        loose_cloud([0, 0, 0], [0.2, 0.1, 0.2], 10**12, 0.01, 0.4, 1)
    pos, r = loose_cloud([0, 0, 0], [0.2, 0.1, 0.2], 50, 0.01, 0.4, 1)  # a fitting one is unchanged
    assert pos.shape == (50, 3) and r.max() <= 0.014
