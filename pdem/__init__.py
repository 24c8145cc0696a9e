"""pdem: a parallel discrete element code for railway ballast.

Public names: `Scene` (declare and build a simulation), `Simulation`, `Material`, `InputError`,
`InstabilityError`. See README.md and docs/.

The names are loaded on first use (PEP 562), so that ``import pdem.format`` (the file format,
numpy and h5py only) does not load the engine, numba or mpi4py.
"""
from importlib import import_module

# public name -> module (relative to this package) that defines it
_PUBLIC = {"Scene": ".build.scene", "Simulation": ".simulation", "Material": ".build.materials",
           "InputError": ".errors", "InstabilityError": ".errors", "__version__": ".version"}

__all__ = list(_PUBLIC)


def __getattr__(name):
    if name not in _PUBLIC:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_PUBLIC[name], __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_PUBLIC))
