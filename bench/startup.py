"""Start-up time with a warm numba cache: what a user waits before the first step.

    python -m bench.startup [--reps 3]

Each measurement is a fresh process (the cache is warmed by one untimed run first); the median
of ``--reps`` is reported [s]:

- ``interpreter_s``: ``python -c pass``;
- ``import_s``: importing what a run imports (the engine, the scenes, the driver);
- ``first_step_50k_s``: the 50k bench bed (``bench/cache``) built into a Simulation and its first
  step (this is where compiled kernels are loaded from the numba cache), after the imports;
- ``pdem_run_s``: ``python -m pdem run jobs/deposition.toml --steps 1`` end to end (interpreter,
  imports, scene build with its generated spheres, kernels, one step, results files written;
  most of it is the results plot at the end: matplotlib's import and drawing, ~2.7 s under load).

The record goes into ``bench/results.json`` as case ``startup``. Target: < 3 s.
"""
import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

IMPORTS = "import pdem.cli, pdem.scenes, pdem.simulation, pdem.driver.plain, pdem.driver.stages"

PHASES = f"""
import time, json
t0 = time.perf_counter()
{IMPORTS}
from bench.__main__ import bed, make_scene
t1 = time.perf_counter()
pos, radius = bed(50000)
sim = make_scene(pos, radius).build()
sim.run(1)
t2 = time.perf_counter()
print("PHASES " + json.dumps({{"import_s": t1 - t0, "first_step_50k_s": t2 - t1}}))
"""


def _wall(cmd, **kw):
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=HERE.parent, **kw)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {out.stderr[-2000:]}")
    return time.perf_counter() - t0, out.stdout


def measure(reps=3):
    py = sys.executable
    with tempfile.TemporaryDirectory(prefix="pdem-startup-") as tmp:
        run = [py, "-m", "pdem", "run", "jobs/deposition.toml", "--steps", "1", "--fresh", "--out", tmp]
        _wall(run)  # warm the numba cache (and the page cache)
        _wall([py, "-c", PHASES])
        rows = []
        for _ in range(reps):
            phases = json.loads([ln for ln in _wall([py, "-c", PHASES])[1].splitlines()
                                 if ln.startswith("PHASES ")][-1][7:])
            phases["interpreter_s"] = _wall([py, "-c", "pass"])[0]
            phases["pdem_run_s"] = _wall(run)[0]
            rows.append(phases)
    return {key: statistics.median(r[key] for r in rows) for key in rows[0]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args(argv)
    rec = {"case": "startup", "ranks": 1, "threads": 1, "reps": args.reps, **measure(args.reps)}
    for key, value in rec.items():
        if key.endswith("_s"):
            print(f"{key:<18} {value:6.2f} s")
    from bench.__main__ import merge_results

    merge_results([rec])
    return 0


if __name__ == "__main__":
    sys.exit(main())
