"""`@kernel`: one Python source compiled twice by numba, serial and `parallel=True`; and
`specialize`: one template compiled per combination of the inline functions it calls; and the
choice of numba's threading layer.

Threading layer: GNU OpenMP (``omp``) when numba can load it (gcc's libgomp), else
``workqueue``; an explicit ``NUMBA_THREADING_LAYER`` wins. A parallel launch costs ~3 µs with
omp and ~30 µs with workqueue on the 2-core bench machine (2000 launches of a 4096-element
prange), which is what made two threads slower than one on small scenes. omp threads spin briefly after a region:
keep ranks × threads within the cores (`pdem.parallel.comm.configure_threads` does so).
A call runs the serial twin when the work (the argument at `size_arg`) is below `PARALLEL_MIN`
or numba has one thread, so single-threaded ranks never start a thread pool. Both twins
execute the same race-free loops and give the same bits. The serial twin gets its own
qualified name so the two never share a numba cache entry.

`specialize(template, name, bindings, sources)` is how the contact loops are generated from a
(geometry, law) pair (`pdem.contact.loops`): a copy of ``template`` whose global names in
``bindings`` (upper-case placeholders such as ``GEOM_CONTACT``, ``LAW_FORCE``) are bound to the
chosen njit functions and constants. numba inlines them and prunes branches on the constants, so
the generated kernel is the hand-written loop of that pair. A closure would do the same but
numba caches closures over dispatchers under a key that changes every session (numba issue
6264); a copy with its own globals and a unique qualified name is cached like any function. The
qualified name carries a hash of the ``sources`` (the modules the bound functions come from):
numba checks only the template's file for staleness, so without the hash an edit to a law would
silently run the old compiled loop.
"""
import hashlib
import os
import types
from pathlib import Path

import numba
from numba import njit

PARALLEL_MIN = 4096


def choose_threading_layer():
    """Set numba's threading layer (before the first parallel launch): the environment's
    ``NUMBA_THREADING_LAYER`` if given, else ``omp`` if numba's OpenMP pool loads, else
    ``workqueue``. Returns the layer chosen."""
    if os.environ.get("NUMBA_THREADING_LAYER"):
        return numba.config.THREADING_LAYER
    try:
        from numba.np.ufunc import omppool  # noqa: F401  (loads libgomp)

        numba.config.THREADING_LAYER = "omp"
    except ImportError:
        numba.config.THREADING_LAYER = "workqueue"
    return numba.config.THREADING_LAYER


choose_threading_layer()


class Kernel:
    def __init__(self, parallel, serial, size_arg):
        self.parallel = parallel
        self.serial = serial
        self.size_arg = size_arg
        self.__doc__ = getattr(parallel, "py_func", parallel).__doc__
        self.__name__ = getattr(parallel, "py_func", parallel).__name__

    def __call__(self, *args):
        if args[self.size_arg] >= PARALLEL_MIN and numba.get_num_threads() > 1:
            return self.parallel(*args)
        return self.serial(*args)


def _copy(f, qualname, namespace=None):
    """A new function object with ``f``'s code, named ``qualname``, globals ``namespace``."""
    g = types.FunctionType(f.__code__, f.__globals__ if namespace is None else namespace,
                           qualname.rsplit(".", 1)[-1], f.__defaults__, f.__closure__)
    g.__qualname__ = qualname
    g.__module__ = f.__module__
    g.__doc__ = f.__doc__
    return g


def _twins(f, size_arg):
    serial = _copy(f, f.__qualname__ + "_serial", f.__globals__)
    return Kernel(njit(parallel=True, cache=True)(f), njit(cache=True)(serial), size_arg)


def kernel(size_arg=0):
    """Decorator: compile `f` as a serial and a parallel twin; the call picks one by work size."""

    def wrap(f):
        return _twins(f, size_arg)

    return wrap


def source_hash(*modules):
    """8 hex digits of the source text of the given modules (their files)."""
    h = hashlib.sha256()
    for m in modules:
        h.update(Path(m.__file__).read_bytes())
    return h.hexdigest()[:8]


def specialize(template, name, bindings, sources=(), size_arg=0):
    """The `Kernel` (serial and parallel twins) of ``template`` with the global names of
    ``bindings`` bound to the given values; cached by numba under ``<template>__<name>_<hash>``
    where the hash covers the template's module and ``sources``."""
    import sys

    namespace = dict(template.__globals__)
    namespace.update(bindings)
    tag = source_hash(sys.modules[template.__module__], *sources)
    f = _copy(template, f"{template.__qualname__}__{name}_{tag}", namespace)
    return _twins(f, size_arg)
