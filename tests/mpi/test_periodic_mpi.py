"""Periodic ends (#30): the same bits on 1, 2 and 3 ranks and after a restart.

Run under ``mpiexec -n 2`` and ``-n 3`` (and serially, where it checks determinism and the
restart on one rank). A periodic packing (`factories.periodic_lattice_scene`: 384 spheres
drifting along x under gravity, a floor and two side walls, periodic along x, the slab axis)
runs long enough that bodies wrap at the ends, migrate across the ring (rank size − 1 to rank
0) and touch across the ends. Every rank also runs the scene on one rank (`SerialComm`, a ring
of one with image ghosts of its own bodies) and compares, bit for bit, the state of every body
by gid and the contact tables by key; then the run is stopped at step K, checkpointed, restored
on the same ranks and on one rank, continued to N, and compared again.
"""
import numpy as np
from factories import periodic_lattice_scene
from run_files import bodies_by_gid, state, state_differences

from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm, configure_threads

N_STEPS, K_STEP = 1600, 1037
_REFERENCE = {}


def make_scene():
    return periodic_lattice_scene(11, (16, 4, 6), vx=0.6, vz=0.5, dt_interval=50, check_interval=40)[0]


def across_ends(sim):
    """Real contacts of this rank whose pair crosses the periodic ends (an end is an image ghost)."""
    c, dom = sim.kind("sphere_sphere").contacts, sim.domain
    rows = c.real_rows()
    shift = dom.image[c.j[rows], 0] - dom.image[c.i[rows], 0]
    return int(np.count_nonzero(shift != 0.0))


def reference():
    if not _REFERENCE:
        ref = make_scene().build(comm=SerialComm())
        crossing = 0
        for _ in range(N_STEPS // 100):
            ref.run(100)
            crossing += across_ends(ref)
        ref.run(N_STEPS - ref.step)
        _REFERENCE.update(state(ref, SerialComm()), wrapped=ref.domain.n_wrapped, crossing=crossing,
                          cpp=ref.contacts_per_particle())
    return _REFERENCE


def assert_matches(comm, sim, what):
    bad = state_differences(reference(), comm, sim)
    assert bad == [], f"{what}: rank {comm.rank}: differs from one rank: {bad}"


def test_periodic_same_bits_on_any_rank_count(comm):
    configure_threads(comm)
    ref = reference()
    assert ref["wrapped"] > 10, "no body wrapped at the ends: the test does not test the wrap"
    assert ref["crossing"] > 0, "no contact across the ends"
    sim = make_scene().build(comm=comm)
    crossing = 0
    for _ in range(N_STEPS // 100):
        sim.run(100)
        crossing += across_ends(sim)
    sim.run(N_STEPS - sim.step)
    assert_matches(comm, sim, f"{comm.size} ranks")
    assert sim.contacts_per_particle() == ref["cpp"]  # an image end counts for its body on one rank too
    assert comm.allreduce_sum_int(crossing) > 0
    if comm.size > 1:
        assert comm.allreduce_sum_int(sim.domain.n_migrated) > 0


def test_periodic_restart(comm, mpi_tmp_path):
    configure_threads(comm)
    reference()
    first = make_scene().build(comm=comm)
    first.run(K_STEP)
    tables, meta = first.checkpoint_tables()
    path = write_checkpoint(mpi_tmp_path, K_STEP, tables, meta, comm)
    del first
    saved, saved_meta = read_checkpoint(path)
    assert saved_meta["scene"]["settings"]["periodic"] == [0.0, 16 * 0.016]
    again = make_scene().build(comm=comm)
    again.restore_checkpoint(saved, saved_meta)
    again.run(N_STEPS - K_STEP)
    assert_matches(comm, again, f"restart on {comm.size} ranks")
    alone = make_scene().build(comm=SerialComm())
    alone.restore_checkpoint(saved, saved_meta)
    alone.run(N_STEPS - K_STEP)
    c = SerialComm()
    ref = reference()
    for name, a, b in zip(("gid", "pos", "vel"), ref["bodies"], bodies_by_gid(c, alone)):
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), f"restart on one rank: {name}"


def test_ring_exchange_closes_the_chain(comm):
    """`neighbor_exchange(..., ring=True)`: rank 0's lo neighbour is rank size - 1 (a ring of one
    rank gets its own rows back), with and without receive buffers."""
    r, n = comm.rank, comm.size
    lo_msg = np.full((2, 3), 10.0 * r + 1.0)  # to (r - 1) % n
    hi_msg = np.full((3, 3), 10.0 * r + 2.0)  # to (r + 1) % n
    from_lo, from_hi = comm.neighbor_exchange(lo_msg, hi_msg, ring=True)
    assert np.array_equal(from_lo, np.full((3, 3), 10.0 * ((r - 1) % n) + 2.0))
    assert np.array_equal(from_hi, np.full((2, 3), 10.0 * ((r + 1) % n) + 1.0))
    into_lo, into_hi = np.empty((3, 3)), np.empty((2, 3))
    comm.neighbor_exchange(lo_msg, hi_msg, into_lo, into_hi, ring=True)
    assert np.array_equal(into_lo, from_lo) and np.array_equal(into_hi, from_hi)
    if n > 1:  # the plain chain is unchanged: nothing from beyond its ends
        a, b = comm.neighbor_exchange(lo_msg, hi_msg)
        assert (len(a) == 0) == (r == 0) and (len(b) == 0) == (r == n - 1)
