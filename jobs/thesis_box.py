"""The box-test comparisons with the thesis (SPEC.md 2.3, thesis 5.2.1), run as a small campaign.

    .venv/bin/python jobs/thesis_box.py [a] [b] [c] [--out runs/thesis_box] [--parallel 2] [--report DIR]

Each case is ``jobs/box_test.toml`` with the thesis's settings on top, run with ``pdem run`` on
one rank (``--parallel`` runs at a time; re-running resumes or skips finished cases). Then it
writes ``comparison.md`` (the tables) and PNGs into ``--out``:

(a) study B, table 5.8: E_k = 2.8e7 Pa, 0 ↔ 3 kN at 1 Hz, 10 cycles, constant radius; the
    settlement within each cycle (peak − start; thesis: 26.5 mm falling to 3.35 mm). Run with the
    default preparation (vibrated) and without vibration.
(b) table 5.3: E_k = 2.8e6 Pa, 0 ↔ 3 kN, radii (0.6–1.4) r, 10 seeds; settlement at the peak
    load (thesis: 55.1–76.0 mm, mean 63.5 mm).
(c) table 5.6–5.7: E_k = 2.8e6 Pa, 0 ↔ 3 kN, constant radius, λ_D = 0.3, 0.2, 0.1, 0.0 (thesis:
    below 0.2 unstable); what pdem does: the exit status and the cause it names.
"""
import argparse
import os
import subprocess
import sys
import time
import tomllib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path


ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from pdem.format.read import ResultFileError, read_box_test  # noqa: E402
from analysis.variability import variability  # noqa: E402

THESIS_A = (26.5, 3.35)  # mm, settlement within cycle 1 and cycle 10
THESIS_B = (55.1, 76.0, 63.5)  # mm, min, max, mean of the settlement at peak load


def soft(young):
    """Materials of the thesis's box test at E_k = young (table 5.1)."""
    return {"ballast": {"young": young}, "steel": {"young": 10 * young}, "rubber": {"young": 0.1 * young}}


def cases(which):
    out = []
    if "a" in which:
        base = {"materials": soft(2.8e7), "box_test": {"f_min": 0.0, "f_max": 3000.0, "cycles": 10}}
        out.append(("a_vibrated", base))
        out.append(("a_not_vibrated", merge(base, {"box_test": {"vibration_time": 0.0}})))
    if "b" in which:
        # vib: the default preparation; novib: without the vibration stage; *lax: overlaps up to a
        # whole radius allowed (max_overlap_ratio = 1 instead of 0.5), as the thesis's runs had no check
        for prep, extra, lax in (("vib", {}, 0.5), ("novib", {"vibration_time": 0.0}, 0.5),
                                 ("viblax", {}, 1.0), ("novlax", {"vibration_time": 0.0}, 1.0)):
            for seed in range(1, 11):
                out.append((f"b_{prep}_seed{seed:02d}", {"simulation": {"max_overlap_ratio": lax},
                                                         "materials": soft(2.8e6), "box_test": {
                    "f_min": 0.0, "f_max": 3000.0, "cycles": 1, "radius_spread": 0.4, "seed": seed, **extra}}))
    if "c" in which:
        for lam in (0.3, 0.2, 0.1, 0.0):
            out.append((f"c_damping{lam:.1f}", {"simulation": {"damping": lam}, "materials": soft(2.8e6),
                                               "box_test": {"f_min": 0.0, "f_max": 3000.0, "cycles": 1}}))
        # a really unstable run for contrast: a fixed time step 4x the one pdem chooses (~2.4e-4 s)
        out.append(("c_damping0.1_dt1e-3", {"simulation": {"damping": 0.1, "dt": 1e-3}, "materials": soft(2.8e6),
                                            "box_test": {"f_min": 0.0, "f_max": 3000.0, "cycles": 1}}))
    return out


def merge(a, b):
    out = dict(a)
    for k, v in b.items():
        out[k] = merge(a[k], v) if isinstance(v, dict) and isinstance(a.get(k), dict) else v
    return out


