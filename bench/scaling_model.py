"""Scaling model of the slab decomposition, from the measured MPI benchmark and ping-pong.

    python -m bench.scaling_model [--length 6 --width 4 --depth 0.5]
    python -m bench.scaling_model --scene track --run1 RUN1 --run2 RUN2 [--png docs/scaling_track.png]
    python -m bench.scaling_model --scene track --inputs bench/track_scaling.json [--png ...]  (runs' inputs
        stored by the line above; the packing u, o measured again)
    python -m bench.scaling_model --packing G [G ...]   (u, o of the packing: numba vs numpy)
    mpiexec -n 2 python -m bench.scaling_model --ghost-update N   (time per ghost update, messages included)

Reads bench/results.json (MPI records, ranks 1 and 2, the largest size measured) and
bench/pingpong.json (`python -m bench.pingpong` under mpiexec -n 2), and prints the model of
docs/scaling.md for a track section of the given size. Measured inputs are printed first;
everything after "model" is extrapolation.

Model, per step, P ranks, slabs of thickness T = L/P along the track (x):
    t(N, P) = c N/P + c_g g + 2 (alpha + 72 g/2 / beta) + ceil(log2 P) alpha + o
  c      compute per owned sphere-step, 1 rank (neighbour rebuilds amortised)      [measured]
  g      ghosts of an interior rank = 2 n_x h, n_x spheres per metre of x, h = 2 r_max + skin
  c_g    extra compute per ghost-step: a pair of an owned body and a ghost is computed by both
         ranks, and ghosts' cells are scanned; about half a ghost's contacts reach owned bodies,
         so c_g = c/2 [modelled]. The 2-rank fit (compute_2 - c N/2) / ghosts_per_rank is
         printed too; on a machine shared with other jobs it measures contention, not ghosts.
  alpha, beta  latency and bandwidth of one message (pos, vel, angvel: 72 B per ghost)   [ping-pong]
  log2 P alpha the rebuild test (an allreduce of the max displacement) every step
  u g    packing/unpacking the ghost update (numba kernels of `pdem.parallel.packing`, 9
         float64 per ghost) plus the ghost-layer rebuild (`pack_fields` of every FIELDS column)
         every k steps (k from the benchmark's rebuild count), per ghost   [measured here, serial]
  o      per rank-step fixed Python overhead of the pack/unpack calls            [measured, serial]
    python -m bench.scaling_model --packing 1978 2793 8600   times u, o of the numba path and of
         the numpy path it replaced (alternating, 3 times): the A/B of docs/scaling.md
The residual of the measured 2-rank communication time (waiting for the slower rank, load
imbalance, CPU contention) is printed, not modelled.
Efficiency E(P) = c N / (P t(N, P)). Interior slabs exist only while T >= h: P_max = L / h.

``--scene track`` (`track_model`): the same model measured on the track section
(`pdem.scenes.track`), from the ``scaling.json`` of a 1-rank and a 2-rank run of that scene
(e.g. ``pdem run jobs/track_large_loading.toml --steps N`` from a prepared bed). Its bed has a
fixed cross-section, so a track of N bodies is L = N / n_x long (n_x bodies per metre,
measured) with L / spacing sleepers, and per step it adds to the model above:
  b      load imbalance of the busiest rank after balancing (max/mean of owned bodies +
         contacts, measured at 2 ranks; the sleepers make the work uneven along x)   [measured]
  the rigid sleepers' force sums: one allreduce of 3 n_b accumulators of 68 int64 (exact,
         rank-count independent sums, `comm.exact_sum_groups`) per step: ceil(log2 P)
         (alpha + 3 n_b 544 B / beta)                                                  [modelled]
  t(N, P) = b c N/P + c_g g + 2 (alpha + 72 g/2 / beta) + ceil(log2 P) alpha
            + ceil(log2 P) (alpha + 1632 n_b / beta) + u g + o
The halo per slab side is measured (the ghosts of the busier rank of the 2-rank run: one
neighbour); the track's cross-section is fixed, so it does not depend on N, and an interior slab
has twice that. It is compared with n_x h from the measured n_x and h = 2 r_max + skin.
"""
import argparse
import json
import math
import os
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
R_MEAN = 0.01625
BED_VOLUME_PER_SPHERE = 2.3e-5  # m^3 of settled bed per sphere (bench/__main__.make_scene)


