"""Results files of pdem's runs, in the one format `analysis.schema` defines.

The schema (name, version, the columns of every kind of run and their units) lives in
`analysis.schema`; `analysis.io` reads it back with a version check, and
tests/analysis/test_schema_roundtrip.py checks that a file pdem writes is one analysis reads.
Writers are the engine's generic ones (`pdem.io.timeseries`) given that schema.
"""
import json

from analysis import schema

from ..version import __version__
from ..io.timeseries import TimeSeriesWriter, write_table

SCHEMA = (schema.SCHEMA, schema.SCHEMA_VERSION)


def series_writer(path, columns, comm, restart_step=None, every=10):
    """A /series writer of ``columns`` (units by name) on rank 0; appends after a restart."""
    return TimeSeriesWriter(path, columns, schema=SCHEMA, every=every, comm=comm, append=restart_step is not None,
                            restart_step=restart_step)


def write_cycles(path, columns, comm):
    """The whole /cycles table (columns of `analysis.schema.CYCLE_COLUMNS`)."""
    write_table(path, "cycles", columns, schema.CYCLE_COLUMNS, schema=SCHEMA, comm=comm)


def write_root_attrs(path, scene_spec, kind):
    """Root attributes ``scene`` (JSON), ``pdem_version`` and ``kind`` (rank 0 only)."""
    from ..io._h5 import open_h5

    with open_h5(path, "a") as f:
        f.attrs["scene"] = json.dumps(scene_spec)
        f.attrs["pdem_version"] = __version__
        f.attrs["kind"] = kind
