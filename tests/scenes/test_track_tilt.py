"""The track with turning sleepers (`[track] sleeper_rotation = true`) on the rail as a beam:
bad input without a run, then end to end.

Bad input: one line naming the key, exit 2 (a sleeper inertia that is not positive definite or
not symmetric, an inertia without rotation, blocked letters that free the vertical axis or, in a
half model, the tilt across the symmetry plane, a pad stiffness <= 0, a rail longer than the
track).

End to end (slow): the reduced half track of `test_track_beam` (3 sleepers, about 800 spheres,
stiffness scaled down) prepared with turning sleepers, then three passages of a bogie on the
beam rail: on 1 and 2 ranks the same bits, 3 ranks `--steps` to a checkpoint inside the traffic
gives the bodies and the sleepers' turning state of the 1-rank run there, and a 2-rank run
resumed in the middle of passage 2 rewrites the same records (the shared helpers of
`track_runs`). The records: the sleepers tilt (about y only: the half model's symmetry), both end
settlements are alike and differ from the centre's by the tilt's lever only, the load shares are those of the
peak loads, and `python -m analysis track` draws and tabulates them.
"""
import copy

import numpy as np
import pytest

from pdem.errors import InputError
from pdem.format.groups import read_track
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.bodies.boxes import Boxes
from pdem.scenes.track import check, check_pad_step, seat_offsets, track_settings, traffic_settings
from pdem_cli import needs_mpiexec, run_pdem
from test_track import DOC
from test_track_beam import PREPARE, beam_scene
from track_runs import assert_resume_in_passage, assert_same_bodies_on_3_ranks, assert_same_results, prepared_runs

TURNING = "half = true\nsleeper_rotation = true"


def doc(track=None, **traffic):
    d = copy.deepcopy(DOC)
    d["track"].update({"sleeper_rotation": True, **(track or {})})
    d["traffic"].update(traffic)
    return d


def test_turning_sleepers_check_whole_and_half():
    for track in ({}, {"half": True}):
        for rail in ({}, {"rail_model": "beam"}):
            check(doc(track, **rail))
    assert track_settings(doc({"sleeper_blocked": "xyzZ"}))["sleeper_blocked"] == "xyzZ"


