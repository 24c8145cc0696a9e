"""The blast layer against the paper (SPEC.md 2.5) as a seeds x plates campaign, run locally.

    .venv/bin/python jobs/blast_paper.py [--seeds 1 2 3 4 5] [--out runs/blast_paper] [--ranks 1]
                                         [--parallel 1] [--set blast.box=[0.3,0.3,0.3] ...]
                                         [--prepared runs/blast_layers]

Each seed s is ``jobs/blast_campaign.toml`` with ``[blast] seed = s`` (and the ``--set``
overrides), run with ``pdem run`` into ``OUT/seed_<s>/``: one packing prepared once, loaded
by the three plates in turn (prepare once, load many). A seed whose run finished is skipped, an
interrupted one resumes from its checkpoint. Then ``python -m analysis blast`` compares all
plates over all seeds into ``OUT/compare/`` (blast_compare.txt/.json/.png: I_s and the
amplification per plate, mean, scatter and 95 % interval, against the paper) and the wall time of
every run goes to ``OUT/wall_times.txt``.

Two steps on a busy machine or a cluster: ``--set "blast.plates=[]"`` prepares the layers only
(``OUT/seed_<s>/prepared_layer``); ``--prepared OUT_OF_THAT`` then loads every seed's own layer
(``prepared_from = PREPARED/seed_<s>``) with the plates.
"""
import argparse
import ast
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from jobs.thesis_box import to_toml  # noqa: E402

PLATES = (10780.0, 2700.0, 244.0)


def scene_text(seed, overrides, prepared=None):
    doc = tomllib.loads((ROOT / "jobs" / "blast_campaign.toml").read_text())
    doc["blast"]["seed"] = seed
    if prepared is not None:
        doc["blast"]["prepared_from"] = str(Path(prepared).resolve() / f"seed_{seed}")
    for item in overrides:
        key, value = item.split("=", 1)
        table, name = key.split(".", 1)
        doc.setdefault(table, {})
        if "." in name:  # materials.grain.kn
            sub, name = name.split(".", 1)
            doc[table].setdefault(sub, {})[name] = ast.literal_eval(value)
        else:
            doc[table][name] = ast.literal_eval(value)
    return f"# jobs/blast_campaign.toml with seed = {seed} {' '.join(overrides)}\n" + to_toml(doc)


def run_seed(seed, out, ranks, overrides, prepared=None):
    d = out / f"seed_{seed}"
    d.mkdir(parents=True, exist_ok=True)
    scene = d / "scene.toml"
    text = scene_text(seed, overrides, prepared)
    if scene.exists() and scene.read_text() != text:
        raise SystemExit(f"{scene}: exists with other settings; remove {d} or use another --out")
    scene.write_text(text)
    if (d / "summary.txt").exists():
        return seed, 0, 0.0
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "pdem", "run", str(scene), "--out", str(d)]
    if ranks > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks)] + cmd
    t0 = time.perf_counter()
    with open(d / "stdout.txt", "a") as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT, env=env, check=False).returncode
    wall = time.perf_counter() - t0
    print(f"seed {seed}: exit {rc} in {wall:.0f} s", flush=True)
    return seed, rc, wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "blast_paper")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--parallel", type=int, default=1, help="runs at a time")
    ap.add_argument("--set", nargs="*", default=[], metavar="TABLE.KEY=VALUE")
    ap.add_argument("--prepared", type=Path, help="load each seed's layer from PREPARED/seed_<s> (prepared_from)")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    with ThreadPoolExecutor(a.parallel) as pool:
        runs = list(pool.map(lambda s: run_seed(s, a.out, a.ranks, a.set, a.prepared), a.seeds))
    (a.out / "wall_times.txt").write_text("".join(f"seed {s}: exit {rc}, {w:.0f} s\n" for s, rc, w in runs))
    done = [a.out / f"seed_{s}" / f"plate_{m:g}" for s, rc, _ in runs if rc == 0 for m in PLATES
            if (a.out / f"seed_{s}" / f"plate_{m:g}" / "results.h5").exists()]
    if len(done) > 1:
        subprocess.run([sys.executable, "-m", "analysis", "blast", *map(str, done), "--out", str(a.out / "compare")],
                       cwd=ROOT, check=False)
    return 0 if all(rc == 0 for _, rc, _ in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
