"""The box test's options (issue 14, docs/box_test.md "Options"): piece by piece without running a
box test, then end to end.

Pieces: per-cycle records from one zero, the bottom/side force split, friction changed for new
contacts only (Yade), the cut by centre, the sleeper lowered onto the cut, the half-sine program,
the two-sided base and the one-line errors of every option key.

End to end (slow), short: a ~200-sphere box test run with pdem's defaults and with the options
the thesis's Yade scripts suggest, on 1 and 2 ranks (the same bits), resumed on 3 ranks in the
middle of the vibration (the same bits), and each option's effect visible in the records.

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
from math import pi, sin, tan
from pathlib import Path

import numpy as np
import pytest
import tomllib

from pdem_cli import needs_mpiexec, run_pdem
from run_files import datasets
from factories import BOX_MATERIALS
from pdem.scenes.cycles import CycleRecorder
from pdem.driver.observables import box_face_forces
from pdem.errors import InputError
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.boundaries.loads import HalfSine, Haversine
from pdem.build.scene import Scene
from pdem.scenes.box_test import DEFAULTS, box_settings, check, cut, sleeper_geometry, sleeper_members, sleeper_on_top


# ---------------------------------------------------------------------------- records
def test_cycle_records_settlement_at_largest_force_largest_settlement_and_split_at_peak():
    rec = CycleRecorder(Haversine(0.0, 10.0, 1.0, 2))
    # cycle 0: the force peaks at t = 0.4 (before the load peak at 0.5), the settlement at t = 0.6
    samples = [(0.0, 0.0, 1.0), (0.2, 1.0, 5.0), (0.4, 2.0, 9.0), (0.5, 3.0, 8.0), (0.6, 4.0, 7.0),
               (0.8, 2.5, 2.0), (1.0, 2.0, 0.0), (1.5, 6.0, 9.5), (2.0, 5.0, 0.0)]
    peaks = []
    for t, s, f in samples:
        split = {"force_bottom": 10 * t, "force_side": -t} if rec.at_peak(t) else None
        if split:
            peaks.append(t)
        rec.sample(t, s, f, split=split)
    assert peaks == [0.5, 1.5]
    tab = rec.table()
    assert list(tab["settlement_at_force_max"]) == [2.0, 6.0]
    assert list(tab["settlement_max"]) == [4.0, 6.0]
    assert list(tab["settlement_peak"]) == [3.0, 6.0] and list(tab["settlement_end"]) == [2.0, 5.0]
    assert list(tab["force_bottom_peak"]) == [5.0, 15.0] and list(tab["force_side_peak"]) == [-0.5, -1.5]


def test_cycle_recorder_restores_a_checkpoint_written_before_the_new_fields():
    rec = CycleRecorder(Haversine(0.0, 10.0, 1.0, 3))
    for t, s in ((0.0, 0.0), (0.5, 1.0), (1.0, 0.5), (1.2, 0.7)):
        rec.sample(t, s, 1.0)
    old = rec.state()
    for r in old["records"] + [old["open"]]:
        for k in ("settlement_at_force_max", "settlement_max"):
            r.pop(k)
    back = CycleRecorder(Haversine(0.0, 10.0, 1.0, 3)).restore(old)
    back.sample(2.0, 0.9, 1.0)
    tab = back.table()
    assert np.isnan(tab["settlement_max"]).all() and list(tab["settlement_end"]) == [0.5, 0.9]


@pytest.mark.parametrize("direction", [(0.0, 0.0, -1.0), (0.0, 1.0, 0.0), (0.6, 0.0, -0.8)])
def test_cycle_recorder_reads_a_box_as_the_dot_products_along_its_direction(direction):
    """sample_box's shortcut for an axis-aligned load direction gives, bit for bit, the values
    of the dot products it replaces (the general ones for any other direction)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(7)
    d = np.array(direction)
    rec = CycleRecorder(Haversine(0.0, 10.0, 1.0, 3))
    got = []
    rec.sample = lambda t, s, f, load, split: got.append((s, f, load))
    ref = None
    for t in np.linspace(0.0, 3.0, 50):
        bx = SimpleNamespace(direction=d[None], center=rng.normal(size=(1, 3)),
                             contact_force=rng.normal(size=(1, 3)) * 1e4, load_force=rng.normal(size=(1, 3)) * 1e4)
        ref = bx.center[0].copy() if ref is None else ref
        rec.sample_box(SimpleNamespace(boxes=bx, time=t))
        want = (float((bx.center[0] - ref) @ d), float(-(bx.contact_force[0] @ d)), float(bx.load_force[0] @ d))
        assert got[-1] == want


