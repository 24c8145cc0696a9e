"""Pieces of the blast scene (`pdem.scenes.blast`) that need no run: settings, stage list, the
plate-step stop and the prepared layer's clock."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import tomllib

from pdem import InputError, InstabilityError
from pdem.scenes import blast

DOC = tomllib.loads((Path(__file__).parents[2] / "jobs" / "blast.toml").read_text())


def stage_names(c):
    """The names of `BlastRun.stage_list` for the settings ``c`` (no run made)."""
    run = object.__new__(blast.BlastRun)
    run.c = c
    return tuple(stage.name for stage in run.stage_list())


def test_defaults_of_the_job_file():
    c = blast.blast_settings(DOC)
    assert c["box"] == [0.3, 0.3, 0.3] and c["plates"] == [10780.0, 2700.0, 244.0]
    assert c["F0"] == 9e6 and c["tau"] == 1e-4 and c["duration"] == 9e-3
    assert stage_names(c) == ("pour", "settle", "plate_0", "blast_0", "plate_1", "blast_1", "plate_2", "blast_2")
    assert stage_names({**c, "prepared_from": "x", "plates": [244.0]}) == ("plate_0", "blast_0")
    _, radius = blast.cloud(c)
    assert radius.min() >= 0.0045 and radius.max() <= 0.005
    # the cloud holds the layer at the assumed packing fraction, overfilled by 10 %
    assert np.sum(4 / 3 * np.pi * radius ** 3) == pytest.approx(1.1 * 0.6 * 0.027, rel=1e-3)


@pytest.mark.parametrize("key, value, field", [("plates", [244.0, 244.0], "blast.plates"),
                                               ("diameter_max", 0.008, "blast.diameter_max"),
                                               ("grain_material", "sand", "blast.grain_material"),
                                               ("tau", 0.0, "blast.tau"), ("dt", 1e-6, "blast.dt")])
def test_bad_settings_one_line(key, value, field):
    doc = {**DOC, "blast": {**DOC["blast"], key: value}}
    with pytest.raises(InputError) as exc:
        blast.blast_settings(doc)
    assert field in str(exc.value) and "\n" not in str(exc.value)


def test_plate_that_outruns_the_grains_stops_the_run():
    sim = SimpleNamespace(step=12, dt=1e-5, boxes=SimpleNamespace(velocity=np.array([[0.0, 0.0, -200.0]])))
    with pytest.raises(InstabilityError, match="cover plate moved 2.000e-03 m in one step"):
        blast.check_plate_step(sim, 0.25 * 0.0045)
    sim.boxes.velocity[0, 2] = -50.0
    blast.check_plate_step(sim, 0.25 * 0.0045)


def test_every_plate_starts_on_the_prepared_clock():
    """The first plate starts at the prepared step; a later one at the next step congruent to it
    modulo the schedules (dt_interval, check_interval, check_every, record_every, output_every)."""
    run = SimpleNamespace(doc={"simulation": {"dt_interval": 100, "check_interval": 40}},
                          c={"check_every": 200, "record_every": 1}, meta=None,
                          run_cfg={"output_every": 500, "snapshot_every": 0, "checkpoint_every": 0})
    prepared = {"step": 18600, "time": 0.3}
    blast.BlastRun.restart_clock(run, prepared)
    assert run.meta["step"] == 18600 and run.meta["time"] == 0.3
    run.meta = {"step": 25017, "time": 0.41}
    blast.BlastRun.restart_clock(run, prepared)
    assert run.meta["step"] == 18600 + 7 * 1000 and run.meta["time"] == 0.3  # lcm(100, 40, 200, 500) = 1000


def test_plate_is_lowered_until_the_grains_carry_it_then_let_go():
    """v = speed (1 − F/W) downwards while F < 0.98 W; then the plate is free in z, at rest."""
    state = {"plate_free": False}
    lower = blast.PlateLowering(0.1, state)
    boxes = SimpleNamespace(mass=np.array([2.0]), contact_force=np.zeros((1, 3)), velocity=np.zeros((1, 3)),
                            blocked=np.array([0b111111]))
    sim = SimpleNamespace(boxes=boxes, gravity=np.array([0.0, 0.0, -10.0]))  # W = 20 N
    lower(sim)
    assert boxes.velocity[0, 2] == -0.1 and not state["plate_free"]
    boxes.contact_force[0, 2] = 15.0
    lower(sim)
    assert boxes.velocity[0, 2] == pytest.approx(-0.025) and boxes.blocked[0] == 0b111111
    boxes.contact_force[0, 2] = 19.7  # carried within 2 %: let go
    lower(sim)
    assert state["plate_free"] and boxes.velocity[0, 2] == 0.0 and boxes.blocked[0] == 0b111011
    boxes.velocity[0, 2] = 0.3  # free from now on: the lowering leaves it alone
    lower(sim)
    assert boxes.velocity[0, 2] == 0.3