def to_toml(doc):
    """The scene dict as TOML (tables of scalars and lists, nested one level for materials)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    for table, body in doc.items():
        if table == "materials":
            for name, m in body.items():
                lines += [f"[materials.{name}]"] + [f"{k} = {value(v)}" for k, v in m.items()] + [""]
        else:
            lines += [f"[{table}]"] + [f"{k} = {value(v)}" for k, v in body.items()] + [""]
    return "\n".join(lines)


def run_case(name, overrides, out, base):
    d = out / name
    d.mkdir(parents=True, exist_ok=True)
    scene = d / "scene.toml"
    scene.write_text(f"# {name}: jobs/box_test.toml with {overrides}\n" + to_toml(merge(base, overrides)))
    if (d / "stdout.txt").exists():  # done before: report what it said
        text = (d / "stdout.txt").read_text().strip().splitlines()
        tail = text[-1] if text and text[-1].startswith("pdem: ") else ""
        return name, (4 if "unstable" in tail else 2) if tail else 0, 0.0, tail
    t0 = time.perf_counter()
    # one numba thread per run: several runs share the cores (2 threads each would oversubscribe)
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "pdem", "run", str(scene), "--out", str(d), "--fresh"],
                       capture_output=True, text=True, cwd=ROOT, env=env)
    (d / "stdout.txt").write_text(r.stdout + r.stderr)
    tail = (r.stderr.strip().splitlines() or [""])[-1]
    print(f"{name}: exit {r.returncode} in {time.perf_counter() - t0:.0f} s {tail}", flush=True)
    return name, r.returncode, time.perf_counter() - t0, tail


def cycles_of(d):
    try:
        return read_box_test(d / "results.h5").cycles
    except (ResultFileError, OSError):
        return None


def report(out, runs, dest):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    md = ["# Box test: pdem against the thesis (generated by jobs/thesis_box.py)", ""]
    names = [n for n, *_ in runs]
    status = {n: (rc, wall, tail) for n, rc, wall, tail in runs}
    a = [n for n in names if n.startswith("a_")]
    if a:
        md += ["## (a) E_k = 2.8e7 Pa, 0 ↔ 3 kN, 10 cycles, constant radius",
               "", "settlement within each cycle (peak − start) [mm]; thesis: 26.5 in cycle 1 → 3.35 in cycle 10", "",
               "| cycle | " + " | ".join(a) + " |", "|---|" + "---|" * len(a)]
        per = {n: cycles_of(out / n) for n in a}
        fig, ax = plt.subplots(figsize=(7, 4))
        n_cyc = max((len(c["cycle"]) for c in per.values() if c is not None), default=0)
        for k in range(n_cyc):
            row = [f"{1e3 * (per[n]['settlement_peak'][k] - per[n]['settlement_start'][k]):.3f}"
                   if per[n] is not None and k < len(per[n]["cycle"]) else "-" for n in a]
            md.append(f"| {k + 1} | " + " | ".join(row) + " |")
        for n, c in per.items():
            if c is not None:
                ax.plot(c["cycle"], 1e3 * (c["settlement_peak"] - c["settlement_start"]), "o-", label=f"pdem {n}")
        ax.plot([1, 10], THESIS_A, "ks", label="thesis (cycles 1 and 10)")
        ax.set_xlabel("cycle")
        ax.set_ylabel("settlement within the cycle [mm]")
        ax.set_yscale("log")
        ax.legend()
        fig.tight_layout()
        fig.savefig(dest / "a_settlement_within_cycle.png", dpi=110)
        plt.close(fig)
        md += ["", "![(a)](a_settlement_within_cycle.png)", ""]
    b = [n for n in names if n.startswith("b_")]
    if b:
        md += ["## (b) E_k = 2.8e6 Pa, 0 ↔ 3 kN, radii (0.6–1.4) r, 10 seeds", "",
               "settlement at peak load [mm] per seed, with (vib) and without (novib) the vibration stage", "",
               "| seed | " + " | ".join(sorted({n.split("_")[1] for n in b})) + " |",
               "|---|" + "---|" * len({n.split("_")[1] for n in b})]
        groups, stops = {}, []
        for n in b:
            cyc = cycles_of(out / n)
            if cyc is None:
                stops.append(f"- {n}: {status[n][2]}")
            groups.setdefault(n.split("_")[1], {})[n[-2:]] = (1e3 * cyc["settlement_peak"][0] if cyc is not None
                                                              else "stopped")
        seeds = sorted({s for g in groups.values() for s in g})
        for sd in seeds:
            cells = [groups[g].get(sd, "-") for g in sorted(groups)]
            md.append(f"| {sd} | " + " | ".join(f"{x:.2f}" if isinstance(x, float) else x for x in cells) + " |")
        md.append("")
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.axhspan(THESIS_B[0], THESIS_B[1], color="0.85", label="thesis range")
        ax.axhline(THESIS_B[2], color="k", ls="--", label="thesis mean")
        for k, g in enumerate(sorted(groups)):
            vals = [x for x in groups[g].values() if isinstance(x, float)]
            xs = [int(sd) + 0.2 * k for sd, x in groups[g].items() if isinstance(x, float)]
            ax.bar(xs, vals, width=0.35, label=f"pdem {g}")
            if len(vals) >= 2:
                v = variability(vals)
                md.append(
                    f"pdem {g}: {v.n} of {len(groups[g])} seeds finished; range {v.minimum:.1f}–{v.maximum:.1f} mm, "
                    f"mean {v.mean:.1f} mm, standard deviation {v.std:.2f} mm, CoV {v.cov:.3f}, 95 % CI of the "
                    f"mean {v.ci_low:.1f}–{v.ci_high:.1f} mm"
                )
                md.append("")
        md += [f"thesis: range {THESIS_B[0]}–{THESIS_B[1]} mm, mean {THESIS_B[2]} mm", "", "Runs that stopped:", ""]
        md += stops + [""]
        ax.set_xlabel("seed")
        ax.set_ylabel("settlement at peak load [mm]")
        ax.set_yscale("log")
        ax.legend()
        fig.tight_layout()
        fig.savefig(dest / "b_seed_variability.png", dpi=110)
        plt.close(fig)
        md += ["![(b)](b_seed_variability.png)", ""]
    c = [n for n in names if n.startswith("c_")]
    if c:
        md += ["## (c) damping λ_D, E_k = 2.8e6 Pa, 0 ↔ 3 kN, constant radius", "",
               "| λ_D | exit status | settlement at peak [mm] | what pdem said |", "|---|---|---|---|"]
        for n in c:
            cyc = cycles_of(out / n)
            peak = f"{1e3 * cyc['settlement_peak'][0]:.2f}" if cyc is not None and len(cyc["cycle"]) else "-"
            md.append(f"| {n[len('c_damping'):]} | {status[n][0]} | {peak} | {status[n][2] or 'finished'} |")
        md.append("")
    (dest / "comparison.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("which", nargs="*", default=["a", "b", "c"], choices=["a", "b", "c"])
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "thesis_box")
    ap.add_argument("--parallel", type=int, default=2)
    ap.add_argument("--report", type=Path, default=None, help="where comparison.md and the PNGs go (default --out)")
    args = ap.parse_args()
    base = tomllib.loads((ROOT / "jobs" / "box_test.toml").read_text())
    base["run"] = {**base["run"], "progress_every": 0, "checkpoint_every_s": 0.0}
    todo = cases(args.which)
    args.out.mkdir(parents=True, exist_ok=True)
    with ThreadPoolExecutor(args.parallel) as pool:
        runs = list(pool.map(lambda nc: run_case(nc[0], nc[1], args.out, base), todo))
    dest = args.report or args.out
    dest.mkdir(parents=True, exist_ok=True)
    report(args.out, runs, dest)


if __name__ == "__main__":
    main()
