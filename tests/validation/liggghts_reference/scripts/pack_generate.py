#!/usr/bin/env python3
"""Deterministic initial state of pack_settle: 64 spheres on a jittered 4 x 4 x 4 grid in a 6 cm box.

    python3 pack_generate.py [OUT.data]      (default: pack_settle.data next to this script)

Radii uniform in [4, 6] mm, positions on the grid {9, 23, 37, 51} mm in x and y with a +-1 mm jitter,
layer k at z = 8 mm + 14 mm k (+-1 mm jitter), zero velocities. Python's random.Random(20240601)
(Mersenne Twister; random() is stable across Python versions), numbers drawn in the order
radius, jx, jy, jz per sphere. Every number is written with repr(), so the data file holds the exact
doubles that also go into the JSON ("generation").
"""
import random
import sys
from pathlib import Path

N_SIDE, N_LAYERS = 4, 4
GRID = [0.009, 0.023, 0.037, 0.051]
Z0, DZ = 0.008, 0.014
R_MIN, R_MAX, JITTER = 0.004, 0.006, 0.001
BOX = (0.06, 0.06, 0.12)
DENSITY = 2500.0
SEED = 20240601


def generate():
    rng = random.Random(SEED)
    spheres = []
    for k in range(N_LAYERS):
        for iy in range(N_SIDE):
            for ix in range(N_SIDE):
                r = R_MIN + (R_MAX - R_MIN) * rng.random()
                jx = JITTER * (2.0 * rng.random() - 1.0)
                jy = JITTER * (2.0 * rng.random() - 1.0)
                jz = JITTER * (2.0 * rng.random() - 1.0)
                spheres.append({"id": len(spheres) + 1, "radius": r, "diameter": 2.0 * r,
                                "pos": [GRID[ix] + jx, GRID[iy] + jy, Z0 + DZ * k + jz]})
    return spheres


def write_data(path, spheres):
    with open(path, "w") as f:
        f.write("LIGGGHTS data file: pack_settle (pdem liggghts_reference, scripts/pack_generate.py). "
                "Columns: id type diameter density x y z\n\n")
        f.write(f"{len(spheres)} atoms\n2 atom types\n\n")
        f.write(f"0.0 {BOX[0]!r} xlo xhi\n0.0 {BOX[1]!r} ylo yhi\n0.0 {BOX[2]!r} zlo zhi\n\nAtoms\n\n")
        for s in spheres:
            x, y, z = s["pos"]
            f.write(f"{s['id']} 1 {s['diameter']!r} {DENSITY!r} {x!r} {y!r} {z!r}\n")


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent / "pack_settle.data"
    sp = generate()
    # no initial overlaps, no wall overlaps
    for a in sp:
        assert a["pos"][0] - a["radius"] > 0 and a["pos"][0] + a["radius"] < BOX[0]
        assert a["pos"][1] - a["radius"] > 0 and a["pos"][1] + a["radius"] < BOX[1]
        assert a["pos"][2] - a["radius"] > 0
        for b in sp:
            if b["id"] > a["id"]:
                d2 = sum((a["pos"][c] - b["pos"][c]) ** 2 for c in range(3))
                assert d2 > (a["radius"] + b["radius"]) ** 2, (a["id"], b["id"])
    write_data(out, sp)
    print(f"wrote {out}: {len(sp)} spheres")
