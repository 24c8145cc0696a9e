"""Pieces of the box-test pipeline (`pdem.scenes.box_test`, `pdem.scenes.common.preparation`) without running it:
trimming, cloud sizing,
sleeper placement, and friction lowered and restored for the vibration stage (Ip2 again)."""
from math import pi, tan

import numpy as np

from pdem.scenes.common.preparation import cloud, cloud_count
from pdem.driver.stages import remove_above
from pdem.scenes.box_test import DEFAULTS, sleeper_geometry
from pdem.scene import Scene


def test_remove_above_uses_the_top_of_each_sphere():
    p = {"gid": np.arange(4), "pos": np.array([[0, 0, 0.10], [0, 0, 0.28], [0, 0, 0.29], [0, 0, 0.5]]),
         "radius": np.array([0.01, 0.02, 0.01, 0.01])}
    kept, removed = remove_above({"particles": p, "contacts/sphere_sphere": {"key": np.zeros(0)}}, 0.30)
    assert removed == 2 and list(kept["particles"]["gid"]) == [0, 2]
    assert "contacts/sphere_sphere" in kept


def test_cloud_count_fills_the_volume_at_the_packing_fraction():
    c = dict(DEFAULTS, radius=0.01, radius_spread=0.0, packing_fraction=0.6, overfill=1.0)
    v = 4.0 / 3.0 * pi * 0.01**3
    assert cloud_count(c, 1000 * v / 0.6) == 1000
    # radii uniform in r(1 ± s): the mean volume uses E[r^3] = (b^4 - a^4) / (4 (b - a))
    c = dict(c, radius_spread=0.4)
    a, b = 0.006, 0.014
    mean_v = 4.0 / 3.0 * pi * (b**4 - a**4) / (4 * (b - a))
    assert cloud_count(c, 500 * mean_v / 0.6) in (500, 501)


def test_cloud_stays_in_its_column_without_overlaps():
    c = dict(DEFAULTS, radius=0.0125, radius_spread=0.3, seed=3)
    pos, r = cloud(c, (0.0, 0.0), (0.1, 0.15), 0.2, 0.1 * 0.15 * 0.05, 3)
    assert np.all(pos[:, 0] - r >= 0) and np.all(pos[:, 0] + r <= 0.1)
    assert np.all(pos[:, 1] - r >= 0) and np.all(pos[:, 1] + r <= 0.15) and np.all(pos[:, 2] - r >= 0.2)
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) - r[:, None] - r[None]
    assert d[~np.eye(len(r), dtype=bool)].min() > 0


def test_sleeper_sits_on_the_cut_centred_in_the_box():
    center, half = sleeper_geometry(DEFAULTS, 0.30)
    assert np.allclose(center, [0.35, 0.15, 0.375]) and np.allclose(half, [0.125, 0.15, 0.075])


def test_friction_scale_reruns_ip2_for_existing_contacts_and_restores_bits():
    scene = Scene(dt=1e-5, damping=0.3, gravity=(0, 0, -9.81), allow_initial_overlap=True)
    a = scene.material(density=2600, young=1e7, poisson=0.3, friction_angle=0.5)
    b = scene.material(density=7850, young=1e8, poisson=0.25, friction_angle=0.3)
    pos = [(0, 0, 0.0095), (0.019, 0, 0.0095), (0.0095, 0.0, 0.0265)]
    scene.add_spheres(pos, 0.01, [a, a, b])
    scene.add_wall("z", 0.0, b, sense=1)
    sim = scene.build()
    sim.run(1)
    for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts):
        assert len(cl.real_rows()) > 0
    before = {
        id(cl): cl.params[: cl.n].copy()
        for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts)
    }
    sim.set_friction_scale(0.1)
    ss = sim.kind("sphere_sphere").contacts.real_rows()
    expect = [
        tan(0.05)
        if {
            int(sim.particles.material[i])
            for i in (sim.kind("sphere_sphere").contacts.i[k], sim.kind("sphere_sphere").contacts.j[k])
        }
        == {0}
        else tan(0.03)
        for k in ss
    ]
    assert np.array_equal(sim.kind("sphere_sphere").contacts.params[ss, 2], expect)
    assert np.all(sim.kind("sphere_wall").contacts.params[sim.kind("sphere_wall").contacts.real_rows(), 2] == tan(0.03))
    assert np.array_equal(sim.props[:, 2], np.array([0.5, 0.3]) * 0.1)
    sim.set_friction_scale(1.0)
    for cl in (sim.kind("sphere_sphere").contacts, sim.kind("sphere_wall").contacts):
        assert np.array_equal(cl.params[: cl.n], before[id(cl)])
