"""The box test (`pdem.scenes.box_test`, `pdem.scenes.common.preparation`): its pieces without a run, then
end to end through the command line on 1, 2 and 3 ranks.

Pieces: trimming, cloud sizing, sleeper placement, and friction lowered and restored for the
vibration stage (Ip2 again).

End to end (slow): a small box test (about 650 spheres, stiffness scaled down, 2 cycles at 5 Hz)
runs all five stages (pour, refill, vibrate, settle, load). The same scene on 1 and 2 ranks must
give the same per-cycle records, load series and preparation series bit for bit; a 2-rank run
resumed on 3 ranks from a stage-boundary checkpoint, and one stopped by SIGTERM in the middle of a
stage and resumed on 1 rank, must end with the same bits too. The run leaves the files a user looks
at (results.h5 readable by `analysis`, PNGs, summary). Bad input stops with one line and status 2.
"""
import os
import shutil
import signal
import subprocess
import time
from math import pi, tan

import h5py
import numpy as np
import pytest

from pdem.format.read import read_box_test
from pdem_cli import needs_mpiexec, pdem_cmd, run_pdem
from run_files import run_differences
from factories import BOX_MATERIALS
from pdem.scenes.common.preparation import cloud, cloud_count
from pdem.driver.stages import remove_above
from pdem.io.checkpoint import list_checkpoints
from pdem.build.scene import Scene
from pdem.scenes.box_test import DEFAULTS, sleeper_geometry


# ---------------------------------------------------------------------------- pieces
def test_remove_above_uses_the_top_of_each_sphere():
    p = {"gid": np.arange(4), "pos": np.array([[0, 0, 0.10], [0, 0, 0.28], [0, 0, 0.29], [0, 0, 0.5]]),
         "radius": np.array([0.01, 0.02, 0.01, 0.01])}
    kept, removed = remove_above({"particles": p, "contacts/sphere_sphere": {"key": np.zeros(0)}}, 0.30)
    assert removed == 2 and list(kept["particles"]["gid"]) == [0, 2]
    assert "contacts/sphere_sphere" in kept


def test_cloud_count_fills_the_volume_at_the_packing_fraction():
    c = dict(DEFAULTS, radius=0.01, radius_spread=0.0, packing_fraction=0.6, overfill=1.0)
    v = 4.0 / 3.0 * pi * 0.01**3
    assert cloud_count(c, 1000 * v / 0.6) == 1000
    # radii uniform in r(1 ± s): the mean volume uses E[r^3] = (b^4 - a^4) / (4 (b - a))
    c = dict(c, radius_spread=0.4)
    a, b = 0.006, 0.014
    mean_v = 4.0 / 3.0 * pi * (b**4 - a**4) / (4 * (b - a))
    assert cloud_count(c, 500 * mean_v / 0.6) in (500, 501)


def test_cloud_stays_in_its_column_without_overlaps():
    c = dict(DEFAULTS, radius=0.0125, radius_spread=0.3, seed=3)
    pos, r = cloud(c, (0.0, 0.0), (0.1, 0.15), 0.2, 0.1 * 0.15 * 0.05, 3)
    assert np.all(pos[:, 0] - r >= 0) and np.all(pos[:, 0] + r <= 0.1)
    assert np.all(pos[:, 1] - r >= 0) and np.all(pos[:, 1] + r <= 0.15) and np.all(pos[:, 2] - r >= 0.2)
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) - r[:, None] - r[None]
    assert d[~np.eye(len(r), dtype=bool)].min() > 0


def test_sleeper_sits_on_the_cut_centred_in_the_box():
    center, half = sleeper_geometry(DEFAULTS, 0.30)
    assert np.allclose(center, [0.35, 0.15, 0.375]) and np.allclose(half, [0.125, 0.15, 0.075])


