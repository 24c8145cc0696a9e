"""The track's sleeper as a shell of member spheres (`[track] sleeper_surface = "spheres"`,
`pdem.scenes.common.sleepers`, shared with the box test): the thesis slice's half-sleeper
1300 x 300 x 220 mm at r = 5 mm has the member count and mass of the lattice rule, counted here
by formula (n_a = size_a / 2r sites per axis, the shell = all sites less the interior block);
every member lies on the sleeper's faces; the body's mass is the members' plus the rail's; the
inputs that cannot work are refused in one line (one of them through `pdem run --check`, exit
2); the flat sleeper is unchanged.

End to end (slow): the reduced track of `test_track` with member sleepers (r = 12.5 mm, 400
members each) and the box test's calibrated options (no vibration, the members' mass), prepared
once, then a bogie's passage from that bed on 1 and 2 ranks: the same bits; the sleepers settle
under it.
"""
import copy
import math

import numpy as np
import pytest
import tomllib

from pdem.errors import InputError
from pdem.format.groups import read_track
from pdem.scenes.common.sleepers import sleeper_members
from pdem.scenes.track import sleeper_boxes, track_settings
from pdem_cli import needs_mpiexec, run_pdem
from test_track import DOC, SCENE
from track_runs import assert_same_results, prepared_runs



def slice_doc(**track):
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    d = tomllib.loads((root / "jobs" / "track_slice_calibrated.toml").read_text())
    d["track"].update(track)
    return d


def test_the_half_sleeper_of_the_slice_has_the_lattice_rules_members_and_mass():
    c = track_settings(slice_doc())
    r = 0.005
    assert c["sleeper_member_radius"] == r and c["half"]
    # the half-sleeper 300 x 1300 x 220 mm (x, y, z): 30 x 130 x 22 lattice sites of 10 mm
    nx, ny, nz = 300 // 10, 1300 // 10, 220 // 10
    shell = nx * ny * nz - (nx - 2) * (ny - 2) * (nz - 2)
    assert shell == 14120
    m = c["sleeper_members"]
    assert m.shape == (shell, 3)
    mass = shell * 4.0 / 3.0 * math.pi * r ** 3 * 2600.0  # concrete (the scene's sleeper material)
    assert mass == pytest.approx(19.22, abs=0.01)
    assert c["sleeper_mass"] / 2 == pytest.approx(mass, rel=1e-12)  # the whole sleeper's: twice the half's
    assert c["body_mass"] == pytest.approx(mass + 60.21 * 0.6, rel=1e-12)  # plus the rail over one spacing
    # every member inside the body's box, its outer surface on one of the box's faces; neighbours 2r apart
    half = sleeper_boxes(c)[1]
    assert np.allclose(half, [0.15, 0.65, 0.11])
    reach = np.abs(m) + r
    assert np.all(reach <= half * (1 + 1e-12))
    assert np.all(np.isclose(reach, half, rtol=0, atol=1e-12).any(axis=1))
    for a, n in enumerate((nx, ny, nz)):
        assert len(np.unique(np.round(m[:, a], 9))) == n
        assert np.allclose(np.diff(np.unique(np.round(m[:, a], 9))), 2 * r)
    assert len(np.unique(np.round(m, 9), axis=0)) == shell  # no site twice


def test_the_box_tests_tube_is_the_open_shell():
    open_tube = sleeper_members([0.25, 0.3, 0.15])
    closed = sleeper_members([0.25, 0.3, 0.15], closed=True)
    assert len(open_tube) == 2 * 25 * 30 + 2 * 30 * 13 == 2280  # the thesis's clump (5.2)
    assert len(closed) == 2280 + 2 * 23 * 13  # plus the two end walls


def test_the_flat_sleeper_is_unchanged():
    c = track_settings(copy.deepcopy(DOC))
    assert c["sleeper_members"] is None and c["sleeper_surface"] == "flat"
    w, length, h = c["sleeper_size"]
    assert c["sleeper_mass"] == pytest.approx(2600.0 * w * length * h)


