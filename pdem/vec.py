"""Inline 3-vector arithmetic in the evaluation order of Yade's Eigen build.

Yade's Eigen is compiled with EIGEN_DONT_VECTORIZE: a dot product of 3-vectors is evaluated as
``x0*y0 + (x1*y1 + x2*y2)`` (YADE_MODEL.md §9). Using these helpers everywhere keeps pdem
bit-identical to Yade on the linear model. numba (without fastmath) contracts nothing into FMA.
"""
from numba import njit


@njit(inline="always", cache=True)
def dot3(ax, ay, az, bx, by, bz):
    """a·b in Yade's order."""
    return ax * bx + (ay * by + az * bz)


@njit(inline="always", cache=True)
def cross3(ax, ay, az, bx, by, bz):
    """a×b = (a1 b2 − a2 b1, a2 b0 − a0 b2, a0 b1 − a1 b0)."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(inline="always", cache=True)
def scgeom_rotate(x, y, z, ox, oy, oz, tx, ty, tz):
    """Yade's ScGeom::rotate: a vector carried by the contact (the stored shear force) follows the
    contact's rotation in the step: v −= v × o (o the orthonormal axis n_old × n), then
    v −= v × t (t the twist axis)."""
    cx, cy, cz = cross3(x, y, z, ox, oy, oz)
    x -= cx
    y -= cy
    z -= cz
    cx, cy, cz = cross3(x, y, z, tx, ty, tz)
    return x - cx, y - cy, z - cz
