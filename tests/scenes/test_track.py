"""The track section (`pdem.scenes.track`, `pdem.scenes.track_record`): its pieces without a run,
then end to end through the command line, on 1, 2 and 3 ranks.

Pieces: the bed's shape and the sleeper slots, the gap under a box, the passage tracker against
the analysis package's own passage table, the results writer's restart cut, and one-line errors.

End to end: a reduced track (half model, 3 sleepers, about 800 spheres after the cut, stiffness scaled down,
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
import copy
import shutil

import h5py
import numpy as np
import pytest
import tomllib

from pdem.format import schema
from pdem.format.groups import read_track
from analysis.track import analyse_track, passage_table
from pdem.driver import observables
from pdem.scenes.track_record import PassageTracker, TrackWriter
from pdem.errors import InputError
from pdem.boundaries.facets import facet_row
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.boundaries.loads import rail_seat_share
from pdem.parallel.comm import SerialComm
from pdem.build.scene import Scene
from pdem.scenes.track import (check, check_ranks, in_sleepers, outside_bed, profile, same_preparation, sleeper_boxes,
                               sleeper_x, slope_facets, track_settings, traffic_settings)
from pdem_cli import needs_mpiexec, run_pdem
from run_files import datasets
from factories import BOX_MATERIALS

CONCRETE = """
[materials.concrete]
density = 2600.0
young = 4.0e6
poisson = 0.3
friction_angle = 0.5
"""


# ---------------------------------------------------------------------------- pieces
MATERIALS = tomllib.loads(BOX_MATERIALS + CONCRETE)["materials"]
DOC = {"simulation": {"damping": 0.3, "gravity": [0.0, 0.0, -9.81]}, "materials": MATERIALS,
       "track": {"sleepers": 6, "radius": 0.01625},
       "traffic": {"program": "axles", "axle_load": 20e3, "speed": 10.0}}


def doc(**edits):
    d = copy.deepcopy(DOC)
    for where, kv in edits.items():
        if kv is None:
            d.pop(where, None)
        else:
            d.setdefault(where, {}).update(kv)
    return d


def test_defaults_are_the_b91_track_of_the_thesis():
    c = track_settings(doc())
    assert c["sleeper_size"] == [0.3, 2.6, 0.2] and c["spacing"] == 0.6 and c["bed_depth"] == 0.35
    assert c["sleeper_mass"] == pytest.approx(2600 * 2.6 * 0.3 * 0.2)  # ρV of the concrete box
    assert c["body_mass"] == pytest.approx(c["sleeper_mass"] + 2 * 60.21 * 0.6)  # plus two rails over a spacing
    assert c["sleeper_blocked"] == "xyXYZ"
    assert np.allclose(sleeper_x(c), [0.3, 0.9, 1.5, 2.1, 2.7, 3.3])
    g = profile(c)
    assert g["z_top"] == pytest.approx(0.55) and g["y_top"] == pytest.approx(1.7)
    assert g["y_toe"] == pytest.approx(1.7 + 1.5 * 0.55) and g["y_lo"] == -g["y_toe"]
    assert g["length"] == pytest.approx(3.6)
    half = track_settings(doc(track={"half": True, "sleepers": 1}))
    assert half["sleeper_blocked"] == "yXYZ" and profile(half)["y_lo"] == 0.0
    assert half["body_mass"] == pytest.approx(half["sleeper_mass"] / 2 + 60.21 * 0.6)
    centres, h = sleeper_boxes(half)
    assert np.allclose(centres, [[0.3, 0.65, 0.45]]) and np.allclose(h, [0.15, 0.65, 0.1])
    check(doc())
    check(doc(traffic=None))


def test_the_cut_keeps_only_spheres_wholly_inside_the_bed():
    c = track_settings(doc())
    g = profile(c)
    z_top, y_top, y_toe = g["z_top"], g["y_top"], g["y_toe"]
    r = 0.02
    n = np.array([z_top, y_toe - y_top]) / np.hypot(z_top, y_toe - y_top)  # outward normal (y, z) of the right slope
    on_slope = np.array([0.5 * (y_top + y_toe), 0.5 * z_top])
    pos = np.array([[1.0, 0.0, 0.2],                                   # middle of the bed
                    [1.0, 0.0, z_top - r],                             # touching the top from below: kept
                    [1.0, 0.0, z_top - r + 1e-9],                      # sticking out above
                    [1.0, *(on_slope - r * n * (1 + 1e-9))],           # just inside the slope
                    [1.0, *(on_slope - r * n * (1 - 1e-9))],           # just through it
                    [1.0, -on_slope[0] + r * n[0] * 1.01, on_slope[1] - r * n[1] * 1.01],  # mirrored: left slope
                    [1.0, -on_slope[0] + 0.5 * r * n[0], on_slope[1]]])
    assert outside_bed(c, pos, np.full(len(pos), r)).tolist() == [False, False, True, False, True, False, True]


def test_slots_and_slope_facets():
    c = track_settings(doc(track={"half": True, "sleepers": 2}))
    centres, half = sleeper_boxes(c)
    r = np.full(3, 0.01)
    pos = np.array([centres[0] + [0.0, 0.0, -half[2] - 0.0099],       # under the base, overlapping
                    centres[0] + [0.0, 0.0, -half[2] - 0.0101],       # just below it
                    centres[1] + [half[0] + 0.005, 0.3, 0.0]])         # in the crib face
    assert in_sleepers(c, pos, r).tolist() == [True, False, True]
    tris = slope_facets(c)
    assert len(tris) == 4  # half model: one side, slope and lip, two triangles each
    g = profile(c)
    n = np.array([0.0, g["z_top"], g["y_toe"] - g["y_top"]]) / np.hypot(g["z_top"], g["y_toe"] - g["y_top"])
    for k, tri in enumerate(tris):
        normal = facet_row(*tri)[3:6]
        expected = n if k < 2 else np.array([0.0, 1.0, 0.0])  # the slope, then the vertical lip
        assert abs(abs(normal @ expected) - 1.0) < 1e-12
        assert min(v[0] for v in tri) == 0.0 and max(v[0] for v in tri) == pytest.approx(g["length"])
    # a sphere the cut keeps stays clear of the slope's plane
    y, z = 0.5 * (g["y_top"] + g["y_toe"]), 0.5 * g["z_top"]
    p = np.array([[0.1, y - 0.0201 * n[1], z - 0.0201 * n[2]]])
    assert not outside_bed(c, p, np.array([0.02]))[0]
    assert (p[0] - np.array(tris[0][0])) @ n <= -0.02


def test_gap_under_a_box():
    scene = Scene(gravity=(0, 0, 0))
    m = scene.material(density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    pos = [(0.0, 0.0, 0.10), (0.05, 0.02, 0.12), (0.3, 0.0, 0.5), (0.0, 0.0, 0.5), (1.0, 0.0, 0.1)]
    scene.add_spheres(pos, [0.02, 0.02, 0.02, 0.02, 0.02], m)
    scene.add_box((0.0, 0.0, 0.25), (0.1, 0.1, 0.05), m, 10.0, fixed=True)   # base 0.2; highest top under it 0.14
    scene.add_box((1.0, 0.0, 0.145), (0.1, 0.1, 0.025), m, 10.0, fixed=True)  # base 0.12: presses into sphere 4
    scene.add_box((3.0, 0.0, 0.3), (0.1, 0.1, 0.05), m, 10.0, fixed=True)    # nothing under it
    sim = scene.build(SerialComm())
    gap = observables.box_gaps(sim)
    assert gap[0] == pytest.approx(0.2 - 0.14, abs=1e-15) and gap[1] == 0.0 and gap[2] == pytest.approx(0.25)


def test_passage_tracker_agrees_with_the_analysis_passage_table():
    """Fed every step, the tracker's peak and permanent settlement are those of
    `analysis.track.passage_table` over the same samples (an independent implementation)."""
    rng = np.random.default_rng(4)
    ends, peaks = [1.0, 2.0, 3.0], [0.5, 1.5, 2.5]
    z0 = np.array([0.50, 0.52, 0.49])
    tr = PassageTracker(ends, peaks, z0)
    t = np.arange(0, 3.2, 0.01)
    z = z0 - np.cumsum(rng.normal(0, 1e-4, (len(t), 3)), axis=0) - 1e-3 * np.sin(np.pi * t)[:, None] ** 2
    tr.start(t[0], tr.settlement(z[0]))
    tr.energy0 = 0.0  # the energy ledger (tested end to end in test_track_energy)
    rows, events = [], []
    for ti, zi in zip(t[1:], z[1:]):
        s = tr.settlement(zi)
        ev = tr.update(ti, s)
        events += [(e, tr.p) for e in ev]
        if "end" in ev:
            rows.append(tr.close(ti, s, 0.0))
    assert tr.done and len(rows) == 3
    assert [e for e in events if e[0] == "peak"] == [("peak", 0), ("peak", 1), ("peak", 2)]
    t_start = np.array([r[0] for r in rows])
    t_end = np.array([r[1] for r in rows])
    assert t_start[0] == 0.0 and np.all(t_start[1:] == t_end[:-1]) and np.all(t_end >= ends)
    peak, permanent = passage_table(t, np.array([tr.settlement(zi) for zi in z]), t_start, t_end)
    assert np.array_equal(peak, np.array([r[2] for r in rows]))
    assert np.array_equal(permanent, np.array([r[3] for r in rows]))
    again = PassageTracker.restore(tr.state())
    assert again.state() == tr.state()


def test_writer_cuts_rows_and_passages_after_a_restart(tmp_path):
    path = tmp_path / "results.h5"
    comm = SerialComm()
    w = TrackWriter(path, [0.3, 0.9], comm)
    for k in range(25):
        w.append({"step": 10 * k, "time": 0.1 * k, "dt": 1e-3, "applied_load": 1.0, "ballast_force": 2.0,
                  "mean_settlement": 0.0, "kinetic_energy": 0.0, "contacts_per_particle": 4.0},
                 [k, 2 * k], [1.0, 1.0])
        if k in (9, 19):
            w.passage(0.0, 0.1 * k, [k, k], [k, k], [0.0, 0.0])
    w.close()
    with h5py.File(path, "r") as f:
        assert f["series/step"].shape == (25,) and f["track/settlement"].shape == (25, 2)
        assert f["passages/passage"][...].tolist() == [1.0, 2.0]
    TrackWriter(path, [0.3, 0.9], comm, restart_step=120, passages_done=1).close()  # a checkpoint at step 120
    with h5py.File(path, "r") as f:
        assert f["series/step"][...].tolist() == [10 * k for k in range(13)]
        assert f["track/settlement"][:, 1].tolist() == [2.0 * k for k in range(13)]
        assert f["passages/passage"].shape == (1,) and f["passages/gap"].shape == (1, 2)
    TrackWriter(path, [0.3, 0.9], comm).close()  # a fresh start removes the old groups
    with h5py.File(path, "r") as f:
        assert f["track/settlement"].shape == (0, 2) and schema.PASSAGES not in f


@pytest.mark.parametrize("edits, message", [
    ({"traffic": {"speed": 0}}, "traffic.speed = 0: must be a number > 0 [m/s]"),
    ({"traffic": {"x_from": 10.0, "x_to": 12.0}}, "no axle load reaches any sleeper"),
    ({"track": {"sleeper_size": [0.3, 1.4, 0.2]}}, "track.sleeper_size = [0.3, 1.4, 0.2]: the rail seats at y = ±0.75"),
    ({"track": {"sleepers": 0}}, "track.sleepers = 0: must be an integer >= 1"),
    ({"track": {"sleeper_size": [0.7, 2.6, 0.2]}}, "the sleeper width 0.7 m must be less than the spacing 0.6 m"),
    ({"track": {"half": True, "sleeper_blocked": "xXYZ"}}, "a half model needs 'y'"),
    ({"track": {"base_material": "clay"}}, "track.base_material = 'clay': no [materials.clay] table"),
    ({"traffic": {"program": "static"}}, "traffic.program = 'static': must be 'axles' or 'haversine'"),
    ({"traffic": {"f_max": 3.0}}, "traffic.f_max: not used by program = 'axles'; remove it"),
    ({"traffic": {"program": "haversine", "axle_load": None}}, None),
    ({"walls": {"axis": "x"}}, "scene file.walls: unknown table for a track scene"),
])
def test_bad_input_is_one_line(edits, message):
    d = doc(**{k: v for k, v in edits.items() if k != "traffic" or v.get("axle_load", 0) is not None})
    if message is None:  # haversine with the axle keys left in: refused by name
        d["traffic"]["program"] = "haversine"
        message = "traffic.axle_load: not used by program = 'haversine'; remove it"
    with pytest.raises(InputError) as err:
        c = track_settings(d)
        traffic_settings(d, c)
    assert message in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_a_track_shorter_than_its_slabs_is_refused():
    c = track_settings(doc(track={"half": True, "sleepers": 1, "spacing": 0.12, "sleeper_size": [0.1, 2.6, 0.2]}))
    check_ranks(c, DOC, 2)
    with pytest.raises(InputError) as err:
        check_ranks(c, DOC, 3)
    assert str(err.value).startswith("track.sleepers = 1: a track of 0.12 m is shorter than 3 slabs allow")
    assert "use at most 2 rank(s)" in str(err.value)


def test_prepared_beds_are_matched_on_the_preparation_tables():
    a = doc()
    assert same_preparation(a, doc(traffic={"speed": 20.0}, run={"output_every": 5})) is None
    assert same_preparation(a, doc(track={"seed": 2})) == "track.seed = (absent) there, 2 here"
    b = doc()
    b["materials"]["rubber"] = dict(b["materials"]["rubber"], young=2.8e6)
    assert same_preparation(a, b).startswith("materials.rubber = {")


# ---------------------------------------------------------------------------- end to end
# slow: the track prepared and run on 1 and 2 ranks (a minute or more), more runs on 3 ranks
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

""" + BOX_MATERIALS + CONCRETE + """
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


@needs_mpiexec
@pytest.mark.slow
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


@needs_mpiexec
@pytest.mark.slow
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


@needs_mpiexec
@pytest.mark.slow
def test_same_bits_on_1_and_2_ranks(runs):
    base = runs[0]
    assert_same_files(base / "r1", base / "r2")
    last = lambda d: read_checkpoint(list_checkpoints(d / "checkpoints")[-1][1])[0]  # noqa: E731
    assert_same_bodies(last(base / "r1"), last(base / "r2"), "final bodies")


@needs_mpiexec
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


@needs_mpiexec
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


@needs_mpiexec
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
@needs_mpiexec
def test_bad_input_one_line(tmp_path, edit, ranks, message):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.replace(*edit))
    r = run_pdem(ranks, scene, tmp_path / "out", expect=2)
    # one line, printed once however many ranks found it (docs/reliability.md), no traceback
    assert message in r.stderr and r.stderr.count("pdem: error:") == r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.stderr
