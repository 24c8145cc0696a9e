"""The box test's options (issue 14, docs/box_test.md "Options") piece by piece, without running a
box test: per-cycle records from one zero, the bottom/side force split, friction changed for new
contacts only (Yade), the cut by centre, the sleeper lowered onto the cut, the half-sine program,
the two-sided base and the one-line errors of every option key."""
from math import pi, sin, tan
from pathlib import Path

import numpy as np
import pytest
import tomllib

from pdem.scenes.cycles import CycleRecorder
from pdem.driver.observables import box_face_forces
from pdem.errors import InputError
from pdem.loads import HalfSine, Haversine
from pdem.scene import Scene
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
    of jobs/campaigns/box_checks.toml (the calibration's choice)."""
    jobs = Path(__file__).parents[2] / "jobs"
    doc = tomllib.loads((jobs / "box_test_full_calibrated.toml").read_text())
    full = tomllib.loads((jobs / "box_test_full_10.toml").read_text())
    chosen = {k: v for k, v in tomllib.loads((jobs / "campaigns" / "box_checks.toml").read_text())["set"].items()
              if k.startswith("box_test.")}
    check(doc)
    assert chosen and all(doc["box_test"][k.split(".", 1)[1]] == v for k, v in chosen.items())
    different = {k for k in set(doc["box_test"]) | set(full["box_test"])
                 if doc["box_test"].get(k) != full["box_test"].get(k)}
    assert different == {k.split(".", 1)[1] for k in chosen}
    assert {k: v for k, v in doc.items() if k != "box_test"} == {k: v for k, v in full.items() if k != "box_test"}
    assert box_settings(doc)["sleeper_mass"] < 10.0  # Yade's member mass, 9.37 kg
