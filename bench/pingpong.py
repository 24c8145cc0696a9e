"""Ping-pong between ranks 0 and 1: latency alpha [s] and bandwidth beta [B/s] of this MPI.

    mpiexec -n 2 python -m bench.pingpong [--reps 2000]

Sends float64 buffers of 8 B .. 16 MB back and forth with the uppercase (buffer) mpi4py calls
the slab exchange uses (Sendrecv), and fits the one-way time t(m) = alpha + m / beta by least
squares over the sizes (weighted to the relative error). Prints a JSON line ``PINGPONG {...}``
and writes it to ``bench/pingpong.json`` (read by ``python -m bench.scaling_model``).
"""
import argparse
import json
import sys
import time

import numpy as np


def main(argv=None):
    from mpi4py import MPI

    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=2000)
    args = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    rank = comm.Get_rank()
    if comm.Get_size() != 2:
        if rank == 0:
            print("run with exactly 2 ranks", file=sys.stderr)
        return 1
    other = 1 - rank
    sizes = [8 * 2**k for k in range(0, 22, 2)]  # 8 B .. 16 MiB
    rows = []
    for m in sizes:
        buf = np.ones(m // 8)
        rbuf = np.empty_like(buf)
        reps = max(5, min(args.reps, int(2e8 / max(m, 1))))
        for _ in range(3):  # warm-up
            comm.Sendrecv(buf, other, 5, rbuf, other, 5)
        comm.Barrier()
        t0 = time.perf_counter()
        for _ in range(reps):
            if rank == 0:
                comm.Send(buf, 1, 7)
                comm.Recv(rbuf, 1, 8)
            else:
                comm.Recv(rbuf, 0, 7)
                comm.Send(buf, 0, 8)
        t = (time.perf_counter() - t0) / reps / 2  # one way
        # the pattern of the ghost update: both ranks exchange at once (Sendrecv)
        comm.Barrier()
        t0 = time.perf_counter()
        for _ in range(reps):
            comm.Sendrecv(buf, other, 9, rbuf, other, 9)
        ts = (time.perf_counter() - t0) / reps
        rows.append((m, t, ts))
    if rank == 0:
        m = np.array([r[0] for r in rows], float)
        out = {}
        for name, col in (("pingpong", 1), ("sendrecv", 2)):
            t = np.array([r[col] for r in rows])
            a = np.stack([np.ones_like(m), m], axis=1) / t[:, None]
            alpha, inv_beta = np.linalg.lstsq(a, np.ones_like(t), rcond=None)[0]
            out[name] = {"alpha_s": float(alpha), "beta_B_per_s": float(1.0 / inv_beta),
                         "t_s": {str(int(mm)): float(tt) for mm, tt in zip(m, t)}}
            print(f"{name:9s} alpha = {alpha * 1e6:.2f} us   beta = {1e-9 / inv_beta:.2f} GB/s", flush=True)
            for mm, tt in zip(m, t):
                print(f"   {int(mm):>9d} B  {tt * 1e6:10.2f} us", flush=True)
        print("PINGPONG " + json.dumps(out), flush=True)
        from pathlib import Path

        (Path(__file__).resolve().parent / "pingpong.json").write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
