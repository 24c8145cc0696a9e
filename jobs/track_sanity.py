"""Is the track section's settlement pattern sane? A small campaign on a reduced track.

    .venv/bin/python jobs/track_sanity.py [--out runs/track_sanity] [--parallel 2] [--seeds 4] [--report DIR]

The reduced track: a half model (symmetry about the track's centre line) of 5 sleepers
150 x 1200 x 100 mm at 300 mm on a 120 mm bed, spheres r = 25 mm ± 30 %, stiffness scaled down
(E_k = 2.8e6 Pa, table 6.1 ratios), about 1 700 spheres after the cut. Each case runs with
``pdem run`` on one rank (``--parallel`` at a time; re-running skips finished cases), then the
report (``sanity.md`` and PNGs in ``--report``, default the output directory) answers:

1. symmetric loading gives symmetric settlement: every sleeper carries the same haversine
   0 -> 0.7 kN (3 cycles); the settlement of sleeper k and of its mirror image 4 - k differ by
   no more than the seeds scatter (the mean difference over the seeds, with its 95 % CI, against
   the seed-to-seed standard deviation of a sleeper's settlement);
2. a stiffer subgrade gives less settlement: the same seeds with the subgrade 10 times stiffer
   (rubber E = E_k instead of 0.1 E_k), paired seed by seed;
3. the sleepers under a passing load settle: a bogie (2 axles of 1.4 kN, 0.6 m apart) passing at
   5 m/s, 2 passages: every sleeper settles, springs back after the bogie, each one's pulse
   shifted by spacing/speed.
"""
import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "jobs"))
from pdem.format.groups import read_track  # noqa: E402
from analysis.variability import variability  # noqa: E402
from thesis_box import merge, to_toml  # noqa: E402

E_K = 2.8e6
BASE = {
    "simulation": {"dt": "auto", "damping": 0.3, "gravity": [0.0, 0.0, -9.81]},
    "run": {"progress_every": 0, "output_every": 20, "snapshot_every": 0, "checkpoint_keep": 1},
    "materials": {"ballast": {"density": 2600.0, "young": E_K, "poisson": 0.3, "friction_angle": 0.5},
                  "steel": {"density": 7850.0, "young": 10 * E_K, "poisson": 0.25, "friction_angle": 0.5},
                  "rubber": {"density": 1000.0, "young": 0.1 * E_K, "poisson": 0.5, "friction_angle": 0.7},
                  "concrete": {"density": 2600.0, "young": 1.43 * E_K, "poisson": 0.3, "friction_angle": 0.5}},
    "track": {"half": True, "sleepers": 5, "spacing": 0.3, "sleeper_size": [0.15, 1.2, 0.1], "gauge": 0.8,
              "rail_foot_width": 0.1, "bed_depth": 0.12, "shoulder_width": 0.08, "slope": 1.5, "radius": 0.025,
              "radius_spread": 0.3, "seed": 1, "overfill": 1.1, "settle_max_time": 1.0, "vibration_time": 0.2},
    "traffic": {"program": "haversine", "f_min": 0.0, "f_max": 700.0, "frequency": 2.0, "cycles": 3},
}
STIFF = {"materials": {"rubber": {"young": E_K}}}
AXLES = {"traffic": {"program": "axles", "axle_load": 1400.0, "axles": [0.0, 0.6], "speed": 5.0, "passages": 2,
                     "rest_time": 0.2}}


def cases(n_seeds):
    out = []
    for seed in range(1, n_seeds + 1):
        s = {"track": {"seed": seed}}
        out.append((f"sym_seed{seed}", merge(BASE, s)))
        out.append((f"stiff_seed{seed}", merge(merge(BASE, STIFF), s)))
    for seed in (1, 2):
        axles = merge(BASE, AXLES)
        axles["traffic"] = AXLES["traffic"]  # the haversine keys are not used by program = "axles"
        out.append((f"axles_seed{seed}", merge(axles, {"track": {"seed": seed}})))
    return out


