"""The run's account for its post-processing: ``RUN/run_info.json`` (format "pdem-run-info", v1).

A run (a plain scene, `pdem.driver.plain`, or a staged one: box test, oedometer, blast, track)
writes it on rank 0 at the end of a complete run, atomically; ``python -m analysis summary RUN``
(launched by ``pdem run`` after a successful run) reads it with the run's other files and writes
``summary.txt``, the plots and ``analysis/``. It holds what only the run knows; everything
computed from the results is the analysis's:

``summary``      the post-processing the run declares: "scene" (plain), "box_test", "oedometer",
                 "blast", "track"
``title``        what the run is ("box test", ...); ``scene_file`` (path of the scene file)
``ranks``        [-]; ``wall_s`` wall time of the run [s]
``about``        lines describing the run, shown under the title (text)
``stages``       one row per stage (none for a plain run): ``stage``, ``t_end`` [s], ``step_end``
                 [-], ``spheres`` [-], ``unbalanced_force`` [-], ``bed_top`` [m], ``wall_s`` [s]
                 and the scene's own entries
``stage_columns`` [[key, label, format]] of those own entries shown in the stage table
``preparation``  {``stages``: names, ``body``: label of the rigid body's height} for the plot of
                 preparation.h5, or null (no preparation in this run)
``notes``        lines shown under the stage table (load program, load balance, ...)
``timing``       the timing table (text)
``pdem_version`` the pdem that ran it; ``finished`` when it ended (UTC, ISO 8601)
``materials``    the scene file's [materials] tables as written (SI units: density [kg/m^3],
                 young [Pa], friction_angle [rad], ...)
``seeds``        {dotted key of the scene file: value} of every random seed it sets
and the entries of its kind: oedometer ``intact_members`` [-]; blast ``plates`` [[areal mass
[kg/m^2], run directory relative to RUN]]; track ``traffic`` (bool: traffic was run).

`clear_run_info` removes the account of an earlier run before a run starts, so that only a run
that completed leaves one. Imports the standard library only.
"""
import json
import os
import time
from pathlib import Path

RUN_INFO = "run_info.json"
FORMAT = "pdem-run-info"
VERSION = 1


def scene_facts(doc) -> dict:
    """``materials`` and ``seeds`` of the parsed scene file ``doc`` (entries of run_info.json):
    every key named ``seed`` or ending in ``_seed``, at any depth, by its dotted path."""
    seeds = {}

    def walk(table, prefix):
        for key, value in table.items():
            if isinstance(value, dict):
                walk(value, f"{prefix}{key}.")
            elif key == "seed" or key.endswith("_seed"):
                seeds[prefix + key] = value

    walk(doc, "")
    return {"materials": doc.get("materials", {}), "seeds": seeds,
            "finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def write_run_info(run_dir, **info) -> Path:
    """Write ``RUN/run_info.json`` atomically (temporary file, then rename)."""
    path = Path(run_dir) / RUN_INFO
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps({"format": FORMAT, "version": VERSION, **info}, indent=1) + "\n")
    os.replace(tmp, path)
    return path


def read_run_info(run_dir) -> dict | None:
    """The account of the run in ``run_dir``, or None if it has none (ValueError if malformed)."""
    path = Path(run_dir) / RUN_INFO
    try:
        info = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    if not isinstance(info, dict) or info.get("format") != FORMAT or info.get("version") != VERSION:
        raise ValueError(f"{path}: not a {FORMAT} file of version {VERSION}")
    return info


def clear_run_info(run_dir) -> None:
    """Remove the account of an earlier run (if any; an output path that is no folder is left to
    the run's own check, which names it as bad input)."""
    path = Path(run_dir) / RUN_INFO
    if path.is_file():
        path.unlink()
