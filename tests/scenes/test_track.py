"""The track section end to end (`pdem.scenes.track`) through the command line, on 1, 2 and 3 ranks.

A reduced track (half model, 3 sleepers, about 800 spheres after the cut, stiffness scaled down,
one passage of a two-axle bogie) runs every stage: the preparation shared with the box test, then
traffic. The same scene on 1 and 2 ranks gives the same bits (results.h5 with /series, /track,
/passages, /forces; preparation.h5; snapshots; the final bodies); its first 2000 steps on 3 ranks
(`pdem run --steps 2000`) end with the bodies of the 1- and 2-rank runs at step 2000; a second
scene file that starts from the prepared bed of the 2-rank run ([traffic] prepared) on 3 ranks
loads it without preparing again and gives the traffic records of the 1-rank run bit for bit; a
run resumed on 3 ranks from a checkpoint in the middle of the traffic cuts and rewrites its
records to the same bits. The records are sane: every sleeper settles under the passing bogie,
recovers most of it after, carries its weight at rest and the rail-seat share of the wheels
(within the dynamics), and the sleepers' peaks follow the bogie at spacing/speed. Bad input
stops with one line and status 2.
"""
import shutil

import h5py
import numpy as np
import pytest

from analysis.track import analyse_track, passage_table
from pdem.format.groups import read_track
from pdem_cli import MPIEXEC, run_pdem
from scene_text import BOX_MATERIALS
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.loads import rail_seat_share

SCENE = """[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]

[run]
progress_every = 0
output_every = 20
snapshot_every = 1000
checkpoint_every = 1000
checkpoint_keep = 0

""" + BOX_MATERIALS + """
[materials.concrete]
density = 2600.0
young = 4.0e6
poisson = 0.3
friction_angle = 0.5

[track]
half = true
sleepers = 3
spacing = 0.3
sleeper_size = [0.15, 1.2, 0.1]
gauge = 0.8
rail_foot_width = 0.1
bed_depth = 0.12
shoulder_width = 0.08
slope = 1.5
radius = 0.025
radius_spread = 0.3
seed = 3
overfill = 1.0
settle_min_time = 0.1
settle_max_time = 0.5
vibration_time = 0.05

[traffic]
program = "axles"
axle_load = 2000.0
axles = [0.0, 0.6]
speed = 10.0
passages = 1
rest_time = 0.05
"""
SPACING, SPEED, AXLE_LOAD, N_SLEEPERS = 0.3, 10.0, 2000.0, 3
L = (4 * 6.38e6 * SPACING / 6.0e7) ** 0.25  # the scene's characteristic length [m]

pytestmark = pytest.mark.skipif(not MPIEXEC.exists(), reason="no mpiexec next to the Python executable")


def datasets(path):
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def assert_same_files(ref, got, names=("results.h5", "preparation.h5", "snapshots.h5")):
    for name in names:
        a, b = datasets(ref / name), datasets(got / name)
        assert sorted(a) == sorted(b), f"{got}/{name}: datasets differ: {sorted(set(a) ^ set(b))}"
        for k in a:
            assert np.array_equal(a[k], b[k], equal_nan=True), f"{got}/{name}:/{k} differs"


def bodies_at(run_dir, step):
    return dict(read_checkpoint(run_dir / "checkpoints" / f"ckpt_{step:012d}.h5")[0])


def assert_same_bodies(ta, tb, where):
    for c in ta["particles"]:
        assert np.array_equal(ta["particles"][c], tb["particles"][c]), f"{where}: particles/{c}"
    if "boxes" in ta:
        assert np.array_equal(ta["boxes"]["center"], tb["boxes"]["center"]), f"{where}: boxes"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("track")
    scene = base / "scene.toml"
    scene.write_text(SCENE)
    r1 = run_pdem(1, scene, base / "r1")
    r2 = run_pdem(2, scene, base / "r2")
    return base, scene, r1, r2


