"""Results files of pdem's runs, in the one format `pdem.format.schema` defines.

The schema (name, version, the columns of every kind of run and their units) lives in
`pdem.format.schema`; `pdem.format.read` reads it back with a version check, and
tests/analysis/test_schema_roundtrip.py checks that a file pdem writes is one analysis reads.
Writers are the engine's generic ones (`pdem.io.timeseries`) given that schema.
"""
import json

import numpy as np

from ..format import schema

from ..checks.diagnostics import check_finite
from ..errors import InstabilityError

from ..version import __version__
from ..io.timeseries import TimeSeriesWriter, write_table

SCHEMA = (schema.SCHEMA, schema.SCHEMA_VERSION)


class FiniteSeriesWriter(TimeSeriesWriter):
    """A /series writer that never writes a NaN or an infinity: a row with one stops the run
    (`finite_row`). Rows are reduced values, the same on every rank, so every rank stops together."""

    def append(self, row=None, **values):
        finite_row({**(row or {}), **values})
        super().append(row, **values)


def finite_row(row, sim=None):
    """``row`` if all its values are finite; else raise `InstabilityError` naming the step and the
    columns (first naming the body with a non-finite state, if ``sim`` is given: collective)."""
    bad = [k for k, v in row.items() if not np.all(np.isfinite(v))]
    if bad:
        if sim is not None:
            check_finite(sim)
        raise InstabilityError(f"step {row.get('step', '?')}: {', '.join(bad)} not finite in the results: the state "
                               "blew up between two stability checks (a time step too large for the stiffness, or "
                               "an input that is not finite)")
    return row


def series_writer(path, columns, comm, restart_step=None, every=10):
    """A /series writer of ``columns`` (units by name) on rank 0; appends after a restart.
    A row with a non-finite value is never written: it stops the run (`finite_row`)."""
    return FiniteSeriesWriter(path, columns, schema=SCHEMA, every=every, comm=comm, append=restart_step is not None,
                              restart_step=restart_step)


def write_cycles(path, columns, comm):
    """The whole /cycles table (columns of `pdem.format.schema.CYCLE_COLUMNS`)."""
    write_table(path, "cycles", columns, schema.CYCLE_COLUMNS, schema=SCHEMA, comm=comm)


def write_root_attrs(path, scene_spec, kind, external_work=None):
    """Root attributes ``scene`` (JSON), ``pdem_version``, ``kind`` and, if given,
    ``external_work`` (0/1: boundaries move or loads act; rank 0 only)."""
    from ..io._h5 import open_h5

    with open_h5(path, "a") as f:
        f.attrs["scene"] = json.dumps(scene_spec)
        f.attrs["pdem_version"] = __version__
        f.attrs["kind"] = kind
        if external_work is not None:
            f.attrs["external_work"] = int(bool(external_work))
