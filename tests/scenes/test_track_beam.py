"""The track with the rail as a beam on pads (`[traffic] rail_model = "beam"`,
`pdem.boundaries.rail_beam.SleeperRails`): the coupling without a run, then end to end.

Pieces: the sleepers' loads from the rails are the beams' pad forces (a whole track: two rails,
twice a half model's), computed once per instant and sleeper positions; they carry the wheels
on the rail plus the rail's weight; a sinking sleeper sheds load to its neighbours; the sleeper's
mass leaves the rail out; bad keys one line.

End to end: the reduced track of `test_track` (half model, 3 sleepers, about 800 spheres,
stiffness scaled down, with the rail's EI and pads scaled with it) prepared once, then three
passages of a bogie on the beam rail from that bed: on 1 and 2 ranks the same bits; 3 ranks
`--steps` to a checkpoint in the first passage gives the bodies of the 1-rank run there; a 2-rank
run resumed from a checkpoint in the middle of a passage rewrites the same records. At every
recorded step the pads carry exactly the wheels on the rail plus the rail's weight (the
quasi-static beam's equilibrium, against the train's own axle positions), the passage table has
the peak load on every sleeper, and the analysis says why it did not fit 3 passages.
"""
import copy
import tomllib

import h5py
import numpy as np
import pytest

from analysis.track import MIN_FIT_PASSAGES, fit_settlement
from pdem.boundaries.loads import AxleTrain
from pdem.boundaries.rail_beam import UIC60, RailBeam, SleeperRails
from pdem.errors import InputError
from pdem.format.groups import read_track
from pdem.scenes.track import make_train, track_settings, traffic_settings
from pdem_cli import needs_mpiexec, run_pdem
from test_track import DOC, SCENE
from track_runs import assert_resume_in_passage, assert_same_bodies_on_3_ranks, assert_same_results, prepared_runs

# the reduced track's rail scaled with its stiffness (E_k / 1e5): EI and pads so that the rail spreads a
# wheel over about as many sleepers as a real track's; 1 kN axles (2 kN overloads this 2.4-grain bed)
BEAM = """rail_model = "beam"
rail_pad_stiffness = 5.0e5
rail_bending_stiffness = 5.0e3
"""
PREPARE = SCENE.split("[traffic]")[0]
RAIL_LENGTH = 0.9  # the track's: 3 sleepers x 0.3 m


def doc(**traffic):
    d = copy.deepcopy(DOC)
    d["traffic"].update(traffic)
    return d


# ---------------------------------------------------------------------------- pieces
class Boxes:
    """What `SleeperRails` reads of the sleepers: their centres."""

    def __init__(self, z):
        self.center = np.stack([np.zeros(len(z)), np.zeros(len(z)), z], axis=1)


def rails_on(n_rails, z0):
    train = AxleTrain(2.0e5, [0.0, 2.5], 20.0, 1, spacing=0.6, length=0.7, x_from=-1.0, x_to=5.0)
    x = (np.arange(6) + 0.5) * 0.6
    rails = SleeperRails([RailBeam(x, 1.0e8, x_start=0.0, x_end=3.6) for _ in range(n_rails)], train)
    rails.attach(Boxes(z0), z0)
    return rails, x


