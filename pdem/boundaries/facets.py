"""Facets: fixed (or translating) triangles, Yade's ``utils.facet`` with ``Facet::postLoad``.

A facet is stored as one row of `FACET_COLUMNS` floats in Yade's local frame: the centre of the
inscribed circle c [m], the unit normal n, the three in-plane edge normals ne_k, the inscribed
radius icr [m], unit vectors vu_k from c to the vertices and their lengths vl_k [m]
(YADE_MODEL.md §2). Facets translate with a prescribed velocity [m/s]; they do not rotate.

Storage: the rows the contact loop reads (`pdem.contact.geometry.SphereFacet`): ``kernel_f``
[n, FACET_COLUMNS + 3] = geometry row, velocity and ``kernel_i`` [n, 1] = material; ``geom``,
``velocity`` and ``material`` are views of them. ``vertices`` [n, 3, 3] are the global vertices.
"""
import numpy as np

from ..errors import InputError

FACET_COLUMNS = 28  # c(3) n(3) ne(9) icr(1) vu(9) vl(3)


def _norm(v):
    return np.sqrt(v[0] * v[0] + (v[1] * v[1] + v[2] * v[2]))


def _normalized(v):
    return v / _norm(v)


def facet_row(v0, v1, v2):
    """The geometry row of triangle (v0, v1, v2), in Yade's evaluation order."""
    v0, v1, v2 = (np.asarray(v, np.float64) for v in (v0, v1, v2))
    # utils.inscribedCircleCenter
    a, b, c = _norm(v1 - v0), _norm(v2 - v1), _norm(v0 - v2)
    centre = v0 + ((v2 - v0) * a + (v1 - v0) * c) / (a + b + c)
    verts = [v0 - centre, v1 - centre, v2 - centre]
    e = [verts[1] - verts[0], verts[2] - verts[1], verts[0] - verts[2]]
    n = np.cross(e[0], e[1])
    area = 0.5 * _norm(n)
    if not area > 0.0:
        raise InputError(f"facet vertices {v0.tolist()}, {v1.tolist()}, {v2.tolist()}: degenerate triangle (zero area)")
    n = n / (2.0 * area)
    ne = [_normalized(np.cross(e[k], n)) for k in range(3)]
    perimeter = _norm(e[0]) + _norm(e[1]) + _norm(e[2])
    icr = _norm(e[0]) * (ne[0][0] * e[2][0] + (ne[0][1] * e[2][1] + ne[0][2] * e[2][2])) / perimeter
    vl = [_norm(v) for v in verts]
    vu = [verts[k] / vl[k] for k in range(3)]
    return np.concatenate([centre, n, *ne, [icr], *vu, vl])


class Facets:
    def __init__(self):
        self.kernel_f = np.zeros((0, FACET_COLUMNS + 3))
        self.kernel_i = np.zeros((0, 1), np.int64)
        self.vertices = np.zeros((0, 3, 3))
        self.names = []

    geom = property(lambda self: self.kernel_f[:, :FACET_COLUMNS])
    velocity = property(lambda self: self.kernel_f[:, FACET_COLUMNS:])
    material = property(lambda self: self.kernel_i[:, 0])

    def __len__(self):
        return len(self.kernel_i)

    def search_arrays(self):
        """Arguments of `pdem.contact.neighbors.build_facet_candidates` after the particles."""
        return self.geom, self.vertices

    def add(self, vertices, material, velocity=(0.0, 0.0, 0.0), name=""):
        v = np.asarray(vertices, np.float64)
        if v.shape != (3, 3) or not np.all(np.isfinite(v)):
            raise InputError(f"facets[{len(self)}].vertices: must be three finite points (x, y, z), got {vertices!r}")
        row = np.concatenate([facet_row(*v), np.asarray(velocity, float).reshape(3)])
        self.kernel_f = np.vstack([self.kernel_f, row[None]])
        self.kernel_i = np.vstack([self.kernel_i, np.array([[material]], np.int64)])
        self.vertices = np.concatenate([self.vertices, v[None]])
        self.names.append(name or str(len(self.names)))
        return len(self) - 1

    def move(self, dt):
        """Translate every facet with its prescribed velocity (after forces)."""
        if np.any(self.velocity):
            self.geom[:, 0:3] += self.velocity * dt
            self.vertices += self.velocity[:, None, :] * dt
