"""Probe of the `pdem.kernels.Kernel` twins: serial twin vs parallel twin on 1 and 2 threads.

    NUMBA_NUM_THREADS=2 python -m bench.kernel_threads [N]     (NUMBA_THREADING_LAYER=workqueue to compare)

Builds the cached settled bed of N spheres (default 10000), runs 50 steps, then times each
kernel of a step called directly (serial twin / parallel twin) and prints µs per call.
"""
import sys
import time

import numba

from bench.__main__ import bed, make_scene
from pdem.contact import forces
from pdem import integrator


def timeit(f, reps=200):
    f()
    t0 = time.perf_counter()
    for _ in range(reps):
        f()
    return (time.perf_counter() - t0) / reps


def main(n=10000):
    pos, radius = bed(n)
    sim = make_scene(pos, radius).build()
    sim.run(50)
    pairs = sim.kind("sphere_sphere")
    p, ss = sim.particles, pairs.contacts
    other_f, other_i = pairs.kernel_arrays()
    hist = ss.history.copy(), ss.state.copy(), ss.params.copy()

    def ssf(k):
        return lambda: k(ss.n, ss.i, ss.j, ss.state, ss.params, ss.history, ss.force, ss.torque, ss.overlap,
                         pairs.slot, pairs.slot_f, pairs.slot_t, p.pos, p.vel, p.angvel, p.radius, p.material,
                         p.mass, sim.props, other_f, other_i, sim.dt, sim.step)

    def sums(k):
        return lambda: k(p.n_local, pairs.ptr, pairs.slot_f, pairs.slot_t, p.force, p.torque)

    pos0, vel0, w0 = p.pos.copy(), p.vel.copy(), p.angvel.copy()

    def integ(k):
        def f():
            k(p.n_local, p.pos, p.vel, p.angvel, p.force, p.torque, p.mass, p.inertia, p.blocked, sim.gravity,
              sim.damping, 0.0)  # dt = 0: positions do not move between calls
        return f

    print(f"N = {n}, candidate pairs = {ss.n}, layer = {numba.config.THREADING_LAYER}, "
          f"NUMBA_NUM_THREADS = {numba.config.NUMBA_NUM_THREADS}")
    for name, k, mk in (("sphere_sphere_forces", pairs.loop, ssf),
                        ("sum_sphere_pairs", forces.sum_sphere_pairs, sums),
                        ("leapfrog_cundall", integrator.leapfrog_cundall, integ)):
        numba.set_num_threads(1)
        ts = timeit(mk(k.serial))
        tp1 = timeit(mk(k.parallel))
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        tp2 = timeit(mk(k.parallel))
        print(f"{name:22s} serial {ts * 1e6:9.1f} us   parallel/1 thr {tp1 * 1e6:9.1f} us   "
              f"parallel/{numba.get_num_threads()} thr {tp2 * 1e6:9.1f} us", flush=True)
    ss.history[:], ss.state[:], ss.params[:] = hist
    p.pos[:], p.vel[:], p.angvel[:] = pos0, vel0, w0


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10000)
