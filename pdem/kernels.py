"""`@kernel`: one Python source compiled twice by numba, serial and `parallel=True`.

A parallel region costs ~0.1–0.3 ms to launch, more than a whole step of a small scene, so a call
runs the serial twin when the work (the argument at `size_arg`) is below `PARALLEL_MIN` or numba
has one thread. Both twins execute the same race-free loops and give the same bits. The serial
twin gets its own qualified name so the two never share a numba cache entry.
"""
import types

import numba
from numba import njit

PARALLEL_MIN = 4096


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


def kernel(size_arg=0):
    """Decorator: compile `f` as a serial and a parallel twin; the call picks one by work size."""

    def wrap(f):
        par = njit(parallel=True, cache=True)(f)
        g = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial", f.__defaults__, f.__closure__)
        g.__qualname__ = f.__qualname__ + "_serial"
        g.__module__ = f.__module__
        g.__doc__ = f.__doc__
        return Kernel(par, njit(cache=True)(g), size_arg)

    return wrap
