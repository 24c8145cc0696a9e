"""Checking a campaign member's resolved scene without running it.

Owns `check_member`, the one place where the campaign layer asks whether a scene document is
valid: the scene registry's check (`pdem.scenes.check`: the scene's own table, run settings,
simulation settings and materials; a plain scene otherwise). It raises pdem's `InputError` (one
line naming the key) for an unknown key or a bad value, exactly as ``pdem run`` would at its
start.
"""
from ..errors import InputError


def check_member(doc):
    """Raise `InputError` (one line) if the scene document ``doc`` would not run."""
    from ..scenes import check

    if not isinstance(doc, dict):
        raise InputError(f"scene: must be a table, got {type(doc).__name__}")
    check(doc)
