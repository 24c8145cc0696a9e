"""The oedometer (`pdem.scenes.oedometer`, SPEC 2.2): input errors, the reduced breakable-clump
oedometer of jobs/oedometer_ci.toml end to end through the command line, and its resume.

End to end: every stage runs; the platen's applied load is the program 250 N → F_max → 250 N
(here scaled: f_min → f_max → f_min, a haversine of one period) at every sample; the ballast
carries the platen (mean ballast force over the load stage = mean load + platen weight, the
platen's momentum balance); the fragment records "initial", "vibrated", "peak", "unloaded"
hold the same mass (bonds break, mass stays), the initial one has only intact grains and the
peak one has broken grains; the grading and stiffness analysis is written. A run resumed from
the checkpoint at the end of a stage ends with the same bits (series, fragments, bodies). The
overlap statistics of the load record (issue #32) are the bodies' overlaps of the checkpoint at
the end of the load, and `python -m analysis oedometer-overlap` gives what a hand computation
from the results file gives.
"""
import json
import math
import shutil

import h5py
import numpy as np
import pytest
from factories import OEDOMETER_CI_JOB, oedometer_ci_doc, toml_text
from run_files import run_differences

from pdem.format.groups import read_fragments
from pdem.errors import InputError
from pdem.io.checkpoint import list_checkpoints
from pdem.scenes import oedometer
from pdem_cli import run_pdem


# ---------------------------------------------------------------------------- input errors
@pytest.mark.parametrize("change, field", [
    ({"diameter": -0.3}, "oedometer.diameter"),
    ({"facets": 3}, "oedometer.facets"),
    ({"f_max": 0.1}, "oedometer.f_max"),
    ({"load_time": "fast"}, "oedometer.load_time"),
    ({"wall_material": "glass"}, "oedometer.wall_material"),
    ({"heigth": 0.15}, "oedometer.heigth"),
    ({"clumps": {"shape": "cube"}}, "oedometer.clumps.shape"),
    ({"clumps": {"shape": "ellipsoid", "radii": [0.01, 0.01, 0.01], "member_radius": 0.003, "count": 5}},
     "oedometer.clumps.count"),
    ({"clumps": {"shape": "nottingham", "breakable": "yes"}}, "oedometer.clumps.breakable"),
    ({"radius_spread": 1.0}, "oedometer.radius_spread"),
    ({"clumps": {"shape": "nottingham", "mass_model": "exact"}}, "oedometer.clumps.mass_model"),
    ({"bond_boost": 0.0, "bond_boost_time": 0.01}, "oedometer.bond_boost"),
    ({"bond_boost": 10.0}, "oedometer.bond_boost_time"),
    ({"bond_boost": 10.0, "bond_boost_time": 0.01, "clumps": {"shape": "nottingham"}}, "oedometer.bond_boost"),
])
def test_input_errors_name_the_field(change, field):
    doc = oedometer_ci_doc(**change)
    with pytest.raises(InputError) as e:
        oedometer.check(doc)
    msg = str(e.value)
    assert field in msg and "\n" not in msg, msg


def test_breakable_needs_the_cohesive_law():
    doc = oedometer_ci_doc()
    doc["simulation"]["law"] = "linear"
    for m in doc["materials"].values():
        m.pop("normal_cohesion"), m.pop("shear_cohesion")
    with pytest.raises(InputError, match="oedometer.clumps.breakable.*cohesive"):
        oedometer.check(doc)


def test_grains_must_fit():
    with pytest.raises(InputError, match="oedometer.diameter"):
        oedometer.check(oedometer_ci_doc(diameter=0.012))
    doc = oedometer_ci_doc(diameter=0.03)
    del doc["oedometer"]["clumps"]
    with pytest.raises(InputError, match="oedometer.diameter"):
        oedometer.check(doc)


def test_steps_refused_through_the_cli(tmp_path):
    r = run_pdem(1, OEDOMETER_CI_JOB, tmp_path / "r", "--steps", "10", expect=2)
    assert "--steps" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_cylinder_geometry():
    """24 faces of two triangles each, vertices on the circle, closed around the axis."""
    tri = oedometer.ring_facets(0.15, 24, 0.0, 0.15)
    assert tri.shape == (48, 3, 3)
    assert np.allclose(np.hypot(tri[..., 0], tri[..., 1]), 0.15)
    assert set(np.round(tri[..., 2].ravel(), 12)) == {0.0, 0.15}
    c = oedometer.settings(oedometer_ci_doc())
    sites = oedometer.lattice_sites(c, 0.008, 0.0, 100.0, 1.0)
    assert len(sites) == 100 and np.all(np.hypot(sites[:, 0], sites[:, 1]) + 0.008 <= oedometer.inner_radius(c))


