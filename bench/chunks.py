"""Least-disturbed throughput on a shared machine: the step rate of 30-step chunks.

    python -m bench.chunks N THREADS [CHUNKS]

Builds the cached settled bed of N spheres (`bench.__main__.bed`), runs 50 warm-up steps, then
CHUNKS (default 12) chunks of 30 steps and prints the rate of the fastest chunk, of the chunk at
the first quartile and of the median chunk [M particle-steps/s]. Another process that takes the
core for a while slows some chunks and not others, so the fastest chunks compare two trees (run
alternately, one after the other) better than whole-run means do.
"""
import sys
import time


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    n, threads = int(argv[0]), int(argv[1])
    chunks = int(argv[2]) if len(argv) > 2 else 12
    import numba

    numba.set_num_threads(threads)
    from bench.__main__ import bed, make_scene

    pos, radius = bed(n)
    sim = make_scene(pos, radius).build()
    sim.run(50)
    per_step = []
    for _ in range(chunks):
        t0 = time.perf_counter()
        sim.run(30)
        per_step.append((time.perf_counter() - t0) / 30)
    per_step.sort()
    rates = [n / per_step[k] / 1e6 for k in (0, len(per_step) // 4, len(per_step) // 2)]
    print(f"RESULT {n} {threads} fastest {rates[0]:.3f} q25 {rates[1]:.3f} median {rates[2]:.3f} M particle-steps/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