def load():
    recs = [r for r in json.loads((HERE / "results.json").read_text()) if r.get("mpi")]
    n = max(r["n_particles"] for r in recs if r["ranks"] == 2)
    r1 = [r for r in recs if r["n_particles"] == n and r["ranks"] == 1][0]
    r2 = [r for r in recs if r["n_particles"] == n and r["ranks"] == 2][0]
    pp = json.loads((HERE / "pingpong.json").read_text())
    return n, r1, r2, pp


def measure_packing(g, k, reps=50, path="numba", repeats=5):
    """Seconds per ghost per step of the Python side of the exchange: (u, o), measured serially.

    Mirrors `SlabDomain.update_ghosts` (every step) and the ghost-layer rebuild (every k steps)
    on a `Particles` of 4 g owned bodies with g ghosts, half from each neighbour, without the
    messages (the received blocks are the packed ones). ``path``: "numba" (`pdem.parallel.
    packing`: buffers kept between steps) or "numpy" (the code before it, for the A/B: the
    concatenation of pos/vel/angvel rows and slice assignments every step, ``pack_rows(columns)``
    and ``unpack_rows`` at rebuilds). Each time is the best of ``repeats`` batches of ``reps``.
    u = (t_update(g) - t_update(2)) / g + t_rebuild(g) / (g k); o = t_update(2) (one row per list)."""
    import time

    from pdem.parallel.packing import GhostBuffers, field_views, pack_fields
    from pdem.parallel.slab_domain import pack_rows, unpack_rows
    from pdem.bodies.state import FIELDS, Particles

    if path not in ("numba", "numpy"):
        raise ValueError(f"path must be 'numba' or 'numpy', got {path!r}")
    g = max(int(g), 2)
    n = max(4 * g, 1000)
    rng = np.random.default_rng(1)
    p = Particles(n + g)
    p.append_local({key: rng.random((n,) + shape).astype(dtype) for key, (dtype, shape) in FIELDS.items()})
    rows = rng.choice(n, g, replace=False)  # send lists: unsorted, like after a spatial reorder
    lists = (rows[: g // 2], rows[g // 2 :])

    def ghost_update_numpy(lo, hi):  # main before packing.py: slab_domain.update_ghosts
        def pack(r):
            return np.concatenate([p.pos[r], p.vel[r], p.angvel[r]], axis=1)

        a = p.n_local
        for blk in (pack(lo), pack(hi)):
            b = a + blk.shape[0]
            p.pos[a:b], p.vel[a:b], p.angvel[a:b] = blk[:, 0:3], blk[:, 3:6], blk[:, 6:9]
            a = b

    def ghost_update_numba(gb):
        gb.pack(p.pos, p.vel, p.angvel)
        gb.unpack(p.pos, p.vel, p.angvel, p.n_local)

    def ghost_layer(lo, hi):
        if path == "numpy":
            (li, lf), (hi_, hf) = pack_rows(p.columns(lo), lo.size), pack_rows(p.columns(hi), hi.size)
            p.set_ghosts(unpack_rows(np.concatenate([li, hi_]), np.concatenate([lf, hf])))
        else:
            (li, lf), (hi_, hf) = pack_fields(vars(p), lo), pack_fields(vars(p), hi)
            p.set_ghosts(field_views(np.concatenate([li, hi_]), np.concatenate([lf, hf])))

    def timed(f, *a):
        f(*a)
        best = math.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            for _ in range(reps):
                f(*a)
            best = min(best, (time.perf_counter() - t0) / reps)
        return best

    ghost_layer(*lists)  # ghost rows exist (n_ghost = g) for the updates
    if path == "numpy":
        t_upd = timed(ghost_update_numpy, *lists)
        t_fixed = timed(ghost_update_numpy, lists[0][:1], lists[1][:1])
    else:
        gb, gb1 = GhostBuffers(), GhostBuffers()
        gb.set_lists(lists[0], lists[1], lists[0].size, lists[1].size)
        gb1.set_lists(lists[0][:1], lists[1][:1], 1, 1)
        t_upd = timed(ghost_update_numba, gb)
        t_fixed = timed(ghost_update_numba, gb1)
    t_reb = timed(ghost_layer, *lists)
    return (t_upd - t_fixed) / g + t_reb / g / k, t_fixed


def packing_ab(argv=None):
    """``python -m bench.scaling_model --packing G [G ...]``: u, o of both paths (the A/B)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--packing", type=int, nargs="+", required=True, help="ghost counts per rank")
    ap.add_argument("--k", type=float, default=24.0, help="steps per ghost-layer rebuild")
    ap.add_argument("--repeats", type=int, default=3, help="alternations numpy/numba")
    args = ap.parse_args(argv)
    out = []
    for g in args.packing:
        for rep in range(args.repeats):
            for path in ("numpy", "numba"):
                u, o = measure_packing(g, args.k, path=path)
                out.append({"g": g, "path": path, "repeat": rep, "u_ns": u * 1e9, "o_us": o * 1e6})
                print(f"  g = {g:6d}  {path:5s}  u = {u * 1e9:7.1f} ns per ghost-step  o = {o * 1e6:6.2f} us per step",
                      flush=True)
    return out


def ghost_update_mpi(argv=None):
    """``mpiexec -n 2 python -m bench.scaling_model --ghost-update N``: seconds per
    `SlabDomain.update_ghosts` (packing, the two messages each way, unpacking) on the benchmark
    bed of N spheres (`python -m bench`'s scene, one numba thread per rank), max over ranks, best
    and median of 7 batches of ``--reps`` calls. The rank's own part of the exchange, not the
    steps around it: the A/B of the packing with the messages included."""
    import time

    import numba

    from bench.__main__ import bed, make_scene
    from pdem.parallel.comm import get_comm

    ap = argparse.ArgumentParser()
    ap.add_argument("--ghost-update", type=int, required=True, metavar="N")
    ap.add_argument("--reps", type=int, default=2000)
    args = ap.parse_args(argv)
    numba.set_num_threads(1)
    comm = get_comm()
    pos, radius = bed(args.ghost_update)
    sim = make_scene(pos, radius).build(comm=comm)
    sim.run(50)  # warm-up, first migration and load balancing
    d, p = sim.domain, sim.particles
    for _ in range(50):
        d.update_ghosts(p)
    per_call = []
    for _ in range(7):
        comm.barrier()
        t0 = time.perf_counter()
        for _ in range(args.reps):
            d.update_ghosts(p)
        per_call.append(comm.allreduce_max(time.perf_counter() - t0) / args.reps)
    ghosts = comm.allreduce_max(int(p.n_ghost))
    if comm.rank == 0:
        print(f"update_ghosts, {comm.size} ranks, {args.ghost_update} spheres, {ghosts} ghosts on the busier rank: "
              f"best {min(per_call) * 1e6:.1f} us, median {float(np.median(per_call)) * 1e6:.1f} us per call "
              f"({min(per_call) / max(ghosts, 1) * 1e9:.1f} ns per ghost); load average {os.getloadavg()}")
    return per_call


def model(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--length", type=float, default=6.0)
    ap.add_argument("--width", type=float, default=4.0)
    ap.add_argument("--depth", type=float, default=0.5)
    ap.add_argument("--ranks", type=int, nargs="+", default=[2, 16, 64, 121, 256])
    args = ap.parse_args(argv)
    n, r1, r2, pp = load()
    s1, s2 = r1["steps"], r2["steps"]
    c = r1["wall_s"] / s1 / n
    compute2 = (r2["neighbours_s"] + r2["contacts_s"] + r2["integration_s"]) / s2
    g_rank = r2["ghosts"] / 2  # 2 ranks: one neighbour each
    c_g_fit = (compute2 - c * n / 2) / g_rank
    c_g = 0.5 * c
    alpha, beta = pp["sendrecv"]["alpha_s"], pp["sendrecv"]["beta_B_per_s"]
    comm_model2 = 2 * alpha + 72 * g_rank / beta + alpha  # one neighbour: 1 message each way + allreduce
    comm2 = r2["comm_s"] / s2
    k = s2 / max(r2["rebuilds"], 1)
    u, o = measure_packing(int(g_rank), k)
    comm_model2 += u * g_rank + o
    t2 = r2["wall_s"] / s2
    r_max = 1.4 * R_MEAN
    h = 2 * r_max + 0.25 * R_MEAN
    print(f"measured ({n} spheres, {s1}/{s2} steps, 1 thread per rank):")
    print(f"  c      = {c * 1e9:8.1f} ns per sphere-step (1 rank, {r1['wall_s'] / s1 * 1e3:.2f} ms/step)")
    print(f"  2 ranks: {t2 * 1e3:.2f} ms/step, speedup {r1['wall_s'] / s1 / t2:.2f}, compute {compute2 * 1e3:.2f} ms, "
          f"comm {comm2 * 1e3:.3f} ms, ghosts/rank {g_rank:.0f}, halo fraction {r2['halo_fraction']:.4f}")
    print(f"  c_g    = {c_g * 1e9:8.1f} ns per ghost-step (modelled c/2; 2-rank fit {c_g_fit * 1e9:.0f} ns)")
    print(
        f"  u      = {u * 1e9:8.1f} ns per ghost-step (pack/unpack, rebuild every {k:.0f} steps), o = "
        f"{o * 1e6:.1f} us/step"
    )
    print(f"  alpha  = {alpha * 1e6:8.2f} us, beta = {beta / 1e9:.2f} GB/s (sendrecv ping-pong, shared memory)")
    print(f"  comm explained by the model: {comm_model2 * 1e6:.1f} us/step of {comm2 * 1e6:.1f} us/step measured "
          f"(the rest: waiting for the other rank)")
    t2_model = c * n / 2 + c_g * g_rank + comm_model2
    print(
        f"  model at 2 ranks: {t2_model * 1e3:.2f} ms/step, speedup {c * n / t2_model:.2f} (measured "
        f"{r1['wall_s'] / s1 / t2:.2f})"
    )
    L, W, D = args.length, args.width, args.depth
    N = L * W * D / BED_VOLUME_PER_SPHERE
    nx = N / L
    print(f"\nmodel: track section {L} x {W} x {D} m, N = {N:.3g} spheres, h = 2 r_max + skin = {h * 1e3:.1f} mm, "
          f"P_max = L/h = {L / h:.0f}, halo fraction = 2h/T for interior slabs")
    rows = []
    c_meas = c
    for label, a, b, cs in (("measured alpha, beta (shared memory), measured c", alpha, beta, 1.0),
                            ("assumed network alpha = 2 us, beta = 5 GB/s, measured c", 2e-6, 5e9, 1.0),
                            ("network as above, c / 2 (compute twice as fast: the weight of communication)",
                             2e-6, 5e9, 1 / 2)):
        c = c_meas * cs
        c_g = 0.5 * c
        print(f"  [{label}]")
        print(f"  {'P':>5} {'T [m]':>7} {'spheres/rank':>12} {'ghosts/rank':>11} {'halo frac':>9} {'t/step ms':>9} "
              f"{'comm %':>6} {'E':>6}")
        for P in args.ranks:
            T = L / P
            g = nx * h * (0 if P == 1 else 1 if P == 2 else 2)  # the busiest rank: interior for P > 2
            t_comp = c * N / P + c_g * g
            t_comm = (2 * (a + 72 * (g / 2) / b) + math.ceil(math.log2(P)) * a + u * g + o) if P > 1 else 0.0
            t = t_comp + t_comm
            e = c * N / (P * t)
            ok = T >= h
            rows.append((label, P, T, N / P, g, g / (N / P), t, t_comm / t, e, ok))
            print(f"  {P:>5} {T:>7.4f} {N / P:>12.0f} {g:>11.0f} {g / (N / P):>9.3f} {t * 1e3:>9.3f} "
                  f"{100 * t_comm / t:>6.1f} {e:>6.2f}" + ("" if ok else "   slab thinner than the halo: not possible"))
    return rows


def track_inputs(run1, run2):
    """The measured inputs of the track model from two runs' scaling.json (1 and 2 ranks)."""
    r1 = json.loads((Path(run1) / "scaling.json").read_text())
    r2 = json.loads((Path(run2) / "scaling.json").read_text())
    if r1["ranks"] != 1 or r2["ranks"] != 2:
        raise SystemExit(f"--run1 must be a 1-rank run and --run2 a 2-rank run (got {r1['ranks']}, {r2['ranks']})")
    n = r1["bodies"]
    compute = ("neighbours", "contacts", "integration")
    c = r1["timers_total_max_s"] / r1["steps"] / n  # everything a 1-rank step costs, per body
    c_compute = sum(r1["timers_max_s"][k] for k in compute) / r1["steps"] / n
    t2 = r2["timers_total_max_s"] / r2["steps"]
    compute2 = sum(r2["timers_max_s"][k] for k in compute) / r2["steps"]
    ld = r2["loads"]
    g2 = max(ld["ghosts"])  # 2 ranks: each has one neighbour
    n_x = n / r1["track_length"]
    r_max = r1["radius"] * (1 + r1["radius_spread"])
    h = ld["halo"]
    pp = json.loads((HERE / "pingpong.json").read_text())
    _, bed1, _, _ = load()  # the bed benchmark on an idle machine (bench/results.json, 1 rank)
    c_idle = bed1["wall_s"] / bed1["steps"] / bed1["n_particles"]
    return {"n": n, "c": c, "c_idle": c_idle, "c_compute": c_compute, "t1": r1["timers_total_max_s"] / r1["steps"],
            "t2": t2, "compute2": compute2, "comm2": r2["timers_max_s"]["communication"] / r2["steps"], "g2": g2,
            "n_x": n_x, "h": h, "h_formula": 2 * r_max + 0.25 * r1["radius"], "b": ld["imbalance"],
            "work": ld["work"], "owned": ld["owned"], "spacing": r1["spacing"],
            "k": r2["steps"] / max(r2["rebuilds"], 1), "alpha": pp["sendrecv"]["alpha_s"],
            "beta": pp["sendrecv"]["beta_B_per_s"], "uptime": [r1.get("uptime"), r2.get("uptime")],
            "runs": [str(run1), str(run2)], "steps": [r1["steps"], r2["steps"]]}


def track_step(m, N, P, alpha, beta, c=None):
    """(t per step [s], comm part [s], ghosts of the busiest rank, sleepers) of the track model."""
    c = m["c"] if c is None else c
    c_g = 0.5 * c
    L = N / m["n_x"]
    n_b = L / m["spacing"]
    g = m["g2"] * (0 if P == 1 else 1 if P == 2 else 2)  # measured ghosts per slab side (fixed cross-section)
    b = 1.0 if P == 1 else m["b"]
    t_comp = b * c * N / P + c_g * g
    lg = math.ceil(math.log2(P)) if P > 1 else 0
    t_comm = ((2 * (alpha + 72 * (g / 2) / beta) + lg * alpha + lg * (alpha + 3 * n_b * 544 / beta)
               + m["u"] * g + m["o"]) if P > 1 else 0.0)
    return t_comp + t_comm, t_comm, g, n_b


def track_model(args):
    if args.inputs:  # the runs' inputs stored by an earlier --run1/--run2 model; packing re-measured
        m = json.loads(Path(args.inputs).read_text())["inputs"]
    else:
        m = track_inputs(args.run1, args.run2)
    m["u"], m["o"] = measure_packing(int(m["g2"]), m["k"], path=args.packing_path)
    m["packing_path"], m["packing_load_average"] = args.packing_path, list(os.getloadavg())
    print(f"measured on the track section ({m['n']} bodies, {m['steps'][0]} / {m['steps'][1]} steps on 1 / 2 ranks, "
          f"load average {m['uptime']}):")
    print(f"  c_idle = {m['c_idle'] * 1e9:.1f} ns per sphere-step: the bed benchmark on an idle machine "
          "(bench/results.json), for comparison")
    print(f"  c     = {m['c'] * 1e9:8.1f} ns per body-step, 1 rank, every part of the step "
          f"({m['t1'] * 1e3:.2f} ms/step; compute alone {m['c_compute'] * 1e9:.1f} ns)")
    print(f"  n_x   = {m['n_x']:8.0f} bodies per metre of track; h = {m['h'] * 1e3:.1f} mm (formula "
          f"{m['h_formula'] * 1e3:.1f} mm)")
    print(f"  halo  = {m['g2']:8.0f} ghosts per slab at 2 ranks (model n_x h = {m['n_x'] * m['h']:.0f})")
    print(f"  b     = {m['b']:8.3f} load imbalance max/mean at 2 ranks (work {m['work']}, owned {m['owned']})")
    print(f"  u, o  = {m['u'] * 1e9:.1f} ns per ghost-step, {m['o'] * 1e6:.1f} us per step (packing, rebuild every "
          f"{m['k']:.0f} steps); alpha = {m['alpha'] * 1e6:.2f} us, beta = {m['beta'] / 1e9:.2f} GB/s (ping-pong)")
    t2m, _, _, _ = track_step(m, m["n"], 2, m["alpha"], m["beta"])
    print(f"  2 ranks: measured {m['t2'] * 1e3:.2f} ms/step (speedup {m['t1'] / m['t2']:.2f}; compute "
          f"{m['compute2'] * 1e3:.2f}, communication {m['comm2'] * 1e3:.2f} ms); model {t2m * 1e3:.2f} ms/step "
          f"(speedup {m['t1'] / t2m:.2f})")
    rows = []
    cases = (("measured alpha, beta (shared memory)", m["alpha"], m["beta"]),
             ("network alpha = 2 us, beta = 5 GB/s (assumed)", 2e-6, 5e9))
    for N in (1e6, 1e7):
        L = N / m["n_x"]
        p_max = int(L / m["h"])
        print(f"\nmodel: N = {N:.0e} bodies: track L = {L:.1f} m ({L / m['spacing']:.0f} sleepers), "
              f"P_max = L/h = {p_max} (slabs thinner than the halo beyond)")
        print(f"  {'P':>5} {'T [m]':>7} {'bodies/rank':>11} {'ghosts':>7} {'halo frac':>9} {'t/step ms':>9} "
              f"{'comm %':>6} {'E shm':>6} {'E net':>6} {'E net, c idle':>13}")
        for P in args.ranks:
            T = L / P
            es = []
            for _, a, b in cases:
                t, tc, g, _ = track_step(m, N, P, a, b)
                es.append((m["c"] * N / (P * t), t, tc, g))
            t_i = track_step(m, N, P, 2e-6, 5e9, c=m["c_idle"])[0]
            e_idle = m["c_idle"] * N / (P * t_i)
            ok = T >= m["h"]
            e_shm, t, tc, g = es[0]
            rows.append({"N": N, "P": P, "T": T, "bodies_per_rank": N / P, "ghosts": g, "halo_fraction": g / (N / P),
                         "t_step": t, "comm_fraction": tc / t, "E_shm": e_shm, "E_net": es[1][0],
                         "E_net_c_idle": e_idle, "possible": ok, "P_max": p_max})
            print(f"  {P:>5} {T:>7.4f} {N / P:>11.0f} {g:>7.0f} {g / (N / P):>9.3f} {t * 1e3:>9.3f} "
                  f"{100 * tc / t:>6.1f} {e_shm:>6.2f} {es[1][0]:>6.2f} {e_idle:>13.2f}"
                  + ("" if ok else "   slab thinner than the halo: not possible"))
    out = {"inputs": {k: v for k, v in m.items()}, "rows": rows}
    (HERE / "track_scaling.json").write_text(json.dumps(out, indent=1) + "\n")
    if args.png:
        plot_track(m, args.png)
    return rows


def plot_track(m, png):
    """E(P) of the track model for 1e6 and 1e7 bodies, measured and network messages; P_max marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for N, colour in ((1e6, "C0"), (1e7, "C1")):
        L = N / m["n_x"]
        p_max = int(L / m["h"])
        P = np.unique(np.round(np.logspace(0, np.log10(p_max), 60)).astype(int))
        for (a, b, c), ls, what in (((m["alpha"], m["beta"], m["c"]), "-", "shared memory, c measured"),
                                    ((2e-6, 5e9, m["c"]), "--", "network, c measured"),
                                    ((2e-6, 5e9, m["c_idle"]), ":", "network, c of the idle bench")):
            e = [c * N / (p * track_step(m, N, p, a, b, c=c)[0]) for p in P]
            ax.semilogx(P, e, ls, color=colour, label=f"N = {N:.0e}, {what}")
        ax.axvline(p_max, color=colour, lw=0.8, ls="-.")
        ax.text(p_max, 0.02, f" P_max = {p_max}", color=colour, fontsize=8, rotation=90, va="bottom")
    for p in (16, 64, 256):
        ax.axvline(p, color="0.85", lw=0.8, zorder=0)
    ax.set(xlabel="ranks P (slabs along the track)", ylabel="parallel efficiency E [-]", ylim=(0, 1.05),
           title="Track section: modelled efficiency (inputs measured on 1 and 2 ranks)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(allow_abbrev=False)  # --packing is not --packing-path
    ap.add_argument("--scene", choices=("bed", "track"), default="bed")
    ap.add_argument("--run1", help="track: run directory of the 1-rank run (its scaling.json)")
    ap.add_argument("--run2", help="track: run directory of the 2-rank run")
    ap.add_argument("--inputs", help="track: instead of --run1/--run2, the inputs stored in a track_scaling.json "
                    "(u and o are measured again)")
    ap.add_argument("--png", help="track: write the efficiency plot there")
    ap.add_argument("--packing-path", choices=("numba", "numpy"), default="numba",
                    help="track: time u, o of this packing (numpy: the code before pdem.parallel.packing)")
    ap.add_argument("--ranks", type=int, nargs="+", default=None)
    args, rest = ap.parse_known_args(argv)
    if "--packing" in rest:
        return packing_ab(rest)
    if "--ghost-update" in rest:
        return ghost_update_mpi(rest)
    if args.scene == "track":
        if not (args.run1 and args.run2) and not args.inputs:
            raise SystemExit("--scene track needs --run1 and --run2 (or --inputs bench/track_scaling.json)")
        args.ranks = args.ranks or [2, 16, 64, 256]
        return track_model(args)
    return model(rest + (["--ranks", *map(str, args.ranks)] if args.ranks else []))


if __name__ == "__main__":
    main()
