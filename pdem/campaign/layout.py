"""The campaign directory: its manifest and one directory per member, written idempotently.

Owns `write_campaign`, which expands a parsed campaign into its directory in the layout of
`pdem.format.campaign` (manifest, member files; a member's directory also holds what ``pdem run``
writes there: results.h5, checkpoints/, ...). A member's scene.toml is never rewritten.

Expanding again changes nothing (files whose content would not change are not rewritten) and
adds members that are new in the campaign file. It refuses, before writing anything, a
directory that holds another campaign (manifest name) or that is not a campaign directory, and
a member whose scene or parameters would change its results (they would no longer match its
scene). A change of output-only keys only (`pdem.build.config.OUTPUT_ONLY_KEYS`: progress,
output, snapshot, checkpoint intervals) is not one: the member's files are rewritten with it.
"""
import json
import os
import tomllib
from pathlib import Path

from ..build.config import OUTPUT_ONLY_KEYS, result_identity
from ..errors import InputError
from ..format import campaign as fmt
from ..format.campaign import MANIFEST, MEMBER, SCENE
from .spec import jsonable
from .tomlw import dumps


def write_text_if_changed(path, text):
    """Write ``text`` atomically unless the file already holds exactly it; True if written."""
    path = Path(path)
    if path.exists() and path.read_text() == text:
        return False
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
    return True


def json_text(obj):
    return json.dumps(obj, indent=1, sort_keys=False) + "\n"


def scene_text(camp, m):
    sets = "; ".join(f"{k} = {v!r}" for k, v in m.overrides.items()) or "nothing"
    header = (f"member {m.name} of campaign {camp.name} (written by pdem campaign; do not edit)\n"
              f"base scene: {camp.base_text}\nset: {sets}")
    return dumps(m.doc, header=header)


def member_json(camp, m):
    return json_text({"campaign": camp.name, "name": m.name, "params": jsonable(m.params),
                      "overrides": jsonable(m.overrides)})


def manifest(camp):
    return fmt.manifest(camp.name, camp.path, camp.base, camp.seed_key, camp.varied, camp.has_cases,
                        jsonable(camp.analysis),
                        [{"name": m.name, "dir": m.name, "params": jsonable(m.params), "ranks": m.ranks,
                          "threads": m.threads} for m in camp.members])


def read_manifest(out):
    """The manifest of the campaign directory ``out`` (InputError if it has none or a bad one)."""
    try:
        return fmt.read_manifest(out)
    except fmt.ManifestError as exc:
        raise InputError(str(exc)) from None


def same_results(fname, old, new):
    """True if the member file ``fname`` (scene.toml or member.json) with text ``old`` describes
    a run with the same results as with text ``new``: they differ at most in output-only keys."""
    if old == new:
        return True
    try:
        if fname == SCENE:
            return result_identity(tomllib.loads(old)) == result_identity(tomllib.loads(new))
        a, b = json.loads(old), json.loads(new)
    except (ValueError, tomllib.TOMLDecodeError):
        return False
    for d in (a, b):
        if isinstance(d.get("overrides"), dict):
            d["overrides"] = {k: v for k, v in d["overrides"].items() if k not in OUTPUT_ONLY_KEYS}
    return a == b


def write_campaign(camp, log=print):
    """Expand ``camp`` into its directory (idempotent); returns the manifest."""
    out = Path(camp.out)
    old, plan = plan_campaign(camp)
    out.mkdir(parents=True, exist_ok=True)
    new = 0
    for d, texts in plan:
        if not d.exists():
            new += 1
        d.mkdir(exist_ok=True)
        for fname, text in texts.items():
            write_text_if_changed(d / fname, text)
    man = manifest(camp)
    if old is not None:
        dropped = [e["name"] for e in old.get("members", []) if e["name"] not in {m.name for m in camp.members}]
        if dropped:
            log(f"{out}: {len(dropped)} member(s) no longer in {camp.path.name}, left alone and out of the manifest: "
                + ", ".join(dropped))
    write_text_if_changed(out / MANIFEST, json_text(man))
    if new:
        log(f"{out}: {new} new member(s) of campaign {camp.name} ({len(camp.members)} in all)")
    return man


def plan_campaign(camp):
    """(the directory's old manifest or None, [(member directory, {file name: text})]) of
    ``camp``: every check `write_campaign` makes before writing, writing nothing (``pdem campaign
    check``). InputError (one line) for a directory that is not a campaign directory or holds
    another campaign, a member directory of another campaign, or a member that would change."""
    out = Path(camp.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    old = None
    if (out / MANIFEST).exists():
        old = read_manifest(out)
        if old.get("name") != camp.name:
            raise InputError(f"{out}: holds the members of campaign {old.get('name')!r} ({MANIFEST}), not of "
                             f"{camp.name!r}; give this campaign another out directory")
    elif out.exists() and any(out.iterdir()):
        raise InputError(f"{out}: exists, is not empty and is not a campaign directory (no {MANIFEST}); "
                         "give the campaign another out directory")
    plan = []
    for m in camp.members:
        d = out / m.name
        texts = {SCENE: scene_text(camp, m), MEMBER: member_json(camp, m)}
        if (d / MEMBER).exists():
            try:
                owner = json.loads((d / MEMBER).read_text()).get("campaign")
            except ValueError:
                owner = None
            if owner != camp.name:
                raise InputError(f"{d}: belongs to campaign {owner!r} ({MEMBER}), not {camp.name!r}; "
                                 "give this campaign another out directory")
        for fname, text in texts.items():
            if (d / fname).exists() and not same_results(fname, (d / fname).read_text(), text):
                what = "its scene" if fname == SCENE else "its parameters"
                raise InputError(f"{d}: {what} ({fname}) differ from what {camp.path.name} expands to now "
                                 "(the campaign or its base scene changed since it was expanded); members are never "
                                 "overwritten: give the campaign another out directory, or remove that member's "
                                 "directory")
        plan.append((d, texts))
    return old, plan
