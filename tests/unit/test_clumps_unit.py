"""Clump generators, mass models, fragments and the input checks of clumps and bonds."""
import math

import numpy as np
import pytest

import pdem
from pdem import Scene
from pdem.bodies.clump_generators import THESIS_SHAPES, ballast8, grain_cloud, nottingham_grain, shape_members
from pdem.bodies.clump_properties import clump_properties
from pdem.build.config import scene_from_dict
from pdem.bodies.fragments import label_fragments
from pdem.parallel.slab_domain import SlabDomain


# ---------------------------------------------------------------------------- generators
def pair_distances(pos):
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    return d[np.triu_indices(len(pos), 1)]


def test_nottingham_grain():
    """135 spheres of Ø7.1 mm in FCC close packing: each touches its neighbours, none overlaps,
    every member touches at least 3 others, and the grain fits in Ø48 mm."""
    pos, r = nottingham_grain()
    assert len(pos) == 135 and np.all(r == 0.00355)
    d = pair_distances(pos)
    assert d.min() == pytest.approx(0.0071, rel=1e-12)
    touching = np.abs(np.linalg.norm(pos[:, None] - pos[None], axis=2) - 0.0071) < 1e-12
    assert touching.sum(axis=1).min() >= 3
    assert np.abs(pos.mean(axis=0)).max() < 1e-15  # centred
    assert 2 * (np.linalg.norm(pos, axis=1).max() + 0.00355) <= 0.048


def test_ballast8_and_thesis_shapes():
    pos, _ = ballast8()
    assert len(pos) == 8 and pair_distances(pos).min() == pytest.approx(0.017, rel=1e-12)
    # thesis 4.4: the 48 mm grain of spheres r = 8.48 mm is the 8-sphere clump
    pos, _ = shape_members("ellipsoid", 0.00848, THESIS_SHAPES["sphere"])
    assert len(pos) == 8
    for name, radii in THESIS_SHAPES.items():
        pos, _ = shape_members("ellipsoid", 0.0036, radii)
        q = pos / (np.asarray(radii) - 0.0036)  # each member sphere inside the ellipsoid
        assert np.all(np.einsum("ij,ij->i", q, q) <= 1 + 1e-9) and len(pos) > 50, name
        assert pair_distances(pos).min() == pytest.approx(0.0072, rel=1e-12)
    pos, _ = shape_members("cylinder", 0.0036, (0.018, 0.018, 0.040))
    assert np.abs(pos[:, 2]).max() <= 0.040 - 0.0036 and np.hypot(pos[:, 0], pos[:, 1]).max() <= 0.018 - 0.0036
    pos, _ = shape_members("cake", 0.0036, (0.010, 0.037, 0.037))
    assert np.abs(pos[:, 0]).max() <= 0.010 - 0.0036 and np.hypot(pos[:, 1], pos[:, 2]).max() <= 0.037 - 0.0036


def test_member_spacing_overlaps_nearest_neighbours():
    """``spacing`` < 2r: the same members (same grid, scaled), nearest neighbours overlapping by
    2r − spacing (the thesis's Ø7.2 mm spheres 7.1 mm apart), the same bond graph."""
    from pdem.bodies.bonds import touching_pairs

    for make in (lambda h: nottingham_grain(0.0036, h), lambda h: shape_members("ellipsoid", 0.0036, (0.024,) * 3, h),
                 lambda h: ballast8(0.0036, h)):
        (p0, _), (p1, r1) = make(None), make(0.0071)
        assert len(p1) == len(p0) and np.allclose(p1, p0 * (0.0071 / 0.0072), rtol=0, atol=1e-15)
        assert pair_distances(p1).min() == pytest.approx(0.0071, rel=1e-12)
        assert [a.tolist() for a in touching_pairs("x", p1, r1)] == [a.tolist() for a in touching_pairs("x", p0, r1)]


