"""The public read API: bodies by gid, contacts by gid pair, boundaries by name, and the
declaration options it pairs with (given gids, explicit mass and inertia, facets from a centre)."""
import numpy as np
import pytest

from pdem import InputError, Scene


def scene():
    sc = Scene(dt=1e-5, gravity=(0.0, 0.0, -9.81), allow_initial_overlap=True)
    m = sc.material(density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    gids = sc.add_spheres([(0.0, 0.0, 0.0099), (0.05, 0.0, 0.0099), (0.0, 0.0, 0.0297)], 0.01, m,
                          gid=[10, 3, 7], mass=[0.01, 0.02, 0.03], inertia=[1e-6, 2e-6, 3e-6])
    sc.add_wall("z", 0.0, m, sense=1, name="floor")
    sc.add_facet(center=(0.0, 0.2, 0.0), local=[(0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.1, 0.0)], material=m,
                 name="tile")
    return sc, m, gids


def test_bodies_by_gid_with_given_mass_and_inertia():
    sc, _, gids = scene()
    assert list(gids) == [10, 3, 7]
    sim = sc.build()
    sim.run(20)
    b = sim.bodies()
    assert list(b["gid"]) == [3, 7, 10]
    assert list(b["mass"]) == [0.02, 0.03, 0.01] and list(b["inertia"]) == [2e-6, 3e-6, 1e-6]
    one = sim.body(7)
    assert one["gid"] == 7 and np.array_equal(one["pos"], b["pos"][1])
    assert sim.body(99) is None


def test_contacts_by_gid_pair_and_creation_step():
    sc, _, _ = scene()
    sim = sc.build()
    sim.run(30)
    c = sim.contacts("sphere_sphere")
    assert list(zip(c["gid1"], c["gid2"])) == [(7, 10)]  # gid1 < gid2; the pair overlaps from the start
    assert c["created"][0] == 0 and c["overlap"][0] > 0
    np.testing.assert_allclose(c["normal_force"][0], c["kn"][0] * c["overlap"][0] * c["normal"][0], rtol=1e-12)
    assert c["tan_phi"][0] == np.tan(0.5)
    w = sim.contacts("sphere_wall")
    assert sorted(w["gid1"]) == [3, 10] and set(w["index"]) == {sim.wall_index("floor")}
    # Newton's third law in the read API: the wall pushes the sphere up by its weight plus the top sphere's
    assert np.all(w["force"][:, 2] > 0)
    with pytest.raises(KeyError, match="sphere_box"):
        sim.contacts("sphere_box")


def test_boundaries_by_name_and_facet_from_centre():
    sc, m, _ = scene()
    sim = sc.build()
    assert sim.wall_index("floor") == 0 and sim.facet_index("tile") == 0
    np.testing.assert_allclose(
        sim.facets.vertices[0], [(0.0, 0.2, 0.0), (0.1, 0.2, 0.0), (0.0, 0.3, 0.0)], rtol=0, atol=1e-16
    )
    with pytest.raises(KeyError, match="no wall called 'roof'"):
        sim.wall_index("roof")


@pytest.mark.parametrize("kw, words", [
    ({"gid": [1, 1]}, "spheres.gid"),
    ({"gid": [1, -2]}, "spheres.gid"),
    ({"mass": [1.0, -1.0]}, "spheres.mass"),
    ({"inertia": "heavy"}, "spheres.inertia"),
])
def test_bad_declarations_one_line(kw, words):
    sc = Scene()
    m = sc.material(density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    with pytest.raises(InputError, match=words):
        sc.add_spheres([(0, 0, 0), (1, 0, 0)], 0.01, m, **kw)


def test_given_gids_must_not_clash():
    sc = Scene()
    m = sc.material(density=2600.0, young=1e7, poisson=0.3, friction_angle=0.5)
    sc.add_spheres([(0, 0, 0)], 0.01, m, gid=[5])
    with pytest.raises(InputError, match="id 5 is already taken"):
        sc.add_spheres([(1, 0, 0)], 0.01, m, gid=[5])
