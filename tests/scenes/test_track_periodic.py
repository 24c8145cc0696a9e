"""The track with periodic ends (`[track] periodic = true`, #30): no end walls, the engine's
periodic ends over [0, L] along x and the beam rail joined over the period.

Pieces without a run: the stage scenes have no x walls and declare the period, every axle runs
one period; bad input is one line (axles on the prescribed shares, a rail shorter than the period,
`simulation.periodic` set by hand, another slab axis, an axle run that is not a whole number of
periods).

End to end (slow): the reduced track of `test_track_beam` (half model, 3 sleepers, 0.9 m) with
periodic ends and turning sleepers (`test_track_tilt`: the tilt about y, along the period), all
three together, prepared once on one rank, then two passages of a bogie on the periodic beam
rail: on 1 and 2 ranks the same bits; 3 ranks `--steps` to a checkpoint in the first passage
gives the bodies and the sleepers' turning state of the 1-rank run there; a 2-rank run resumed
in the middle of passage 2 rewrites the same records; every body stays inside the period and
the sleepers tilt.
"""
import copy

import numpy as np
import pytest

from pdem.errors import InputError
from pdem.format.groups import read_track
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.driver.stages import empty_tables
from pdem.scenes.track import profile, stage_scene, track_settings, traffic_settings
from pdem_cli import needs_mpiexec
from test_track import DOC
from track_runs import assert_resume_in_passage, assert_same_bodies_on_3_ranks, assert_same_results, prepared_runs
from test_track_beam import PREPARE, beam_scene
from test_track_tilt import TURNING


def periodic(text):
    """Periodic ends and turning sleepers."""
    return text.replace("[track]\n", "[track]\nperiodic = true\n", 1).replace("half = true", TURNING)


def doc(traffic=None, simulation=None):
    d = copy.deepcopy(DOC)
    d["track"]["periodic"] = True
    d["traffic"].update({"rail_model": "beam"} if traffic is None else traffic)
    d["simulation"].update(simulation or {})
    return d


def test_the_stage_scenes_have_no_end_walls_and_declare_the_period():
    d = doc()
    c = track_settings(d)
    sc = stage_scene(d, c, empty_tables())
    assert sc.settings.periodic == (0.0, profile(c)["length"]) and sc.settings.slab_axis == 0
    assert 0 not in [int(a) for a in sc.walls.axis]  # no wall across x
    plain = copy.deepcopy(DOC)
    sc = stage_scene(plain, track_settings(plain), empty_tables())
    assert sc.settings.periodic is None and [int(a) for a in sc.walls.axis].count(0) == 2
    t = traffic_settings(d, c)
    assert t["rail_length"] == pytest.approx(profile(c)["length"])
    assert (t["x_from"], t["x_to"]) == (0.0, profile(c)["length"])  # every axle over one period


@pytest.mark.parametrize("traffic, simulation, message", [
    ({}, None, "traffic.rail_model = 'share': its rail-seat shares end at the track's ends"),
    ({"rail_model": "beam", "rail_length": 3.0}, None, "traffic.rail_length = 3.0: track.periodic = true needs"),
    (None, {"periodic": [0.0, 3.6]}, "simulation.periodic: set by track.periodic"),
    (None, {"slab_axis": "y"}, "simulation.slab_axis = 'y': track.periodic = true needs 'x'"),
    ({"rail_model": "beam", "x_from": -0.2, "x_to": 3.6}, None,
     "traffic.x_to = 3.6: with track.periodic = true an axle must run a whole number of periods"),
    ({"rail_model": "beam", "x_from": "0.3"}, None, "traffic.x_from = '0.3': must be a finite number"),
])
def test_bad_periodic_track_input_is_one_line(traffic, simulation, message):
    d = doc(traffic, simulation)
    with pytest.raises(InputError) as err:
        traffic_settings(d, track_settings(d))
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


# ---------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def periodic_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("periodic_track")
    scene, r1, r2 = prepared_runs(base, periodic(PREPARE), lambda bed: periodic(beam_scene(base, bed, passages=2)))
    return base, scene, r1, r2


@needs_mpiexec
@pytest.mark.slow
def test_periodic_track_passages(periodic_runs):
    base, _, r1, _ = periodic_runs
    assert "passage 2/2 done" in r1.stdout and "the rail as a beam" in r1.stdout
    rec = read_track(base / "r1" / "results.h5")
    assert rec.passages["load_peak"].shape == (2, 3) and np.all(rec.passages["load_peak"] > 0)
    ckpts = list_checkpoints(base / "r1" / "checkpoints")
    x = read_checkpoint(ckpts[-1][1])[0]["particles"]["pos"][:, 0]
    assert x.min() >= 0.0 and x.max() < 0.9  # every body inside the period
    assert "x_min" not in (base / "r1" / "summary.txt").read_text()
    assert np.all(rec.passages["tilt_x"] == 0.0) and np.any(rec.passages["tilt_y"] != 0.0)


@needs_mpiexec
@pytest.mark.slow
def test_periodic_track_same_bits_on_1_2_3_ranks_and_after_a_restart(periodic_runs):
    base, scene, _, _ = periodic_runs
    a = assert_same_results(base / "r1" / "results.h5", base / "r2" / "results.h5", "1 and 2 ranks")
    assert "passages/load_peak" in a and "passages/tilt_y" in a
    start = int(read_checkpoint(base / "bed" / "prepared.h5")[1]["step"])
    step = min(s for s, _ in list_checkpoints(base / "r1" / "checkpoints") if s >= start + 300)
    assert_same_bodies_on_3_ranks(base, scene, step, box_columns=("center", "ori", "angmom", "angvel", "rotation"))
    assert_resume_in_passage(base, scene)