@pytest.mark.parametrize("track, traffic, message", [
    ({"sleeper_inertia": [100.0, -1.0, 100.0]}, {},
     "track.sleeper_inertia = [100.0, -1.0, 100.0]: must be 3 principal moments or a 3x3 tensor [kg m^2]"),
    ({"sleeper_inertia": [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}, {},
     "track.sleeper_inertia = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]: must be 3 principal"),
    ({"sleeper_inertia": [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}, {},
     "track.sleeper_inertia = [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]: must be 3 principal"),
    ({"sleeper_inertia": "heavy"}, {}, "track.sleeper_inertia = 'heavy': must be 3 principal moments"),
    ({"sleeper_rotation": False, "sleeper_inertia": [1.0, 1.0, 1.0]}, {},
     "track.sleeper_inertia: used only with sleeper_rotation = true; remove it"),
    ({"sleeper_rotation": "yes"}, {}, "track.sleeper_rotation = 'yes'"),
    ({"sleeper_blocked": "xy"}, {}, "track.sleeper_blocked = 'xy': must be letters from 'xyzXYZ' including Z "
                                    "(turning sleepers: the vertical axis blocked)"),
    ({"half": True, "sleeper_blocked": "yZ"}, {}, "track.sleeper_blocked = 'yZ': must be letters from 'xyzXYZ' "
                                                  "including X, Z (turning sleepers: the vertical axis blocked; a "
                                                  "half model's symmetry plane y = 0 allows only the tilt about y)"),
    ({}, {"rail_model": "beam", "rail_pad_stiffness": 0.0}, "traffic.rail_pad_stiffness = 0.0: must be a number > 0"),
    ({}, {"rail_model": "beam", "rail_length": 4.0}, "traffic.rail_length = 4.0: longer than the track (3.6 m"),
])
def test_bad_input_is_one_line(track, traffic, message):
    d = doc(track, **traffic)
    with pytest.raises(InputError) as err:
        traffic_settings(d, track_settings(d))
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_the_time_step_must_resolve_the_rocking_on_the_pads():
    """A whole sleeper on two pads k at its seats ±y_s: rocking about x at sqrt(2 k y_s²/I_x);
    the check refuses a step above sqrt(I_x/(2 k y_s²)) that sqrt(m/(2 k)) alone would let pass."""
    class Sim:
        dt = 1e-3
        boxes = Boxes()

    c = track_settings(doc())
    seats = seat_offsets(c)
    Sim.boxes.add((0.0, 0.0, 0.0), (0.15, 1.3, 0.1), 0, 500.0, blocked="xyZ", inertia=[50.0, 50.0, 50.0])
    k = 1.0e8
    rocking = (50.0 / (k * 2 * seats[0, 1] ** 2)) ** 0.5
    assert rocking < Sim.dt < (500.0 / (2 * k)) ** 0.5  # the translation alone would pass
    with pytest.raises(InputError) as err:
        check_pad_step(Sim, {"rail_pad_stiffness": k}, 2, seats)
    assert f"about x rocking on its pads needs dt <= sqrt(I/(k sum lever^2)) = {rocking:.3g} s" in str(err.value)
    Sim.dt = 0.99 * rocking
    check_pad_step(Sim, {"rail_pad_stiffness": k}, 2, seats)


@needs_mpiexec
def test_bad_inertia_exits_2_with_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(PREPARE.replace("half = true", TURNING + "\nsleeper_inertia = [0.1, 0.0, 0.1]"))
    r = run_pdem(1, bad, tmp_path / "out", expect=2)
    assert r.stderr.startswith("pdem: error: track.sleeper_inertia = [0.1, 0.0, 0.1]: must be")
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


# ---------------------------------------------------------------------------- end to end
def tilt_scene(base, bed):
    return beam_scene(base, bed).replace("half = true", TURNING)


@pytest.fixture(scope="module")
def tilt_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("tilt")
    scene, r1, r2 = prepared_runs(base, PREPARE.replace("half = true", TURNING), lambda bed: tilt_scene(base, bed))
    return base, scene, r1, r2


@needs_mpiexec
@pytest.mark.slow
def test_the_tilting_track_records_ends_tilts_voids_and_shares(tilt_runs):
    base, _, r1, _ = tilt_runs
    assert "passage 3/3: tilt about x" in r1.stdout
    rec = read_track(base / "r1" / "results.h5")
    p = rec.passages
    n = (3, 3)
    for name in ("settlement_lo", "settlement_hi", "tilt_x", "tilt_y", "gap_lo", "gap_hi", "load_share"):
        assert p[name].shape == n and np.all(np.isfinite(p[name])), name
    assert np.all(p["tilt_x"] == 0.0) and np.any(p["tilt_y"] != 0.0)  # the half model tilts about y only
    # no turn about x: both ends settle alike; they differ from the centre only by the base's
    # lever h_z under the tilt about y, h_z (cos φ − cos φ0) <= h_z (1 − cos φ_max) with φ, φ0 <= 0.3 rad
    np.testing.assert_allclose(p["settlement_lo"], p["settlement_hi"], rtol=0, atol=1e-12)
    assert np.all(np.abs(p["tilt_y"]) < 0.3)
    assert np.all(np.abs(p["settlement_lo"] - p["settlement_permanent"]) <= 0.05 * (1 - np.cos(0.3)))
    assert np.all(p["gap_lo"] >= 0.0) and np.all(p["gap_hi"] >= 0.0)
    # the share: the peak load less the rail's weight on the sleeper, per wheel (0.5 kN on the one rail)
    assert np.all(p["load_share"] > 0.0) and np.all(p["load_share"] < p["load_peak"] / 500.0)
    text = (base / "r1" / "analysis" / "track.txt").read_text()
    assert "tilt_y" in text and "share" in text
    for name in ("track_tilt.png", "track_shares.png"):
        assert (base / "r1" / "analysis" / name).stat().st_size > 0


@needs_mpiexec
@pytest.mark.slow
def test_same_bits_on_1_2_and_3_ranks(tilt_runs):
    base, scene, _, _ = tilt_runs
    a = assert_same_results(base / "r1" / "results.h5", base / "r2" / "results.h5", "1 and 2 ranks")
    assert "passages/tilt_y" in a
    start = int(read_checkpoint(base / "bed" / "prepared.h5")[1]["step"])
    step = min(s for s, _ in list_checkpoints(base / "r1" / "checkpoints") if s >= start + 300)
    assert_same_bodies_on_3_ranks(base, scene, step, box_columns=("center", "ori", "angmom", "angvel", "rotation"))


@needs_mpiexec
@pytest.mark.slow
def test_resume_in_the_middle_of_a_passage(tilt_runs):
    base, scene, _, _ = tilt_runs
    assert_resume_in_passage(base, scene)
