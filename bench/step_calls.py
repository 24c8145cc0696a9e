"""Where a step of a whole scene goes on one rank: inside each compiled call, the dispatch of
those calls, and the interpreter around them (Python, numpy).

    python -m bench.step_calls [--case box_full_calibrated] [--steps 20000]

Resumes the case's stiffened bed (`bench.box_full`: ``bench/cache/<case>``, made if missing) in
this process, through ``pdem run``: ``WARMUP`` steps load every kernel, then every numba call
made from Python (`pdem.kernels.Kernel` twins and the plain ``@njit`` dispatchers in pdem's module
globals) is wrapped in a timer for ``--steps`` steps more. The wrapper's own cost, measured on an
empty call, is subtracted. Each call site's dispatch cost is that of a do-nothing ``@njit`` taking
the same arguments. The step's time is the run's timing table less its output. Prints the split
and the call sites by time per step [µs]. One thread; keep the other cores idle.
"""
import argparse
import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

import numba
from numba.core.registry import CPUDispatcher

from bench.box_full import CASES, ROOT, WARMUP, stiffened, stiffened_copy, timing


class CallTimes:
    """Seconds and counts per call site, with one sample of each site's arguments."""

    def __init__(self):
        self.sites = {}

    def call(self, name, f, args):
        t0 = time.perf_counter()
        out = f(*args)
        dt = time.perf_counter() - t0
        site = self.sites.get(name)
        if site is None:
            site = self.sites[name] = [0, 0.0, args]
        site[0] += 1
        site[1] += dt
        return out

    def install(self):
        """Time every Kernel call and every @njit dispatcher held in a pdem module's globals."""
        import pdem.kernels as kernels

        call, plain = self.call, kernels.Kernel.__call__
        kernels.Kernel.__call__ = lambda k, *a: call("kernel " + k.__name__, lambda *b: plain(k, *b), a)
        for mod in [m for n, m in list(sys.modules.items()) if n.startswith("pdem") and m is not None]:
            for attr, val in list(vars(mod).items()):
                if isinstance(val, CPUDispatcher):
                    setattr(mod, attr, (lambda f, nm: lambda *a: call(nm, f, a))(val, f"{mod.__name__}.{attr}"))


def dispatch_seconds(args, n=20000):
    """Seconds per call of a do-nothing @njit taking ``args``."""
    ns = {}
    exec(f"def nothing({', '.join(f'a{i}' for i in range(len(args)))}):\n    return None", ns)
    g = numba.njit(ns["nothing"])
    g(*args)
    t0 = time.perf_counter()
    for _ in range(n):
        g(*args)
    return (time.perf_counter() - t0) / n


def wrapper_seconds(n=20000):
    """The timer's own cost per call [s]: a timed empty call less the empty call."""
    empty, times = numba.njit(lambda: None), CallTimes()
    empty()
    t0 = time.perf_counter()
    for _ in range(n):
        times.call("empty", empty, ())
    return (time.perf_counter() - t0) / n - dispatch_seconds(())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), default="box_full_calibrated")
    ap.add_argument("--steps", type=int, default=20000)
    a = ap.parse_args(argv)
    from pdem.cli import main as pdem_main

    step, _ = stiffened(a.case)
    scene = str(ROOT / "jobs" / CASES[a.case][0])
    with tempfile.TemporaryDirectory(prefix="pdem-step-calls-") as tmp:
        run = stiffened_copy(a.case, step, Path(tmp) / "run")
        with contextlib.redirect_stdout(io.StringIO()):
            pdem_main(["run", scene, "--out", str(run), "--steps", str(step + WARMUP)])
        times = CallTimes()
        times.install()
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            pdem_main(["run", scene, "--out", str(run), "--steps", str(step + WARMUP + a.steps)])
    loop = sum(v for k, v in timing(out.getvalue()).items() if k != "output")
    wrap = wrapper_seconds()
    rows = sorted(((sec - n * wrap, name, n, dispatch_seconds(args)) for name, (n, sec, args) in times.sites.items()),
                  key=lambda r: r[0], reverse=True)
    inside = sum(r[0] for r in rows)
    dispatch = sum(r[2] * r[3] for r in rows)
    us = 1e6 / a.steps
    print(f"{a.case}: {a.steps} steps on one rank, {us * loop:.1f} us per step (timing table less output); "
          f"{sum(r[2] for r in rows) / a.steps:.1f} compiled calls per step")
    for label, sec in (("compiled work", inside - dispatch), ("dispatch of the calls", dispatch),
                       ("interpreter (Python, numpy)", loop - inside)):
        print(f"  {label:28s} {us * sec:7.1f} us  {100 * sec / loop:5.1f} %")
    print("call sites [calls per step, us per step inside, dispatch us per call]:")
    for sec, name, n, d in rows[:15]:
        print(f"  {name:62s} {n / a.steps:5.2f} {us * sec:8.2f} {1e6 * d:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
