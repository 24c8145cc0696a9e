"""A loaded rigid box on a settling bed: the same box trajectory, bit for bit, on 1, 2 or 3 ranks.

Run: ``.venv/bin/mpiexec -n 2 .venv/bin/python -m mpi4py -m pytest -q --capture=sys tests/mpi``.
~700 spheres fall in a long box of 5 walls (slabs along x); a rigid box (z translation only,
haversine load plus its weight) spanning every slab lands on them. The box is replicated and
integrated on every rank from the exact global sum of its contact forces, so its centre,
velocity and contact force must equal those of a serial run of the same scene at every sample.
"""
import numpy as np

from pdem.loads import Haversine
from pdem.parallel.comm import SerialComm, configure_threads
from pdem.parallel.slab_domain import SlabDomain
from pdem.scene import Scene

N_STEPS, EVERY = 3000, 50


def make_scene():
    rng = np.random.default_rng(7)
    spacing = 0.016
    nx, ny, nz = 20, 6, 6
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * spacing + rng.uniform(-0.0005, 0.0005, (len(g), 3))
    radius = 0.005 * rng.uniform(0.6, 1.4, len(g))
    vel = np.zeros((len(g), 3))
    vel[:, 0] = rng.uniform(-0.3, 0.3, len(g))
    scene = Scene(dt="auto", damping=0.3, gravity=(0.0, 0.0, -9.81), slab_axis=0)
    m = scene.material(density=2700.0, young=1e7, poisson=0.3, friction_angle=0.5)
    steel = scene.material(density=7850.0, young=1e8, poisson=0.25, friction_angle=0.5)
    scene.add_spheres(pos, radius, m, vel=vel)
    lx, ly = nx * spacing, ny * spacing
    for axis, lo, hi in ((0, 0.0, lx), (1, 0.0, ly)):
        scene.add_wall(axis, lo, m)
        scene.add_wall(axis, hi, m)
    scene.add_wall(2, 0.0, m)
    top = nz * spacing
    scene.add_box((0.5 * lx, 0.5 * ly, top + 0.012), (0.4 * lx, 0.4 * ly, 0.01), steel, mass=2.0,
                  blocked="xyXYZ", load=Haversine(0.0, 5.0, 20.0, 2), velocity=(0.0, 0.0, -0.2))
    return scene


def trajectory(sim):
    rows = []
    for _ in range(N_STEPS // EVERY):
        sim.run(EVERY)
        b = sim.boxes
        rows.append(np.concatenate([b.center[0], b.velocity[0], b.contact_force[0]]))
    return np.array(rows)


def test_box_trajectory_rank_invariant(comm):
    configure_threads(comm)
    domain = SlabDomain(comm, axis=0) if comm.size > 1 else None
    sim = make_scene().build(comm=comm, domain=domain)
    par = trajectory(sim)
    ref = trajectory(make_scene().build(comm=SerialComm()))
    same = bool(np.array_equal(par.view(np.uint8), ref.view(np.uint8)))
    first = int(np.flatnonzero(np.any(par != ref, axis=1))[0]) if not same else -1
    assert not comm.any_flag(not same), f"rank {comm.rank}: box trajectory differs from serial from sample {first}"
    assert np.max(ref[:, 8]) > 0.0, "the box never touched the bed"
    if comm.size > 1:
        assert comm.allreduce_sum_int(len(sim.kind("sphere_box").contacts.real_rows())) > 0
        assert comm.allreduce_sum_int(int(len(sim.kind("sphere_box").contacts.real_rows()) > 0)) > 1, "box contacts on one rank only"