@pytest.mark.parametrize("track, message", [
    ({"sleeper_surface": "spheres", "sleeper_rotation": True},
     "track.sleeper_surface = 'spheres': a sleeper of member spheres cannot rotate"),
    ({"sleeper_mass": "members"}, "track.sleeper_mass = 'members': needs sleeper_surface = 'spheres'"),
    ({"sleeper_surface": "spheres", "sleeper_member_radius": 0.0},
     "track.sleeper_member_radius = 0.0: must be a radius > 0 [m]"),
    ({"sleeper_surface": "spheres", "sleeper_member_radius": -0.005},
     "track.sleeper_member_radius = -0.005: must be a radius > 0 [m]"),
    ({"sleeper_surface": "spheres", "sleeper_member_radius": 0.06},
     "track.sleeper_member_radius = 0.06: at most a quarter of the sleeper body's smallest dimension (0.2 m / 4"),
    ({"sleeper_surface": "spheres", "sleeper_member_radius": 0.007},
     "track.sleeper_member_radius = 0.007: its lattice of [21, 186, 14] spheres"),
    ({"sleeper_surface": "spheres", "periodic": True}, "track.sleeper_surface = 'spheres': member sleepers with "
     "periodic ends are untested"),
    ({"sleeper_member_radius": 0.005},
     "track.sleeper_member_radius = 0.005: used only with sleeper_surface = 'spheres'"),
    ({"sleeper_surface": "bumpy"}, "track.sleeper_surface = 'bumpy': must be one of 'flat', 'spheres'"),
])
def test_bad_member_input_is_one_line(track, message):
    d = copy.deepcopy(DOC)
    d["track"].update(track)
    with pytest.raises(InputError) as err:
        track_settings(d)
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


@needs_mpiexec
def test_rotation_with_members_is_refused_by_the_check(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.replace("vibration_time = 0.05", 'vibration_time = 0.05\nsleeper_surface = "spheres"\n'
                                   "sleeper_member_radius = 0.0125\nsleeper_rotation = true"))
    r = run_pdem(1, scene, tmp_path / "out", "--check", expect=2)
    assert "track.sleeper_surface = 'spheres': a sleeper of member spheres cannot rotate" in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr


# ---------------------------------------------------------------------------- end to end
# the reduced track with the box test's calibrated options: no vibration, member sleepers of their own
# mass (r = 12.5 mm: 6 x 24 x 4 sites, 400 members per half-sleeper body), shorter settling; 1 kN axles
MEMBERS = SCENE.replace("vibration_time = 0.05", 'vibration_time = 0.0\nsleeper_surface = "spheres"\n'
                        'sleeper_member_radius = 0.0125\nsleeper_mass = "members"').replace(
    "settle_max_time = 0.5", "settle_max_time = 0.3").replace("axle_load = 2000.0", "axle_load = 1000.0")
PREPARE = MEMBERS.split("[traffic]")[0]


@needs_mpiexec
@pytest.mark.slow
def test_member_sleepers_give_the_same_bits_on_1_and_2_ranks(tmp_path):
    """slow: the reduced track with member sleepers prepared on 1 rank, its traffic on 1 and 2 ranks."""
    assert MEMBERS.count('sleeper_surface = "spheres"') == 1 and "axle_load = 1000.0" in MEMBERS
    scene, r1, r2 = prepared_runs(tmp_path, PREPARE,
                                  lambda bed: MEMBERS.replace('program = "axles"',
                                                              f'program = "axles"\nprepared = "{bed}"'))
    assert "starting from the prepared bed" in r1.stdout
    assert_same_results(tmp_path / "r1" / "results.h5", tmp_path / "r2" / "results.h5", "1 and 2 ranks")
    # the body: 400 members of concrete plus the rail over one spacing
    mass = (6 * 24 * 4 - 4 * 22 * 2) * 4.0 / 3.0 * math.pi * 0.0125 ** 3 * 2600.0 + 60.21 * 0.3
    assert f"sleeper body {mass:.1f} kg" in (tmp_path / "r1" / "summary.txt").read_text()
    p = read_track(tmp_path / "r1" / "results.h5").passages
    assert np.all(p["settlement_peak"] > 0) and np.all(p["settlement_peak"] >= p["settlement_permanent"])