def test_half_sine_peaks_where_the_haversine_does_and_is_steeper_at_the_ends():
    h, s = Haversine(1.0, 11.0, 2.0, 3, start=0.5), HalfSine(1.0, 11.0, 2.0, 3, start=0.5)
    for k in range(3):
        t_peak = 0.5 + (k + 0.5) / 2.0
        assert h.value(t_peak) == pytest.approx(11.0) and s.value(t_peak) == pytest.approx(11.0)
        t = 0.5 + k / 2.0 + 0.05
        assert s.value(t) == pytest.approx(1.0 + 10.0 * sin(pi * 2.0 * 0.05)) and s.value(t) > h.value(t)
    assert s.value(0.4) == s.value(2.1) == 1.0 and s.spec()["type"] == "half_sine"


def test_face_forces_split_the_sleeper_force_into_bottom_and_sides():
    scene = Scene(dt=1e-5, damping=0.3, gravity=(0, 0, -9.81), allow_initial_overlap=True)
    m = scene.material(density=2600, young=1e7, poisson=0.3, friction_angle=0.5)
    # the box spans z in [0.1, 0.2], x in [-0.05, 0.05]: two spheres under it, one pressed on each side
    scene.add_box((0.0, 0.0, 0.15), (0.05, 0.05, 0.05), m, 2.0, blocked="xyXYZ")
    scene.add_spheres([(0.0, 0.0, 0.091), (0.03, 0.0, 0.092), (-0.059, 0.0, 0.15), (0.0595, 0.0, 0.16)], 0.01, m)
    sim = scene.build()
    sim.run(1)
    bottom, side = box_face_forces(sim, 0)
    total = sim.boxes.contact_force[0]
    assert bottom[2] > 0 and abs(side[0]) > 0 and bottom[0] == 0.0
    assert np.allclose(bottom + side, total, rtol=1e-14, atol=0.0)
    # the left sphere overlaps the box by 1 mm, the right one by 0.5 mm: the sides push it to +x
    assert side[0] > 0 and side[2] == 0.0


# ---------------------------------------------------------------------------- friction as Yade
def _friction_scene():
    scene = Scene(dt=1e-5, damping=0.3, gravity=(0, 0, -9.81), allow_initial_overlap=True)
    a = scene.material(density=2600, young=1e7, poisson=0.3, friction_angle=0.5)
    scene.add_spheres([(0, 0, 0.0095), (0.019, 0, 0.0095)], 0.01, a, fixed=True)  # a pair in contact, held
    # a third sphere falling onto the pair: its contacts are made later
    scene.add_spheres([(0.0095, 0.0, 0.0300)], 0.01, a)
    return scene.build()


def _tan(sim, kind="sphere_sphere"):
    c = sim.contacts(kind)
    return {tuple(int(g) for g in key): t for key, t in zip(zip(c["gid1"], c.get("gid2", c.get("index"))),
                                                            c["tan_phi"])}


def test_friction_for_new_contacts_only_keeps_existing_contacts_tan_phi():
    sim = _friction_scene()
    sim.run(1)
    first = _tan(sim)
    assert first == {(0, 1): tan(0.5)}
    sim.set_friction_scale(0.1, existing=False)
    assert _tan(sim) == first  # existing contact unchanged
    for _ in range(400):  # the third sphere lands on the pair
        sim.run(10)
        if len(_tan(sim)) == 3:
            break
    now = _tan(sim)
    assert now[(0, 1)] == tan(0.5) and now[(0, 2)] == tan(0.05) and now[(1, 2)] == tan(0.05)
    sim.set_friction_scale(1.0, existing=False)  # restoring: the reduced contacts keep theirs too
    assert _tan(sim) == now
    # the default ("all") changes every contact
    sim.set_friction_scale(1.0)
    assert set(_tan(sim).values()) == {tan(0.5)}