# ---------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def r1(tmp_path_factory):
    out = tmp_path_factory.mktemp("oedometer") / "r1"
    run_pdem(1, OEDOMETER_CI_JOB, out)
    return out


@pytest.mark.slow
def test_platen_follows_the_program(r1):
    """slow: a whole reduced oedometer through `pdem run` (~20 s on a loaded 2-core machine)."""
    c = oedometer.settings(oedometer_ci_doc())
    with h5py.File(r1 / "results.h5", "r") as f:
        assert f.attrs["kind"] == "oedometer"
        s = {k: f["series"][k][()] for k in f["series"]}
    t0, T = s["time"][0], c["load_time"]
    at = np.concatenate([[t0], (s["time"] - s["dt"])[1:]])  # the load of a step acts from its start
    expect = [c["f_min"] + (c["f_max"] - c["f_min"]) * (1 - math.cos(2 * math.pi * (t - t0) / T)) / 2
              if t0 < t < t0 + T else c["f_min"] for t in at]
    # within what a change of Δt between the step and its sample can shift (Δt is updated every
    # dt_interval steps; the series holds the new one): 20 % of Δt at the steepest slope
    slope = math.pi * (c["f_max"] - c["f_min"]) / T
    np.testing.assert_allclose(s["platen_load"], expect, rtol=0, atol=0.2 * slope * s["dt"].max())
    assert np.mean(np.isclose(s["platen_load"], expect, rtol=1e-12, atol=1e-9)) > 0.8
    assert s["time"][-1] >= t0 + T and abs(s["platen_load"].max() - c["f_max"]) < 1e-3 * c["f_max"]
    # the platen's momentum balance over the load: mean ballast force = mean load + weight
    weight = c["platen_mass"] * 9.81
    mean_force = np.trapezoid(s["platen_force"], s["time"]) / (s["time"][-1] - t0)
    mean_load = np.trapezoid(s["platen_load"], s["time"]) / (s["time"][-1] - t0)
    assert mean_force == pytest.approx(mean_load + weight, rel=0.1)
    assert s["platen_displacement"][0] == 0.0 and s["platen_displacement"].max() > 0
    # the largest overlap / radius: positive under load, below the stability guard's 0.5
    assert 0.0 < s["max_overlap_ratio"].min() and s["max_overlap_ratio"].max() < 0.5


@pytest.mark.slow
def test_fragments_and_grading(r1):
    """slow: uses the run of `test_platen_follows_the_program`."""
    fr = read_fragments(r1 / "results.h5")
    labels = [r.label for r in fr.records]
    assert labels == ["initial", "vibrated", "peak", "unloaded"]
    mass = [r.mass.sum() for r in fr.records]
    assert np.allclose(mass, mass[0], rtol=1e-12)
    n = oedometer.intact_members(oedometer.settings(oedometer_ci_doc()))
    initial, peak = fr.records[0], fr.records[2]
    assert np.all(initial.n_members == n)  # whole grains after the cut
    assert len(peak.n_members) > len(initial.n_members) and peak.n_members.min() == 1  # breakage at F_max
    text = (r1 / "analysis" / "grading.txt").read_text()
    assert "B_g" in text and "BBI" in text
    report = (r1 / "analysis" / "oedometer.txt").read_text()
    assert "unloading stiffness" in report
    for png in ("oedometer.png", "grading.png"):
        assert (r1 / "analysis" / png).stat().st_size > 1000
    assert (r1 / "preparation.png").exists() and "load" in (r1 / "summary.txt").read_text()


@pytest.mark.slow
def test_resume_after_a_stage_checkpoint(r1, tmp_path):
    """slow: reruns the stages after 'refill' of the reduced oedometer (~10 s)."""
    got = tmp_path / "resumed"
    shutil.copytree(r1, got)
    cks = list_checkpoints(got / "checkpoints")
    step = cks[1][0]  # end of stage refill
    for s, p in cks[2:]:
        p.unlink()
    with h5py.File(got / "results.h5", "a") as f:  # records written after the checkpoint must come back
        for label in list(f["fragments"]):
            if f["fragments"][label].attrs["step"] > step:
                del f["fragments"][label]
    shutil.rmtree(got / "analysis")
    r = run_pdem(1, OEDOMETER_CI_JOB, got)
    assert "resuming" in r.stdout
    assert run_differences(r1, got) == []