def run_case(name, doc, out):
    d = out / name
    d.mkdir(parents=True, exist_ok=True)
    scene = d / "scene.toml"
    scene.write_text(f"# {name} (jobs/track_sanity.py)\n" + to_toml(doc))
    if (d / "summary.txt").exists():  # finished before
        return name, 0, 0.0
    t0 = time.perf_counter()
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "pdem", "run", str(scene), "--out", str(d), "--fresh"],
                       capture_output=True, text=True, cwd=ROOT, env=env)
    (d / "stdout.txt").write_text(r.stdout + r.stderr)
    wall = time.perf_counter() - t0
    print(f"{name}: exit {r.returncode} in {wall:.0f} s", flush=True)
    return name, r.returncode, wall


def permanent(out, name):
    """(permanent settlement after the last passage [n_sleepers], peak in it) [mm]."""
    p = read_track(out / name / "results.h5").passages
    return 1e3 * p["settlement_permanent"][-1], 1e3 * p["settlement_peak"][-1]


def report(out, names, dest, n_seeds):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seeds = range(1, n_seeds + 1)
    sym = np.array([permanent(out, f"sym_seed{s}")[0] for s in seeds])
    stiff = np.array([permanent(out, f"stiff_seed{s}")[0] for s in seeds])
    sym_pk = np.array([permanent(out, f"sym_seed{s}")[1] for s in seeds])
    stiff_pk = np.array([permanent(out, f"stiff_seed{s}")[1] for s in seeds])
    n = sym.shape[1]
    md = ["# Track section: is the settlement pattern sane? (generated by jobs/track_sanity.py)", "",
          "Reduced track: half model, 5 sleepers 150 x 1200 x 100 mm at 300 mm, 120 mm bed, spheres r = 25 mm ± 30 %, "
          f"E_k = {E_K:g} Pa; {n_seeds} seeds. Settlement in mm, positive down.", "",
          "## 1. Symmetric loading: 0 -> 0.7 kN on every sleeper, 3 cycles (soft subgrade)", "",
          "permanent settlement after the 3rd cycle [mm]:", "",
          "| seed | " + " | ".join(f"sleeper {k}" for k in range(n)) + " |", "|---|" + "---|" * n]
    for s, row in zip(seeds, sym):
        md.append(f"| {s} | " + " | ".join(f"{v:.3f}" for v in row) + " |")
    md += ["", "| pair | mean difference S_k - S_(4-k) [mm] | 95 % CI of the mean | seed scatter of S_k (std) [mm] "
           "| within the scatter |", "|---|---|---|---|---|"]
    verdict = []
    for k in range(n // 2):
        d = sym[:, k] - sym[:, n - 1 - k]
        v = variability(d)
        scatter = float(np.std(np.concatenate([sym[:, k], sym[:, n - 1 - k]]), ddof=1))
        ok = v.ci_low <= 0.0 <= v.ci_high or abs(v.mean) < scatter
        verdict.append(ok)
        md.append(f"| {k}, {n - 1 - k} | {v.mean:+.3f} | {v.ci_low:+.3f} .. {v.ci_high:+.3f} | {scatter:.3f} | "
                  f"{'yes' if ok else 'NO'} |")
    md += ["", f"Symmetric within the seed scatter: **{'yes' if all(verdict) else 'no'}**.", "",
           "## 2. A stiffer subgrade (rubber E = E_k instead of 0.1 E_k), same seeds", "",
           "| seed | soft: mean permanent / peak [mm] | stiff: mean permanent / peak [mm] | stiff < soft |",
           "|---|---|---|---|"]
    less = []
    for s, a, b, pa, pb in zip(seeds, sym, stiff, sym_pk, stiff_pk):
        ok = b.mean() < a.mean() and pb.mean() < pa.mean()
        less.append(ok)
        md.append(f"| {s} | {a.mean():.3f} / {pa.mean():.3f} | {b.mean():.3f} / {pb.mean():.3f} | "
                  f"{'yes' if ok else 'NO'} |")
    md += ["", f"Less settlement (permanent and peak) on the stiffer subgrade for every seed: "
           f"**{'yes' if all(less) else 'no'}**; mean ratio stiff/soft permanent "
           f"{stiff.mean() / sym.mean():.2f}, peak {stiff_pk.mean() / sym_pk.mean():.2f}.", "",
           "## 3. A bogie passing (2 axles of 1.4 kN, 0.6 m apart, 5 m/s, 2 passages)", "",
           "| seed | passage | peak settlement per sleeper [mm] | permanent per sleeper [mm] | pulse shift [s] "
           "(spacing/speed = 0.06 s) |", "|---|---|---|---|---|"]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    x = np.arange(n)
    for s, row in zip(seeds, sym):
        ax[0].plot(x, row, "o-", color="C0", alpha=0.6, label="soft subgrade" if s == 1 else None)
    for s, row in zip(seeds, stiff):
        ax[0].plot(x, row, "s--", color="C1", alpha=0.6, label="stiff subgrade" if s == 1 else None)
    ax[0].plot(x, sym.mean(axis=0), "-", color="k", lw=2, label="soft, mean over the seeds")
    ax[0].plot(x, sym.mean(axis=0)[::-1], ":", color="k", lw=2, label="soft, mean mirrored (4 - k)")
    ax[0].invert_yaxis()
    ax[0].set(xlabel="sleeper", ylabel="permanent settlement [mm]", title="Symmetric loading, 3 cycles")
    ax[0].set_xticks(x)
    ax[0].legend(fontsize="small")
    moving = []
    for seed in (1, 2):
        rec = read_track(out / f"axles_seed{seed}" / "results.h5")
        p = rec.passages
        t, f = rec.results.series["time"], rec.force
        for i in range(len(p["passage"])):
            inside = (t >= p["t_start"][i]) & (t <= p["t_end"][i])
            extra = np.maximum(f[inside] - f[inside].min(axis=0), 0.0)
            t_c = (t[inside][:, None] * extra).sum(axis=0) / extra.sum(axis=0)
            shift = np.diff(t_c)
            ok = bool(np.all(p["settlement_permanent"][i] > 0) and np.all(p["settlement_peak"][i] > 0)
                      and np.all(np.abs(shift - 0.06) < 0.02))
            moving.append(ok)
            md.append(f"| {seed} | {i + 1} | " + ", ".join(f"{1e3 * v:.3f}" for v in p["settlement_peak"][i]) + " | "
                      + ", ".join(f"{1e3 * v:.3f}" for v in p["settlement_permanent"][i]) + " | "
                      + ", ".join(f"{v:.3f}" for v in shift) + " |")
        for k in range(n):
            ax[1 if seed == 1 else 2].plot(t, 1e3 * rec.settlement[:, k], lw=0.9, label=f"sleeper {k}")
    for a, seed in ((ax[1], 1), (ax[2], 2)):
        a.invert_yaxis()
        a.set(xlabel="time [s]", ylabel="settlement [mm]", title=f"Bogie passing, seed {seed}")
        a.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(dest / "sanity.png", dpi=110)
    plt.close(fig)
    md += ["", f"Every sleeper settles under the passing bogie, with its pulse shifted by spacing/speed: "
           f"**{'yes' if all(moving) else 'no'}**.", "", "![sanity](sanity.png)", ""]
    (dest / "sanity.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "track_sanity")
    ap.add_argument("--parallel", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--report", type=Path, default=None)
    args = ap.parse_args(argv)
    todo = cases(args.seeds)
    with ThreadPoolExecutor(args.parallel) as pool:
        runs = list(pool.map(lambda c: run_case(c[0], c[1], args.out), todo))
    bad = [n for n, rc, _ in runs if rc != 0]
    if bad:
        print(f"failed: {bad} (see their stdout.txt); no report")
        return 1
    dest = args.report or args.out
    dest.mkdir(parents=True, exist_ok=True)
    report(args.out, [n for n, *_ in runs], dest, args.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
