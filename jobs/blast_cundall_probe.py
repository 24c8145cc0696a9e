"""Probe of a question of the blast layer (docs/blast.md, "Resolved questions"): does Cundall
damping with the viscous law keep a settled column of grains agitated? (No: a loose column
collapses slowly, fed by gravity.)

    .venv/bin/python jobs/blast_cundall_probe.py [--damping 0.3] [--dt-safety 0.8]
        [--rolling-stiffness 11.3] [--rolling-coefficient 0.1] [--damping-ratio 0.2] [--steps 300000]

300 spheres of r = 4.75 mm ± 5 % (ρ 2000 kg/m³) fall from a loose cloud into a 4 × 4 cm column of
five walls under gravity; viscous law k_n 5.6 MN/m, k_s 2 MN/m, μ 0.3 (the blast paper's grains)
with the given damping ratio ζ, rolling stiffness k_θ [N·m/rad] and rolling coefficient β;
Cundall damping λ_D = ``--damping`` on every grain; Δt automatic with the given safety factor.
Prints the translational and rotational kinetic energy [J] and the grains' mean height [mm]
every 25 000 steps.
"""
import argparse
import sys

import numpy as np

from pdem import Scene
from pdem.build.generators import loose_cloud


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--damping", type=float, default=0.3)
    ap.add_argument("--dt-safety", type=float, default=0.8)
    ap.add_argument("--rolling-stiffness", type=float, default=11.3)
    ap.add_argument("--rolling-coefficient", type=float, default=0.1)
    ap.add_argument("--damping-ratio", type=float, default=0.2)
    ap.add_argument("--steps", type=int, default=300000)
    a = ap.parse_args(argv)
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([0.04, 0.04, 0.5])
    pos, radius = loose_cloud(lo, hi, 300, 0.00475, 0.05, 3)
    sc = Scene(dt="auto", dt_safety=a.dt_safety, damping=a.damping, gravity=(0, 0, -9.81), law="viscous",
               energy_check=False)
    m = sc.material(density=2000.0, kn=5.6e6, ks=2e6, damping_ratio=a.damping_ratio, friction=0.3,
                    rolling_stiffness=a.rolling_stiffness, rolling_coefficient=a.rolling_coefficient)
    sc.add_spheres(pos, radius, m)
    sc.add_wall("z", 0.0, m, sense=1)
    for axis in ("x", "y"):
        k = "xyz".index(axis)
        sc.add_wall(axis, lo[k], m, sense=1)
        sc.add_wall(axis, hi[k], m, sense=-1)
    sim = sc.build()
    for _ in range(a.steps // 25000):
        sim.run(25000)
        e = sim.energy()
        z = float(sim.particles.pos[: sim.particles.n_local, 2].mean())
        print(f"step {sim.step} t {sim.time:.3f} s  dt {sim.dt:.2e} s  kinetic {e['kinetic']:.2e} J  "
              f"rotational {e['rotational']:.2e} J  mean height {1000 * z:.2f} mm", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
