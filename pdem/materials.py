"""Materials and their table of per-material arrays.

A material is a density ρ [kg/m³] plus the properties the scene's contact law asks for
(``law.MATERIAL_KEYS``; for the linear law Yade's ``FrictMat``: Young's modulus E [Pa],
"Poisson ratio" ν [-] (only the ratio k_s/k_n, YADE_MODEL.md §4) and friction angle φ [rad]).
Per-contact parameters are computed from the two materials once, when a contact is created
(Yade's Ip2), by the law from the table `MaterialTable.props` (one row per material, one column
per law key, in the law's order).
"""
from dataclasses import dataclass

import numpy as np

from .errors import InputError
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

    def __len__(self):
        return len(self.materials)

    def props(self):
        """float64 [n_materials, n_keys]: the law properties, one column per law key."""
        return np.array([[v for _, v in m.properties] for m in self.materials], np.float64).reshape(
            len(self.materials), len(self.law.MATERIAL_KEYS))

    def density(self):
        return np.array([m.density for m in self.materials], np.float64)

    def column(self, key):
        """float64 [n_materials]: one law property of every material."""
        return self.props()[:, list(self.law.MATERIAL_KEYS).index(key)]

    def spec(self):
        """JSON-able list of the materials (name, density, the law's keys)."""
        return [dict(name=n, density=m.density, **dict(m.properties)) for n, m in zip(self.names, self.materials)]
