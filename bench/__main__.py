"""``make bench``: throughput of pdem on a dense settled ballast bed.

Bed: spheres r = 16.25 mm ± 40 %, ρ = 2600 kg/m³, linear model (E = 2.8e6 Pa, ν 0.3, φ 0.5),
Cundall damping 0.3, gravity, five steel walls (10 E). The packing is made once by the benchmark
itself (a seeded loose cloud settled under gravity) and cached in ``bench/cache/``. Each case
runs `--steps` steps after a warm-up and records, in ``bench/results.json`` (a list of records):
case, n_particles, ranks, threads, steps, wall_s, particle_steps_per_s, contacts_per_particle,
bytes_per_particle, and the time split neighbours / contacts / integration / communication.

Clump bed (``clump_bed_N``): N member spheres in N/8 rigid 8-sphere clumps (member r = 8.5 mm,
SPEC 2.3; `pdem.bodies.clump_generators.ballast8`, randomly turned, settled once and cached), the same
materials, damping and walls; ``particle_steps_per_s`` counts member-steps, and
``per_member_ratio`` is that over the sphere bed of the same N and threads.

    python -m bench [--sizes 10000 50000 200000] [--clump-sizes 50000] [--threads 1 2] [--steps 200]
    python -m bench --mpi [--mpi-sizes 50000 200000] [--ranks 1 2] [--steps 300]

``--mpi``: the slab-decomposed code (slabs along x, the long axis of the box) on 1 and 2 ranks,
each run as ``mpiexec -n R python -m bench --one-mpi N`` with one numba thread per rank
(NUMBA_NUM_THREADS=1). Records get ``ranks``, ``comm_s`` (max over ranks of the time in the
communication timer: ghost update every step plus the domain rebuild, i.e. migration, load
balancing and ghost-layer set-up, including the wait for the slower neighbour) and
``halo_fraction`` (ghost bodies summed over ranks / owned bodies). The 200k bed is the cached 50k
bed tiled 2 x 2 in x, y (the box of 4 N spheres is exactly twice as long and twice as wide),
see `tiled_bed`. For R > 1 the same case is also run as R independent 1-rank processes at
once (``independent_ceiling``: their summed throughput over one alone), the speedup this
machine allows without any MPI traffic: on a machine shared with other jobs it is well below R.
MPI records are merged into ``bench/results.json`` (replacing the records of
the same case, ranks and threads).
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
CLUMP_MEMBER_R = 0.0085


def make_scene(pos=None, radius=None, n=None, seed=7):
    from pdem import Scene
    from pdem.build.generators import loose_cloud

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
    from pdem.driver.observables import unbalanced_force

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


def tiled_bed(n):
    """(pos, radius) of 4 copies of the settled bed of n/4 spheres, 2 x 2 in x, y.

    make_scene's box side grows like sqrt(n), so the box of n spheres is exactly 2 x 2 boxes of
    n/4: the copies fit the walls. Seams are two wall-side faces of the small bed (allowed
    overlaps at most the small wall overlaps); the benchmark lets the bed relax in its warm-up."""
    path = CACHE / f"bed_{n}.npz"
    if path.exists():
        d = np.load(path)
        return d["pos"], d["radius"]
    m = n // 4
    if 4 * m != n:
        raise ValueError(f"tiled bed: {n} is not a multiple of 4")
    pos, radius = settled_bed(m)
    side_y = max(0.3, (m * 2.3e-5 / 0.6 / 0.6 / 2.0) ** 0.5)
    parts = [pos + np.array([ix * 2.0 * side_y, iy * side_y, 0.0]) for iy in (0, 1) for ix in (0, 1)]
    pos4, rad4 = np.concatenate(parts), np.concatenate([radius] * 4)
    np.savez(path, pos=pos4, radius=rad4, tiled_from=m)
    print(f"tiled bed of {n} spheres from 4 x {m} (cached in {path})", flush=True)
    return pos4, rad4


def bed(n):
    """Settled bed of n spheres: made by settling up to 50k, tiled from n/4 above."""
    if n > 50000 and n % 4 == 0 and not (CACHE / f"bed_{n}.npz").exists():
        return tiled_bed(n)
    return settled_bed(n)


def make_clump_scene(grains=None, n_members=None, seed=7):
    """The clump bed: 8-sphere clumps (member r = 8.5 mm, SPEC 2.3; the materials, damping and
    walls of the sphere bed) in a box scaled so that the settled bed is about 0.6 m high."""
    from pdem import Scene
    from pdem.bodies.clump_generators import ballast8, grain_cloud

    n_clumps = len(grains) if grains is not None else n_members // 8
    side_y = max(0.3, (n_clumps * 4.5e-5 / 0.6 / 2.0) ** 0.5)
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([2.0 * side_y, side_y, 40.0])
    if grains is None:
        pos, radius = ballast8(CLUMP_MEMBER_R)
        grains = grain_cloud(pos, radius, lo, hi, n_clumps, seed)
    scene = Scene(dt="auto", damping=0.3, gravity=(0, 0, -9.81), allow_initial_overlap=True, energy_check=False)
    ballast = scene.material(name="ballast", density=2600, young=2.8e6, poisson=0.3, friction_angle=0.5)
    steel = scene.material(name="steel", density=7850, young=2.8e7, poisson=0.25, friction_angle=0.5)
    scene.add_clumps(grains, ballast)
    scene.add_wall("z", 0.0, steel, sense=1)
    scene.add_wall("x", lo[0], steel, sense=1)
    scene.add_wall("x", hi[0], steel, sense=-1)
    scene.add_wall("y", lo[1], steel, sense=1)
    scene.add_wall("y", hi[1], steel, sense=-1)
    return scene


def settled_clump_bed(n_members):
    """[(member pos [8, 3], member radius [8])] of a settled clump bed, from the cache or made now."""
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"clump_bed_{n_members}.npz"
    if path.exists():
        d = np.load(path)
        return [(p, r) for p, r in zip(d["pos"], d["radius"])]
    print(f"making a settled bed of {n_members // 8} 8-sphere clumps (cached in {path}) ...", flush=True)
    sim = make_clump_scene(n_members=n_members).build()
    sim.damping = 0.7  # settles faster (the measured runs use the scene's 0.3)
    t0 = time.perf_counter()
    from pdem.driver.observables import unbalanced_force

    while True:
        sim.run(500)
        ub = unbalanced_force(sim)
        vmax = float(np.abs(sim.clumps.vel).max())
        print(f"  step {sim.step}  t = {sim.time:.3f} s  unbalanced = {ub:.3f}  v_max = {vmax:.3f} m/s", flush=True)
        if (sim.time > 1.0 and ub < 0.01) or sim.step > 12000:
            break
    p = sim.particles
    order = np.argsort(p.gid[: p.n_local])
    pos, radius = p.pos[order].reshape(-1, 8, 3), p.radius[order].reshape(-1, 8)
    np.savez(path, pos=pos, radius=radius)
    print(f"  settled in {time.perf_counter() - t0:.0f} s", flush=True)
    return [(a, b) for a, b in zip(pos, radius)]


def run_clump_case(n, threads, steps):
    """One measurement of the clump bed of n members in this process."""
    import numba

    numba.set_num_threads(threads)
    sim = make_clump_scene(settled_clump_bed(n)).build()
    sim.run(50)
    for k in sim.timers.seconds:
        sim.timers.seconds[k] = 0.0
    rebuilds = sim.n_rebuilds
    t0 = time.perf_counter()
    sim.run(steps)
    wall = time.perf_counter() - t0
    split = dict(sim.timers.seconds)
    nbytes = sim.memory_bytes()
    return {
        "case": f"clump_bed_{n}",
        "n_particles": int(n),
        "clumps": int(sim.clumps.n),
        "ranks": 1,
        "threads": threads,
        "steps": steps,
        "wall_s": wall,
        "particle_steps_per_s": n * steps / wall,
        "contacts_per_particle": sim.contacts_per_particle(),
        "bytes_per_particle": nbytes / n,
        "rebuilds": sim.n_rebuilds - rebuilds,
        "dt": sim.dt,
        "neighbours_s": split["neighbours"],
        "contacts_s": split["contacts"],
        "integration_s": split["integration"],
        "comm_s": split["communication"],
        "other_s": split["other"] + split["output"],
        "halo_fraction": 0.0,
        "machine": f"{platform.machine()} {os.cpu_count()} cores",
        "date": time.strftime("%Y-%m-%d"),
    }


def clump_ratios(records):
    """Lines: member-steps/s of each clump bed over the particle-steps/s of the sphere bed of the
    same size and threads (records of this run, else of bench/results.json)."""
    path = HERE / "results.json"
    known = (json.loads(path.read_text()) if path.exists() else []) + records
    out = []
    for r in records:
        if not r["case"].startswith("clump_bed_"):
            continue
        base = [b for b in known if b["case"] == f"settled_bed_{r['n_particles']}" and b["threads"] == r["threads"]
                and not b.get("mpi")]
        if base:
            ratio = r["particle_steps_per_s"] / base[-1]["particle_steps_per_s"]
            r["per_member_ratio"] = ratio
            out.append(f"{r['case']} ({r['clumps']} clumps), {r['threads']} thread(s): "
                       f"{r['particle_steps_per_s'] / 1e6:.2f} M member-steps/s = {100 * ratio:.0f} % of the sphere "
                       f"bed's {base[-1]['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s")
    return "\n".join(out)


def run_mpi_case(n, steps):
    """One measurement on the ranks of this mpiexec job (one numba thread per rank)."""
    import numba

    from pdem.parallel.comm import get_comm

    numba.set_num_threads(1)
    comm = get_comm()
    pos, radius = bed(n)
    sim = make_scene(pos, radius).build(comm=comm)
    sim.run(50)  # warm-up: compilation, cache loads, first migration / load balancing
    for k in sim.timers.seconds:
        sim.timers.seconds[k] = 0.0
    sim.domain.comm_seconds = 0.0
    rebuilds = sim.n_rebuilds
    comm.barrier()
    t0 = time.perf_counter()
    sim.run(steps)
    comm.barrier()
    wall = time.perf_counter() - t0
    p = sim.particles
    split = {k: comm.allreduce_max(v) for k, v in sim.timers.seconds.items()}
    nbytes = sim.memory_bytes()
    nbytes = comm.allreduce_sum_int(int(nbytes))
    owned = comm.allreduce_sum_int(int(p.n_local))
    ghosts = comm.allreduce_sum_int(int(p.n_ghost))
    cpp = sim.contacts_per_particle()
    n_owned = comm.gather_rows(np.array([p.n_local], np.int64))
    ghost_rows = comm.gather_rows(np.array([p.n_ghost], np.int64))
    edges = getattr(sim.domain, "edges", None)
    # bytes sent per step in the ghost update: 9 float64 per ghost row (pos, vel, angvel)
    rec = {"case": f"settled_bed_{n}", "n_particles": int(n), "ranks": comm.size, "threads": 1, "steps": steps,
           "wall_s": wall, "particle_steps_per_s": n * steps / wall,
           "contacts_per_particle": cpp, "bytes_per_particle": nbytes / n,
           "rebuilds": sim.n_rebuilds - rebuilds, "dt": sim.dt,
           "neighbours_s": split["neighbours"], "contacts_s": split["contacts"],
           "integration_s": split["integration"], "comm_s": split["communication"],
           "domain_comm_s": comm.allreduce_max(float(sim.domain.comm_seconds)),
           "other_s": split["other"] + split["output"], "halo_fraction": ghosts / max(owned, 1),
           "ghosts": int(ghosts), "ghost_bytes_per_step": int(ghosts) * 9 * 8,
           "owned_per_rank": [int(v) for v in np.asarray(n_owned).ravel()] if comm.rank == 0 else None,
           "ghosts_per_rank": [int(v) for v in np.asarray(ghost_rows).ravel()] if comm.rank == 0 else None,
           "edges": [float(e) for e in edges] if edges is not None else None,
           "mpi": True, "machine": f"{platform.machine()} {os.cpu_count()} cores", "date": time.strftime("%Y-%m-%d")}
    return rec if comm.rank == 0 else None


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
    split = dict(sim.timers.seconds)
    nbytes = sim.memory_bytes()
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
        lines.append(
            f"{r['case']:<20} {r['ranks']:>5} {r['threads']:>3} {r['steps']:>6} {w:>8.2f} "
            f"{r['particle_steps_per_s'] / 1e6:>11.2f} {r['contacts_per_particle']:>5.2f} "
            f"{r['bytes_per_particle']:>6.0f} {100 * r['neighbours_s'] / w:>6.1f} {100 * r['contacts_s'] / w:>6.1f} "
            f"{100 * r['integration_s'] / w:>6.1f} {100 * r['comm_s'] / w:>6.1f}"
        )
    return "\n".join(lines)


def speedups(records):
    """Lines 'N: R ranks x.xx x' relative to the 1-rank MPI record of the same size."""
    out = []
    for r in records:
        base = [b for b in records if b.get("mpi") and b["n_particles"] == r["n_particles"] and b["ranks"] == 1]
        if r.get("mpi") and r["ranks"] > 1 and base:
            s = base[0]["wall_s"] / r["wall_s"] * r["steps"] / base[0]["steps"]
            out.append(f"{r['case']}: {r['ranks']} ranks  speedup {s:.2f}x  efficiency {100 * s / r['ranks']:.0f} %  "
                       f"comm {100 * r['comm_s'] / r['wall_s']:.1f} % of wall  halo fraction {r['halo_fraction']:.3f}")
            if r.get("independent_ceiling"):
                out[-1] += (f"  (machine ceiling: {r['ranks']} independent 1-rank runs at once "
                            f"{r['independent_ceiling']['ceiling']:.2f}x)")
    return "\n".join(out)


def merge_results(new):
    """Write `new` into results.json, replacing records with the same (case, ranks, threads, mpi)."""
    path = HERE / "results.json"
    old = json.loads(path.read_text()) if path.exists() else []
    keys = {(r["case"], r["ranks"], r["threads"], bool(r.get("mpi"))) for r in new}
    kept = [r for r in old if (r["case"], r["ranks"], r["threads"], bool(r.get("mpi"))) not in keys]
    path.write_text(json.dumps(kept + new, indent=1) + "\n")
    return kept + new


def ceiling(mpiexec, env, n, r, steps):
    """Speedup this machine allows r processes: r independent 1-rank runs at once (no MPI
    traffic between them), their summed throughput over that of one run alone."""
    cmd = [str(mpiexec), "-n", "1", sys.executable, "-m", "bench", "--one-mpi", str(n), "--steps", str(steps)]

    def rate(outs):
        return [json.loads([l for l in o.splitlines() if l.startswith("RESULT ")][-1][7:])["particle_steps_per_s"]
                for o in outs]

    alone = rate([subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=HERE.parent).stdout])[0]
    procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                              cwd=HERE.parent) for _ in range(r)]
    together = rate([pr.communicate()[0] for pr in procs])
    return {"alone_particle_steps_per_s": alone, "together_particle_steps_per_s": together,
            "ceiling": sum(together) / alone}


def main_mpi(args):
    mpiexec = Path(sys.executable).parent / "mpiexec"
    records = []
    for n in args.mpi_sizes:
        bed(n)  # made (or tiled) once, serially, before any mpiexec
        for r in args.ranks:
            env = dict(os.environ, NUMBA_NUM_THREADS="1")
            cmd = [str(mpiexec), "-n", str(r), sys.executable, "-m", "bench", "--one-mpi", str(n),
                   "--steps", str(args.steps)]
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=HERE.parent)
            if out.returncode != 0:
                print(out.stdout, out.stderr, file=sys.stderr)
                return 1
            rec = json.loads([l for l in out.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])
            if r > 1 and not args.no_ceiling:
                rec["independent_ceiling"] = ceiling(mpiexec, env, n, r, args.steps)
            records.append(rec)
            print(table([rec]).splitlines()[-1], flush=True)
    merge_results(records)
    print("\n" + table(records))
    print("\n" + speedups(records))
    print(f"\nwrote {HERE / 'results.json'}")
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10000, 50000, 200000])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--mpi", action="store_true", help="run the MPI cases (1 vs 2 ranks) instead")
    ap.add_argument("--mpi-sizes", type=int, nargs="+", default=[50000, 200000])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--no-ceiling", action="store_true",
                    help="skip the reference run of R independent 1-rank processes at once")
    ap.add_argument("--clump-sizes", type=int, nargs="*", default=[50000],
                    help="member counts of the clump beds (8-sphere clumps); none: skip them")
    ap.add_argument("--one", nargs=2, type=int, metavar=("N", "THREADS"), help=argparse.SUPPRESS)
    ap.add_argument("--one-clumps", nargs=2, type=int, metavar=("N", "THREADS"), help=argparse.SUPPRESS)
    ap.add_argument("--one-mpi", type=int, metavar="N", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one_mpi:
        rec = run_mpi_case(args.one_mpi, args.steps)
        if rec is not None:
            print("RESULT " + json.dumps(rec), flush=True)
        return 0
    if args.mpi:
        return main_mpi(args)
    if args.one:
        print("RESULT " + json.dumps(run_case(args.one[0], args.one[1], args.steps)), flush=True)
        return 0
    if args.one_clumps:
        print("RESULT " + json.dumps(run_clump_case(args.one_clumps[0], args.one_clumps[1], args.steps)), flush=True)
        return 0
    records = []
    cases = [("--one", n, bed) for n in args.sizes] + [("--one-clumps", n, settled_clump_bed)
                                                                for n in args.clump_sizes]
    for flag, n, prepare in cases:
        prepare(n)
        for th in args.threads:
            env = dict(os.environ, NUMBA_NUM_THREADS=str(max(args.threads)))
            out = subprocess.run([sys.executable, "-m", "bench", flag, str(n), str(th), "--steps", str(args.steps)],
                                 env=env, capture_output=True, text=True, cwd=HERE.parent)
            if out.returncode != 0:
                print(out.stdout, out.stderr, file=sys.stderr)
                return 1
            rec = json.loads([l for l in out.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])
            records.append(rec)
            print(table([rec]).splitlines()[-1], flush=True)
    ratios = clump_ratios(records)
    merge_results(records)
    print("\n" + table(records))
    if ratios:
        print("\n" + ratios)
    print(f"\nwrote {HERE / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