# ---------------------------------------------------------------------------- cut and sleeper
def _tables(pos, r):
    pos = np.asarray(pos, float)
    return {"particles": {"gid": np.arange(len(pos)), "pos": pos, "radius": np.full(len(pos), r)}}


def test_cut_by_centre_keeps_the_spheres_whose_centre_is_below():
    c = dict(DEFAULTS, cut="center")
    t = _tables([[0.1, 0.1, 0.28], [0.1, 0.1, 0.295], [0.1, 0.1, 0.305]], 0.01)
    kept, removed = cut(c, t, 0.30)
    assert removed == 1 and list(kept["particles"]["gid"]) == [0, 1]
    kept, removed = cut(dict(c, cut="top"), t, 0.30)
    assert removed == 2 and list(kept["particles"]["gid"]) == [0]


def test_sleeper_on_top_touches_the_highest_sphere_under_it_without_overlap():
    c = dict(DEFAULTS)  # sleeper 0.25 x 0.3 centred in the 0.7 x 0.3 box: x in [0.225, 0.475]
    t = _tables([[0.30, 0.15, 0.29], [0.20, 0.15, 0.31], [0.22, 0.15, 0.295], [0.6, 0.15, 0.4]], 0.01)
    bottom = sleeper_on_top(c, t)
    # the second sphere is 0.025 beyond the edge (never under it); the third 0.005 beyond: sqrt(r²-d²)
    assert bottom == pytest.approx(0.295 + np.sqrt(0.01**2 - 0.005**2))
    center, half = sleeper_geometry(c, bottom)
    assert center[2] - half[2] == pytest.approx(bottom)


# ---------------------------------------------------------------------------- settings
DOC = {"materials": {"ballast": {}, "steel": {}, "rubber": {}}, "box_test": {}}


@pytest.mark.parametrize("key, value, message", [
    ("cut", "middle", "box_test.cut = 'middle': must be one of 'top', 'center'"),
    ("sleeper_placement", "drop", "box_test.sleeper_placement = 'drop': must be one of 'cut', 'on_top'"),
    ("refill", "all", "box_test.refill = 'all': must be one of 'beside', 'whole'"),
    ("waveform", "sine", "box_test.waveform = 'sine': must be one of 'haversine', 'half_sine'"),
    ("base", 2, "box_test.base = 2: must be one of 'one_sided', 'two_sided'"),
    ("vibration_friction_contacts", "old", "box_test.vibration_friction_contacts = 'old': must be 'all'"),
    ("prep_stiffness_factor", 0.0, "box_test.prep_stiffness_factor = 0.0: must be in (0, 1]"),
    ("prep_stiffness_factor", 2.0, "box_test.prep_stiffness_factor = 2.0: must be in (0, 1]"),
    ("stiffen_time", -1.0, "box_test.stiffen_time = -1.0"),
    ("clumps", {"shape": "ballast8", "breakable": True}, "box_test.clumps.breakable: unknown key"),
    ("clumps", {"shape": "pebble"}, "box_test.clumps.shape = 'pebble': must be one of"),
])
def test_bad_option_one_line(key, value, message):
    with pytest.raises(InputError) as e:
        box_settings({**DOC, "box_test": {key: value}})
    assert message in str(e.value) and "\n" not in str(e.value)


def test_clump_ballast_refuses_the_centre_cut_and_keeps_the_grain():
    with pytest.raises(InputError, match="box_test.cut = 'center': cuts spheres, which would split the clumps"):
        box_settings({**DOC, "box_test": {"cut": "center", "sleeper_placement": "on_top",
                                          "clumps": {"shape": "ballast8"}}})
    g = box_settings({**DOC, "box_test": {"clumps": {"shape": "ballast8"}}})["grain"]
    assert len(g["member_radii"]) == 8 and np.all(g["member_radii"] == 0.0085) and g["mass_model"] == "members"
    assert box_settings(DOC)["grain"] is None


def test_defaults_are_pdem_s_choices():
    c = box_settings(DOC)
    assert (c["cut"], c["sleeper_placement"], c["refill"], c["waveform"], c["base"],
            c["vibration_friction_contacts"]) == ("top", "cut", "beside", "haversine", "one_sided", "all")


