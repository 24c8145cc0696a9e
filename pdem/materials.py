"""Materials and their table of per-material arrays.

A material is the data of Yade's ``FrictMat``: density ρ [kg/m³], Young's modulus E [Pa],
"Poisson ratio" ν [-] (in this model only the ratio k_s/k_n, YADE_MODEL.md §4), and friction
angle φ [rad]. Per-contact parameters are computed from the two materials once, when a contact is
created (Yade's Ip2), by the contact law module.
"""
from dataclasses import dataclass

import numpy as np

from .errors import InputError


@dataclass(frozen=True)
class Material:
    density: float
    young: float
    poisson: float
    friction_angle: float
    name: str = ""

    def __post_init__(self):
        label = self.name or "material"
        for field, lo, allow in (("density", 0.0, "> 0"), ("young", 0.0, "> 0")):
            v = getattr(self, field)
            if not (np.isfinite(v) and v > lo):
                raise InputError(f"{label}.{field} = {v!r}: must be a finite number {allow}")
        if not (np.isfinite(self.poisson) and self.poisson >= 0.0):
            raise InputError(f"{label}.poisson = {self.poisson!r}: must be a finite number >= 0 (it is k_s/k_n)")
        if not (np.isfinite(self.friction_angle) and 0.0 <= self.friction_angle < np.pi / 2):
            raise InputError(f"{label}.friction_angle = {self.friction_angle!r}: must be in [0, pi/2) rad")


class MaterialTable:
    """Materials by index, with contiguous arrays for the kernels."""

    def __init__(self):
        self.materials = []

    def add(self, material):
        self.materials.append(material)
        return len(self.materials) - 1

    def __len__(self):
        return len(self.materials)

    def arrays(self):
        """(young, poisson, friction_angle, density) as float64 arrays indexed by material."""
        m = self.materials
        return (np.array([x.young for x in m], np.float64), np.array([x.poisson for x in m], np.float64),
                np.array([x.friction_angle for x in m], np.float64), np.array([x.density for x in m], np.float64))
