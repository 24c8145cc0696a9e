"""The box test's options (docs/box_test.md "Options") end to end, short: a ~200-sphere box test
run with pdem's defaults and with the options the thesis's Yade scripts suggest, on 1 and 2
ranks (the same bits), resumed on 3 ranks in the middle of the vibration (the same bits), and
each option's effect visible in the records.

Option sets (each a few seconds per run):
- ``yade``: friction lowered for new contacts only, cut by centre with the sleeper lowered onto
  what the cut leaves, refill over the whole box, half-sine load, two-sided base on a very soft
  rubber (grains pass through and are counted);
- ``overlap``: cut by centre with the sleeper at the cut (its initial overlaps loaded at once,
  as Yade; a soft sleeper and max_overlap_ratio = 1), vibration off;
- ``stiffen``: every material 10 times stiffer, prepared at 0.1 of it and stiffened in 0.05 s
  before loading: after the stiffen stage every contact's k_n and k_s are the ones Ip2 gives at
  the full stiffness (within rounding), and a resume in the middle of it gives the same bits;
- ``clumps``: ballast of rigid 8-sphere clumps (member r = 6 mm) on a stiffer base: every cut
  removes whole clumps;
- ``clump_sleeper``: the sleeper as the thesis's clump of steel spheres (r = 5 mm: 240 here) with
  the mass Yade sums from them.
"""
import shutil

import h5py
import numpy as np
import pytest

from pdem_cli import needs_mpiexec, run_pdem
from scene_text import BOX_MATERIALS
from pdem.io.checkpoint import list_checkpoints, read_checkpoint

# slow: 3 short box tests on 1 rank, 2 on 2 ranks and a resume on 3 (4-8 min on a loaded 2-core machine)
pytestmark = pytest.mark.slow

SCENE = """[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]
slab_axis = "x"

[run]
progress_every = 0
output_every = 10
snapshot_every = 0
checkpoint_keep = 0

""" + BOX_MATERIALS + """
[box_test]
box = [0.24, 0.1, 0.2]
radius = 0.0125
radius_spread = 0.3
seed = 3
cut_height = 0.1
height = 0.16
sleeper_size = [0.08, 0.1, 0.06]
sleeper_mass = 2.0
settle_min_time = 0.05
settle_max_time = 1.0
vibration_time = 0.05
f_min = 0.0
f_max = 50.0
frequency = 10.0
cycles = 2
"""
OPTIONS = {
    "default": "",
    "yade": """vibration_friction_contacts = "new"
cut = "center"
sleeper_placement = "on_top"
refill = "whole"
waveform = "half_sine"
base = "two_sided"
""",
    "overlap": """cut = "center"
""",
    "stiffen": """prep_stiffness_factor = 0.1
stiffen_time = 0.05
""",
    "clump_sleeper": """sleeper_surface = "spheres"
sleeper_member_radius = 0.005
""",
    "clumps": """
[box_test.clumps]
shape = "ballast8"
member_radius = 0.006
""",
}

def scene_text(name):
    text = SCENE + OPTIONS[name]
    if name == "yade":  # a base so soft that the sleeper pushes grains through it; checkpoints inside the stages
        text = text.replace("young = 2.8e5", "young = 2.0e4").replace("checkpoint_keep = 0",
                                                                      "checkpoint_keep = 0\ncheckpoint_every = 100")
    if name == "overlap":  # vibration off; a soft sleeper, so that its initial overlaps do not shoot spheres away
        text = text.replace("vibration_time = 0.05", "vibration_time = 0.0").replace("young = 2.8e7", "young = 2.8e5")
        text = text.replace('slab_axis = "x"', 'slab_axis = "x"\nmax_overlap_ratio = 1.0')
    if name == "stiffen":  # 10 times the stiffness, prepared at the usual one; checkpoints inside the stages
        for soft, stiff in (("2.8e7", "2.8e8"), ("2.8e6", "2.8e7"), ("2.8e5", "2.8e6")):  # steel, ballast, rubber
            text = text.replace(f"young = {soft}", f"young = {stiff}")
        text = text.replace("checkpoint_keep = 0", "checkpoint_keep = 0\ncheckpoint_every = 200")
    if name == "clump_sleeper":  # the mass Yade sums from the members
        text = text.replace("sleeper_mass = 2.0", 'sleeper_mass = "members"')
    if name == "clumps":  # small members sink into the soft base under the load: a 10 times stiffer base
        text = text.replace("young = 2.8e5", "young = 2.8e6")
    return text


