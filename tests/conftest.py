"""Test-suite plumbing: the ``one_line_error`` check, the ``jit`` marker's skip, and running pytest
on several MPI ranks.

Tests marked ``jit`` need numba's compiled kernels: the contact carry's hash (``pdem.contact.store``)
multiplies int64 keys with wrap-around, which Python's integers do not do, so under
``NUMBA_DISABLE_JIT=1`` (``make test-nojit``) they are skipped.

Owns: the hooks that make ``mpiexec -n N python -m mpi4py -m pytest --capture=sys tests/mpi``
fail fast and print one report (TOOLCHAIN.md, "MPI tests under pytest"), and the
``mpi_tmp_path`` fixture.  Imports MPI only through ``pdem.parallel.comm``.  In a serial run
(no launcher, or one rank) every hook here does nothing.

Under MPI with more than one rank:

* any failure on any rank (collection, setup, call or teardown) prints the rank and the
  traceback on stderr and calls ``MPI_Abort(1)``: otherwise the other ranks' collectives pair
  up across different tests and the job hangs;
* a per-test ``faulthandler.dump_traceback_later(PDEM_TEST_WATCHDOG_S, exit=True)`` watchdog
  (default 600 s) prints every thread's stack and exits even while a rank is blocked in MPI
  holding the GIL, where pytest-timeout's thread method cannot fire (use ``--capture=sys``
  so that the dump reaches the console);
* ranks > 0 write their terminal report to ``$PDEM_TEST_LOG_DIR/rank<r>.log`` (default
  ``<tmp>/pdem-pytest-mpi``) so that only rank 0 prints the closing "N passed" line.
"""

import faulthandler
import os
import sys
import tempfile
from pathlib import Path

import numba
import pytest

from pdem.parallel.comm import configure_threads, get_comm

_COMM = get_comm()
_PARALLEL = _COMM.size > 1
if _PARALLEL:  # ranks x threads within the cores (OpenMP threads spin: oversubscribing costs ~3x)
    configure_threads(_COMM)


_LOG_DIR = Path(
    os.environ.get("PDEM_TEST_LOG_DIR") or Path(tempfile.gettempdir()) / "pdem-pytest-mpi"
)


def pytest_collection_modifyitems(config, items):
    if not numba.config.DISABLE_JIT:
        return
    skip = pytest.mark.skip(reason="needs numba's compiled kernels: int64 arithmetic that wraps around")
    for item in items:
        if "jit" in item.keywords:
            item.add_marker(skip)


def _abort(what, longrepr):
    rank, size = _COMM.rank, _COMM.size
    _COMM.abort(f"pytest: {what} failed on rank {rank} of {size}; aborting all ranks\n{longrepr}")


if _PARALLEL:

    @pytest.hookimpl(trylast=True)
    def pytest_configure(config):
        if _COMM.rank == 0:
            return
        # Ranks > 0: replace the terminal reporter by one that writes to a per-rank log.
        _LOG_DIR.mkdir(parents=True, exist_ok=True)
        log = open(_LOG_DIR / f"rank{_COMM.rank}.log", "w", buffering=1)  # closed at exit
        config.pluginmanager.unregister(name="terminalreporter")
        config.pluginmanager.register(pytest.TerminalReporter(config, log), "terminalreporter")

    def pytest_report_header(config):
        return [f"MPI: {_COMM.size} ranks; ranks > 0 report to {_LOG_DIR}/rank<r>.log"]

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        seconds = float(os.environ.get("PDEM_TEST_WATCHDOG_S", "600"))
        # sys.__stderr__: the real stream, not pytest's capture (the process may die).
        faulthandler.dump_traceback_later(seconds, exit=True, file=sys.__stderr__)
        try:
            return (yield)
        finally:
            faulthandler.cancel_dump_traceback_later()

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(item, call):
        report = yield
        if report.failed:
            _abort(f"{item.nodeid} ({report.when})", report.longreprtext)
        return report

    @pytest.hookimpl(wrapper=True)
    def pytest_make_collect_report(collector):
        report = yield
        if report.failed:
            _abort(f"collecting {collector.nodeid or collector.name}", report.longreprtext)
        return report


@pytest.fixture
def one_line_error():
    """``one_line_error(error, call, *words)``: ``call()`` raises ``error`` with a message of one
    line that holds every word; returns the message."""
    def check(error, call, *words):
        with pytest.raises(error) as info:
            call()
        message = str(info.value)
        assert "\n" not in message, message
        for word in words:
            assert word in message, (word, message)
        return message
    return check


@pytest.fixture
def comm():
    """The communicator of this test run (SerialComm when not under MPI)."""
    return _COMM


@pytest.fixture
def mpi_tmp_path(request):
    """A temporary directory shared by all ranks: rank 0 creates it, the others get its path.

    Assumes a file system visible from every rank (one node, or a shared tmp).  Serially, it
    is ``tmp_path``.
    """
    if not _PARALLEL:
        return request.getfixturevalue("tmp_path")
    path = None
    if _COMM.rank == 0:
        factory = request.getfixturevalue("tmp_path_factory")
        name = "".join(c if c.isalnum() else "_" for c in request.node.name)[:30]
        path = str(factory.mktemp(name, numbered=True))
    return Path(_COMM.bcast(path))
