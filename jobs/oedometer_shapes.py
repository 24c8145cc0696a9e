"""Rigid-clump shape study of the oedometer (thesis 4.4.1, table 4.11, figure 4.19) at reduced size.

One command runs the four grain shapes of table 4.11 — sphere (24, 24, 24), ellipsoid
(24, 30, 19), "cylinder" (18, 18, 40), "cake" (10, 37, 37) mm, all ellipsoids filled with
spheres on a grid (`pdem.bodies.clump_generators`) — in the oedometer, then tabulates and plots the
loading and unloading stiffness of the platen record (`analysis.oedometer`):

    python jobs/oedometer_shapes.py --out runs/oedometer_shapes [--ranks 2] [--scale 0.4] [--grain-scale 0.5]

Reduced size (defaults): the cylinder's lengths × ``scale`` = 0.4 (Ø120 × 60 mm), the grains'
× ``grain_scale`` = 0.5 (the sphere R = 12 mm: 5 grains across the cylinder instead of the
thesis's 6.25, about 100 grains), member radius 3 mm (the thesis's 3.6 mm at full size would give ~90 members a grain),
the thesis's study stiffness of table 4.9 lowered 100 times with the load (E_k = 5.55e7 Pa,
steel 10 E_k, φ_steel 0.3; F_max = 150 kN / 100 × scale² = 1.5 kN × scale², the same F_max/(E_k A)
as table 4.9). The thesis found the spheres
stiffest and the cakes softest ("the stiffness depends on how well the clumps fill the
oedometer"); the script says whether this run ranks them so. Writes, in --out: one run
directory per shape, ``shapes.txt``, ``shapes.json`` and ``shapes.png``.
"""
import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.oedometer import analyse, read_oedometer  # noqa: E402
from pdem.campaign.tomlw import dumps  # noqa: E402
from pdem.bodies.clump_generators import THESIS_SHAPES  # noqa: E402

SHAPES = ("sphere", "ellipsoid", "cylinder", "cake")


def scene(shape, scale, member_radius, seed, grain_scale=None, settle_max_time=2.0):
    """The scene file (parsed) of one shape: the cylinder's lengths × ``scale``, the grain's ×
    ``grain_scale`` (default ``scale``)."""
    radii = [(scale if grain_scale is None else grain_scale) * r for r in THESIS_SHAPES[shape]]
    return {
        "simulation": {"law": "linear", "dt": "auto", "damping": 0.3, "gravity": [0.0, 0.0, -9.81],
                       "slab_axis": "x"},
        "run": {"progress_every": 0, "output_every": 20, "checkpoint_keep": 1},
        "materials": {
            "ballast": {"density": 2600.0, "young": 5.55e7, "poisson": 0.3, "friction_angle": 0.5},
            "steel": {"density": 7850.0, "young": 5.55e8, "poisson": 0.25, "friction_angle": 0.3},
        },
        "oedometer": {
            "diameter": 0.30 * scale, "height": 0.15 * scale, "packing_fraction": 0.3, "overfill": 1.15,
            "seed": seed, "settle_ratio": 0.02, "settle_min_time": 0.1, "settle_max_time": settle_max_time,
            "vibration_time": 0.0, "platen_thickness": 0.02 * scale, "platen_mass": 11.1 * scale**3,
            "f_min": 2.5 * scale**2, "f_max": 1500.0 * scale**2, "load_time": 0.2,
            "clumps": {"shape": "ellipsoid", "radii": radii, "member_radius": member_radius},
        },
    }


