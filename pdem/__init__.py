"""pdem: a parallel discrete element code for railway ballast.

Public names: `Scene` (declare and build a simulation), `Simulation`, `Material`, `InputError`,
`InstabilityError`. See README.md and docs/.
"""
from .errors import InputError, InstabilityError
from .materials import Material
from .scene import Scene
from .simulation import Simulation
from .version import __version__

__all__ = ["Scene", "Simulation", "Material", "InputError", "InstabilityError", "__version__"]