def test_clump_sleeper_geometry_has_the_thesis_count_mass_and_size():
    m = sleeper_members([0.25, 0.3, 0.15])
    assert len(m) == 2280  # thesis 5.2
    assert 2280 * 4 / 3 * pi * 0.005**3 * 7850 == pytest.approx(9.37, abs=0.005)
    lo, hi = m.min(axis=0) - 0.005, m.max(axis=0) + 0.005
    assert np.allclose(hi - lo, [0.25, 0.3, 0.15]) and np.allclose(lo + hi, 0.0)
    assert len(np.unique(np.round(m, 9), axis=0)) == 2280
    # a closed surface seen from below and from the x sides: every column under the footprint has a
    # bottom sphere, every (y, z) row a sphere at each x end
    bottom = m[np.isclose(m[:, 2], m[:, 2].min())]
    assert len(bottom) == 25 * 30
    assert len(m[np.isclose(m[:, 0], m[:, 0].min())]) == 30 * 15


def test_stiffening_needs_the_linear_law_and_the_full_stiffness_job_checks():
    with pytest.raises(InputError) as e:
        box_settings({**DOC, "simulation": {"law": "viscous"}, "box_test": {"prep_stiffness_factor": 0.1}})
    assert "needs simulation.law = 'linear'" in str(e.value) and "\n" not in str(e.value)
    doc = tomllib.loads((Path(__file__).parents[2] / "jobs" / "box_test_full_10.toml").read_text())
    check(doc)
    c = box_settings(doc)
    assert (c["prep_stiffness_factor"], c["cycles"], doc["materials"]["ballast"]["young"]) == (1e-4, 10, 2.8e11)


def test_the_calibrated_full_stiffness_job_uses_the_checks_option_set():
    """jobs/box_test_full_calibrated.toml = jobs/box_test_full_10.toml prepared with the option set
    of jobs/campaigns/box_checks.toml (the calibration's choice) and the stiffen stage cut to 0.1 s
    (its error against the 3 s stage measured by jobs/campaigns/box_full_stiffen_error.toml,
    docs/box_test.md "The stiffen stage's length")."""
    jobs = Path(__file__).parents[2] / "jobs"
    doc = tomllib.loads((jobs / "box_test_full_calibrated.toml").read_text())
    full = tomllib.loads((jobs / "box_test_full_10.toml").read_text())
    chosen = {k: v for k, v in tomllib.loads((jobs / "campaigns" / "box_checks.toml").read_text())["set"].items()
              if k.startswith("box_test.")}
    check(doc)
    assert chosen and all(doc["box_test"][k.split(".", 1)[1]] == v for k, v in chosen.items())
    different = {k for k in set(doc["box_test"]) | set(full["box_test"])
                 if doc["box_test"].get(k) != full["box_test"].get(k)}
    assert different == {k.split(".", 1)[1] for k in chosen} | {"stiffen_settle_max_time"}
    assert doc["box_test"]["stiffen_settle_max_time"] == 0.1
    assert {k: v for k, v in doc.items() if k != "box_test"} == {k: v for k, v in full.items() if k != "box_test"}
    assert box_settings(doc)["sleeper_mass"] < 10.0  # Yade's member mass, 9.37 kg


# ---------------------------------------------------------------------------- end to end
# slow: 3 short box tests on 1 rank, 2 on 2 ranks and a resume on 3 (4-8 min on a loaded 2-core machine)
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


def assert_same(a, b):
    for name in ("results.h5", "preparation.h5"):
        x, y = datasets(a / name), datasets(b / name)
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
    return {k[len("cycles/"):]: v for k, v in datasets(d / "results.h5").items() if k.startswith("cycles/")}


def series(d, name="results.h5"):
    return {k[len("series/"):]: v for k, v in datasets(d / name).items() if k.startswith("series/")}


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
@needs_mpiexec
@pytest.mark.parametrize("name", ["yade", "overlap", "stiffen", "clumps", "clump_sleeper"])
def test_same_bits_on_2_ranks(runs, tmp_path, name):
    d, _, scene = runs[name]
    run_pdem(2, scene, tmp_path / "r2")
    assert_same(d, tmp_path / "r2")


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
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
