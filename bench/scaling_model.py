"""Scaling model of the slab decomposition, from the measured MPI benchmark and ping-pong.

    python -m bench.scaling_model [--length 6 --width 4 --depth 0.5]

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
  u g    packing/unpacking the ghost update (numpy fancy indexing, 9 float64 per ghost)
         plus the ghost-layer rebuild (`pack_rows`/`unpack_rows` of every FIELDS column) every
         k steps (k from the benchmark's rebuild count), per ghost            [measured here, serial]
  o      per rank-step fixed Python overhead of the exchange calls                [measured, serial]
The residual of the measured 2-rank communication time (waiting for the slower rank, load
imbalance, CPU contention) is printed, not modelled.
Efficiency E(P) = c N / (P t(N, P)). Interior slabs exist only while T >= h: P_max = L / h.
"""
import argparse
import json
import math
from pathlib import Path

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


def measure_packing(g, k, reps=50):
    """Seconds per ghost per step of the Python side of the exchange: (u, o)."""
    import time

    import numpy as np

    from pdem.parallel.slab_domain import pack_rows, unpack_rows
    from pdem.state import FIELDS

    n = max(4 * g, 1000)
    rng = np.random.default_rng(1)
    pos, vel, w = rng.random((n, 3)), rng.random((n, 3)), rng.random((n, 3))
    rows = np.sort(rng.choice(n, g, replace=False))
    dst = np.zeros((n + g, 3))

    def update(rows):
        buf = np.concatenate([pos[rows], vel[rows], w[rows]], axis=1)
        dst[n : n + len(rows)] = buf[:, 0:3]
        dst[n : n + len(rows)] = buf[:, 3:6]
        dst[n : n + len(rows)] = buf[:, 6:9]

    def timed(f, *a):
        f(*a)
        t0 = time.perf_counter()
        for _ in range(reps):
            f(*a)
        return (time.perf_counter() - t0) / reps

    t_upd = timed(update, rows)
    t_fixed = timed(update, rows[:1])
    cols = {key: np.zeros((g,) + shape, dtype) for key, (dtype, shape) in FIELDS.items()}
    t_reb = timed(lambda: unpack_rows(*pack_rows(cols, g)))
    u = (t_upd - t_fixed) / g + t_reb / g / k
    return u, 4 * t_fixed  # 2 neighbour messages each way per step: 4 small pack/unpack calls


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


if __name__ == "__main__":
    model()