def h5(path):
    with h5py.File(path, "r") as f:
        out = {}
        f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None)
        return out


def assert_same(a, b):
    for name in ("results.h5", "preparation.h5"):
        x, y = h5(a / name), h5(b / name)
        assert sorted(x) == sorted(y), name
        for k in x:
            assert np.array_equal(x[k], y[k], equal_nan=True), f"{b}/{name}:{k} differs"
    last = lambda d: read_checkpoint(list_checkpoints(d / "checkpoints")[-1][1])[0]  # noqa: E731
    ta, tb = last(a), last(b)
    for c in ta["particles"]:
        assert np.array_equal(ta["particles"][c], tb["particles"][c]), f"{b}: particles/{c}"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """name -> (run directory on 1 rank, its stdout)."""
    base = tmp_path_factory.mktemp("box_options")
    out = {}
    for name in OPTIONS:
        scene = base / f"{name}.toml"
        scene.write_text(scene_text(name))
        out[name] = (base / name, run_pdem(1, scene, base / name).stdout, scene)
    return out


def cycles(d):
    return {k[len("cycles/"):]: v for k, v in h5(d / "results.h5").items() if k.startswith("cycles/")}


def series(d, name="results.h5"):
    return {k[len("series/"):]: v for k, v in h5(d / name).items() if k.startswith("series/")}


def test_records_split_the_force_and_share_one_zero(runs):
    for name, (d, _, _) in runs.items():
        c, s = cycles(d), series(d)
        # the bottom face carries most of the load, the sides the rest; together the ballast force
        assert np.all(c["force_bottom_peak"] > c["force_side_peak"]), name
        assert np.allclose(s["sleeper_force_bottom"] + s["sleeper_force_side"], s["sleeper_force"], rtol=1e-12,
                           atol=1e-9), name
        # one zero: the largest settlement bounds the others of its cycle
        for k in ("settlement_peak", "settlement_start", "settlement_at_force_max"):
            assert np.all(c["settlement_max"] >= c[k]), (name, k)
        assert c["settlement_start"][0] == pytest.approx(0.0, abs=1e-6)


def test_each_option_shows_in_the_run(runs):
    d, out, _ = runs["yade"]
    assert "spheres over the whole box" in out
    c, s = cycles(d), series(d)
    assert s["base_passed"].max() > 0 and c["base_passed_end"][-1] > 0, "no grain passed the two-sided base"
    # the half-sine program (the load of a row is the one of the step's start, t - dt; dt may change between
    # rows, so within 0.1 N), far from the haversine
    t, load, start = s["time"][1:] - s["dt"][1:], s["sleeper_load"][1:], c["t_start"][0]
    phase = np.pi * 10.0 * np.maximum(t - start, 0.0)
    assert np.abs(load - 50.0 * np.abs(np.sin(phase))).max() < 0.1
    assert np.abs(load - 50.0 * (1 - np.cos(2 * phase)) / 2).max() > 5.0
    d0, out0, _ = runs["default"]
    assert "beside it" in out0 and series(d0)["base_passed"].max() == 0
    # cut by centre: spheres stick out of the cut, so the sleeper lowered onto them sits above it
    assert bottom_of(out) > 0.1
    # ... and placed at the cut it starts overlapping them; vibration off: the vibrate stage takes no step
    d1, out1, _ = runs["overlap"]
    assert bottom_of(out1) == 0.1
    prep = series(d1, "preparation.h5")
    t_vib = prep["time"][prep["stage"] == 2]
    assert len(t_vib) and t_vib.max() == t_vib.min(), "vibration_time = 0 still vibrated"


def bottom_of(stdout):
    line = next(s for s in stdout.splitlines() if "placed the sleeper (bottom" in s)
    return float(line.split("(bottom ")[1].split(" m")[0])


