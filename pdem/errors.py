"""Errors pdem raises on purpose: each carries one line naming the field or cause.

`InputError` is bad input (a scene field, a value, a file); `InstabilityError` is a run stopped
because it blew up (NaN, overlap beyond the allowed fraction of a radius, energy growth).
The command line prints these as one line and exits with status 2 (input) or 4 (instability);
every exit status is listed below, and `pdem.driver.failures` maps exceptions to them.
"""


class InputError(ValueError):
    """Bad input: the message names the field, the value and what is allowed."""


class InstabilityError(RuntimeError):
    """The run became numerically unstable; the message names the cause and the step."""


# The exit statuses of pdem (all of them, here only; docs/reliability.md): pdem.driver.failures
# maps every exception to one of them (`classify`)
EXIT_DONE = 0
EXIT_INTERNAL_ERROR = 1  # a bug: the message is followed by the traceback
EXIT_INPUT_ERROR = 2
EXIT_CHECKPOINTED_ON_SIGNAL = 3  # stopped on SIGTERM/SIGUSR1 after a checkpoint (pdem.io.signals): run again
EXIT_INSTABILITY = 4
EXIT_SYSTEM_ERROR = 5  # a write failed (disk full ...) or memory ran out
EXIT_INTERRUPTED = 130  # KeyboardInterrupt (SIGINT, Ctrl-C): the shells' 128 + 2