# ---------------------------------------------------------------------------- overlaps (issue #32)
def _closest_on_triangle(x, a, b, c):
    """The point of triangle abc closest to x (Ericson, Real-Time Collision Detection 5.1.5)."""
    ab, ac, ax = b - a, c - a, x - a
    d1, d2 = ab @ ax, ac @ ax
    if d1 <= 0 and d2 <= 0:
        return a
    d3, d4 = ab @ (x - b), ac @ (x - b)
    if d3 >= 0 and d4 <= d3:
        return b
    if d1 * d4 - d3 * d2 <= 0 and d1 >= 0 and d3 <= 0:
        return a + d1 / (d1 - d3) * ab
    d5, d6 = ab @ (x - c), ac @ (x - c)
    if d6 >= 0 and d5 <= d6:
        return c
    if d5 * d2 - d1 * d6 <= 0 and d2 >= 0 and d6 <= 0:
        return a + d2 / (d2 - d6) * ac
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    if va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)
    return a + ab * vb / (va + vb + vc) + ac * vc / (va + vb + vc)


def _overlaps_from_checkpoint(path, platen_half):
    """δ/r of every contact in compression of a checkpoint, by group, from the bodies' positions
    (not the contact store's overlaps): sphere pairs (bonded where the bond's adhesions are > 0),
    the base plane z = 0, the cylinder's facets and the platen's bottom face; and the intact bonds."""
    with h5py.File(path, "r") as f:
        t = f["tables"]
        gid, pos, rad = (t["particles"][k][()] for k in ("gid", "pos", "radius"))
        row = {int(g): k for k, g in enumerate(gid)}
        con = {k: (t["contacts"][k]["key"][()], t["contacts"][k]["history"][()]) for k in t["contacts"]}
        tri, fidx = t["facets"]["vertices"][()], list(t["facets"]["index"][()])
        bottom = float(t["boxes"]["center"][0, 2]) - platen_half
    key, hist = con["sphere_sphere"]
    i = np.array([row[int(g)] for g in key >> 32])
    j = np.array([row[int(g)] for g in key & ((1 << 32) - 1)])
    ratio = (rad[i] + rad[j] - np.linalg.norm(pos[i] - pos[j], axis=1)) / np.minimum(rad[i], rad[j])
    bonded = (hist[:, 4] > 0) | (hist[:, 5] > 0)  # cohesive law: a_N, a_T
    out = {"pair": ratio[~bonded & (ratio > 0)], "bond": ratio[bonded & (ratio > 0)], "bonds": int(bonded.sum())}
    wall = []
    for kind in ("sphere_wall", "sphere_facet", "sphere_box"):
        for g, b in zip(con[kind][0] >> 20, con[kind][0] & ((1 << 20) - 1)):
            x, r = pos[row[int(g)]], rad[row[int(g)]]
            d = (x[2] if kind == "sphere_wall" else bottom - x[2] if kind == "sphere_box"
                 else np.linalg.norm(x - _closest_on_triangle(x, *tri[fidx.index(b)])))
            wall.append((r - d) / r)
    out["boundary"] = np.array([w for w in wall if w > 0])
    return out


