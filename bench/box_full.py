"""Throughput of the small scene of issue 14: the ~2300-body box test at full stiffness
(E_k = 2.8e11 Pa, 3 <-> 40 kN), stepping its load stage on 1 and 2 ranks.

    python -m bench.box_full [--steps 20000] [--ranks 1 2]

The bed is ``jobs/box_test_full_10.toml`` prepared at 1e-4 of the stiffness and stiffened (the
stiffen stage, docs/box_test.md "Full stiffness"); it is made once into ``bench/cache/box_full``
(``pdem run ... --steps 300000``: the preparation, the stiffening and the first load steps, a few
minutes) and reused. Each rank count resumes the run from the checkpoint at the end of the stiffen
stage twice, to ``--steps`` = that step + 2000 and + 2000 + ``--steps``; the difference of the two
wall times is the time of ``--steps`` load steps without the start-up. Recorded into
``bench/results.json`` as case ``box_full`` (steps/s, body-steps/s, bodies, Δt).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SCENE = ROOT / "jobs" / "box_test_full_10.toml"
CACHE = HERE / "cache" / "box_full"
PREPARE_STEPS = 300000  # past the end of the stiffen stage (~150 000 steps): stops inside the load stage
WARMUP = 2000


def pdem_run(ranks, out, steps):
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "pdem", "run", str(SCENE), "--out", str(out), "--steps", str(steps)]
    if ranks > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks)] + cmd
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return time.perf_counter() - t0, r.stdout


def stiffened():
    """(checkpoint step at the end of the stiffen stage, its log) of the cached bed, made if missing."""
    log = CACHE / "log.txt"
    if not log.exists() or "(end of stage stiffen" not in log.read_text():
        shutil.rmtree(CACHE, ignore_errors=True)
        CACHE.mkdir(parents=True)
        print(f"preparing the full-stiffness bed in {CACHE} (a few minutes) ...", flush=True)
        log.write_text(pdem_run(2, CACHE / "run", PREPARE_STEPS)[1])
    text = log.read_text()
    step = int(re.search(r"step (\d+): checkpoint \S+ \(end of stage stiffen", text).group(1))
    return step, text


def resumed(ranks, step, steps):
    """Wall time [s] of `steps` load steps on `ranks` ranks from the stiffened checkpoint."""
    walls = []
    for n in (WARMUP, WARMUP + steps):
        with tempfile.TemporaryDirectory(prefix="pdem-box-full-") as tmp:
            run = Path(tmp) / "run"
            shutil.copytree(CACHE / "run", run)
            for ck in (run / "checkpoints").glob("ckpt_*.h5"):
                if int(ck.stem.split("_")[1]) > step:
                    ck.unlink()
            walls.append(pdem_run(ranks, run, step + n)[0])
    return walls[1] - walls[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    a = ap.parse_args(argv)
    step, text = stiffened()
    bodies = int(re.search(r"stage load: (\d+) spheres", text).group(1))
    dt = float(re.search(r"stage load: \d+ spheres, t = \S+ s, dt = (\S+) s", text).group(1))
    records = []
    for ranks in a.ranks:
        wall = resumed(ranks, step, a.steps)
        rec = {"case": "box_full", "ranks": ranks, "threads": 1, "mpi": ranks > 1, "bodies": bodies, "dt_s": dt,
               "steps": a.steps, "wall_s": wall, "steps_per_s": a.steps / wall,
               "particle_steps_per_s": a.steps * bodies / wall}
        records.append(rec)
        print(f"box test at full stiffness, {bodies} spheres, dt {dt:.3g} s, {ranks} rank(s): "
              f"{rec['steps_per_s']:.0f} steps/s ({rec['particle_steps_per_s'] / 1e6:.2f} M body-steps/s); "
              f"10 cycles at 1 Hz = {10 / dt:.3g} steps: {10 / dt / rec['steps_per_s'] / 60:.0f} min", flush=True)
    from bench.__main__ import merge_results

    merge_results(records)
    return 0


if __name__ == "__main__":
    sys.exit(main())