def test_the_sleepers_carry_the_pad_forces_of_every_rail():
    z0 = np.full(6, 0.45)
    half, x = rails_on(1, z0)
    whole, _ = rails_on(2, z0)
    z = z0 - [0.0, 1e-3, 2e-3, 0.0, 5e-4, 0.0]  # settled sleepers
    half.boxes.center[:, 2] = z
    whole.boxes.center[:, 2] = z
    t = 0.1  # the first axle at x = 1.0 m, the second off the rail
    assert half.train.axle_positions(t) == [pytest.approx(1.0)]
    expected = -half.beams[0].seat_forces(z - z0, [1.0], [1.0e5])
    got = np.array([half.load(t, xk) for xk in x])
    assert np.array_equal(got, expected)
    assert np.array_equal(np.array([whole.load(t, xk) for xk in x]), 2 * expected)
    # the pads carry the wheel on the rail and the rail's weight, wherever the sleepers are
    assert got.sum() == pytest.approx(1.0e5 + UIC60.mass * 9.81 * 3.6, rel=1e-10)
    assert half.weight == pytest.approx(UIC60.mass * 9.81 * 3.6) and whole.weight == 2 * half.weight
    # one beam answer per instant and positions: a sleeper whose ballast gives way (it sinks 1 mm more)
    # carries less, and its neighbours carry what it sheds
    half.boxes.center[2, 2] -= 1e-3
    sunk = np.array([half.load(t, xk) for xk in x])
    assert sunk[2] < got[2] and sunk[1] > got[1] and sunk[3] > got[3]
    assert sunk.sum() == pytest.approx(got.sum(), rel=1e-12)


def test_with_the_beam_the_sleeper_mass_leaves_the_rail_out():
    c = track_settings(doc())
    t = traffic_settings(doc(rail_model="beam"), c)
    assert t["body_mass"] == pytest.approx(c["sleeper_mass"])  # whole track: two rails through the pads
    assert t["rail_length"] == pytest.approx(3.6) and t["rail_pad_stiffness"] == 1.0e8
    assert traffic_settings(doc(), c)["body_mass"] == c["body_mass"]  # the prescribed share: unchanged


@pytest.mark.parametrize("traffic, message", [
    ({"rail_model": "beam", "rail_pad_stiffness": 0.0}, "traffic.rail_pad_stiffness = 0.0: must be a number > 0 [N/m]"),
    ({"rail_model": "beam", "rail_pad_stiffness": -5e7}, "traffic.rail_pad_stiffness = -50000000.0: must be a"),
    ({"rail_model": "beam", "rail_length": 4.0}, "traffic.rail_length = 4.0: longer than the track (3.6 m"),
    ({"rail_model": "beam", "rail_length": 2.5}, "traffic.rail_length: the rail [0.55, 3.05] m must reach over every"),
    ({"rail_model": "timoshenko"}, "traffic.rail_model = 'timoshenko': must be 'share'"),
    ({"rail_pad_stiffness": 1e8}, "traffic.rail_pad_stiffness: not used by rail_model = 'share'; remove it"),
])
def test_bad_rail_input_is_one_line(traffic, message):
    d = doc(**traffic)
    with pytest.raises(InputError) as err:
        traffic_settings(d, track_settings(d))
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_fits_need_enough_passages():
    n = np.arange(1, MIN_FIT_PASSAGES)
    assert "not fitted: 4 passage(s), at least 5 needed" in fit_settlement(n, 1e-3 * n).reason
    n = np.arange(1.0, 21.0)
    fits = fit_settlement(n, 2e-3 + 1e-3 * np.log10(n))
    assert fits.forms["a + b log10 N"]["a"] == pytest.approx(2e-3) and fits.forms["a + b log10 N"]["b"] == \
        pytest.approx(1e-3)
    power = fit_settlement(n, 1.5e-3 * n**0.3).forms["a N^b"]
    assert power["a"] == pytest.approx(1.5e-3, rel=1e-6) and power["b"] == pytest.approx(0.3, rel=1e-6)


# ---------------------------------------------------------------------------- end to end
def beam_scene(base, prepared, passages=3, extra=""):
    text = SCENE.replace("passages = 1", f"passages = {passages}").replace("axle_load = 2000.0", "axle_load = 1000.0")
    text = text.replace("checkpoint_every = 1000", "checkpoint_every = 300")  # some inside every passage
    return text.replace('program = "axles"', f'program = "axles"\nprepared = "{prepared}"\n{BEAM}{extra}')


@pytest.fixture(scope="module")
def beam_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("beam")
    scene, r1, r2 = prepared_runs(base, PREPARE, lambda bed: beam_scene(base, bed))
    return base, scene, r1, r2