@pytest.mark.slow
def test_overlap_statistics_are_the_bodies_overlaps(r1):
    """slow: uses the run of `test_platen_follows_the_program`. The load record's overlap statistics
    at its last row (the end of the load stage) against the same figures computed from the bodies'
    positions in the checkpoint written there (one step's motion apart: 1e-4 of the radius); the
    largest of the three groups is the guard's max_overlap_ratio at every row; the intact bonds
    at the start of the load are the grains' bonds counted from the grain's members (all whole,
    `test_fragments_and_grading`), and they only decrease."""
    c = oedometer.settings(oedometer_ci_doc())
    with h5py.File(r1 / "results.h5", "r") as f:
        s = {k: f["series"][k][()] for k in f["series"]}
        n_grains = len(f["fragments"]["vibrated"]["n_members"][()])
    step, ckpt = list_checkpoints(r1 / "checkpoints")[-1]
    assert s["step"][-1] == step
    got = _overlaps_from_checkpoint(ckpt, 0.5 * c["platen_thickness"])
    for g in ("pair", "bond", "boundary"):
        assert len(got[g]) > 0
        assert s[f"{g}_overlap_max"][-1] == pytest.approx(got[g].max(), abs=1e-4), g
        assert s[f"{g}_overlap_mean"][-1] == pytest.approx(got[g].mean(), rel=0.02, abs=1e-5), g
    assert s["intact_bonds"][-1] == got["bonds"]
    largest = np.max([s[f"{g}_overlap_max"] for g in ("pair", "bond", "boundary")], axis=0)
    assert np.array_equal(largest, s["max_overlap_ratio"])
    m = c["grain"]["members"]
    d = np.linalg.norm(m[:, None] - m[None], axis=2)
    touching = np.triu(d <= (c["grain"]["member_radii"][:, None] + c["grain"]["member_radii"][None]) * (1 + 1e-9), 1)
    assert s["intact_bonds"][0] == n_grains * int(touching.sum())
    assert np.all(np.diff(s["intact_bonds"]) <= 0) and s["intact_bonds"][-1] < s["intact_bonds"][0]


@pytest.mark.slow
def test_overlap_analysis_against_hand_computation(r1, tmp_path):
    """slow: `python -m analysis oedometer-overlap` on the run of `test_platen_follows_the_program`
    against the same figures computed here from the file: the bonds broken while the largest
    overlap exceeded θ (a plain loop over the samples), the grading by mass and by number of the
    "unloaded" record, the overlaps at the peak load."""
    from analysis.__main__ import main

    assert main(["oedometer-overlap", str(r1), "--out", str(tmp_path), "--threshold", "0.05", "0.1"]) == 0
    got = json.loads((tmp_path / "overlap.json").read_text())["runs"][str(r1)]
    assert (tmp_path / "overlap.png").stat().st_size > 1000
    assert "threshold 0.1 r" in (tmp_path / "overlap.txt").read_text()
    with h5py.File(r1 / "results.h5", "r") as f:
        s = {k: f["series"][k][()] for k in f["series"]}
        n, mass = (f["fragments"]["unloaded"][k][()] for k in ("n_members", "mass"))
    largest = s["max_overlap_ratio"]  # = the largest of the three groups (the test above)
    bonds = s["intact_bonds"]
    for th, entry in zip((0.05, 0.1), got["thresholds"]):
        before = above = total = 0.0
        for k in range(1, len(bonds)):
            lost = bonds[k - 1] - bonds[k]
            total += lost
            before += lost if largest[k - 1] > th else 0.0
            above += lost if largest[k - 1] > th or largest[k] > th else 0.0
        assert total > 0 and entry["share_above"] == pytest.approx(above / total, rel=1e-12)
        assert entry["share_before"] == pytest.approx(before / total, rel=1e-12)
        assert entry["first_load"] == s["platen_load"][np.argmax(largest > th)]
    assert got["bonds_broken"] == bonds[0] - bonds[-1]
    peak = int(np.argmax(s["platen_load"]))
    assert got["largest_at_peak"] == largest[peak]
    assert got["groups"]["pair"]["mean_at_peak"] == s["pair_overlap_mean"][peak]
    large = oedometer.intact_members(oedometer.settings(oedometer_ci_doc()))  # 8 < 135: the grain's size
    after = got["grading"]["after"]
    assert got["large"] == large and after["label"] == "unloaded"
    assert after["single_mass"] == pytest.approx(mass[n == 1].sum() / mass.sum(), rel=1e-12)
    assert after["large_mass"] == pytest.approx(mass[n >= large].sum() / mass.sum(), rel=1e-12)
    assert after["single_number"] == pytest.approx(np.count_nonzero(n == 1) / len(n), rel=1e-12)
    assert after["large_number"] == pytest.approx(np.count_nonzero(n >= large) / len(n), rel=1e-12)
    assert 0 < after["single_mass"] < 1 and got["grading"]["before"]["large_mass"] == 1.0


