"""`pdem run` restarts through the command line, on 1, 2 and 3 MPI ranks (subprocesses).

One uninterrupted serial run of 3000 steps is the reference. A 2-rank run stops at step k (its
final checkpoint; scheduled checkpoints every 500 steps and every 0.001 s (checked every 100 steps) on the way, 2 kept);
copies of its output directory are resumed on 1, 2 and 3 ranks up to step 3000. The final
checkpoint tables (bodies by gid, contact history by key, walls) and the whole results time
series must equal the reference bit for bit. Also: SIGTERM to a 2-rank run's process group
gives exit status 3 and a checkpoint, from which a resume reaches the same bits; a truncated
newest checkpoint is skipped with a message; a lone truncated checkpoint is refused (exit 2,
one line). The launcher is the venv's mpiexec, next to sys.executable.
"""
import os
import shutil
import signal
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from pdem_cli import MPIEXEC, needs_mpiexec, pdem_cmd, run_pdem
from pdem.io.checkpoint import list_checkpoints, read_checkpoint

# slow: 2000-step runs through `pdem run` subprocesses, killed and resumed on 1-3 ranks
pytestmark = pytest.mark.slow

N_STEPS = 3000
K_STEP = 2137

SCENE = """
[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]
dt_interval = 50
check_interval = 40

[run]
steps = 3000
progress_every = 100
output_every = 50
snapshot_every = 1000
checkpoint_every = 500
checkpoint_every_s = 0.001
checkpoint_keep = 2
kind = "deposition"

[materials.ballast]
density = 2600.0
young = 1.0e7
poisson = 0.3
friction_angle = 0.5

[deposition]
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.6, 0.12, 0.3]
count = 800
radius = 0.01
radius_spread = 0.3
seed = 3
material = "ballast"
walls_material = "ballast"
"""

# the checkpoints are written on 2 ranks; without mpiexec (a machine without MPI) on 1, and the
# tests that need several ranks are skipped
WRITER_RANKS = 2 if MPIEXEC.exists() else 1


def final_tables(out, step=N_STEPS):
    return read_checkpoint(Path(out) / "checkpoints" / f"ckpt_{step:012d}.h5")


def series(out):
    with h5py.File(Path(out) / "results.h5", "r") as f:
        return {c: f["series"][c][()] for c in f["series"]}


def assert_same_run(ref_dir, got_dir):
    ref, ref_meta = final_tables(ref_dir)
    got, got_meta = final_tables(got_dir)
    assert sorted(ref) == sorted(got)
    for t in ref:
        for c in ref[t]:
            a, b = ref[t][c], got[t][c]
            assert a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8)), f"{got_dir}: {t}/{c}"
    for k in ("step", "time", "dt", "energy_reference"):
        assert ref_meta[k] == got_meta[k], k
    s_ref, s_got = series(ref_dir), series(got_dir)
    for c in s_ref:
        assert np.array_equal(s_ref[c], s_got[c]), f"{got_dir}: series {c}"
    assert len(s_ref["step"]) == N_STEPS // 50 + 1


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("restart_cli")
    scene = base / "scene.toml"
    scene.write_text(SCENE)
    run_pdem(1, scene, base / "ref")
    r = run_pdem(WRITER_RANKS, scene, base / "k2", "--steps", str(K_STEP))
    return base, scene, r


@pytest.mark.parametrize("n_ranks", [1, pytest.param(2, marks=needs_mpiexec), pytest.param(3, marks=needs_mpiexec)])
def test_written_on_2_resumed_on_n(runs, n_ranks):
    base, scene, first = runs
    steps = [s for s, _ in list_checkpoints(base / "k2" / "checkpoints")]
    assert steps[-1] == K_STEP and len(steps) == 2, steps  # checkpoint_keep = 2
    assert "(every 500 steps, every 0.001 s," in first.stdout
    tables, meta = final_tables(base / "k2", K_STEP)
    assert meta["ranks"] == WRITER_RANKS and len(tables["contacts/sphere_sphere"]["key"]) > 100
    out = base / f"resume{n_ranks}"
    shutil.copytree(base / "k2", out)
    r = run_pdem(n_ranks, scene, out)
    assert f"resuming from {out / 'checkpoints' / f'ckpt_{K_STEP:012d}.h5'} at step {K_STEP}" in r.stdout
    assert_same_run(base / "ref", out)
    with h5py.File(out / "snapshots.h5", "r") as f:
        assert sorted(f) == sorted(h5py.File(base / "ref" / "snapshots.h5", "r"))


def test_sigterm_checkpoint_and_resume(runs):
    base, scene, _ = runs
    out = base / "sigterm"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    p = subprocess.Popen(
        pdem_cmd(WRITER_RANKS, scene, out),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        env=env,
    )
    seen = []
    for line in p.stdout:
        seen.append(line)
        if line.startswith("step") and " t = " in line:  # first progress line: the loop runs
            os.killpg(p.pid, signal.SIGTERM)  # like a batch system: the whole job gets it
            break
    rest = p.stdout.read()
    rc = p.wait(timeout=300)
    assert rc == 3, "".join(seen) + rest
    assert "stop signal received" in rest
    steps = [s for s, _ in list_checkpoints(out / "checkpoints")]
    assert steps and steps[-1] < N_STEPS and steps[-1] % 100 == 0, steps
    r = run_pdem(WRITER_RANKS, scene, out)
    assert f"at step {steps[-1]}" in r.stdout
    assert_same_run(base / "ref", out)


def test_damaged_checkpoints(runs):
    base, scene, _ = runs
    out = base / "damaged"
    shutil.copytree(base / "k2", out)
    (old_step, old), (_, newest) = list_checkpoints(out / "checkpoints")
    with open(newest, "r+b") as fh:
        fh.truncate(newest.stat().st_size // 2)
    lone = base / "lone"
    (lone / "checkpoints").mkdir(parents=True)
    shutil.copy(newest, lone / "checkpoints" / newest.name)
    r = run_pdem(1, scene, out)
    assert f"checkpoint {newest.name} is damaged" in r.stdout and f"resuming from {old.name}" in r.stdout
    assert f"at step {old_step}" in r.stdout
    assert_same_run(base / "ref", out)

    r = run_pdem(1, scene, lone, expect=2)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "no valid checkpoint" in lines[0] and "--fresh" in lines[0], r.stderr
    run_pdem(1, scene, lone, "--fresh", "--steps", "10")
    assert [s for s, _ in list_checkpoints(lone / "checkpoints")] == [10]
