"""pdem.io.signals: SIGTERM/SIGUSR1 only set a flag; all ranks agree on a stop."""

import os
import signal
import time

import pytest
from io_fakecomm import SerialComm, run_ranks

from pdem.io.signals import (
    EXIT_CHECKPOINTED_ON_SIGNAL,
    StopFlag,
    install_signal_handlers,
    stop_requested,
)


def wait_for(flag):
    """Until the handler has run (Python runs it between bytecodes of the main thread); no wall-clock
    limit on a loaded machine: a hang is pytest-timeout's to stop."""
    while not flag.local:
        time.sleep(0.001)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGUSR1])
def test_signal_sets_flag_only(signum):
    before = signal.getsignal(signum)
    flag = install_signal_handlers()
    try:
        assert not stop_requested(SerialComm())
        os.kill(os.getpid(), signum)
        wait_for(flag)
        assert flag.signum == signum
        assert stop_requested(SerialComm()) and stop_requested()
        os.kill(os.getpid(), signal.SIGTERM)  # a second signal changes nothing
        assert flag.signum == signum
    finally:
        flag.uninstall()
    assert signal.getsignal(signum) == before
    assert not stop_requested()


def test_ranks_agree_when_one_rank_got_the_signal():
    flags = [StopFlag(), StopFlag()]
    flags[1].signum = signal.SIGUSR1  # only rank 1 was signalled
    results, errors = run_ranks(2, lambda comm: flags[comm.rank].stop_requested(comm))
    assert errors == [None, None] and results == [True, True]
    flags[1].clear()
    results, _ = run_ranks(2, lambda comm: flags[comm.rank].stop_requested(comm))
    assert results == [False, False]


def test_exit_status_constant():
    assert EXIT_CHECKPOINTED_ON_SIGNAL == 3