def test_bond_push_is_the_overlap_force_over_the_normal_strength():
    """k_n δ / a_N = E r (2r − s) / (c r²) for equal members r a grid spacing s apart."""
    doc = oedometer_ci_doc()
    doc["oedometer"]["clumps"].update(member_spacing=0.0057, stress_free=False)
    m, r = doc["materials"]["ballast"], 0.003
    expect = m["young"] * r * (2 * r - 0.0057) / (m["normal_cohesion"] * r * r)
    assert oedometer.bond_push(doc, oedometer.settings(doc)) == pytest.approx(expect, rel=1e-9)
    doc["oedometer"]["clumps"]["stress_free"] = True
    assert oedometer.bond_push(doc, oedometer.settings(doc)) == 0.0


@pytest.mark.slow
def test_bond_boost_holds_grains_made_on_overlaps(tmp_path):
    """slow (~20 s): the CI oedometer with Yade's loaded bonds made on an overlap that pushes with
    3.4 a_N (members 5.7 mm apart). Released at once every bond breaks (a warning says so); held
    at ten times their strength for the first 0.01 s of the pour (thesis 4.5), then returned,
    every grain is whole after the cut."""
    runs = {}
    for boost in (1.0, 10.0):
        doc = oedometer_ci_doc(bond_boost=boost, bond_boost_time=0.01)
        doc["oedometer"]["clumps"].update(member_spacing=0.0057, stress_free=False)
        scene = tmp_path / f"boost_{boost:g}.toml"
        scene.write_text(toml_text(doc))
        r = run_pdem(1, scene, tmp_path / scene.stem)
        runs[boost] = r.stdout, read_fragments(tmp_path / scene.stem / "results.h5").records[0]
    n = oedometer.intact_members(oedometer.settings(doc))
    out, initial = runs[1.0]
    assert "push with up to 3.43 a_N" in out and initial.label == "initial" and np.all(initial.n_members == 1)
    out, initial = runs[10.0]
    assert "bond strengths x 10 until t = 0.01 s" in out and "bond strengths returned at t = 0.01" in out
    assert "warning: the grains' bonds" not in out and np.all(initial.n_members == n)


def test_scene_file_round_trip(tmp_path):
    """The helper's TOML writer keeps the CI scene (the MPI test writes variants with it)."""
    import tomllib

    doc = oedometer_ci_doc(load_time=0.05)
    assert tomllib.loads(toml_text(doc)) == doc


def test_the_scaled_thesis_size_job_is_the_thesis_job_scaled():
    """jobs/oedometer_breakable_scaled.toml is jobs/oedometer_breakable.toml with every stiffness,
    cohesion and force × s = 1e-2 and the load time × 1/√s, nothing else in [materials] and
    [oedometer] changed; both pass the scene's checks."""
    import tomllib

    jobs = OEDOMETER_CI_JOB.parent
    thesis, scaled = (tomllib.loads((jobs / f"oedometer_breakable{suffix}.toml").read_text())
                      for suffix in ("", "_scaled"))
    s = 1e-2
    strengths = ("young", "normal_cohesion", "shear_cohesion")
    for name, m in thesis["materials"].items():
        for k in strengths:
            assert scaled["materials"][name][k] == pytest.approx(s * m[k], rel=1e-12)
        rest = {k: v for k, v in m.items() if k not in strengths}
        assert {k: scaled["materials"][name][k] for k in rest} == rest
    t, c = thesis["oedometer"], scaled["oedometer"]
    for k in ("f_min", "f_max"):
        assert c[k] == pytest.approx(s * t[k], rel=1e-12)
    assert c["load_time"] == pytest.approx(t["load_time"] / math.sqrt(s), rel=1e-12)
    scaled_keys = {"f_min", "f_max", "load_time"}
    assert {k: v for k, v in c.items() if k not in scaled_keys} == {k: v for k, v in t.items() if k not in scaled_keys}
    for doc in (thesis, scaled):
        assert oedometer.settings(doc)["grain"]["breakable"]