def test_every_stage_runs_and_leaves_results(runs):
    base, _, r1, _ = runs
    out = base / "r1"
    for stage in ("pour", "refill", "vibrate", "settle", "traffic"):
        assert f"stage {stage} done" in r1.stdout
    for f in ("results.h5", "preparation.h5", "preparation.png", "prepared.h5", "summary.txt", "scaling.json",
              "snapshots.xmf", "analysis/track_settlement.png", "analysis/track_voids.png", "analysis/track_forces.png",
              "analysis/track_sleepers.png", "analysis/track.txt"):
        assert (out / f).stat().st_size > 0, f
    rec = read_track(out / "results.h5")
    assert rec.results.kind == "track" and rec.n_sleepers == N_SLEEPERS
    assert np.allclose(rec.sleeper_x, [0.15, 0.45, 0.75])
    assert list(rec.passages["passage"]) == [1.0] and sorted(rec.forces) == ["end_passage_1", "peak_passage_1"]
    # the passage table written during the run agrees with the analysis's own one over the samples: the
    # same permanent settlement (a sample is taken where a passage ends), a peak at least as large (the
    # run follows every step, the samples every 20th)
    t = rec.results.series["time"]
    peak, perm = passage_table(t, rec.settlement, rec.passages["t_start"], rec.passages["t_end"])
    assert np.array_equal(perm, rec.passages["settlement_permanent"])
    assert np.all(rec.passages["settlement_peak"] >= peak) and np.allclose(rec.passages["settlement_peak"], peak,
                                                                           rtol=0.05)
    analyse_track(rec)
    assert "load balance" in (out / "summary.txt").read_text()


def test_sleepers_settle_under_the_passing_bogie(runs):
    base = runs[0]
    rec = read_track(base / "r1" / "results.h5")
    f, t = rec.force, rec.results.series["time"]
    peak, perm = rec.passages["settlement_peak"][0], rec.passages["settlement_permanent"][0]
    assert np.all(peak > 2e-4) and np.all(perm > 0) and np.all(perm < 0.6 * peak)  # settle, mostly spring back
    with h5py.File(base / "r1" / "results.h5") as h:
        body = json_body_mass(h)
    weight = body * 9.81
    assert np.allclose(f[0], weight, rtol=0.05) and np.allclose(f[-1], weight, rtol=0.05)  # at rest: its own weight
    # under the bogie: its weight plus about the rail-seat share of one wheel (half model), within the dynamics
    wheel = AXLE_LOAD / 2
    top = wheel * max(sum(rail_seat_share(x, SPACING, L) for x in (d, d - 0.6)) for d in np.linspace(-0.3, 0.9, 121))
    assert np.allclose(f.max(axis=0), weight + top, rtol=0.15)
    # each sleeper's load pulse (centroid in time of its force above its weight) comes spacing/speed after
    # the previous one's: the bogie passes at 10 m/s
    extra = np.maximum(f - weight, 0.0)
    t_c = (t[:, None] * extra).sum(axis=0) / extra.sum(axis=0)
    assert np.allclose(np.diff(t_c), SPACING / SPEED, rtol=0.2), t_c
    assert np.all(rec.passages["gap"] >= 0)


def json_body_mass(h):
    import json

    track = json.loads(h.attrs["scene"])["track"]
    size, spacing = track["sleeper_size"], track["spacing"]
    return 2600.0 * size[0] * size[1] * size[2] / 2 + 60.21 * spacing  # half sleeper (ρV) + one rail over a spacing


def test_same_bits_on_1_and_2_ranks(runs):
    base = runs[0]
    assert_same_files(base / "r1", base / "r2")
    last = lambda d: read_checkpoint(list_checkpoints(d / "checkpoints")[-1][1])[0]  # noqa: E731
    assert_same_bodies(last(base / "r1"), last(base / "r2"), "final bodies")


