"""Cost of the runaway guard (`pdem.checks.guard`): the same dense bed stepped by two source trees,
alternating, one numba thread.

    python bench/guard_overhead.py BEFORE_SRC AFTER_SRC [--n 50000] [--steps 300] [--rounds 3]
    python bench/guard_overhead.py --pass-only [--n 50000]

BEFORE_SRC and AFTER_SRC are checkouts of pdem (e.g. ``git archive <commit> | tar -x -C DIR``);
each case runs in a fresh process with that tree first on sys.path and its own numba cache
(``DIR/.numba_cache``). The bed: n spheres r = 10 mm on a cubic lattice 0.5 % closer than
touching (six contacts each, a dense pack's count), E = 2.8e6 Pa, Cundall damping 0.3, gravity,
a floor and four walls; `--steps` steps are timed after 30 warm-up steps (compilation). Prints
for each run the fastest of six chunks of steps (per step) and the fastest of six timings of the
force loops alone (`Simulation.compute_forces`, 20 calls each), and the medians per tree.

``--pass-only``: the one pass that does more work, timed alone in this process: the rebuild
test's loop over the bodies before (largest displacement since the rebuild) and after
(`pdem.contact.neighbors.max_motion`: also the largest |v|/r, reading v and r too), serial, n bodies;
median over 10 rounds of the fastest of 5 × 50 calls.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

CASE = r"""
import json, sys, time
import numpy as np
import numba
numba.set_num_threads(1)
from pdem import Scene
n, steps = int(sys.argv[1]), int(sys.argv[2])
r, a = 0.01, 0.0199
nx, ny = 50, 25
nz = -(-n // (nx * ny))
g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)[:n]
pos = (g + 0.5) * a + np.array([0.0, 0.0, r])
sc = Scene(dt="auto", damping=0.3, gravity=(0.0, 0.0, -9.81), allow_initial_overlap=True)
m = sc.material(density=2600.0, young=2.8e6, poisson=0.3, friction_angle=0.5)
w = sc.material(density=7850.0, young=2.8e7, poisson=0.25, friction_angle=0.5)
sc.add_spheres(pos, r, m)
sc.add_wall(2, 0.0, w, sense=1)
sc.add_wall(0, 0.0, w, sense=1)
sc.add_wall(0, nx * a + 2 * r, w, sense=-1)
sc.add_wall(1, 0.0, w, sense=1)
sc.add_wall(1, ny * a + 2 * r, w, sense=-1)
sim = sc.build()
sim.run(30)
chunks = []  # the fastest of 6 chunks: the least disturbed by other jobs on the machine
for _ in range(6):
    t0 = time.perf_counter()
    sim.run(steps // 6)
    chunks.append((time.perf_counter() - t0) / (steps // 6))
forces = []  # the force loops alone (what the overlap reduction adds to), the fastest of 6 x 20 calls
for _ in range(6):
    t0 = time.perf_counter()
    for _ in range(20):
        sim.compute_forces()
    forces.append((time.perf_counter() - t0) / 20)
print(json.dumps({"s_per_step": min(chunks), "forces_s": min(forces), "pdem": sys.modules["pdem"].__file__}))
"""


def one(src, n, steps):
    env = dict(os.environ, PYTHONPATH=os.path.abspath(src), NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1",
               NUMBA_CACHE_DIR=os.path.join(os.path.abspath(src), ".numba_cache"))
    out = subprocess.run([sys.executable, "-c", CASE, str(n), str(steps)], env=env, capture_output=True, text=True,
                         check=True, cwd=os.path.abspath(src))
    return json.loads(out.stdout.strip().splitlines()[-1])


def pass_only(n):
    import time

    import numpy as np
    from numba import njit

    from pdem.contact.neighbors import max_motion

    @njit
    def before(pos, pos_at_rebuild, n):  # pdem.contact.neighbors.max_displacement before the guard
        m = 0.0
        for k in range(n):
            dx = pos[k, 0] - pos_at_rebuild[k, 0]
            dy = pos[k, 1] - pos_at_rebuild[k, 1]
            dz = pos[k, 2] - pos_at_rebuild[k, 2]
            m = max(m, dx * dx + dy * dy + dz * dz)
        return m ** 0.5

    rng = np.random.default_rng(0)
    pos = rng.random((n, 3))
    old = pos + 1e-4 * rng.random((n, 3))
    vel, r = 1e-3 * rng.random((n, 3)), 0.01 + 0.001 * rng.random(n)
    after = max_motion.serial
    before(pos, old, n)
    after(pos, old, vel, r, n)
    res = {"before": [], "after": []}
    for _ in range(10):
        for name, f, args in (("before", before, (pos, old, n)), ("after", after, (pos, old, vel, r, n))):
            best = np.inf
            for _ in range(5):
                t0 = time.perf_counter()
                for _ in range(50):
                    f(*args)
                best = min(best, (time.perf_counter() - t0) / 50)
            res[name].append(best)
    b, a = statistics.median(res["before"]), statistics.median(res["after"])
    print(f"rebuild-test pass at {n} bodies: before {1e6 * b:.1f} us, after {1e6 * a:.1f} us ({1e6 * (a - b):+.1f} us)")


def main():
    if "--pass-only" in sys.argv:
        n = int(sys.argv[sys.argv.index("--n") + 1]) if "--n" in sys.argv else 50000
        return pass_only(n)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--n", type=int, default=50000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    times = {"before": [], "after": []}
    forces = {"before": [], "after": []}
    for k in range(args.rounds):
        for name in ("before", "after") if k % 2 == 0 else ("after", "before"):
            rec = one(getattr(args, name), args.n, args.steps)
            times[name].append(rec["s_per_step"])
            forces[name].append(rec["forces_s"])
            print(
                f"round {k} {name:6s} {1e3 * rec['s_per_step']:8.3f} ms/step  force loops "
                f"{1e3 * rec['forces_s']:8.3f} ms"
                f"  ({rec['pdem']})",
                flush=True,
            )
    for what, d in (("step", times), ("force loops", forces)):
        b, a = statistics.median(d["before"]), statistics.median(d["after"])
        print(f"{what}: median before {1e3 * b:.3f} ms, after {1e3 * a:.3f} ms: {100 * (a / b - 1):+.2f} %")


if __name__ == "__main__":
    main()