def test_the_small_member_job_is_the_scaled_job_with_the_spheres_of_table_4_15():
    """jobs/oedometer_breakable_scaled_small_members.toml is the scaled job with only the grain
    changed: the Ø48 mm grain filled with spheres of diameter 3.6 mm (thesis table 4.15) on the
    grid, "135 and more" of them; each bond a quarter of eq. 4.3's a_N (c r² with r = d/2)."""
    import tomllib

    jobs = OEDOMETER_CI_JOB.parent
    scaled, small = (tomllib.loads((jobs / f"oedometer_breakable_scaled{suffix}.toml").read_text())
                     for suffix in ("", "_small_members"))
    members = oedometer.settings(small)["grain"]["members"]
    grain = small["oedometer"].pop("clumps")
    assert scaled["oedometer"].pop("clumps") == {"shape": "nottingham", "breakable": True}
    assert small == scaled
    assert grain == {"shape": "ellipsoid", "radii": [0.024] * 3, "member_radius": 0.0036 / 2, "breakable": True}
    assert len(members) >= 135
    assert np.max(np.linalg.norm(members, axis=1)) + 0.0018 <= 0.024 * (1 + 1e-12)
    s, a_n = 1e-2, 2.1e3  # the scale, the Nottingham bond strength of eq. 4.3 [N]
    c = small["materials"]["ballast"]["normal_cohesion"]
    assert c * 0.0036**2 == pytest.approx(s * a_n, rel=1e-3)
    assert c * 0.0018**2 == pytest.approx(s * a_n / 4, rel=1e-3)


def test_the_thesis_grain_job_is_the_scaled_job_with_the_grain_and_preparation_of_4_5():
    """jobs/oedometer_breakable_scaled_thesis_grain.toml is the scaled job with the thesis's grain
    (r 3.6 mm members on a grid in the Ø48 mm grain, overlapping: 136 of them, "135 and more") bonded
    as Yade bonds (loaded by the overlap, which pushes with more than a_N, less than 10 a_N) and
    the tenfold strength of the pour's first steps; nothing else changed."""
    import tomllib

    jobs = OEDOMETER_CI_JOB.parent
    scaled, job = (tomllib.loads((jobs / f"oedometer_breakable_scaled{suffix}.toml").read_text())
                   for suffix in ("", "_thesis_grain"))
    oedometer.check(job)
    c = oedometer.settings(job)
    assert len(c["grain"]["members"]) == 136
    push = oedometer.bond_push(job, c)
    assert push > 1.0, push  # released at once, the bonds break
    assert push < c["bond_boost"], (push, c["bond_boost"])  # held at the boosted strength, they do not
    grain = job["oedometer"].pop("clumps")
    preparation = {k: job["oedometer"].pop(k) for k in ("bond_boost", "bond_boost_time", "lattice_gap")}
    assert scaled["oedometer"].pop("clumps") == {"shape": "nottingham", "breakable": True}
    assert job == scaled
    assert grain == {"shape": "ellipsoid", "radii": [0.024] * 3, "member_radius": 0.0036, "member_spacing": 0.0067,
                     "breakable": True, "stress_free": False}
    assert preparation == {"bond_boost": 10.0, "bond_boost_time": 0.05, "lattice_gap": 0.1}


def _campaign_docs(name):
    """{case: the scene of its seed-1 member} of jobs/campaigns/<name>.toml."""
    from pdem.campaign.spec import load_campaign

    camp = load_campaign(OEDOMETER_CI_JOB.parent / "campaigns" / f"{name}.toml", out="/nonexistent")
    return {m.params["case"]: m.doc for m in camp.members if m.params["oedometer.seed"] == 1}


def test_the_unscaled_thesis_grain_job_is_the_scaled_one_unscaled():
    """jobs/oedometer_breakable_thesis_grain.toml (the overlap study's base) is the scaled thesis-grain
    job with E_k, c and forces x 100 and the load's time / 10: table 4.15 (5.55e9 Pa, 162.04 MPa,
    250 N -> 1.5 MN) in 0.2 s; the preparation's times kept; the samples every 10x the steps."""
    import tomllib

    jobs = OEDOMETER_CI_JOB.parent
    scaled, full = (tomllib.loads((jobs / f"oedometer_breakable{suffix}.toml").read_text())
                    for suffix in ("_scaled_thesis_grain", "_thesis_grain"))
    oedometer.check(full)
    ballast, load = full["materials"]["ballast"], full["oedometer"]
    assert (ballast["young"], ballast["normal_cohesion"]) == (5.55e9, 162.04e6)
    assert (load["f_min"], load["f_max"], load["load_time"]) == (250.0, 1.5e6, 0.2)
    for name, m in scaled["materials"].items():
        for k in ("young", "normal_cohesion", "shear_cohesion"):
            assert full["materials"][name][k] == pytest.approx(100 * m[k], rel=1e-12)
            m[k] = full["materials"][name][k]
    for k in ("f_min", "f_max"):
        assert full["oedometer"][k] == pytest.approx(100 * scaled["oedometer"][k], rel=1e-12)
        scaled["oedometer"][k] = full["oedometer"][k]
    assert full["oedometer"]["load_time"] == pytest.approx(scaled["oedometer"]["load_time"] / 10, rel=1e-12)
    scaled["oedometer"]["load_time"] = full["oedometer"]["load_time"]
    assert full["run"]["output_every"] == 10 * scaled["run"]["output_every"]
    scaled["run"].update(output_every=full["run"]["output_every"], checkpoint_every_s=full["run"]["checkpoint_every_s"])
    assert full == scaled


