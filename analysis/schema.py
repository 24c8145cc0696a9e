"""The pdem results file format (HDF5), version 1, and a writer for it.

This module owns the format: names, units and the writer `write_results`. pdem may use the
writer to produce results; tests use it to make synthetic files. It imports only numpy and
h5py (never pdem, numba, mpi4py or matplotlib).

Layout
------
root attributes
    ``schema`` = "pdem-results", ``schema_version`` = 1, ``scene`` (JSON text),
    ``pdem_version`` (text), ``kind`` (text, e.g. "box_test", "deposition").
``/series``
    1-D float64 datasets of equal length (one entry per output sample), each with a ``units``
    attribute. Always ``time`` [s] and ``step`` [-]; the box test adds ``sleeper_load`` [N]
    (applied program), ``sleeper_force`` [N] (force of the ballast on the sleeper, positive
    upward) and ``sleeper_settlement`` [m] (positive downward, zero at the start of cycling).
``/cycles`` (cyclic tests only)
    1-D float64 datasets, one entry per completed cycle: ``cycle`` [-] (1..N), ``t_start`` [s],
    ``settlement_start``, ``settlement_peak``, ``settlement_end`` [m], ``force_peak``,
    ``force_min`` [N].
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Mapping

import h5py
import numpy as np

SCHEMA = "pdem-results"
SCHEMA_VERSION = 1
ROOT_ATTRS = ("schema", "schema_version", "scene", "pdem_version", "kind")

# Units of every dataset name the schema defines [SI].
SERIES_UNITS = {
    "time": "s",
    "step": "-",
    "sleeper_load": "N",
    "sleeper_force": "N",
    "sleeper_settlement": "m",
}
CYCLE_UNITS = {
    "cycle": "-",
    "t_start": "s",
    "settlement_start": "m",
    "settlement_peak": "m",
    "settlement_end": "m",
    "force_peak": "N",
    "force_min": "N",
}
# Optional per-cycle columns pdem writes too: the extremes of the applied load and the step at
# which the cycle was recorded.
CYCLE_OPTIONAL_UNITS = {"load_max": "N", "load_min": "N", "step": "-"}

# What pdem's runs write (pdem's driver imports these; the engine never imports analysis):
# /series of a plain scene run (kind "scene"), the box test's load record (kind "box_test"),
# its preparation record (preparation.h5, kind "preparation") and the /cycles table.
RUN_SERIES = {"step": "-", "time": "s", "dt": "s", "kinetic_energy": "J", "elastic_energy": "J",
              "contacts_per_particle": "-", "unbalanced_force": "-", "bed_top": "m", "floor_force_z": "N"}
BOX_TEST_SERIES = {"step": "-", "time": "s", "dt": "s", "sleeper_load": "N", "sleeper_force": "N",
                   "sleeper_settlement": "m", "kinetic_energy": "J", "contacts_per_particle": "-"}
PREPARATION_SERIES = {"step": "-", "time": "s", "stage": "-", "n_spheres": "-", "kinetic_energy": "J",
                      "unbalanced_force": "-", "contacts_per_particle": "-", "bed_top": "m", "sleeper_z": "m"}
CYCLE_COLUMNS = {**CYCLE_UNITS, **CYCLE_OPTIONAL_UNITS}
REQUIRED_SERIES = ("time", "step")
BOX_SERIES = ("sleeper_load", "sleeper_force", "sleeper_settlement")
CYCLE_FIELDS = tuple(CYCLE_UNITS)


def write_results(path, series: Mapping, cycles: Mapping | None, attrs: Mapping) -> Path:
    """Write a pdem results file, atomically (temporary file, then rename).

    Parameters
    ----------
    path : str or Path
        File to write; replaced if it exists.
    series : mapping name -> array or (array, units)
        Time series of equal length; ``time`` and ``step`` are required. Names in
        `SERIES_UNITS` take their units from there; other names must come as (array, units).
    cycles : mapping name -> array, or None
        Per-cycle table with all of `CYCLE_FIELDS`, or None for non-cyclic runs.
    attrs : mapping
        ``scene`` (dict, written as JSON, or JSON text), ``pdem_version`` and ``kind``.
        ``schema`` and ``schema_version`` are set here.

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    series_data = _prepare(series, SERIES_UNITS, "series")
    missing = [name for name in REQUIRED_SERIES if name not in series_data]
    if missing:
        raise ValueError(f"series lacks {', '.join(missing)}")
    cycle_data = None
    if cycles is not None:
        cycle_data = _prepare(cycles, CYCLE_UNITS, "cycles")
        missing = [name for name in CYCLE_FIELDS if name not in cycle_data]
        if missing:
            raise ValueError(f"cycles lacks {', '.join(missing)}")
    root = _root_attrs(attrs)

    tmp = path.with_name(path.name + ".tmp")
    with h5py.File(tmp, "w") as f:
        f.attrs.update(root)
        _write_group(f.create_group("series"), series_data)
        if cycle_data is not None:
            _write_group(f.create_group("cycles"), cycle_data)
    os.replace(tmp, path)
    return path


def _root_attrs(attrs: Mapping) -> dict:
    """Root attributes with the schema tag; the scene as JSON text."""
    missing = [k for k in ("scene", "pdem_version", "kind") if k not in attrs]
    if missing:
        raise ValueError(f"attrs lacks {', '.join(missing)}")
    scene = attrs["scene"]
    if not isinstance(scene, str):
        scene = json.dumps(scene, sort_keys=True)
    root = {k: v for k, v in attrs.items() if k not in ("schema", "schema_version")}
    root.update(schema=SCHEMA, schema_version=SCHEMA_VERSION, scene=scene,
                pdem_version=str(attrs["pdem_version"]), kind=str(attrs["kind"]))
    return root


def _prepare(data: Mapping, known_units: Mapping, group: str) -> dict:
    """name -> (float64 1-D array, units); all of equal length."""
    out = {}
    for name, value in data.items():
        if isinstance(value, tuple):
            values, units = value
        elif name in known_units:
            values, units = value, known_units[name]
        else:
            raise ValueError(f"{group}/{name}: units unknown, pass (array, units)")
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 1:
            raise ValueError(f"{group}/{name}: must be 1-D, got shape {values.shape}")
        out[name] = (values, str(units))
    lengths = {len(v) for v, _ in out.values()}
    if len(lengths) > 1:
        raise ValueError(f"{group}: datasets differ in length {sorted(lengths)}")
    return out


def _write_group(group: h5py.Group, data: dict) -> None:
    for name, (values, units) in data.items():
        ds = group.create_dataset(name, data=values)
        ds.attrs["units"] = units
