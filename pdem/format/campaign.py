"""The campaign directory's files: the manifest (format "pdem-campaign", version 1) and the names
of the files of each member.

Owns the names below, the manifest's layout (`manifest`), its reader (`read_manifest`) and the
reader of a member's run record (`read_run`). `pdem.campaign` writes them; `analysis.campaign`
and `analysis.stability` read them. Layout of a campaign directory OUT::

    OUT/campaign.json          manifest: format, version, name, campaign_file, base, seed_key,
                               varied keys, cases, [analysis] defaults, members (name, dir,
                               params, ranks, threads)
    OUT/<member>/scene.toml    the member's resolved scene (base + overrides)
    OUT/<member>/member.json   campaign, name, params, overrides
    OUT/<member>/run.json      run record: ``attempts``, one entry per attempt (``start``, ``end``
                               (ISO times, ``end`` null while it runs), ``wall_s`` [s], ``exit``,
                               ``ranks``, ``threads``, ``core_s`` [s], ``cpu_s`` [s] or null,
                               ``host``, ...) and their totals (`pdem.campaign.record`)
    OUT/<member>/pdem.log      stdout and stderr of every attempt, each after a line starting
                               with `ATTEMPT_MARK`

Imports the standard library only.
"""
import json
from pathlib import Path

MANIFEST = "campaign.json"
SCENE = "scene.toml"
MEMBER = "member.json"
RUN = "run.json"
LOG = "pdem.log"
LOCK = ".lock"
FORMAT = "pdem-campaign"
VERSION = 1
ATTEMPT_MARK = "=== pdem campaign: attempt"


class ManifestError(ValueError):
    """A directory without a usable manifest; the message is one line."""


def manifest(name, campaign_file, base, seed_key, varied, cases, analysis, members):
    """The manifest (a JSON-able dict); ``members`` are dicts of name, dir, params, ranks, threads."""
    return {"format": FORMAT, "version": VERSION, "name": name, "campaign_file": str(campaign_file),
            "base": str(base), "seed_key": seed_key, "varied": varied, "cases": cases, "analysis": analysis,
            "members": members}


def read_manifest(out) -> dict:
    """The manifest of the campaign directory ``out`` (ManifestError if it has none or a bad one)."""
    p = Path(out) / MANIFEST
    try:
        man = json.loads(p.read_text())
    except FileNotFoundError:
        raise ManifestError(f"{out}: not a campaign directory (no {MANIFEST})") from None
    except ValueError as exc:
        raise ManifestError(f"{p}: not valid JSON ({exc})") from None
    if not isinstance(man, dict) or man.get("format") != FORMAT:
        raise ManifestError(f"{p}: not a pdem campaign manifest (format is not {FORMAT!r})")
    if man.get("version") != VERSION:
        raise ManifestError(f"{p}: manifest version {man.get('version')!r} not supported (this reader reads "
                            f"{VERSION})")
    return man


def read_run(d):
    """The run record of member directory ``d`` (None if it has none or it is unreadable)."""
    try:
        rec = json.loads((Path(d) / RUN).read_text())
    except (FileNotFoundError, ValueError):
        return None
    return rec if isinstance(rec, dict) and isinstance(rec.get("attempts"), list) else None