def test_the_overlap_campaign_cases_differ_by_the_grains_preparation_and_the_modulus():
    """jobs/campaigns/validation_oedometer_overlap.toml: "thesis" is its base (the thesis's grain,
    Yade's bonds pushing 4.8 a_N, held tenfold); "thesis_expanded" the same grain as it is after
    that preparation (its 136 members 7.2 mm apart: positions x 7.2/6.7; touching, no push, no
    boost) poured on the same lattice sites; "identified" that with E_k = 5.55e11 Pa (thesis
    eq. 4.2, 100x) and steel 10 E_k. Nothing else differs."""
    docs = _campaign_docs("validation_oedometer_overlap")
    thesis, expanded, identified = docs["thesis"], docs["thesis_expanded"], docs["identified"]
    c0, c1 = oedometer.settings(thesis), oedometer.settings(expanded)
    assert len(c1["grain"]["members"]) == len(c0["grain"]["members"]) == 136
    np.testing.assert_allclose(np.sort(c1["grain"]["members"], axis=0),
                               np.sort(c0["grain"]["members"] * 7.2 / 6.7, axis=0), atol=1e-12)
    assert oedometer.bond_push(thesis, c0) > 1.0 and oedometer.bond_push(expanded, c1) < 1e-9
    s0 = np.array([g[0].mean(axis=0) for g in oedometer.grain_fill(c0, 1)])
    s1 = np.array([g[0].mean(axis=0) for g in oedometer.grain_fill(c1, 1)])
    assert s0.shape == s1.shape and np.abs(s0 - s1).max() < 1e-5  # the same pour, seed for seed
    assert [identified["materials"][m]["young"] for m in ("ballast", "steel")] == [5.55e11, 5.55e12]
    for m in ("ballast", "steel"):
        assert identified["materials"][m]["young"] == pytest.approx(100 * expanded["materials"][m]["young"], rel=1e-12)
        identified["materials"][m]["young"] = expanded["materials"][m]["young"]
    assert identified == expanded
    for k in ("clumps", "bond_boost", "lattice_gap"):
        expanded["oedometer"].pop(k), thesis["oedometer"].pop(k)
    assert expanded == thesis


def test_the_reduced_overlap_campaign_keeps_table_4_15_dimensionless():
    """jobs/campaigns/oedometer_overlap_reduced.toml: its base (jobs/oedometer_overlap_reduced.toml)
    has table 4.15's c/E_k and F_max/(E_k A) and the thesis's load in natural periods (0.2 s x
    1/sqrt(1e-3)); its case "identified" is 100x stiffer, loaded in the same natural periods
    (the load's time / 10), nothing else changed."""
    docs = _campaign_docs("oedometer_overlap_reduced")
    soft, stiff = docs["thesis_expanded"], docs["identified"]
    m, c = soft["materials"]["ballast"], soft["oedometer"]
    assert m["normal_cohesion"] / m["young"] == pytest.approx(162.04e6 / 5.55e9, rel=1e-12)
    area = math.pi * (c["diameter"] / 2) ** 2
    assert c["f_max"] / (m["young"] * area) == pytest.approx(1.5e6 / (5.55e9 * math.pi * 0.15**2), rel=1e-4)
    assert c["load_time"] == pytest.approx(0.2 / math.sqrt(1e-3), rel=1e-4)
    for name in ("ballast", "steel"):
        assert stiff["materials"][name]["young"] == pytest.approx(100 * soft["materials"][name]["young"], rel=1e-12)
        stiff["materials"][name]["young"] = soft["materials"][name]["young"]
    assert stiff["oedometer"]["load_time"] == pytest.approx(c["load_time"] / 10, rel=1e-4)
    stiff["oedometer"]["load_time"] = c["load_time"]
    assert stiff == soft
