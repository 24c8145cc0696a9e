"""One grain of jobs/oedometer_breakable_scaled_thesis_grain.toml alone (136 spheres of r 3.6 mm
6.7 mm apart, Yade's loaded bonds, the job's scaled materials, damping 0.3, no gravity): how many
bonds survive the shedding of the initial overlaps when the bond strengths are held at ten times
their value for the first N steps and then returned (thesis 4.5), and never (N = 0, no boost).

    python docs/oedometer/breakable_scaled/thesis_grain/one_grain.py [N ...]

Prints per N: bonds left of those made, fragments (largest, single spheres), kinetic energy [J]
after 0.03 s. Units SI.
"""
import sys

import numpy as np

from pdem.bodies.clump_generators import shape_members
from pdem.bodies.fragments import components
from pdem.build.scene import Scene

T_END = 0.03  # [s]


def grain_after(boost_steps):
    pos, r = shape_members("ellipsoid", 0.0036, (0.024, 0.024, 0.024), 0.0067)
    sc = Scene(dt="auto", damping=0.3, gravity=(0.0, 0.0, 0.0), law="cohesive", allow_initial_overlap=True)
    m = sc.material(density=2600.0, young=5.55e7, poisson=0.3, friction_angle=0.5, normal_cohesion=1.6204e6,
                    shear_cohesion=1.6204e6)
    sc.add_clumps([(pos, r)], m, breakable=True, stress_free=False)
    sim = sc.build()
    made = int(np.sum(sim.contacts("sphere_sphere")["normal_adhesion"] > 0))
    if boost_steps:
        sim.scale_bond_strength(10.0)
        sim.run(boost_steps)
        sim.scale_bond_strength(0.1)
    while sim.time < T_END:
        sim.run(100)
    c = sim.contacts("sphere_sphere")
    bonded = c["normal_adhesion"] > 0
    p = sim.particles
    row = np.argsort(p.gid[: p.n_local])  # one rank: gid -> row
    label = components(p.n_local, row[c["gid1"][bonded]], row[c["gid2"][bonded]])
    _, size = np.unique(label, return_counts=True)
    return made, int(bonded.sum()), size, sim.energy()["kinetic"]


if __name__ == "__main__":
    print(f"{'N':>6} {'bonds':>9} {'fragments':>9} {'largest':>7} {'single':>6} {'KE [J]':>9}")
    for n in [int(a) for a in sys.argv[1:]] or [0, 10, 20, 30, 40, 44, 50, 100, 2250]:
        made, left, size, ke = grain_after(n)
        print(f"{n:>6} {left:>4}/{made:<4} {len(size):>9} {size.max():>7} {np.sum(size == 1):>6} {ke:>9.3g}")
