"""Materials and their table of per-material arrays.

A material is a density ρ [kg/m³] plus the properties the scene's contact law asks for
(``law.MATERIAL_KEYS``; for the linear law Yade's ``FrictMat``: Young's modulus E [Pa],
"Poisson ratio" ν [-] (only the ratio k_s/k_n, YADE_MODEL.md §4) and friction angle φ [rad]).
Per-contact parameters are computed from the two materials once, when a contact is created
(Yade's Ip2), by the law from the table `MaterialTable.props` (one row per material, one column
per law key, in the law's order).

Pair values: a law with ``PAIR_KEYS`` (e.g. Hertz–Mindlin's restitution and friction, which
LIGGGHTS and EDEM define per pair of materials) may have them set per pair of materials
(`MaterialTable.set_pair`); an unset pair gets ``law.combine(key, value_a, value_b)``. `props`
then appends, for every material row a, the pair values with each partner b: column
``n_keys + b·len(PAIR_KEYS) + k`` holds key k of the pair (a, b) (`pair_column`).
"""
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .validate import number


@dataclass(frozen=True)
class Material:
    density: float
    properties: tuple  # ((key, value), ...) in the law's MATERIAL_KEYS order
    name: str = ""

    def __getattr__(self, key):
        for k, v in self.__dict__.get("properties", ()):
            if k == key:
                return v
        raise AttributeError(key)


class MaterialTable:
    """Materials by index, with contiguous arrays for the kernels."""

    def __init__(self, law):
        self.law = law
        self.materials = []
        self.names = []
        self.pairs = {}  # (a, b) with a <= b -> {key: value} (law.PAIR_KEYS only)

    def add(self, name, density, values):
        """Validate and append a material; returns its index. ``values``: the law's keys."""
        label = f"materials.{name}" if name else f"materials[{len(self.materials)}]"
        keys = self.law.MATERIAL_KEYS
        for k in values:
            if k not in keys:
                raise InputError(f"{label}.{k}: unknown key for the {self.law.NAME} law; allowed: density, "
                                 f"{', '.join(keys)}")
        for k in keys:
            if k not in values:
                raise InputError(f"{label}.{k}: required key is missing (the {self.law.NAME} law needs it)")
        rho = number(f"{label}.density", density, 0.0, lo_open=True, allow="a finite number > 0 [kg/m³]")
        props = []
        for k, (allow, test) in keys.items():
            v = number(f"{label}.{k}", values[k], allow=allow)
            if not test(v):
                raise InputError(f"{label}.{k} = {values[k]!r}: must be {allow}")
            props.append((k, v))
        self.materials.append(Material(rho, tuple(props), label))
        self.names.append(name or str(len(self.names)))
        return len(self.materials) - 1

    def set_pair(self, a, b, values, label="material_pairs"):
        """Values of ``law.PAIR_KEYS`` for the pair of materials a, b (indices), checked like a
        material's keys."""
        keys = self.law.PAIR_KEYS
        for k, v in values.items():
            if k not in keys:
                raise InputError(f"{label}.{k}: not a per-pair key of the {self.law.NAME} law; allowed: "
                                 f"{', '.join(keys) or 'none'}")
            allow, test = self.law.MATERIAL_KEYS[k]
            x = number(f"{label}.{k}", v, allow=allow)
            if not test(x):
                raise InputError(f"{label}.{k} = {v!r}: must be {allow}")
            self.pairs.setdefault((min(a, b), max(a, b)), {})[k] = x

    def __len__(self):
        return len(self.materials)

    def props(self, scale=None):
        """float64 [n_materials, n_keys (+ n_materials·len(PAIR_KEYS))]: the law properties,
        one column per law key, then the pair values (module docstring). ``scale``: {key:
        factor} multiplies that key's column (and its pair values)."""
        keys = list(self.law.MATERIAL_KEYS)
        base = np.array([[v for _, v in m.properties] for m in self.materials], np.float64).reshape(
            len(self.materials), len(keys))
        for key, factor in (scale or {}).items():
            base[:, keys.index(key)] *= float(factor)
        pair_keys = self.law.PAIR_KEYS
        if not pair_keys:
            return base
        n, npk = len(self.materials), len(pair_keys)
        pairs = np.zeros((n, n * npk))
        for a in range(n):
            for b in range(n):
                given = self.pairs.get((min(a, b), max(a, b)), {})
                for k, key in enumerate(pair_keys):
                    col = keys.index(key)
                    v = given[key] * float((scale or {}).get(key, 1.0)) if key in given else \
                        self.law.combine(key, base[a, col], base[b, col])
                    pairs[a, b * npk + k] = v
        return np.concatenate([base, pairs], axis=1)

    def density(self):
        return np.array([m.density for m in self.materials], np.float64)

    def column(self, key):
        """float64 [n_materials]: one law property of every material."""
        return self.props()[:, list(self.law.MATERIAL_KEYS).index(key)]

    def spec(self):
        """JSON-able list of the materials (name, density, the law's keys; per-pair values under
        ``pairs`` when some are set)."""
        out = [dict(name=n, density=m.density, **dict(m.properties)) for n, m in zip(self.names, self.materials)]
        for (a, b), values in sorted(self.pairs.items()):
            out[a].setdefault("pairs", {})[self.names[b]] = dict(values)
            if a != b:
                out[b].setdefault("pairs", {})[self.names[a]] = dict(values)
        return out


def pair_column(n_keys, n_pair_keys, b, k):
    """Column of `MaterialTable.props` holding pair key k of a material row with partner b."""
    return n_keys + b * n_pair_keys + k
