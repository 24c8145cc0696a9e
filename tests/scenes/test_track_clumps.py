"""Clump ballast in the track (`[track.clumps]`, `pdem.scenes.track`): rigid clumps and breakable
grains (the oedometer's: bonded members, cohesive law), with the grading per passage.

Pieces without a run: the table is the oedometer's grain (one parser,
`pdem.scenes.common.grains`); the bed's cuts remove whole clumps (with the rigid clumps' rows);
bad input is one line naming the field (periodic ends with clumps, sphere radii beside the
clumps, breakable grains without the cohesive law, a cloud's key in the grain), exit 2 from the
command line.

End to end (slow): a small half track (2 sleepers, grains of 8 spheres of r = 15 mm, the rail as
a beam, the subgrade 10 times as stiff as the ballast: on the usual soft one the few grains
under a sleeper of this thin bed are pressed into it beyond the overlap guard) prepared once
with rigid clumps and once with breakable grains (bonds 10 times stronger while preparing), then
one passage of a bogie from that bed on 1 and 2 ranks: the same bits, and a 2-rank run of the
breakable grains resumed from a checkpoint inside the passage rewrites them. Physics of the breakable run against
independent truth: the fragments' masses add up, at every record, to the grains' mass from the
density and the member radius (nothing is lost or made by breakage); the prepared bed holds 12
bonds per grain (a 2 x 2 x 2 cube of touching spheres has 12 touching pairs) and every grain
whole; every bond still intact after the passage holds within its strength as the cohesive law
says (tension -F_n <= a_N = c r^2, shear |F_s| <= a_T + F_n tan phi); the bonds broken in the
passage are the records' difference, and the analysis (`python -m analysis track`) writes the
grading per passage.
"""
import copy
import math
import tomllib

import numpy as np
import pytest

from pdem.build.config import scene_from_dict
from pdem.driver.stages import append_tables, clump_tables, empty_tables
from pdem.errors import InputError
from pdem.format.groups import read_fragments
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.scenes.common.preparation import remove_where
from pdem.scenes.track import track_settings, traffic_settings
from pdem_cli import needs_mpiexec, run_pdem
from track_runs import assert_resume_in_passage, assert_same_results, prepared_runs

R = 0.015          # member radius [m]
DENSITY = 2600.0   # [kg/m^3]
COHESION = 3.0e4   # [Pa]: a bond holds c r^2 = 6.75 N

MATERIALS = """
[materials.ballast]
density = 2600.0
young = 2.8e6
poisson = 0.3
friction_angle = 0.5
{cohesion}
[materials.steel]
density = 7850.0
young = 2.8e7
poisson = 0.25
friction_angle = 0.5
{zero}
[materials.rubber]
density = 1000.0
young = 2.8e7
poisson = 0.5
friction_angle = 0.7
{zero}
[materials.concrete]
density = 2600.0
young = 4.0e6
poisson = 0.3
friction_angle = 0.5
{zero}"""


def scene(breakable, traffic=True, prepared=None):
    """The scene file's text: rigid clumps (law linear) or breakable grains (law cohesive)."""
    law = 'law = "cohesive"\n' if breakable else ""
    mats = MATERIALS.format(
        cohesion=f"normal_cohesion = {COHESION}\nshear_cohesion = {COHESION}\n" if breakable else "",
        zero="normal_cohesion = 0.0\nshear_cohesion = 0.0\n" if breakable else "")
    text = f"""[simulation]
{law}dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]

[run]
progress_every = 0
output_every = 20
snapshot_every = 0
checkpoint_every = 200
checkpoint_keep = 0
{mats}
[track]
half = true
sleepers = 2
spacing = 0.3
sleeper_size = [0.15, 0.5, 0.08]
gauge = 0.3
rail_foot_width = 0.1
bed_depth = 0.12
shoulder_width = 0.04
slope = 1.0
seed = 5
packing_fraction = 0.35
overfill = 1.3
settle_min_time = 0.1
settle_max_time = 0.6
vibration_time = 0.03
{'bond_boost = 10.0' if breakable else ''}

[track.clumps]
shape = "ballast8"
member_radius = {R}
breakable = {'true' if breakable else 'false'}
"""
    if traffic:
        text += f"""
[traffic]
program = "axles"
{f'prepared = "{prepared}"' if prepared else ''}
rail_model = "beam"
rail_pad_stiffness = 5.0e5
rail_bending_stiffness = 5.0e3
axle_load = 1000.0
axles = [0.0, 0.3]
speed = 20.0
passages = 1
rest_time = 0.03
"""
    return text


