"""Scenes: the ready experiments pdem runs from a scene file, and their registry.

A scene is a module with ``check(doc)`` (validate a parsed scene file without running it: one-line
`InputError`) and ``run(path, doc, out_dir, comm, steps=None, fresh=False)`` (run or resume it on
the ranks of ``comm``; returns the exit status). A scene file selects one by its top-level table
(``[box_test]`` → `pdem.scenes.box_test`, ``[track]`` → `pdem.scenes.track`, ``[oedometer]`` →
`pdem.scenes.oedometer`, ``[shear_box]`` → `pdem.scenes.shear_box`, the one-file example of
docs/design.md); a file with none
of them is a plain scene (`pdem.driver.plain`). Adding a scene is its module plus one line in `SCENES`.
A staged scene lists its stages (`pdem.driver.stages.Stage`); what scenes share lives beside them:
`pdem.scenes.common.preparation` (the pour, refill, vibrate and settle stages of a ballast bed),
`pdem.scenes.cycles` (the box test's per-cycle record), `pdem.scenes.track_record` (the track's).
"""
from importlib import import_module

SCENES = {"box_test": "pdem.scenes.box_test", "blast": "pdem.scenes.blast", "track": "pdem.scenes.track",
          "oedometer": "pdem.scenes.oedometer", "shear_box": "pdem.scenes.shear_box"}


def find(doc):
    """(name, module) of the scene a parsed scene file asks for, or (None, None) for a plain scene."""
    from ..errors import InputError

    if "campaign" in doc and not any(k in doc for k in SCENES):
        raise InputError("scene file.campaign: this is a campaign file, not a scene file: use `pdem campaign check`, "
                         "`expand` or `run` with it (docs/campaigns.md)")
    for key in ("simulation", "run", "materials", *SCENES):  # the tables every scene reads as tables
        if key in doc and not isinstance(doc[key], dict):
            raise InputError(f"{key}: must be a table ([{key}]), got {type(doc[key]).__name__} {doc[key]!r:.40}")
    for name, m in doc.get("materials", {}).items():
        if not isinstance(m, dict):
            raise InputError(f"materials.{name}: must be a table ([materials.{name}]), got {type(m).__name__}")
    named = [k for k in SCENES if k in doc]
    if len(named) > 1:
        raise InputError(f"scene file: tables {', '.join(named)} select different scenes; keep one")
    if not named:
        return None, None
    return named[0], import_module(SCENES[named[0]])


def check(doc):
    """Validate a parsed scene file of any scene (one-line `InputError`), without running it."""
    name, module = find(doc)
    if module is not None:
        return module.check(doc)
    from ..build.config import run_settings, scene_from_dict

    run_settings(doc)
    scene_from_dict(doc, scene_tables=tuple(SCENES))