@needs_mpiexec
@pytest.mark.parametrize("name", ["yade", "overlap", "stiffen", "clumps", "clump_sleeper"])
def test_same_bits_on_2_ranks(runs, tmp_path, name):
    d, _, scene = runs[name]
    run_pdem(2, scene, tmp_path / "r2")
    assert_same(d, tmp_path / "r2")


def test_clump_ballast_is_cut_by_whole_clumps(runs):
    d, out, _ = runs["clumps"]
    tables = read_checkpoint(list_checkpoints(d / "checkpoints")[-1][1])[0]
    clump = tables["particles"]["clump"]
    ids, members = np.unique(clump, return_counts=True)
    assert len(ids) > 50 and np.all(ids >= 0) and np.all(members == 8)
    assert sorted(tables["clumps"]["id"].tolist()) == ids.tolist()
    assert len(cycles(d)["cycle"]) == 2


def step_of(stdout, text):
    return int(next(s for s in stdout.splitlines() if text in s).split(":")[0].split()[1])


def test_stiffened_contacts_have_the_full_stiffness(runs):
    """Linear law (YADE_MODEL.md §4): k_n = 2 E r_i r_j/(r_i + r_j), k_s = ν k_n for two ballast
    spheres (E = 2.8e7 Pa, ν = 0.3); the contacts made at 0.1 of it and stiffened agree."""
    d, out, _ = runs["stiffen"]
    assert "stages pour, refill, vibrate, settle, stiffen, load" in out
    end = step_of(out, "(end of stage stiffen")
    tables = read_checkpoint(dict(list_checkpoints(d / "checkpoints"))[end])[0]
    radius = dict(zip(tables["particles"]["gid"].tolist(), tables["particles"]["radius"].tolist()))
    c = tables["contacts/sphere_sphere"]
    ri = np.array([radius[g] for g in (c["key"] >> 32).tolist()])
    rj = np.array([radius[g] for g in (c["key"] & 0xFFFFFFFF).tolist()])
    kn = 2 * 2.8e7 * ri * rj / (ri + rj)
    assert len(kn) > 100
    assert np.allclose(c["params"][:, 0], kn, rtol=1e-13, atol=0) and np.allclose(c["params"][:, 1], 0.3 * kn,
                                                                                  rtol=1e-13, atol=0)
    prep = series(d, "preparation.h5")
    assert prep["stage"].max() == 4  # a preparation row of the stiffen stage


@needs_mpiexec
@pytest.mark.parametrize("name, stage, before", [("yade", "vibrate", "refill"), ("stiffen", "stiffen", "settle")])
def test_resume_in_the_middle_of_a_stage_on_3_ranks(runs, tmp_path, name, stage, before):
    """With friction lowered for new contacts only, a resume inside the vibrate stage must keep the
    tan φ every contact had (carried in the checkpoint) and lower it only for new ones; inside the
    stiffen stage, the stiffness scale reached and every contact's stiffness."""
    d, out, scene = runs[name]
    start, end = step_of(out, f"(end of stage {before}"), step_of(out, f"(end of stage {stage}")
    mid = next(s for s, _ in list_checkpoints(d / "checkpoints") if start < s < end)
    res = tmp_path / "resumed"
    shutil.copytree(d, res)
    for s, p in list_checkpoints(res / "checkpoints"):
        if s > mid:
            p.unlink()
    r = run_pdem(3, scene, res)
    assert f"at step {mid} (stage {stage}" in r.stdout and f"stage {stage} (resumed)" in r.stdout
    assert_same(d, res)


def test_clump_sleeper_stands_on_its_member_spheres(runs):
    """The sleeper of 240 member spheres (2·8·10 + 2·10·4) weighs what Yade sums from them and
    touches the ballast only through them; it settles under the load like the flat one."""
    d, out, _ = runs["clump_sleeper"]
    tables = read_checkpoint(list_checkpoints(d / "checkpoints")[-1][1])[0]
    assert "contacts/sphere_box" not in tables
    assert len(tables["contacts/sphere_member"]["key"]) > 0  # (unloaded at the end: a few)
    mass = 240 * 4.0 / 3.0 * np.pi * 0.005 ** 3 * 7850.0
    assert f"{mass:.4g} kg, 240 member spheres" in out
    c = cycles(d)
    assert np.all(c["force_bottom_peak"] > 0.5 * 50.0) and c["settlement_max"][-1] > 0.0