def doc(breakable=True, **track):
    d = tomllib.loads(scene(breakable))
    d["track"].update(track)
    return d


# ---------------------------------------------------------------------------- pieces
def test_the_table_is_the_oedometers_grain():
    c = track_settings(doc(breakable=True))
    g = c["grain"]
    assert g["breakable"] and g["stress_free"] and len(g["member_radii"]) == 8
    assert np.all(g["member_radii"] == R)
    rigid = track_settings(doc(breakable=False))["grain"]
    assert not rigid["breakable"] and rigid["mass_model"] == "members"
    spheres = copy.deepcopy(doc(breakable=False))
    del spheres["track"]["clumps"]
    assert track_settings(spheres)["grain"] is None


def test_the_cuts_remove_whole_clumps():
    d = doc(breakable=False)
    sc = scene_from_dict({k: d[k] for k in ("simulation", "materials")})
    pos = np.array([[-1, -1, -1], [1, -1, -1], [-1, 1, -1], [1, 1, -1], [-1, -1, 1], [1, -1, 1], [-1, 1, 1],
                    [1, 1, 1]], float) * R
    grains = [(pos + (0.1, 0.1, 0.1), np.full(8, R)), (pos + (0.3, 0.1, 0.1), np.full(8, R))]
    tables = append_tables(empty_tables(), clump_tables(sc, grains, "ballast", 0, 0))
    tables, removed = remove_where(tables, lambda p, r: p[:, 0] + r > 0.3)  # one member of grain 1 reaches over
    assert removed == 8
    assert np.all(tables["particles"]["clump"] == 0) and len(tables["particles"]["gid"]) == 8
    assert tables["clumps"]["id"].tolist() == [0] and np.all(tables["clump_members"]["clump"] == 0)


@pytest.mark.parametrize("breakable, edit, message", [
    (False, {"periodic": True}, "track.periodic = true: the engine's periodic ends take spheres only, not the clumps"),
    (False, {"radius": 0.02}, "track.radius = 0.02: sizes sphere ballast, but [track.clumps] gives the ballast as"),
    (True, {"radius_spread": 0.3}, "track.radius_spread = 0.3: sizes sphere ballast"),
    (True, {"clumps": {"shape": "ballast8", "count": 10}}, "track.clumps.count: unknown key; allowed: breakable,"),
    (True, {"clumps": {"member_radius": 0.02}}, "track.clumps.shape: "),
    (False, {"bond_boost": 10.0}, "track.bond_boost = 10.0: scales bonds, which only breakable grains have"),
    (True, {"bond_boost": 0.0}, "track.bond_boost = 0.0: must be a factor > 0 [-]"),
])
def test_bad_clump_input_is_one_line(breakable, edit, message):
    d = doc(breakable, **edit)
    with pytest.raises(InputError) as err:
        traffic_settings(d, track_settings(d))
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_breakable_grains_need_the_cohesive_law():
    d = doc(breakable=True)
    del d["simulation"]["law"]
    with pytest.raises(InputError) as err:
        track_settings(d)
    assert str(err.value) == 'track.clumps.breakable = true: bonds need simulation.law = "cohesive", got \'linear\''


def test_periodic_ends_with_clumps_exit_2_with_one_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(scene(True).replace("[track]\n", "[track]\nperiodic = true\n"))
    r = run_pdem(1, path, tmp_path / "out", expect=2)
    assert r.stderr.count("\n") == 1 and "track.periodic = true: the engine's periodic ends" in r.stderr


