"""Throughput of the full-stiffness scenes users run, stepping their load stage on 1 and 2 ranks
from a bed prepared soft and stiffened (`pdem.scenes.common.stiffening`), with the time split:

- ``box_full``: the ~2300-body box test of issue 14 (``jobs/box_test_full_10.toml``: E_k =
  2.8e11 Pa, 3 <-> 40 kN, vibrated bed, smooth 34 kg sleeper);
- ``box_full_calibrated``: the same with the calibrated option set (``jobs/box_test_full_calibrated.toml``:
  unvibrated, the thesis's sleeper of 2280 member spheres);
- ``track_slice_full``: the thesis's track slice at full stiffness (``jobs/track_slice_full.toml``,
  ~20 000 spheres, 200 kN on the rail seat).

    python -m bench.box_full [--cases box_full ...] [--steps N] [--ranks 1 2]

Each bed is made once into ``bench/cache/<case>`` (``pdem run ... --steps N``: the preparation,
the stiffening and the first load steps) and reused. Each rank count resumes the run from the
checkpoint at the end of the stiffen stage twice, to that step + 2000 and + 2000 + ``--steps``; the
difference of the two wall times (and of their timing tables) is the time of ``--steps`` load
steps without the start-up. Recorded into ``bench/results.json`` per case (steps/s, body-steps/s,
bodies, Δt, and the split neighbours / contacts / integration / communication / other [s]).
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
# case: (scene file, steps that end inside the load stage, past the stiffen stage; load steps timed)
CASES = {
    "box_full": ("box_test_full_10.toml", 300000, 20000),                # stiffen ends at ~150 000
    "box_full_calibrated": ("box_test_full_calibrated.toml", 150000, 20000),  # stiffen ends at 132 000
    "track_slice_full": ("track_slice_full.toml", 100000, 5000),         # stiffen ends at ~90 000
}
WARMUP = 2000
SPLIT = ("neighbours", "contacts", "integration", "communication", "other", "output")


def pdem_run(scene, ranks, out, steps):
    """(wall time [s], stdout) of ``pdem run scene --steps steps`` on ``ranks`` ranks, one thread each."""
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "pdem", "run", str(ROOT / "jobs" / scene), "--out", str(out), "--steps", str(steps)]
    if ranks > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks)] + cmd
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return time.perf_counter() - t0, r.stdout


def stiffened(case):
    """(checkpoint step at the end of the stiffen stage, its log) of the case's cached bed, made if missing."""
    scene, prepare_steps, _ = CASES[case]
    cache = HERE / "cache" / case
    log = cache / "log.txt"
    if not log.exists() or "(end of stage stiffen" not in log.read_text():
        shutil.rmtree(cache, ignore_errors=True)
        cache.mkdir(parents=True)
        print(f"preparing the full-stiffness bed of {case} in {cache} ...", flush=True)
        log.write_text(pdem_run(scene, 2, cache / "run", prepare_steps)[1])
    text = log.read_text()
    step = int(re.search(r"step (\d+): checkpoint \S+ \(end of stage stiffen", text).group(1))
    return step, text


def timing(stdout):
    """{section: seconds} of the timing table a run stopped by ``--steps`` prints."""
    found = dict(re.findall(r"^(\w+)\s*\|\s*([\d.]+)\s*\|", stdout, re.M))
    return {k: float(found.get(k, 0.0)) for k in SPLIT}


def stiffened_copy(case, step, run):
    """``run``: a copy of the case's cached run cut back to its checkpoint at ``step`` (the end of
    the stiffen stage), for ``pdem run`` to resume."""
    shutil.copytree(HERE / "cache" / case / "run", run)
    for ck in (run / "checkpoints").glob("ckpt_*.h5"):
        if int(ck.stem.split("_")[1]) > step:
            ck.unlink()
    return run


def resumed(case, ranks, step, steps):
    """(wall time [s], {section: seconds}) of ``steps`` load steps on ``ranks`` ranks from the
    stiffened checkpoint: the differences of a run to step + WARMUP and one to step + WARMUP + steps."""
    runs = []
    for n in (WARMUP, WARMUP + steps):
        with tempfile.TemporaryDirectory(prefix="pdem-bench-full-") as tmp:
            run = stiffened_copy(case, step, Path(tmp) / "run")
            runs.append(pdem_run(CASES[case][0], ranks, run, step + n))
    (w0, out0), (w1, out1) = runs
    t0, t1 = timing(out0), timing(out1)
    return w1 - w0, {k: round(t1[k] - t0[k], 3) for k in SPLIT}  # the table prints ms


def bench_case(case, ranks_list, steps):
    """Records of ``case`` on each rank count (printed as they come)."""
    step, text = stiffened(case)
    load = re.search(r"stage (?:load|traffic): (\d+) spheres, t = \S+ s, dt = (\S+) s", text)
    bodies, dt = int(load.group(1)), float(load.group(2))
    records = []
    for ranks in ranks_list:
        steps = steps or CASES[case][2]
        wall, split = resumed(case, ranks, step, steps)
        rec = {"case": case, "ranks": ranks, "threads": 1, "mpi": ranks > 1, "bodies": bodies, "dt_s": dt,
               "steps": steps, "wall_s": wall, "steps_per_s": steps / wall,
               "particle_steps_per_s": steps * bodies / wall,
               "neighbours_s": split["neighbours"], "contacts_s": split["contacts"],
               "integration_s": split["integration"], "comm_s": split["communication"],
               "other_s": split["other"] + split["output"]}
        records.append(rec)
        shares = ", ".join(f"{k} {100 * v / max(sum(split.values()), 1e-12):.0f} %" for k, v in split.items() if v)
        print(f"{case}: {bodies} spheres, dt {dt:.3g} s, {ranks} rank(s): {rec['steps_per_s']:.0f} steps/s "
              f"({rec['particle_steps_per_s'] / 1e6:.2f} M body-steps/s); 1 s of load = {1 / dt:.3g} steps: "
              f"{1 / dt / rec['steps_per_s'] / 60:.1f} min; rank 0's split: {shares}", flush=True)
    return records


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", choices=sorted(CASES), default=list(CASES))
    ap.add_argument("--steps", type=int, default=None, help="load steps timed (default: the case's)")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    a = ap.parse_args(argv)
    records = [r for case in a.cases for r in bench_case(case, a.ranks, a.steps)]
    from bench.__main__ import merge_results

    merge_results(records)
    return 0


if __name__ == "__main__":
    sys.exit(main())
