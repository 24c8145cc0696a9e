"""The sleeper as a shell of member spheres (thesis 5.2, fig. 5.6: "one clump of 2280 spheres of
radius 5 mm"), shared by the box test (`pdem.scenes.box_test`) and the track
(`pdem.scenes.track`): the member centres of a rectangular sleeper (`sleeper_members`, relative
to its centre [m]) and their mass as Yade sums a clump's (`members_mass` [kg]: the members'
volumes 4/3 π r³ times the density, overlaps not subtracted). The box body that carries them is
`pdem.bodies.boxes.BoxMembers`.
"""
import numpy as np


def sleeper_members(size, r=0.005, closed=False):
    """Member centres [m, relative to the sleeper's centre] of a sleeper of ``size`` [x, y, z] [m]
    made of spheres of radius ``r`` [m] touching on a lattice of spacing 2r, n_a = round(size_a /
    2r) sites along each axis a, the outermost at ±(size_a / 2 − r) (the members' outer surfaces
    on the box's faces): the shell of that lattice. With ``closed`` false a rectangular tube along
    y (top and bottom plates of n_x × n_y spheres, two side walls of n_y × (n_z − 2)): the box
    test's sleeper, whose open ends face the box's y walls; for 250 × 300 × 150 mm and r = 5 mm
    2·25·30 + 2·30·13 = 2280 spheres, the thesis's count. With ``closed`` the two end walls at
    ±y too ((n_x − 2) × (n_z − 2) each): every lattice site with an outermost index on some axis,
    n_x n_y n_z − (n_x − 2)(n_y − 2)(n_z − 2) spheres (the track's sleeper, whose ends face the
    shoulders). Lattice order (x, then y, then z index)."""
    n = [int(round(s / (2 * r))) for s in size]
    axes = [(np.arange(k) - (k - 1) / 2.0) * 2 * r for k in n]
    x, y, z = np.meshgrid(*axes, indexing="ij")
    shell = (np.abs(z) == axes[2].max()) | (np.abs(x) == axes[0].max())
    if closed:
        shell |= np.abs(y) == axes[1].max()
    return np.stack([x[shell], y[shell], z[shell]], axis=1)


def members_mass(members, r, density):
    """Mass [kg] of ``members`` (a [k, 3] array) spheres of radius ``r`` [m] and ``density``
    [kg/m³]: k · 4/3 π r³ ρ, as Yade sums a clump's members (the box test's "9.37 kg" of the
    thesis's steel sleeper)."""
    return len(members) * 4.0 / 3.0 * np.pi * r ** 3 * density