@pytest.mark.slow
def test_first_2000_steps_on_3_ranks(runs):
    """slow: 2000 more steps of the reduced track on 3 ranks (about 20 s on an idle machine)."""
    base, scene, _, _ = runs
    out = base / "steps3"
    r = run_pdem(3, scene, out, "--steps", "2000")
    assert "stopped at step 2000 (--steps 2000)" in r.stdout and (out / "scaling.json").exists()
    got = bodies_at(out, 2000)
    assert_same_bodies(bodies_at(base / "r1", 2000), got, "step 2000, 1 vs 3 ranks")
    assert_same_bodies(bodies_at(base / "r2", 2000), got, "step 2000, 2 vs 3 ranks")


@pytest.mark.slow
def test_load_programs_start_from_the_prepared_bed(runs):
    """slow: the reduced track's traffic again, on 3 ranks (about 20 s on an idle machine)."""
    base, scene, _, r2 = runs
    loading = base / "loading.toml"
    loading.write_text(SCENE.replace('program = "axles"', f'program = "axles"\nprepared = "{base / "r2"}"'))
    r = run_pdem(3, loading, base / "from_prepared")
    assert "starting from the prepared bed" in r.stdout and "stage pour" not in r.stdout
    a, b = datasets(base / "r1" / "results.h5"), datasets(base / "from_prepared" / "results.h5")
    assert sorted(a) == sorted(b)
    for k in a:
        assert np.array_equal(a[k], b[k]), f"/{k} differs from the run that prepared and loaded in one go"
    # a bed prepared from another scene is refused by name
    other = base / "other.toml"
    other.write_text(SCENE.replace("seed = 3", "seed = 4").replace('program = "axles"',
                                                                    f'program = "axles"\nprepared = "{base / "r2"}"'))
    r = run_pdem(1, other, base / "refused", expect=2)
    assert "prepared from another scene (track.seed = 3 there, 4 here)" in r.stderr and r.stderr.count("\n") == 1


@pytest.mark.slow
def test_resume_in_the_middle_of_the_traffic_on_3_ranks(runs):
    """slow: the rest of the reduced track's traffic on 3 ranks (about 15 s on an idle machine)."""
    base, scene, _, r2 = runs
    out = base / "resume3"
    shutil.copytree(base / "r2", out)
    line = next(s for s in r2.stdout.splitlines() if "(end of stage refill" in s)  # the last preparation stage
    prepared = int(line.split(":")[0].split()[1])
    mid = [s for s, _ in list_checkpoints(out / "checkpoints") if s > prepared + 100][0]
    for s, p in list_checkpoints(out / "checkpoints"):
        if s > mid:
            p.unlink()
    r = run_pdem(3, scene, out)
    assert f"at step {mid} (stage traffic" in r.stdout and "(resumed)" in r.stdout
    assert_same_files(base / "r1", out)


@pytest.mark.parametrize("edit, ranks, message", [
    (("speed = 10.0", "speed = 0"), 1, "traffic.speed = 0: must be a number > 0 [m/s]"),
    (("rest_time = 0.05", "rest_time = 0.05\nx_from = 5.0\nx_to = 6.0"), 1, "no axle load reaches any sleeper"),
    (("sleepers = 3\nspacing = 0.3", "sleepers = 1\nspacing = 0.2"), 3,
     "track.sleepers = 1: a track of 0.2 m is shorter than 3 slabs allow"),
    (("gauge = 0.8", "gauge = 1.2"), 1, "beyond the sleeper ends at ±0.6 m: the wheel loads would reach no sleeper"),
])
def test_bad_input_one_line(tmp_path, edit, ranks, message):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.replace(*edit))
    r = run_pdem(ranks, scene, tmp_path / "out", expect=2)
    # one line, printed once however many ranks found it (docs/reliability.md), no traceback
    assert message in r.stderr and r.stderr.count("pdem: error:") == r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.stderr
