"""`pdem run` of a scene file with rigid and breakable clumps: a checkpoint written on 2 ranks, with
clumps and partly broken bonds, resumed on 1, 2 and 3 ranks gives the uninterrupted serial run's
bits: the final checkpoint's tables (bodies, clumps, clump members, contacts with the bond history),
the time series and the fragment records written every 500 steps (run.fragments_every; `/fragments`,
read back with `pdem.format.groups.read_fragments`). And the same run stopped by SIGTERM mid-run on
2 ranks (once its first scheduled checkpoint exists; the stop lands at the next stop poll) resumes
on 3 and on 1 ranks to the same bits.
"""
import shutil
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest
from pdem_cli import needs_mpiexec, pdem_cmd, run_pdem, signal_when

from pdem.format.groups import read_fragments
from pdem.io.checkpoint import list_checkpoints, read_checkpoint

N_STEPS, K_STEP = 3000, 1777

SCENE = """
[simulation]
law = "cohesive"
dt = "auto"
damping = 0.2
gravity = [0.0, 0.0, -9.81]
dt_interval = 50
check_interval = 40

[run]
steps = 3000
progress_every = 500
output_every = 50
checkpoint_every = 1000
fragments_every = 500
kind = "clumps"

[materials.grain]
density = 2600.0
young = 1.0e7
poisson = 0.3
friction_angle = 0.5
normal_cohesion = 6.0e4
shear_cohesion = 6.0e4

[materials.steel]
density = 7850.0
young = 1.0e8
poisson = 0.25
friction_angle = 0.4
normal_cohesion = 0.0
shear_cohesion = 0.0

[[clumps]]
shape = "ballast8"
member_radius = 0.005
material = "grain"
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.4, 0.06, 0.09]
count = 40
seed = 5
vel = [0.5, 0.0, -0.3]

[[clumps]]
shape = "ellipsoid"
radii = [0.022, 0.02, 0.018]
member_radius = 0.004
material = "grain"
box_lo = [0.0, 0.0, 0.09]
box_hi = [0.4, 0.06, 0.2]
count = 5
seed = 6
breakable = true
vel = [-0.5, 0.0, -1.0]

[[walls]]
axis = "z"
position = 0.0
material = "steel"
sense = 1

[[walls]]
axis = "x"
position = 0.0
material = "steel"
sense = 1

[[walls]]
axis = "x"
position = 0.4
material = "steel"
sense = -1

[[walls]]
axis = "y"
position = 0.0
material = "steel"
sense = 1

[[walls]]
axis = "y"
position = 0.06
material = "steel"
sense = -1
"""

pytestmark = [needs_mpiexec, pytest.mark.slow]


def final(out, step=N_STEPS):
    return read_checkpoint(Path(out) / "checkpoints" / f"ckpt_{step:012d}.h5")


def same(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("restart_cli_clumps")
    scene = base / "scene.toml"
    scene.write_text(SCENE)
    run_pdem(1, scene, base / "ref")
    run_pdem(2, scene, base / "k2", "--steps", str(K_STEP))
    return base, scene


@pytest.mark.parametrize("n_ranks", [1, 2, 3])
def test_clumps_written_on_2_resumed_on_n(runs, n_ranks):
    base, scene = runs
    tables, meta = final(base / "k2", K_STEP)
    assert meta["ranks"] == 2 and len(tables["clumps"]["id"]) == 40
    bonds = tables["contacts/sphere_sphere"]["history"][:, 4] > 0  # normal adhesion: intact bonds
    assert 0 < bonds.sum() < 5 * 60, "intact and broken bonds"
    out = base / f"resume{n_ranks}"
    shutil.copytree(base / "k2", out)
    run_pdem(n_ranks, scene, out)
    assert_same_as_ref(base, out)


@pytest.fixture(scope="module")
def stopped(runs):
    """The run on 2 ranks stopped by SIGTERM once its first scheduled checkpoint exists."""
    base, scene = runs
    out = base / "sigterm2"
    status, text = signal_when(pdem_cmd(2, scene, out), lambda: bool(list_checkpoints(out / "checkpoints")),
                               signal.SIGTERM)
    assert status == 3 and "stop signal received" in text, text[-3000:]
    step = list_checkpoints(out / "checkpoints")[-1][0]
    assert 1000 < step < N_STEPS and step % 100 == 0, step
    return out, step


@pytest.mark.parametrize("n_ranks", [3, 1])
def test_clumps_stopped_by_sigterm_on_2_resumed_on_n(runs, stopped, n_ranks):
    base, scene = runs
    src, step = stopped
    out = base / f"sigterm2_resume{n_ranks}"
    shutil.copytree(src, out)
    r = run_pdem(n_ranks, scene, out)
    assert f"at step {step}" in r.stdout
    assert_same_as_ref(base, out)


def assert_same_as_ref(base, out):
    """The final checkpoint's tables, the series and the fragment records of ``out`` are the
    uninterrupted serial run's, bit for bit."""
    ref, ref_meta = final(base / "ref")
    got, got_meta = final(out)
    assert sorted(ref) == sorted(got) and "clump_members" in got
    for t in ref:
        for c in ref[t]:
            assert same(ref[t][c], got[t][c]), f"{t}/{c}"
    assert (ref_meta["step"], ref_meta["time"], ref_meta["dt"]) == (got_meta["step"], got_meta["time"], got_meta["dt"])
    with h5py.File(base / "ref" / "results.h5", "r") as a, h5py.File(out / "results.h5", "r") as b:
        for c in a["series"]:
            assert np.array_equal(a["series"][c][()], b["series"][c][()]), c
    fr, fg = read_fragments(base / "ref" / "results.h5"), read_fragments(out / "results.h5")
    assert [r.step for r in fr.records] == list(range(0, N_STEPS + 1, 500))
    assert [r.step for r in fg.records] == [r.step for r in fr.records]
    for a, b in zip(fr.records, fg.records):
        assert same(a.n_members, b.n_members) and same(a.mass, b.mass) and same(a.clump, b.clump), a.label
    assert len(fr.records[-1].n_members) > len(fr.records[0].n_members) == 45  # grains broke
    assert fr.density == 2600.0 and fr.member_radius_min == 0.004