def test_friction_scale_reruns_ip2_for_existing_contacts_and_restores_bits():
    scene = Scene(dt=1e-5, damping=0.3, gravity=(0, 0, -9.81), allow_initial_overlap=True)
    a = scene.material(density=2600, young=1e7, poisson=0.3, friction_angle=0.5)
    b = scene.material(density=7850, young=1e8, poisson=0.25, friction_angle=0.3)
    pos = [(0, 0, 0.0095), (0.019, 0, 0.0095), (0.0095, 0.0, 0.0265)]
    scene.add_spheres(pos, 0.01, [a, a, b])
    scene.add_wall("z", 0.0, b, sense=1)
    sim = scene.build()
    sim.run(1)
    for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts):
        assert len(cl.real_rows()) > 0
    before = {
        id(cl): cl.params[: cl.n].copy()
        for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts)
    }
    sim.set_friction_scale(0.1)
    ss = sim.kind("sphere_sphere").contacts.real_rows()
    expect = [
        tan(0.05)
        if {
            int(sim.particles.material[i])
            for i in (sim.kind("sphere_sphere").contacts.i[k], sim.kind("sphere_sphere").contacts.j[k])
        }
        == {0}
        else tan(0.03)
        for k in ss
    ]
    assert np.array_equal(sim.kind("sphere_sphere").contacts.params[ss, 2], expect)
    assert np.all(sim.kind("sphere_wall").contacts.params[sim.kind("sphere_wall").contacts.real_rows(), 2] == tan(0.03))
    assert np.array_equal(sim.props[:, 2], np.array([0.5, 0.3]) * 0.1)
    sim.set_friction_scale(1.0)
    for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts):
        assert np.array_equal(cl.params[: cl.n], before[id(cl)])


# ---------------------------------------------------------------------------- end to end
# slow: whole box tests through `pdem run` subprocesses on 1, 2 and 3 ranks (minutes); bad input: seconds
SCENE = """[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]
slab_axis = "x"

[run]
progress_every = 0
output_every = 25
snapshot_every = 2000
checkpoint_keep = 0

""" + BOX_MATERIALS + """
[box_test]
box = [0.35, 0.15, 0.26]
radius = 0.0125
radius_spread = 0.3
seed = 5
cut_height = 0.16
height = 0.24
sleeper_size = [0.12, 0.15, 0.08]
sleeper_mass = 5.0
settle_max_time = 0.8
vibration_time = 0.1
f_min = 0.0
f_max = 300.0
frequency = 5.0
cycles = 2
"""
N_CYCLES, F_MAX, SLEEPER_WEIGHT = 2, 300.0, 5.0 * 9.81


def groups(path):
    with h5py.File(path, "r") as f:
        return {g: {c: f[g][c][()] for c in f[g]} for g in f}


def assert_same_run(ref, got):
    """Every dataset of the results, preparation and snapshot files (the snapshots' blocks nest
    groups) and the last checkpoint's bodies, bit for bit (`run_files.run_differences`)."""
    bad = run_differences(ref, got, files=("results.h5", "preparation.h5", "snapshots.h5"))
    assert bad == [], f"{got}: {bad}"


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    base = tmp_path_factory.mktemp("box_test")
    scene = base / "scene.toml"
    scene.write_text(SCENE)
    return base, scene


@pytest.fixture(scope="module")
def r1(scene_dir):
    base, scene = scene_dir
    return run_pdem(1, scene, base / "r1")


@pytest.fixture(scope="module")
def r2(scene_dir):
    base, scene = scene_dir
    return run_pdem(2, scene, base / "r2")