def test_grain_cloud():
    pos, r = ballast8(0.005)
    grains = grain_cloud(pos, r, (0, 0, 0), (0.2, 0.1, 0.1), 20, seed=4)
    again = grain_cloud(pos, r, (0, 0, 0), (0.2, 0.1, 0.1), 20, seed=4)
    other = grain_cloud(pos, r, (0, 0, 0), (0.2, 0.1, 0.1), 20, seed=5)
    assert len(grains) == 20 and all(np.array_equal(a[0], b[0]) for a, b in zip(grains, again))
    assert not all(np.array_equal(a[0], b[0]) for a, b in zip(grains, other))
    every = np.concatenate([p for p, _ in grains])
    owner = np.repeat(np.arange(20), 8)
    d = np.linalg.norm(every[:, None] - every[None], axis=2)
    apart = owner[:, None] != owner[None]
    assert d[apart].min() > 2 * 0.005  # grains do not touch each other
    for p, _ in grains:  # each is a rotated copy: same shape, a different orientation
        assert np.allclose(np.sort(pair_distances(p)), np.sort(pair_distances(pos)), rtol=0, atol=1e-15)
        assert np.all(p.min(axis=0) >= 0.005 - 1e-15) and np.all(p.max(axis=0) <= np.array([0.2, 0.1, 0.1]) - 0.005)
    first = [(p[0] - p.mean(axis=0)) / np.linalg.norm(p[0] - p.mean(axis=0)) for p, _ in grains]
    assert len({tuple(np.round(a, 6)) for a in first}) == 20  # turned differently
    with pytest.raises(pdem.InputError, match=r"clumps.count = 500: only \d+ grains"):
        grain_cloud(pos, r, (0, 0, 0), (0.2, 0.1, 0.1), 500)


# ---------------------------------------------------------------------------- mass models
def union_of_two(r, d, rho):
    """Mass, and moment about the line of centres, of two spheres of radius r at distance d
    (along z), overlaps once: a solid of revolution, integrated over its cross-sections."""
    z = np.linspace(-d / 2 - r, d / 2 + r, 400001)
    s2 = np.maximum(r * r - (np.abs(z) - d / 2) ** 2, 0.0)  # the nearer sphere's cross-section
    mass = rho * math.pi * np.trapezoid(s2, z)
    axial = rho * math.pi / 2 * np.trapezoid(s2 ** 2, z)
    lens = math.pi * (4 * r + d) * (2 * r - d) ** 2 / 12  # analytic check of the volume
    assert mass == pytest.approx(rho * (2 * 4 / 3 * math.pi * r ** 3 - lens), rel=1e-9)
    return mass, axial


@pytest.mark.parametrize("model, kw, tol", [("grid", {"discretization": 40}, 5e-3),
                                            ("monte_carlo", {"samples": 2_000_000, "seed": 3}, 5e-3)])
def test_volume_corrected_mass(model, kw, tol):
    r, d, rho = 0.01, 0.012, 2600.0
    centres = [(0.0, 0.0, -d / 2), (0.0, 0.0, d / 2)]
    mass, axial = union_of_two(r, d, rho)
    got = clump_properties(centres, [r, r], rho, model, **kw)
    yade = clump_properties(centres, [r, r], rho)
    one = rho * ((4.0 / 3.0) * math.pi * math.pow(r, 3.0))
    assert yade["mass"] == one + one  # overlap counted twice
    assert got["mass"] == pytest.approx(mass, rel=tol)
    assert np.abs(got["pos"]).max() < 1e-3 * r
    assert got["inertia"][0] == pytest.approx(axial, rel=3 * tol)  # the smallest moment: about the axis
    assert got["inertia"][1] == pytest.approx(got["inertia"][2], rel=3 * tol)
    assert yade["inertia"][0] > got["inertia"][0]


# ---------------------------------------------------------------------------- fragments
def test_label_fragments():
    gid = np.array([9, 3, 5, 7, 1, 2, 8, 4, 6])  # any order
    mass = gid * 0.5
    clump = np.array([-1, 0, 0, 1, 0, 1, 2, 1, 2])
    # bonds of breakable clump 0 (1-3-5: one piece), clump 1 split into (2, 4) and (7); rigid clump 2 (6, 8)
    n, m, c = label_fragments(gid, mass, clump, [1, 3, 2], [3, 5, 4], clump_ids=[2], clump_mass=[123.0],
                              member_gid=[6, 8], member_clump=[2, 2])
    # fragments by smallest gid: {1,3,5}, {2,4}, {6,8}, {7}, {9}
    assert n.tolist() == [3, 2, 2, 1, 1]
    assert m.tolist() == [4.5, 3.0, 123.0, 3.5, 4.5]
    assert c.tolist() == [0, 1, 2, 1, -1]


# ---------------------------------------------------------------------------- bad input
COH = {"density": 2600.0, "young": 1e7, "poisson": 0.3, "friction_angle": 0.5, "normal_cohesion": 1e5,
       "shear_cohesion": 1e5}


def cohesive_scene(**mat):
    sc = Scene(law="cohesive")
    sc.material(name="grain", **{**COH, **mat})
    return sc


