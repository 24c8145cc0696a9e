"""The direct shear box (`pdem.scenes.shear_box`, the one-file scene of docs/design.md): input
errors, the frame geometry, and a small box (~330 spheres) through the command line on 1 and 2
ranks: the same bits, a positive shear stress and a peak friction angle atan(τ/σ) between the
grains' friction angle and 60° (dense granular peaks are 30–50°); a resume from a checkpoint
inside the shear stage ends with the same bits."""
import math
import shutil
import tomllib

import numpy as np
import pytest
from factories import ROOT, toml_text
from run_files import run_differences

from pdem.errors import InputError
from pdem.format.read import read_results
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.scenes import shear_box
from pdem_cli import needs_mpiexec, run_pdem

JOB = ROOT / "jobs" / "shear_box.toml"
SMALL = {"side": 0.06, "height": 0.04, "shear_displacement": 0.005, "settle_max_time": 0.3}


def job_doc(run=None, **change):
    doc = tomllib.loads(JOB.read_text())
    doc["shear_box"].update(change)
    doc["run"].update(run or {})
    return doc


@pytest.mark.parametrize("change, field", [
    ({"side": -0.1}, "shear_box.side"), ({"normal_stress": "high"}, "shear_box.normal_stress"),
    ({"shear_displacement": 0.06}, "shear_box.shear_displacement"), ({"frame_material": "glass"}, "shear_box.frame"),
    ({"sied": 0.1}, "shear_box.sied"), ({"radius": 0.08}, "shear_box.radius"),
])
def test_input_errors_name_the_field(change, field):
    with pytest.raises(InputError) as e:
        shear_box.check(job_doc(**change))
    assert field in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_bad_input_is_one_line_exit_2(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(toml_text(job_doc(shear_velocity=0.0)))
    r = run_pdem(1, scene, tmp_path / "r", expect=2)
    assert "shear_box.shear_velocity" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_frame_faces_close_the_square():
    tri = np.array(shear_box.square_faces(0.05, 0.0, 0.03, dx=0.01))
    assert tri.shape == (8, 3, 3)
    assert set(np.round(tri[..., 0].ravel(), 12)) == {-0.04, 0.06} and set(np.round(tri[..., 1].ravel(), 12)) == {
        -0.05, 0.05}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("shear_box")
    scene = base / "small.toml"
    scene.write_text(toml_text(job_doc(run={"checkpoint_every": 300}, **SMALL)))
    for n in (1, 2):
        run_pdem(n, scene, base / f"r{n}")
    return base / "r1", base / "r2", scene


@pytest.mark.slow
@needs_mpiexec
def test_same_bits_on_1_and_2_ranks(runs):
    """slow: the small box on 1 and 2 ranks (~40 s each on a loaded 2-core machine)."""
    assert run_differences(*runs[:2]) == []


@pytest.mark.slow
@needs_mpiexec
def test_shear_stress_and_peak_friction_angle(runs):
    """slow: uses the runs of `test_same_bits_on_1_and_2_ranks`."""
    s = read_results(runs[0] / "results.h5").series
    d, tau, sigma = s["shear_displacement"], s["shear_force"], s["normal_force"]
    assert d[0] == 0.0 and d[-1] >= SMALL["shear_displacement"] - 1e-9
    assert np.all(tau[d > 0.1 * d[-1]] > 0) and np.all(sigma > 0)
    peak = math.atan(float(np.max(tau / sigma)))
    assert job_doc()["materials"]["grains"]["friction_angle"] < peak < math.radians(60.0), math.degrees(peak)
    assert "friction angle" in (runs[0] / "summary.txt").read_text()


@pytest.mark.slow
def test_resume_inside_the_shear_stage(runs, tmp_path):
    """slow: reruns the small box on 2 ranks from its last checkpoint inside the shear stage (the
    upper frame moving: its facets' positions and velocity come back)."""
    got = tmp_path / "resumed"
    shutil.copytree(runs[0], got)
    shutil.rmtree(got / "analysis")
    inside = [step for step, path in list_checkpoints(got / "checkpoints")
              if read_checkpoint(path)[1]["shear_box"]["stage"] == 2]
    assert inside, "no checkpoint inside the shear stage: lower run.checkpoint_every"
    for step, path in list_checkpoints(got / "checkpoints"):
        if step > inside[-1]:
            path.unlink()
    r = run_pdem(2, runs[2], got)
    assert "resuming" in r.stdout and "stage shear (resumed)" in r.stdout
    assert run_differences(runs[0], got) == []
