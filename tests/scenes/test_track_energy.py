"""The energy balance of a passage (#30): over each passage the work W of the rails' pads on the
sleepers (their load and moment times the sleepers' displacement and turn, `Boxes.load_step`)
equals the change ΔE of the mechanical energy of sleepers and ballast (kinetic, rotational,
gravitational, elastic in the contacts: `pdem.scenes.track_record.mechanical_energy`) when nothing
dissipates, and exceeds it when the bed is damped (`/passages/load_work`, `energy_change`).

End to end (slow): the reduced half track of `test_track_beam` (3 sleepers on the beam rail,
about 900 spheres) with every material frictionless (tan φ = tan min(φ_a, φ_b) = 0: no slip to
dissipate), prepared damped at a fifth of the default time-step safety, then two passages of a
bogie with ``traffic.damping = 0``: the contacts are linear springs and nothing else acts, so W =
ΔE up to the leapfrog's error. Measured here: 0.07 % and 0.06 % of W at this Δt, 0.8 % and
0.4 % at the default (four times longer) Δt; the test allows 0.5 %. The frictionless bed flows
under the sleepers (they sink several mm per passage), so W is not small: most of it is the
rail's weight following the sinking sleepers. The damped, frictional runs of `test_track_beam`
check the other side: W − ΔE > 0 in every passage.
"""
import tomllib

import numpy as np
import pytest

from pdem.errors import InputError
from pdem.format.groups import read_track
from pdem.scenes.track import track_settings, traffic_settings
from pdem_cli import needs_mpiexec, run_pdem
from test_track_beam import PREPARE, beam_scene

FINE = 'dt = "auto"\ndt_safety = 0.2'


def frictionless(text):
    return text.replace("friction_angle = 0.5", "friction_angle = 0.0").replace(
        "friction_angle = 0.7", "friction_angle = 0.0").replace('dt = "auto"', FINE)


def test_traffic_damping_is_checked_and_named():
    text = frictionless(beam_scene("x", "bed"))
    d = tomllib.loads(text.replace('rail_model = "beam"', 'rail_model = "beam"\ndamping = 0.0'))
    assert "friction_angle = 0.5" not in frictionless(PREPARE) and "friction_angle = 0.7" not in frictionless(PREPARE)
    assert traffic_settings(d, track_settings(d))["damping"] == 0.0
    d["traffic"]["damping"] = 1.5
    with pytest.raises(InputError) as err:
        traffic_settings(d, track_settings(d))
    assert str(err.value) == "traffic.damping = 1.5: must be in [0, 0.99] (Cundall's lambda_D)"


@needs_mpiexec
@pytest.mark.slow
def test_an_undamped_frictionless_passage_conserves_energy(tmp_path):
    (tmp_path / "prepare.toml").write_text(frictionless(PREPARE))
    run_pdem(1, tmp_path / "prepare.toml", tmp_path / "bed")
    scene = frictionless(beam_scene(tmp_path, tmp_path / "bed", passages=2))
    scene = scene.replace('rail_model = "beam"', 'rail_model = "beam"\ndamping = 0.0')
    (tmp_path / "traffic.toml").write_text(scene)
    r = run_pdem(1, tmp_path / "traffic.toml", tmp_path / "r1")
    assert "damping 0 (traffic.damping)" in r.stdout
    p = read_track(tmp_path / "r1" / "results.h5").passages
    work, change = p["load_work"], p["energy_change"]
    assert work.shape == (2,) and np.all(work > 1.0)  # J: the rail's weight and the wheels doing work
    np.testing.assert_allclose(change, work, rtol=5e-3)