# ---------------------------------------------------------------------------- end to end
def grain_mass():
    return 8 * DENSITY * 4.0 / 3.0 * math.pi * R ** 3


@pytest.fixture(scope="module", params=[False, True], ids=["rigid", "breakable"])
def runs(request, tmp_path_factory):
    breakable = request.param
    base = tmp_path_factory.mktemp("breakable" if breakable else "rigid")
    scene_path, r1, r2 = prepared_runs(base, scene(breakable, traffic=False),
                                       lambda bed: scene(breakable, prepared=bed))
    return breakable, base, scene_path, r1, r2


@needs_mpiexec
@pytest.mark.slow
def test_same_bits_on_1_and_2_ranks_through_a_passage(runs):
    breakable, base, _, r1, _ = runs
    a = assert_same_results(base / "r1" / "results.h5", base / "r2" / "results.h5", "1 and 2 ranks")
    assert "passages/settlement_permanent" in a
    assert ("fragments/passage_1/mass" in a) == breakable  # the grading only where grains can break
    kind = "breakable" if breakable else "rigid"
    assert f"{kind} clumps of 8 spheres" in (base / "bed" / "log.txt").read_text()
    assert "passage 1/1 done" in r1.stdout


@needs_mpiexec
@pytest.mark.slow
def test_breakage_conserves_mass_and_breaks_bonds_only_beyond_their_strength(runs):
    breakable, base, _, r1, _ = runs
    if not breakable:
        pytest.skip("rigid clumps do not break")
    fr = read_fragments(base / "r1" / "results.h5")
    labels = [r.label for r in fr.records]
    assert labels == ["prepared", "passage_1"]
    prepared, after = fr.records
    grains = len(prepared.mass)
    # the prepared bed: every grain whole, 12 bonds each, the mass of its 8 spheres
    assert np.all(prepared.n_members == 8) and prepared.n_bonds == 12 * grains
    assert prepared.mass == pytest.approx(np.full(grains, grain_mass()), rel=1e-12)
    # breakage moves mass between fragments, never makes or loses any
    for r in fr.records:
        assert r.mass.sum() == pytest.approx(grains * grain_mass(), rel=1e-12)
        assert r.n_members.sum() == 8 * grains
    assert after.n_bonds <= prepared.n_bonds
    assert f"{prepared.n_bonds - after.n_bonds} broken since the record before" in r1.stdout
    # every bond still intact holds within its strength (the cohesive law's Law2)
    last = max(s for s, _ in list_checkpoints(base / "r1" / "checkpoints"))
    tables = read_checkpoint(base / "r1" / "checkpoints" / f"ckpt_{last:012d}.h5")[0]
    c = tables["contacts/sphere_sphere"]
    params, history = c["params"], c["history"]
    bonded = history[:, 4] > 0.0
    assert bonded.sum() == after.n_bonds
    a_n = COHESION * R ** 2
    assert np.all(history[bonded, 4] == pytest.approx(a_n, rel=1e-12))
    fn, fs = history[bonded, 3], np.linalg.norm(history[bonded, :3], axis=1)
    assert np.all(-fn <= a_n * (1 + 1e-12))
    assert np.all(fs <= (history[bonded, 5] + fn * params[bonded, 2]) * (1 + 1e-12) + 1e-12)
    # the analysis: a grading curve per passage and the breakage per passage
    out = base / "r1" / "analysis"
    assert (out / "grading.png").stat().st_size > 0 and (out / "breakage.png").stat().st_size > 0
    text = (out / "grading.txt").read_text()
    assert "passage_1" in text and "intact bonds per record" in text


@needs_mpiexec
@pytest.mark.slow
def test_breakable_run_resumed_in_the_passage_rewrites_the_same_records(runs):
    """A copy of the 2-rank run cut back to a checkpoint inside the passage and run again on 2
    ranks writes the records of the 1-rank run bit for bit (the fragments and bonds too)."""
    breakable, base, scene_path, _, _ = runs
    if not breakable:
        pytest.skip("the breakable run only")
    assert_resume_in_passage(base, scene_path, passage=1)
