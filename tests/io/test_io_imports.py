"""pdem.io must not import mpi4py (MPI stays in pdem.parallel) and must not act on import."""

import re
import subprocess
import sys
from pathlib import Path

import pdem.io

IO_DIR = Path(pdem.io.__file__).parent
IMPORT_MPI = re.compile(r"^\s*(import\s+mpi4py|from\s+mpi4py\b)|__import__\(\s*['\"]mpi4py", re.M)


def test_no_mpi4py_import_in_source():
    for path in IO_DIR.glob("*.py"):
        assert not IMPORT_MPI.search(path.read_text()), f"{path.name} imports mpi4py"


def test_import_loads_no_mpi_and_installs_no_handler():
    code = (
        "import sys, signal\n"
        "import pdem.io.checkpoint, pdem.io.timeseries, pdem.io.snapshots, pdem.io.signals\n"
        "assert 'mpi4py' not in sys.modules, 'mpi4py imported'\n"
        "assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL, 'SIGTERM handler set on import'\n"
        "assert signal.getsignal(signal.SIGUSR1) == signal.SIG_DFL, 'SIGUSR1 handler set on import'\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