@pytest.mark.slow
def test_every_stage_runs_and_leaves_results(scene_dir, r1):
    base, _ = scene_dir
    out = base / "r1"
    for stage in ("pour", "refill", "vibrate", "settle", "load"):
        assert f"stage {stage} done" in r1.stdout
    for f in ("results.h5", "preparation.h5", "preparation.png", "summary.txt", "snapshots.xmf", "analysis/loops.png",
              "analysis/settlement.png", "analysis/stiffness.png", "analysis/summary.txt"):
        assert (out / f).stat().st_size > 0, f
    res = read_box_test(out / "results.h5")
    cyc = res.cycles
    assert res.kind == "box_test" and list(cyc["cycle"]) == [1.0, 2.0]
    # the ballast carries the load plus the sleeper's weight (dynamic, damped: within 15 %)
    assert np.all(np.abs(cyc["force_peak"] - (F_MAX + SLEEPER_WEIGHT)) < 0.15 * (F_MAX + SLEEPER_WEIGHT))
    assert np.all(cyc["settlement_peak"] > cyc["settlement_start"])
    prep = groups(out / "preparation.h5")["series"]
    # trimming: after the refill the top of the ballast is at most the final height (plus nothing)
    vib = prep["stage"] == 2
    assert prep["bed_top"][vib][0] <= 0.24 + 1e-12
    # the sleeper rests on the ballast during preparation: its bottom never goes under the first cut by
    # more than the compaction, and it never floats above it
    z = prep["sleeper_z"][prep["stage"] >= 1]
    assert np.all(z - 0.04 <= 0.16 + 1e-12) and np.all(z - 0.04 > 0.08)


@pytest.mark.slow
@needs_mpiexec
def test_same_bits_on_1_and_2_ranks(scene_dir, r1, r2):
    base, _ = scene_dir
    assert_same_run(base / "r1", base / "r2")


@pytest.mark.slow
@needs_mpiexec
def test_resume_from_a_stage_boundary_on_3_ranks(scene_dir, r1, r2):
    base, scene = scene_dir
    out = base / "resume3"
    shutil.copytree(base / "r2", out)
    # keep the checkpoints up to the end of the refill stage: the run restarts at "vibrate"
    line = next(s for s in r2.stdout.splitlines() if "(end of stage refill" in s)
    step = int(line.split(":")[0].split()[1])
    for s, p in list_checkpoints(out / "checkpoints"):
        if s > step:
            p.unlink()
    r = run_pdem(3, scene, out)
    assert f"at step {step} (stage vibrate" in r.stdout
    assert_same_run(base / "r1", out)


@pytest.mark.slow
@needs_mpiexec
def test_sigterm_mid_stage_then_resume_on_1_rank(scene_dir, r1):
    base, scene = scene_dir
    out = base / "term"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    proc = subprocess.Popen(pdem_cmd(2, scene, out), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env, start_new_session=True)
    lines = []
    for line in proc.stdout:  # wait until the refill stage runs, then stop the job as SLURM would
        lines.append(line)
        if line.startswith("stage refill:"):
            time.sleep(0.3)
            os.killpg(proc.pid, signal.SIGTERM)
            break
    lines += proc.stdout.readlines()
    assert proc.wait(timeout=300) == 3, "".join(lines)
    assert any("stop signal received" in s for s in lines), "".join(lines)
    r = run_pdem(1, scene, out)
    assert "(resumed)" in r.stdout
    assert_same_run(base / "r1", out)


@pytest.mark.parametrize("edit, message", [
    (("cycles = 2", "cycles = 0"), "box_test.cycles = 0: must be an integer >= 1"),
    (("seed = 5", "seed = 5\nsleeper_weight = 3"), "box_test.sleeper_weight: unknown key"),
    (('box = [0.35, 0.15, 0.26]', 'box = [0.35, 0.15, 0.26]\nbase_material = "clay"'),
     "box_test.base_material = 'clay': no [materials.clay] table"),
    (("height = 0.24", "height = 0.1"), "box_test.height = 0.1: must be above cut_height"),
])
def test_bad_input_one_line(tmp_path, edit, message):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.replace(*edit))
    r = run_pdem(1, scene, tmp_path / "out", expect=2)
    assert message in r.stderr and r.stderr.count("\n") == 1, r.stderr
