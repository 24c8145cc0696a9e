"""pdem writes the results format `pdem.format.schema` defines, and `analysis` reads it back.

A small plain scene is run through pdem's driver (the same code as ``pdem run``, on one rank);
its results.h5 is read by `pdem.format.read.read_results` (schema name and version checked) and every
/series column carries the units `pdem.format.schema.RUN_SERIES` gives it. The box test's side of
the same contract (BOX_TEST_SERIES, CYCLE_COLUMNS) is exercised end to end by
tests/scenes/test_box_test.py, whose post-processing runs `python -m analysis summary`.
"""
import h5py

from pdem.format import schema
from pdem.format.read import read_results
from pdem.cli import run_file

SCENE = """
[simulation]
damping = 0.3
gravity = [0.0, 0.0, -9.81]
[run]
steps = 60
output_every = 20
progress_every = 0
kind = "deposition"
[materials.ballast]
density = 2600.0
young = 1e7
poisson = 0.3
friction_angle = 0.5
[deposition]
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.1, 0.1, 0.1]
count = 20
radius = 0.008
material = "ballast"
walls_material = "ballast"
"""


def test_plain_run_results_are_read_by_analysis(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    assert run_file(scene, tmp_path / "out", fresh=True) == 0
    res = read_results(tmp_path / "out" / "results.h5", required=tuple(schema.RUN_SERIES))
    assert res.kind == "deposition" and res.attrs["schema_version"] == schema.SCHEMA_VERSION
    assert res.units == schema.RUN_SERIES
    assert list(res.series["step"]) == [0, 20, 40, 60]
    with h5py.File(tmp_path / "out" / "results.h5", "r") as f:
        assert f.attrs["schema"] == schema.SCHEMA
