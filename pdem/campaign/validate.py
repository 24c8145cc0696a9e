"""Checking a campaign member's resolved scene without running it.

Owns `check_member`, the one place where the campaign layer asks the engine whether a scene
document is valid. It raises pdem's `InputError` (one line naming the key) for an unknown key or
a bad value, exactly as ``pdem run`` would at its start. (When the engine gets a scene registry
this function is rewired to it; nothing else in `pdem.campaign` imports engine modules.)
"""
from ..errors import InputError


def check_member(doc):
    """Raise `InputError` (one line) if the scene document ``doc`` would not run.

    A document with a ``[box_test]`` table is checked as the box test reads it (its table, the
    run settings, the simulation settings and materials); any other as a plain scene."""
    from ..config import TOP_KEYS, run_settings, scene_from_dict

    if not isinstance(doc, dict):
        raise InputError(f"scene: must be a table, got {type(doc).__name__}")
    for k in doc:
        if k not in TOP_KEYS:
            raise InputError(f"{k}: unknown key; allowed: {', '.join(sorted(TOP_KEYS))}")
    run_settings(doc)
    if "box_test" in doc:
        from ..boxtest import box_settings

        box_settings(doc)
        scene_from_dict({k: v for k, v in doc.items() if k != "box_test"})
    else:
        scene_from_dict(doc)
