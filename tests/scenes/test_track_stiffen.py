"""The track prepared soft and stiffened before the traffic (`[track] prep_stiffness_factor`,
`pdem.scenes.common.stiffening`, shared with the box test): settings without a run, then end to end.

Settings: defaults give no stiffen stage; bad values stop with one line naming the key.

End to end: the reduced track of `test_track` (half model, 2 sleepers, a few hundred spheres) with
every material ten times stiffer than there, prepared at 0.1 of it (so at `test_track`'s stiffness)
and stiffened in 0.2 s (slow enough that the bed's released elastic strain does not throw the
sleepers up), then one haversine load cycle. After the stiffen stage every ballast
contact's k_n and k_s are what the linear law gives at the full stiffness (YADE_MODEL.md §4: k_n =
2 E r_i r_j / (r_i + r_j), k_s = ν k_n; independent of how the contact was made), the time step
about √0.1 of the preparation's (Δt ∝ 1/√k), and the sleepers, still on the bed, settle
under the load and recover some of it; the same scene on 1 and 2 ranks gives the
same bits (results.h5, preparation.h5).
"""
import copy

import numpy as np
import pytest

from pdem.errors import InputError
from pdem.format.groups import read_track
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.scenes.track import track_settings
from pdem_cli import needs_mpiexec, run_pdem
from test_track import DOC, SCENE
from track_runs import assert_same_results

FACTOR, E_BALLAST, NU = 0.1, 2.8e7, 0.3  # preparation at 0.1 of the materials' stiffness; ballast E, ν


def stiff_scene():
    """`test_track`'s reduced track (2 sleepers) with every young times 10, prepared at 0.1 of it,
    then one haversine cycle 0 -> 1 kN -> 0 per rail seat at 10 Hz."""
    text = SCENE.split("[traffic]")[0].replace("sleepers = 3", "sleepers = 2")
    for soft, stiff in (("2.8e7", "2.8e8"), ("2.8e6", "2.8e7"), ("2.8e5", "2.8e6"), ("4.0e6", "4.0e7")):
        assert f"young = {soft}" in text
        text = text.replace(f"young = {soft}", f"young = {stiff}")
    text = text.replace("vibration_time = 0.05", f"vibration_time = 0.05\nprep_stiffness_factor = {FACTOR}\n"
                        "stiffen_time = 0.2\nstiffen_settle_max_time = 0.1")
    return text + '\n[traffic]\nprogram = "haversine"\nf_max = 1000.0\nfrequency = 10.0\ncycles = 1\n'


def doc(**track):
    d = copy.deepcopy(DOC)
    d["track"].update(track)
    return d


def test_defaults_have_no_stiffen_stage_and_bad_values_one_line():
    c = track_settings(doc())
    assert c["prep_stiffness_factor"] == 1.0 and c["stiffen_settle_max_time"] is None
    for key, value, msg in (("prep_stiffness_factor", 0.0, "track.prep_stiffness_factor = 0.0: must be in (0, 1]"),
                            ("prep_stiffness_factor", 2.0, "track.prep_stiffness_factor = 2.0: must be in (0, 1]"),
                            ("stiffen_time", -1.0, "track.stiffen_time = -1.0"),
                            ("stiffen_settle_max_time", 0.0, "track.stiffen_settle_max_time = 0.0"),
                            ("stiffen_settle_max_time", "long", "track.stiffen_settle_max_time = 'long'")):
        with pytest.raises(InputError, match=msg.replace("(", r"\(").replace(")", r"\)")) as e:
            track_settings(doc(**{key: value}))
        assert "\n" not in str(e.value)
    with pytest.raises(InputError, match="needs simulation.law = 'linear'"):
        track_settings({**doc(prep_stiffness_factor=0.1), "simulation": {"law": "viscous"}})


def test_bad_stiffening_key_exits_2_with_one_line(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(stiff_scene().replace(f"prep_stiffness_factor = {FACTOR}", "prep_stiffness_factor = -3"))
    r = run_pdem(1, scene, tmp_path / "out", expect=2)
    lines = [s for s in (r.stdout + r.stderr).splitlines() if s.strip()]
    assert len(lines) == 1 and "track.prep_stiffness_factor = -3" in lines[0], lines


@pytest.fixture(scope="module")
def stiffened(tmp_path_factory):
    base = tmp_path_factory.mktemp("track_stiffen")
    scene = base / "scene.toml"
    scene.write_text(stiff_scene())
    return scene, base, run_pdem(1, scene, base / "r1")


def step_of(stdout, text):
    return int(next(s for s in stdout.splitlines() if text in s).split(":")[0].split()[1])


@pytest.mark.slow
def test_after_the_stiffen_stage_every_contact_has_the_full_stiffness(stiffened):
    scene, base, r = stiffened
    assert "stages pour, vibrate, settle, refill, stiffen, traffic" in r.stdout
    ckpts = dict(list_checkpoints(base / "r1" / "checkpoints"))
    refill, end = step_of(r.stdout, "(end of stage refill"), step_of(r.stdout, "(end of stage stiffen")
    before, meta0 = read_checkpoint(ckpts[refill])
    tables, meta = read_checkpoint(ckpts[end])
    assert meta["track"]["stiffness_scale"] == 1.0
    radius = dict(zip(tables["particles"]["gid"].tolist(), tables["particles"]["radius"].tolist()))
    c = tables["contacts/sphere_sphere"]
    ri = np.array([radius[g] for g in (c["key"] >> 32).tolist()])
    rj = np.array([radius[g] for g in (c["key"] & 0xFFFFFFFF).tolist()])
    kn = 2 * E_BALLAST * ri * rj / (ri + rj)
    assert len(kn) > 200
    assert np.allclose(c["params"][:, 0], kn, rtol=1e-13, atol=0)
    assert np.allclose(c["params"][:, 1], NU * kn, rtol=1e-13, atol=0)
    # before it, the same law at the preparation's stiffness
    radius0 = dict(zip(before["particles"]["gid"].tolist(), before["particles"]["radius"].tolist()))
    c0 = before["contacts/sphere_sphere"]
    r0i = np.array([radius0[g] for g in (c0["key"] >> 32).tolist()])
    r0j = np.array([radius0[g] for g in (c0["key"] & 0xFFFFFFFF).tolist()])
    assert np.allclose(c0["params"][:, 0], FACTOR * 2 * E_BALLAST * r0i * r0j / (r0i + r0j), rtol=1e-13, atol=0)
    # Δt ∝ 1/√k: about √0.1 of the preparation's (the contacts that opened as the overlaps shrank make it longer)
    assert 0.9 * FACTOR ** 0.5 < meta["dt"] / meta0["dt"] < 2.0 * FACTOR ** 0.5
    # the sleepers rest on the bed: they settle under the load and recover some of it
    res = read_track(base / "r1" / "results.h5")
    peak, permanent = res.passages["settlement_peak"], res.passages["settlement_permanent"]
    assert np.all(peak > 0) and np.all(permanent < peak)


@pytest.mark.slow
@needs_mpiexec
def test_same_bits_on_2_ranks(stiffened, tmp_path):
    scene, base, _ = stiffened
    run_pdem(2, scene, tmp_path / "r2")
    for name in ("results.h5", "preparation.h5"):
        assert_same_results(base / "r1" / name, tmp_path / "r2" / name, f"{name} on 2 ranks")