@pytest.mark.parametrize("make, words", [
    (lambda: cohesive_scene().add_clump([(0, 0, 0)], 0.01, "grain"),
     ["clumps[0].member_pos", "at least 2 member spheres, got 1"]),
    (lambda: cohesive_scene().add_clump([(0, 0, 0), (0.03, 0, 0)], 0.01, "grain"),
     ["clumps[0].member_pos", "member 1", "neither overlaps nor touches"]),
    (lambda: cohesive_scene().add_clump([(0, 0, 0), (0.015, 0, 0)], [0.01, -0.01], "grain"),
     ["member_radius", "> 0"]),
    (lambda: cohesive_scene().add_clump([(0, 0, 0), (0.015, 0, 0)], 0.01, "grain", mass_model="exact"),
     ["mass_model = 'exact'", "members, grid, monte_carlo"]),
    (lambda: cohesive_scene().add_clump([(0, 0, 0), (0.015, 0, 0)], 0.01, "grain", mass_model="grid"),
     ["discretization = 0", "integer >= 1"]),
    (lambda: cohesive_scene(normal_cohesion=-1.0), ["materials.grain.normal_cohesion = -1.0", ">= 0"]),
    (lambda: cohesive_scene().add_clumps([([(0, 0, 0), (0.015, 0, 0)], 0.01)], "grain", breakable=True,
                                         angvel=(0, 0, 1.0)), ["clumps.angvel", "vel only"]),
])
def test_clump_declaration_errors(make, words):
    with pytest.raises(pdem.InputError) as exc:
        make()
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


