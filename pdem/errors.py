"""Errors pdem raises on purpose: each carries one line naming the field or cause.

`InputError` is bad input (a scene field, a value, a file); `InstabilityError` is a run stopped
because it blew up (NaN, overlap beyond the allowed fraction of a radius, energy growth).
The command line prints these as one line and exits with status 2 (input) or 4 (instability).
"""


class InputError(ValueError):
    """Bad input: the message names the field, the value and what is allowed."""


class InstabilityError(RuntimeError):
    """The run became numerically unstable; the message names the cause and the step."""


EXIT_INPUT_ERROR = 2
EXIT_INSTABILITY = 4
