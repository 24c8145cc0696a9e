"""The engine's settings and clock: the settings are one frozen record made by the scene and
held by the simulation; dt = "auto" is the one sentinel; the clock (step, time, Δt, rebuilds,
energy reference) goes into checkpoint meta and comes back unchanged (`clock_state`,
`restore_clock`)."""
import dataclasses

import pytest

from pdem import InputError, Scene
from pdem.io.checkpoint_state import clock_state, restore_clock
from pdem.settings import AUTO


def scene(**settings):
    sc = Scene(gravity=(0.0, 0.0, -9.81), check_interval=10, allow_initial_overlap=True, **settings)
    m = sc.material(density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    sc.add_spheres([(0.0, 0.0, 0.0099), (0.0, 0.0, 0.0297)], 0.01, m)
    sc.add_wall("z", 0.0, m, sense=1)
    return sc


def test_settings_are_frozen_and_shared_by_scene_and_simulation():
    sc = scene(dt=1e-5, damping=0.2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.settings.dt = 2e-5
    sim = sc.build()
    assert sim.settings is sc.settings and sim.dt == 1e-5
    assert sim.spec["settings"] == sc.settings.as_dict() and sim.spec["settings"]["dt"] == 1e-5
    assert sc.settings.damping == sim.damping == 0.2
    assert "domain" not in sim.spec["settings"]  # only when declared: older specs stay as they were


def test_auto_is_the_one_sentinel_of_dt():
    assert scene().settings.dt == AUTO
    with pytest.raises(InputError, match="'auto' or a number > 0"):
        scene(dt=None)


def test_clock_save_restore_round_trip():
    a = scene().build()
    a.run(25)
    saved = clock_state(a)
    assert saved["step"] == 25 and saved["energy_reference"] is not None and saved["time"] > 0
    saved["dt"] *= 0.5  # not what an estimate gives: the restored Δt is the checkpoint's
    b = scene().build()
    assert clock_state(b) != saved
    restore_clock(b, saved)
    assert clock_state(b) == saved
    c = scene().build()
    restore_clock(c, saved, continuing=False)  # a new stage: same step and time, fresh Δt and reference
    fresh = clock_state(c)
    assert (fresh["step"], fresh["time"]) == (saved["step"], saved["time"])
    assert fresh["dt"] == 2 * saved["dt"] and fresh["energy_reference"] is None