@pytest.mark.parametrize("build, words", [
    (lambda: _breakable(cohesive_scene(normal_cohesion=0.0)), ["materials.grain.normal_cohesion = 0.0", "> 0",
                                                               "bonds"]),
    (lambda: _breakable(cohesive_scene(shear_cohesion=0.0)), ["materials.grain.shear_cohesion = 0.0", "> 0"]),
    (lambda: _breakable(_linear()), ["simulation.law = 'linear'", "cohesive"]),
    (lambda: _breakable(cohesive_scene(normal_cohesion=1e12)), ["simulation.skin", "stretches", "larger skin"]),
])
def test_bond_errors_at_build(build, words):
    with pytest.raises(pdem.InputError) as exc:
        build().build()
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def _linear():
    sc = Scene()
    sc.material(name="grain", density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    return sc


def _breakable(sc):
    sc.add_breakable_clump([(0, 0, 0), (0.02, 0, 0)], 0.01, "grain")
    return sc


def test_bonded_spheres_must_touch():
    sc = cohesive_scene()
    sc.add_spheres([(0, 0, 0), (0.03, 0, 0)], 0.01, "grain")
    sc.add_bonds([[1, 0]])
    with pytest.raises(pdem.InputError, match="bonds: spheres gid 0 and 1 are 0.01 m apart"):
        sc.build()


class _ThreeRanks:
    rank, size = 1, 3


def test_clump_wider_than_a_slab():
    d = SlabDomain(_ThreeRanks(), axis=0)
    d.edges = np.array([0.0, 0.1, 0.15, 0.3])
    d.halo = 2 * 0.01 + 0.002 + 2 * 0.02
    with pytest.raises(pdem.InputError) as exc:
        d._check_clump_reach(None, 0.02)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("clumps: the largest clump reaches 0.02 m") and "use fewer ranks" in msg
    d.edges = np.array([0.0, 0.1, 0.2, 0.3])
    d._check_clump_reach(None, 0.02)  # slabs thick enough


TOML = {"simulation": {"law": "cohesive"}, "materials": {"grain": COH},
        "clumps": [{"shape": "ballast8", "member_radius": 0.005, "material": "grain", "box_lo": [0, 0, 0],
                    "box_hi": [0.2, 0.1, 0.1], "count": 4, "seed": 1}]}


@pytest.mark.parametrize("change, words", [
    ({"shap": "x"}, ["clumps[0].shap", "unknown key"]),
    ({"shape": "cube"}, ["clumps[0].shape = 'cube'", "ellipsoid, cylinder, cake, nottingham, ballast8"]),
    ({"shape": "ellipsoid"}, ["clumps[0].radii", "missing"]),
    ({"count": 0}, ["clumps[0].count = 0", ">= 1"]),
    ({"breakable": "yes"}, ["breakable = 'yes'", "true or false"]),
    ({"member_spacing": 0.011}, ["clumps.member_spacing = 0.011", "(0, 2 member_radius = 0.01]"]),
    ({"member_spacing": 0}, ["clumps.member_spacing = 0", "members must touch or overlap"]),
])
def test_toml_clump_errors(one_line_error, change, words):
    import copy

    doc = copy.deepcopy(TOML)
    doc["clumps"][0].update(change)
    one_line_error(pdem.InputError, lambda: scene_from_dict(doc).build(), *words)


def test_toml_clumps_build():
    import copy

    doc = copy.deepcopy(TOML)
    doc["clumps"].append({"shape": "nottingham", "material": "grain", "box_lo": [0, 0, 0.1], "box_hi": [0.2, 0.1, 0.2],
                          "count": 2, "seed": 2, "breakable": True})
    sim = scene_from_dict(doc).build()
    assert sim.clumps.n == 4 and sim.particles.n_local == 4 * 8 + 2 * 135
    c = sim.contacts("sphere_sphere")
    assert len(c["gid1"]) == 2 * 600 and np.all(c["normal_adhesion"] > 0)  # FCC: 600 bonds per grain


# ---------------------------------------------------------------------------- staged scenes
def test_stage_tables_with_clumps():
    """Clumps poured as tables (`clump_tables`), cut (`remove_above` takes whole clumps) and
    loaded into a stage's scene (`add_sphere_columns`, `add_clump_tables`, `load_state`)."""
    from pdem.driver.stages import (
        append_tables,
        clump_tables,
        empty_tables,
        next_free_clump,
        next_free_gid,
        remove_above,
    )

    sc = cohesive_scene()
    p, r = ballast8(0.005)
    t = append_tables(empty_tables(), clump_tables(sc, grain_cloud(p, r, (0, 0, 0), (0.2, 0.1, 0.05), 6, seed=1),
                                                   "grain", 0, 0))
    p, r = shape_members("ellipsoid", 0.004, (0.012, 0.012, 0.012))
    more = clump_tables(sc, grain_cloud(p, r, (0, 0, 0.05), (0.2, 0.1, 0.1), 4, seed=2), "grain", next_free_gid(t),
                        next_free_clump(t), breakable=True)
    t = append_tables(t, more)
    assert len(t["particles"]["gid"]) == 6 * 8 + 4 * 8 and len(t["clumps"]["id"]) == 6
    assert len(t["contacts/sphere_sphere"]["key"]) == 4 * 12 and set(t["particles"]["clump"]) == set(range(10))
    cut, removed = remove_above(t, 0.07)
    gone = set(np.unique(t["particles"]["clump"])) - set(np.unique(cut["particles"]["clump"]))
    assert removed == 8 * len(gone) and gone <= set(range(6, 10)) and gone  # whole breakable grains
    cut2, _ = remove_above(t, 0.02)
    assert len(cut2["clumps"]["id"]) < 6 and np.all(np.isin(cut2["clump_members"]["clump"], cut2["clumps"]["id"]))
    stage = sc.empty_like()
    stage.add_sphere_columns(cut["particles"])
    stage.add_clump_tables(cut["clumps"], cut["clump_members"])
    sim = stage.build()
    sim.load_state(cut)
    assert sim.clumps.n == 6 and sim.particles.n_local == len(cut["particles"]["gid"])
    assert len(sim.contacts()["gid1"]) == 12 * (4 - len(gone))


def test_clump_time_step():
    """A clump's own Δt bound: M/K_t and I_min/K_r with K_r = Σ k (|x_i − x_c| + r_i)²."""
    from pdem.bodies.clumps import clump_dt

    pos = np.array([[-0.01, 0.0, 0.0], [0.01, 0.0, 0.0]])
    kmember = np.array([3e5, 1e5])  # Σ (kn + ks) of each member's contacts
    mass, inertia = 0.01, np.array([[2e-7, 5e-7, 5e-7]])
    got = clump_dt(1, np.array([0, 2]), np.array([0, 1]), np.zeros((1, 3)), pos, np.array([0.01, 0.01]), kmember,
                   np.array([mass]), inertia)
    kr = 4e5 * 0.02 ** 2
    assert got == pytest.approx(math.sqrt(min(mass / 4e5, 2e-7 / kr)), rel=1e-15)
    assert clump_dt(1, np.array([0, 2]), np.array([0, 1]), np.zeros((1, 3)), pos, np.array([0.01, 0.01]),
                    np.zeros(2), np.array([mass]), inertia) == np.inf