@needs_mpiexec
@pytest.mark.slow
def test_three_passages_on_the_beam_rail(beam_runs):
    base, _, r1, _ = beam_runs
    assert "the rail as a beam (EI 5000 N m^2" in r1.stdout and "passage 3/3 done" in r1.stdout
    rec = read_track(base / "r1" / "results.h5")
    p = rec.passages
    assert p["load_peak"].shape == (3, 3) and np.all(p["load_peak"] > 0)
    assert np.all(p["settlement_peak"] > 1e-3)  # every sleeper goes down under the bogie
    # the energy ledger: damping and friction dissipate, so the pads' work exceeds the energy
    # gained (the undamped frictionless balance is test_track_energy's)
    assert p["load_work"].shape == (3,) and np.all(p["load_work"] - p["energy_change"] > 0.0)
    text = (base / "r1" / "analysis" / "track.txt").read_text()
    assert "not fitted: 3 passage(s), at least 5 needed" in text and "Fpeak_max" in text
    assert (base / "r1" / "analysis" / "track_passages.png").stat().st_size > 0
    assert "peak load of the rail (a beam) on each sleeper per passage" in (base / "r1" / "summary.txt").read_text()


@needs_mpiexec
@pytest.mark.slow
def test_the_pads_carry_the_wheels_on_the_rail_and_the_rail(beam_runs):
    """Equilibrium of the quasi-static beam at every recorded step: the sleepers' load (what the
    pads push) is the rail's weight plus the wheels the train has on the rail, counted from the
    train's own axle positions at the step's start or end (a wheel entering or leaving the rail
    in that step may count either way)."""
    base = beam_runs[0]
    with h5py.File(base / "r1" / "results.h5") as f:
        t, dt, load = (f["series"][k][()] for k in ("time", "dt", "applied_load"))
        start = float(f["passages/t_start"][0])
    scene = tomllib.loads(beam_scene(base, base / "bed"))
    c = track_settings(scene)
    tr = traffic_settings(scene, c)
    train = make_train(tr, c, start)
    rail_weight = c["rail_mass"] * 9.81 * RAIL_LENGTH
    wheel = tr["axle_load"] / 2
    on_rail = lambda time: sum(0.0 <= x <= RAIL_LENGTH for x in train.axle_positions(time))  # noqa: E731
    assert len(t) > 50
    loaded = 0
    for ti, dti, fi in zip(t, dt, load):
        counts = {on_rail(ti - dti), on_rail(ti)}
        assert any(fi == pytest.approx(rail_weight + n * wheel, rel=1e-10) for n in counts), (ti, fi, counts)
        loaded += fi > rail_weight + 0.5 * wheel
    assert loaded > 10


@needs_mpiexec
@pytest.mark.slow
def test_same_bits_on_1_and_2_ranks_and_3_ranks_to_a_checkpoint(beam_runs):
    base, scene, _, _ = beam_runs
    a = assert_same_results(base / "r1" / "results.h5", base / "r2" / "results.h5", "1 and 2 ranks")
    assert "passages/load_peak" in a
    assert_same_bodies_on_3_ranks(base, scene, 4200)  # the prepared bed is at step 3600: 600 steps of traffic


@needs_mpiexec
@pytest.mark.slow
def test_resume_in_the_middle_of_a_passage(beam_runs):
    base, scene, _, _ = beam_runs
    assert_resume_in_passage(base, scene)


@needs_mpiexec
@pytest.mark.slow
def test_pads_too_stiff_for_the_time_step_are_one_line(beam_runs):
    base = beam_runs[0]
    bad = base / "stiff.toml"
    bad.write_text(beam_scene(base, base / "bed").replace("rail_pad_stiffness = 5.0e5", "rail_pad_stiffness = 1.0e9"))
    r = run_pdem(1, bad, base / "stiff", expect=2)
    assert "traffic.rail_pad_stiffness = 1000000000.0: too stiff for the time step" in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