def run_one(out, doc, ranks):
    out.mkdir(parents=True, exist_ok=True)
    path = out.with_suffix(".toml")
    path.write_text(dumps(doc))
    cmd = [sys.executable, "-m", "pdem", "run", str(path), "--out", str(out)]
    if ranks > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks)] + cmd
    with open(out.with_suffix(".log"), "w") as log:
        status = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT).returncode
    if status != 0:
        raise SystemExit(f"{path}: pdem exited with status {status} (see {out.with_suffix('.log')})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--scale", type=float, default=0.4, help="cylinder lengths x this (default %(default)s)")
    ap.add_argument("--grain-scale", type=float, default=0.5, help="grain semi-axes x this (default %(default)s)")
    ap.add_argument("--member-radius", type=float, default=0.003)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--settle-max-time", type=float, default=2.0, help="longest settling per stage [s]")
    ap.add_argument("--only-analyse", action="store_true", help="analyse the runs already in --out")
    a = ap.parse_args(argv)
    rows = {}
    for shape in SHAPES:
        run = a.out / shape
        if not a.only_analyse:
            run_one(run, scene(shape, a.scale, a.member_radius, a.seed, a.grain_scale, a.settle_max_time), a.ranks)
        res = read_oedometer(run / "results.h5")
        r = analyse(res.series)
        summary = (run / "summary.txt").read_text().splitlines()
        spheres = [ln for ln in summary if ln.startswith("load ")]
        rows[shape] = {"loading_kN_per_mm": r.loading_stiffness * 1e-6, "unloading_kN_per_mm": r.unloading_stiffness
                       * 1e-6, "u_max_mm": r.u_max * 1e3, "u_end_mm": r.u_end * 1e3,
                       "spheres": int(spheres[0].split()[3]) if spheres else -1, "series": res.series}
    order_load = sorted(SHAPES, key=lambda s: -rows[s]["loading_kN_per_mm"])
    order_unload = sorted(SHAPES, key=lambda s: -rows[s]["unloading_kN_per_mm"])
    thesis = lambda order: order[0] == "sphere" and order[-1] == "cake"  # noqa: E731
    lines = [f"oedometer shape study (thesis table 4.11): cylinder x {a.scale}, grains x {a.grain_scale}, member "
             f"radius {a.member_radius * 1e3} mm",
             "shape       spheres  k_load [kN/mm]  k_unload [kN/mm]  u_max [mm]  u_end [mm]"]
    for s in SHAPES:
        w = rows[s]
        lines.append(f"{s:<10} {w['spheres']:8d} {w['loading_kN_per_mm']:15.5g} {w['unloading_kN_per_mm']:17.5g} "
                     f"{w['u_max_mm']:11.4g} {w['u_end_mm']:11.4g}")
    lines += ["", f"by loading stiffness:   {' > '.join(order_load)} (thesis: sphere stiffest, cake softest: "
                  f"{'yes' if thesis(order_load) else 'no'})",
              f"by unloading stiffness: {' > '.join(order_unload)} ({'yes' if thesis(order_unload) else 'no'})"]
    (a.out / "shapes.txt").write_text("\n".join(lines) + "\n")
    (a.out / "shapes.json").write_text(json.dumps({s: {k: v for k, v in rows[s].items() if k != "series"}
                                                   for s in SHAPES}, indent=1) + "\n")
    plot(rows, a.out / "shapes.png")
    print("\n".join(lines))


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.5))
    for s in SHAPES:
        ser = rows[s]["series"]
        ax.plot(ser["platen_displacement"] * 1e3, ser["platen_force"] * 1e-3, label=s)
    ax.set_xlabel("platen displacement [mm]")
    ax.set_ylabel("ballast force on the platen [kN]")
    ax.legend()
    ax.grid(True, alpha=0.3)
    x = np.arange(len(SHAPES))
    bx.bar(x - 0.2, [rows[s]["loading_kN_per_mm"] for s in SHAPES], 0.4, label="loading")
    bx.bar(x + 0.2, [rows[s]["unloading_kN_per_mm"] for s in SHAPES], 0.4, label="unloading")
    bx.set_xticks(x, SHAPES)
    bx.set_yscale("log")
    bx.set_ylabel("stiffness [kN/mm]")
    bx.legend()
    fig.suptitle("oedometer: clump shape study (thesis table 4.11, figure 4.19)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
