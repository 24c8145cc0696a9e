"""Restart bit for bit (serial): run N steps, or run k, checkpoint, restore into a new
`Simulation` built from the same scene, run N - k; every body's state, every contact's history,
walls, facets, step, time, dt and the energy-check reference must be identical to the last bit.

Scenes: a damped gravity deposition of 432 spheres in a box of five walls (energy check active,
so its reference is restored too), and a small scene with a moving wall and a moving facet
(positions of boundaries restored). k is chosen off the dt_interval/check_interval grid so that Δt
re-estimation, stability checks and neighbour rebuilds all fall at different phases.
"""
import numpy as np
import pytest
from factories import lattice_scene

from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm
from pdem.build.scene import Scene


def deposition_scene():
    return lattice_scene(7, (6, 6, 12), vx=0.5, vz=0.5, one_sided=True, dt_interval=50, check_interval=40)[0]


def moving_boundary_scene():
    rng = np.random.default_rng(11)
    spacing = 0.016
    g = np.stack(np.meshgrid(np.arange(5), np.arange(5), np.arange(4), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * spacing + np.array([0.0, 0.0, 0.004]) + rng.uniform(-0.0005, 0.0005, (len(g), 3))
    radius = 0.005 * rng.uniform(0.8, 1.2, len(g))
    scene = Scene(dt="auto", damping=0.2, gravity=(0.0, 0.0, -9.81), dt_interval=30)
    m = scene.material(density=2700.0, young=1e7, poisson=0.3, friction_angle=0.5)
    scene.add_spheres(pos, radius, m)
    # a conveyor-like floor facet (moving sideways and slowly up) and a closing side wall
    scene.add_facet([(-0.05, -0.05, 0.0), (0.25, -0.05, 0.0), (-0.05, 0.25, 0.0)], m, velocity=(0.02, 0.0, 0.002))
    scene.add_wall(0, 0.0, m, sense=1)
    scene.add_wall(0, 0.082, m, sense=-1, velocity=(-0.01, 0.0, 0.0))
    return scene


def body_state(sim):
    p = sim.particles
    n = p.n_local
    o = np.argsort(p.gid[:n])
    return {k: getattr(p, k)[:n][o].copy() for k in ("gid", "pos", "vel", "angvel", "force", "torque")}


def assert_same_bits(a, b, what):
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype, f"{what}: {a.shape} {a.dtype} vs {b.shape} {b.dtype}"
    assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), (
        f"{what}: differs in {np.count_nonzero(a != b)} entries, max |diff| {np.max(np.abs(a - b)) if a.size else 0}")


def assert_same_simulation(ref, got):
    for k, v in body_state(ref).items():
        assert_same_bits(v, body_state(got)[k], k)
    for name in ("step", "time", "dt", "energy_reference"):
        assert getattr(ref, name) == getattr(got, name), name
    t_ref, _ = ref.checkpoint_tables()
    t_got, _ = got.checkpoint_tables()
    assert sorted(t_ref) == sorted(t_got)
    for t in t_ref:
        o_ref = np.argsort(t_ref[t][next(iter(t_ref[t]))] if t != "particles" else t_ref[t]["gid"])
        o_got = np.argsort(t_got[t][next(iter(t_got[t]))] if t != "particles" else t_got[t]["gid"])
        for c in t_ref[t]:
            assert_same_bits(t_ref[t][c][o_ref], t_got[t][c][o_got], f"{t}/{c}")


@pytest.mark.parametrize("make, n_steps, k", [(deposition_scene, 8000, 4237), (moving_boundary_scene, 8000, 5613)],
                         ids=["deposition", "moving-boundaries"])
def test_restart_bit_identical(tmp_path, make, n_steps, k):
    ref = make().build(comm=SerialComm())
    ref.run(n_steps)

    first = make().build(comm=SerialComm())
    first.run(k)
    tables, meta = first.checkpoint_tables()
    assert len(tables["contacts/sphere_sphere"]["key"]) > 30, "the checkpoint should hold real contacts"
    assert len(tables["contacts/sphere_wall"]["key"]) > 0
    path = write_checkpoint(tmp_path, k, tables, meta, SerialComm())
    del first

    got = make().build(comm=SerialComm())
    got.restore_checkpoint(*read_checkpoint(path))
    assert got.step == k
    got.run(n_steps - k)
    assert_same_simulation(ref, got)
    if make is deposition_scene:
        assert ref.energy_reference is not None  # the check ran, and its reference was restored
    else:
        assert_same_bits(ref.walls.position, got.walls.position, "walls.position")
        assert_same_bits(ref.facets.geom, got.facets.geom, "facets.geom")
        assert_same_bits(ref.facets.vertices, got.facets.vertices, "facets.vertices")


def test_restore_refuses_other_scene(tmp_path):
    sim = moving_boundary_scene().build(comm=SerialComm())
    sim.run(10)
    path = write_checkpoint(tmp_path, 10, *sim.checkpoint_tables(), SerialComm())
    other = deposition_scene().build(comm=SerialComm())
    with pytest.raises(ValueError, match="different scene"):
        other.restore_checkpoint(*read_checkpoint(path))
