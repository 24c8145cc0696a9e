"""jobs/plate_load.toml, the experiment written only as a scene file (docs/own_experiment.md), and
``pdem run --set``: a short run (--steps) on 1 and 2 ranks, and resumed from a checkpoint, gives
the same bits; its series carry the plate's position, force and load, the load following the
haversine formula; --set changes the scene (written to OUT/scene_set.toml), refuses unknown keys
and bad values in one line, and enters the ranks' start digest."""
import math
import tomllib

import numpy as np
import pytest
from factories import ROOT
from run_files import run_differences

from pdem.driver.preflight import input_digests
from pdem.format.read import read_results
from pdem_cli import needs_mpiexec, run_pdem

JOB = ROOT / "jobs" / "plate_load.toml"
STEPS = "300"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("plate_load")
    for n in (1, 2):
        run_pdem(n, JOB, base / f"r{n}", "--steps", STEPS)
    return base / "r1", base / "r2"


@pytest.mark.slow
@needs_mpiexec
def test_same_bits_on_1_and_2_ranks(runs):
    """slow: 300 steps of the job on 1 and 2 ranks."""
    assert run_differences(*runs, files=("results.h5",)) == []


@pytest.mark.slow
@needs_mpiexec
def test_resume_on_another_rank_count_gives_the_same_bits(runs, tmp_path):
    """slow: 150 steps on 1 rank, resumed to 300 on 2, against the straight run."""
    out = tmp_path / "resumed"
    run_pdem(1, JOB, out, "--steps", "150")
    run_pdem(2, JOB, out, "--steps", STEPS)
    assert run_differences(runs[0], out, files=("results.h5",)) == []


@pytest.mark.slow
@needs_mpiexec
def test_series_carry_the_plate_and_its_load(runs):
    """slow: uses the runs of `test_same_bits_on_1_and_2_ranks`."""
    s = read_results(runs[0] / "results.h5").series
    t = s["time"]
    assert s["step"][-1] == int(STEPS)
    f = 50.0 + 450.0 * (1.0 - np.cos(2.0 * math.pi * 10.0 * (t - 0.25))) / 2.0  # the job's program
    assert np.allclose(s["body_plate_load"], np.where((t > 0.25) & (t < 0.55), f, 50.0), rtol=1e-12)
    assert np.all(s["body_plate_x"] == 0.15) and np.all(s["body_plate_y"] == 0.15)  # blocked
    assert s["body_plate_z"][0] == 0.11 and s["body_plate_z"][-1] < 0.11  # it fell
    assert np.all(s["body_plate_force_x"] == 0.0) or np.any(s["body_plate_force_z"] != 0.0)


def test_set_refusals_are_one_line(tmp_path):
    for arg, field in (("simulation.dampin=0.1", "simulation.dampin"), ("loads.3.force=1.0", "loads.3.force"),
                       ("run.steps=abc", "run.steps"), ("bodies.0.mass=[1", "bodies.0.mass"),
                       ("nothing", "nothing")):
        r = run_pdem(1, JOB, tmp_path / "r", "--set", arg, expect=2)
        line = r.stderr.strip()
        assert len(line.splitlines()) == 1 and "--set" in line and field in line, line


@pytest.mark.slow
def test_set_changes_the_scene_and_writes_it(tmp_path):
    """slow: 40 steps on one rank."""
    out = tmp_path / "r"
    run_pdem(1, JOB, out, "--steps", "40", "--set", "loads.0.f_min=80.0", "--set", "run.output_every=10",
             "--set", "simulation.slab_axis=y")
    want = tomllib.loads(JOB.read_text())
    want["loads"][0]["f_min"] = 80.0
    want["run"]["output_every"] = 10
    want["simulation"]["slab_axis"] = "y"
    assert tomllib.loads((out / "scene_set.toml").read_text()) == want
    s = read_results(out / "results.h5").series
    assert list(s["step"]) == [0, 10, 20, 30, 40] and np.all(s["body_plate_load"] == 80.0)


def test_sets_enter_the_start_digest():
    args = {"out": "o", "steps": None, "fresh": False}
    a = input_digests(JOB, {**args, "set": []})
    b = input_digests(JOB, {**args, "set": ["run.steps=5"]})
    assert a[0] == b[0] and a[1] != b[1]
