"""``make bench``: throughput of pdem on a dense settled ballast bed.

Bed: spheres r = 16.25 mm ± 40 %, ρ = 2600 kg/m³, linear model (E = 2.8e6 Pa, ν 0.3, φ 0.5),
Cundall damping 0.3, gravity, five steel walls (10 E). The packing is made once by the benchmark
itself (a seeded loose cloud settled under gravity) and cached in ``bench/cache/``. Each case
runs `--steps` steps after a warm-up and records, in ``bench/results.json`` (a list of records):
case, n_particles, ranks, threads, steps, wall_s, particle_steps_per_s, contacts_per_particle,
bytes_per_particle, and the time split neighbours / contacts / integration / communication.

    python -m bench [--sizes 10000 50000] [--threads 1 2] [--steps 200]
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CACHE = HERE / "cache"
R_MEAN = 0.01625


def make_scene(pos=None, radius=None, n=None, seed=7):
    from pdem import Scene
    from pdem.generators import loose_cloud

    n = len(radius) if radius is not None else n
    # base of the box scaled so that the settled bed is about 0.6 m high
    side_y = max(0.3, (n * 2.3e-5 / 0.6 / 0.6 / 2.0) ** 0.5)
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([2.0 * side_y, side_y, 40.0])
    if pos is None:
        pos, radius = loose_cloud(lo, hi, n, R_MEAN, 0.4, seed)
    scene = Scene(dt="auto", damping=0.3, gravity=(0, 0, -9.81), allow_initial_overlap=True, energy_check=False)
    ballast = scene.material(name="ballast", density=2600, young=2.8e6, poisson=0.3, friction_angle=0.5)
    steel = scene.material(name="steel", density=7850, young=2.8e7, poisson=0.25, friction_angle=0.5)
    scene.add_spheres(pos, radius, ballast)
    scene.add_wall("z", 0.0, steel, sense=1)
    scene.add_wall("x", lo[0], steel, sense=1)
    scene.add_wall("x", hi[0], steel, sense=-1)
    scene.add_wall("y", lo[1], steel, sense=1)
    scene.add_wall("y", hi[1], steel, sense=-1)
    return scene


def settled_bed(n):
    """(pos, radius) of a settled bed of n spheres, from the cache or made now."""
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"bed_{n}.npz"
    if path.exists():
        d = np.load(path)
        return d["pos"], d["radius"]
    print(f"making a settled bed of {n} spheres (cached in {path}) ...", flush=True)
    sim = make_scene(n=n).build()
    t0 = time.perf_counter()
    from pdem.observables import unbalanced_force

    while True:
        sim.run(500)
        p = sim.particles
        ub = unbalanced_force(sim)
        vmax = float(np.abs(p.vel[: p.n_local]).max())
        print(f"  step {sim.step}  t = {sim.time:.3f} s  unbalanced = {ub:.3f}  v_max = {vmax:.3f} m/s", flush=True)
        if (sim.time > 1.2 and ub < 0.01) or sim.step > 20000:
            break
    order = np.argsort(p.gid[: p.n_local])
    np.savez(path, pos=p.pos[order], radius=p.radius[order])
    print(f"  settled in {time.perf_counter() - t0:.0f} s", flush=True)
    return p.pos[order], p.radius[order]


def run_case(n, threads, steps):
    """One measurement in this process (threads already fixed by the environment)."""
    import numba

    numba.set_num_threads(threads)
    pos, radius = settled_bed(n)
    sim = make_scene(pos, radius).build()
    sim.run(50)  # warm-up: compilation and cache loads are not measured
    for k in sim.timers.seconds:
        sim.timers.seconds[k] = 0.0
    rebuilds = sim.n_rebuilds
    t0 = time.perf_counter()
    sim.run(steps)
    wall = time.perf_counter() - t0
    p = sim.particles
    split = dict(sim.timers.seconds)
    nbytes = p.bytes_per_particle() * p.n_total + sum(c.bytes() for c in (sim.ss, sim.sw) if c is not None)
    return {"case": f"settled_bed_{n}", "n_particles": int(n), "ranks": 1, "threads": threads, "steps": steps,
            "wall_s": wall, "particle_steps_per_s": n * steps / wall,
            "contacts_per_particle": sim.contacts_per_particle(), "bytes_per_particle": nbytes / n,
            "rebuilds": sim.n_rebuilds - rebuilds, "dt": sim.dt,
            "neighbours_s": split["neighbours"], "contacts_s": split["contacts"],
            "integration_s": split["integration"], "comm_s": split["communication"],
            "other_s": split["other"] + split["output"], "halo_fraction": 0.0,
            "machine": f"{platform.machine()} {os.cpu_count()} cores", "date": time.strftime("%Y-%m-%d")}


def table(records):
    head = (f"{'case':<20} {'ranks':>5} {'thr':>3} {'steps':>6} {'wall s':>8} {'M p-steps/s':>11} {'c/p':>5} "
            f"{'B/p':>6} {'neigh%':>6} {'cont%':>6} {'integ%':>6} {'comm%':>6}")
    lines = [head, "-" * len(head)]
    for r in records:
        w = r["wall_s"]
        lines.append(f"{r['case']:<20} {r['ranks']:>5} {r['threads']:>3} {r['steps']:>6} {w:>8.2f} "
                     f"{r['particle_steps_per_s'] / 1e6:>11.2f} {r['contacts_per_particle']:>5.2f} "
                     f"{r['bytes_per_particle']:>6.0f} {100 * r['neighbours_s'] / w:>6.1f} {100 * r['contacts_s'] / w:>6.1f} "
                     f"{100 * r['integration_s'] / w:>6.1f} {100 * r['comm_s'] / w:>6.1f}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10000, 50000])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--one", nargs=2, type=int, metavar=("N", "THREADS"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print("RESULT " + json.dumps(run_case(args.one[0], args.one[1], args.steps)), flush=True)
        return 0
    records = []
    for n in args.sizes:
        settled_bed(n)
        for th in args.threads:
            env = dict(os.environ, NUMBA_NUM_THREADS=str(max(args.threads)), NUMBA_THREADING_LAYER="workqueue")
            out = subprocess.run([sys.executable, "-m", "bench", "--one", str(n), str(th), "--steps", str(args.steps)],
                                 env=env, capture_output=True, text=True, cwd=HERE.parent)
            if out.returncode != 0:
                print(out.stdout, out.stderr, file=sys.stderr)
                return 1
            rec = json.loads([l for l in out.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])
            records.append(rec)
            print(table([rec]).splitlines()[-1], flush=True)
    (HERE / "results.json").write_text(json.dumps(records, indent=1) + "\n")
    print("\n" + table(records))
    print(f"\nwrote {HERE / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
