"""Where the time of a step goes: ns per particle-step per kernel, on one thread.

    python -m bench.profile [--sizes 10000 50000 200000] [--steps 200] [--roofline]

Builds the cached settled bed of each size (`bench.__main__.bed`; 200k is the tiled 50k bed),
runs 50 warm-up steps, then profiles ``--steps`` steps with cProfile (a compiled kernel is one
call, so its time is exact; the profiler's own cost is on the Python side only) and prints, per
kernel, the time per particle-step [ns] and its share of the step. Neighbour rebuilds are
amortised over the steps. Writes ``bench/profile.json``.

``--roofline`` also measures this machine's ceilings on one core: the memory bandwidth of a
streaming triad (a = b + s c over 3 × 160 MB) [GB/s], and the throughput of independent
double divisions and square roots [ns each], the operations the Yade-exact law chains.
"""
import argparse
import cProfile
import json
import pstats
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def profile(n, steps):
    from bench.__main__ import bed, make_scene

    pos, radius = bed(n)
    sim = make_scene(pos, radius).build()
    sim.run(50)
    rebuilds = sim.n_rebuilds
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    sim.run(steps)
    prof.disable()
    wall = time.perf_counter() - t0
    stats = pstats.Stats(prof).stats
    rows = {}
    for (path, _, name), (_, calls, tottime, _, _) in stats.items():
        if "/pdem/" not in path and "/bench/" not in path:
            key = "python and numpy (rest)"
        else:
            key = f"{Path(path).stem}.{name}"
        calls_, t = rows.get(key, (0, 0.0))
        rows[key] = (calls_ + calls, t + tottime)
    scale = 1e9 / (n * steps)
    table = sorted(((k, c, t * scale) for k, (c, t) in rows.items()), key=lambda r: -r[2])
    return {"n": n, "steps": steps, "wall_s": wall, "rebuilds": sim.n_rebuilds - rebuilds,
            "ns_per_particle_step": wall * scale,
            "kernels": [{"name": k, "calls": c, "ns": ns} for k, c, ns in table if ns >= 0.5]}


def roofline():
    import numpy as np
    from numba import njit

    @njit
    def triad(a, b, c, s):
        for k in range(a.shape[0]):
            a[k] = b[k] + s * c[k]

    @njit
    def divs(x, reps):
        acc = 0.0
        for _ in range(reps):
            for k in range(x.shape[0]):  # independent divisions (no chain): throughput
                acc += 1.0 / x[k]
        return acc

    @njit
    def sqrts(x, reps):
        acc = 0.0
        for _ in range(reps):
            for k in range(x.shape[0]):
                acc += np.sqrt(x[k])
        return acc

    n = 20_000_000
    a, b, c = np.zeros(n), np.ones(n), np.ones(n)
    triad(a, b, c, 2.0)
    best = min(_timed(triad, a, b, c, 2.0) for _ in range(5))
    x = np.linspace(1.0, 2.0, 4096)
    divs(x, 1), sqrts(x, 1)
    reps = 2000
    t_div = min(_timed(divs, x, reps) for _ in range(3)) / (reps * len(x))
    t_sqrt = min(_timed(sqrts, x, reps) for _ in range(3)) / (reps * len(x))
    return {"triad_GB_per_s": 3 * 8 * n / best / 1e9, "division_ns": t_div * 1e9, "sqrt_ns": t_sqrt * 1e9}


def _timed(f, *args):
    t0 = time.perf_counter()
    f(*args)
    return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10000, 50000, 200000])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--roofline", action="store_true", help="also measure bandwidth and division/sqrt throughput")
    args = ap.parse_args(argv)
    import numba

    numba.set_num_threads(1)
    out = []
    for n in args.sizes:
        rec = profile(n, args.steps)
        out.append(rec)
        print(f"\nN = {n}: {rec['ns_per_particle_step']:.0f} ns per particle-step "
              f"({rec['rebuilds']} rebuilds in {rec['steps']} steps)")
        for k in rec["kernels"]:
            print(f"  {k['name']:<42} {k['calls']:>6} calls {k['ns']:8.1f} ns "
                  f"{100 * k['ns'] / rec['ns_per_particle_step']:5.1f} %")
    record = {"profiles": out}
    if args.roofline:
        record["roofline"] = roofline()
        print("\nroofline (one core): " + ", ".join(f"{k} {v:.2f}" for k, v in record["roofline"].items()))
    (HERE / "profile.json").write_text(json.dumps(record, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
