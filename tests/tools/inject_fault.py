"""``pdem run`` with a fault injected on one rank: for the tests of how failures end a job.

    python tests/tools/inject_fault.py RANK STEP KIND[@SITE] -- run SCENE --out DIR ...
    python tests/tools/inject_fault.py --sites          (the sites, one per line, and what they are)

On rank RANK (of the MPI job, or 0 serially), at the first call of SITE once the run's step
counter has reached STEP, KIND happens on entry to SITE, while the other ranks go on into the
site's collective (or the next one) and wait there. SITE (default ``step``: the whole
`Simulation.advance`) names a collective of pdem — a ghost exchange, the migration, the
rebalancing, an exact sum, the checkpoint, results and snapshot writes, the stage machine's
decisions, the start digest agreement ... (`SITES`, ``--sites``). KIND is an exception raised
there: RuntimeError, MemoryError, OSError, ENOSPC (OSError with errno 28), Instability (an
`InstabilityError` on that rank only), InputError, CheckpointError, CheckpointWriteError,
ResultsFileError, SnapshotWriteError, KeyboardInterrupt; or SIGKILL (the rank's process is
killed, ``kill -9``: nothing of pdem runs after it), SIGTERM (sent to the process itself: the
run stops at the next poll with a checkpoint), none (no fault). RANK -1: on every rank. Every
message names the site and the step: ``injected fault at ghost (step 60)``.

The hooks are made here, in the tool's process, by replacing each site's function or method
with a wrapper (in its module and wherever pdem imported it by name): pdem itself holds no test
code. Everything else is the real ``pdem`` command line (`pdem.cli.main`), so the exit status
and the messages are those a user gets. The step counter is that of the simulation most
recently advanced (0 before the first step); the start-up sites (`STARTUP`) ignore STEP.
"""
import errno
import functools
import importlib
import os
import signal
import sys

from pdem import cli
from pdem.errors import InputError, InstabilityError
from pdem.io.checkpoint import CheckpointError, CheckpointWriteError
from pdem.io.snapshots import SnapshotWriteError
from pdem.io.timeseries import ResultsFileError
from pdem.parallel.comm import get_comm
from pdem.simulation import Simulation

# site -> (module, attributes: "function" or "Class.method" (several: "|"; "name:arg" hooks the
# callable passed as keyword ``arg``), what the site is)
SITES = {
    "step": ("pdem.simulation", "Simulation.advance", "one whole time step (the default site)"),
    "digest": ("pdem.driver.preflight", "agree_on_input",
               "the start digest agreement (allgather of the input digests)"),
    "output": ("pdem.driver.runloop", "prepare_output",
               "the output directory check at start (bcast of rank 0's probe)"),
    "resume": ("pdem.io.checkpoint", "find_resume_checkpoint", "the choice of the checkpoint to resume from (bcast)"),
    "rebuild": ("pdem.simulation", "Simulation._needs_rebuild",
                "the neighbour-rebuild test and the per-step guard (allreduce max)"),
    "rebalance": ("pdem.parallel.slab_domain", "SlabDomain._balance",
                  "the load balance of the slab edges (allgathers of the loads)"),
    "migration": ("pdem.parallel.slab_domain", "SlabDomain._migrate",
                  "the migration of bodies and contacts between slabs (any_flag, neighbour exchanges)"),
    "ghost-build": ("pdem.parallel.slab_domain", "SlabDomain._build_ghosts",
                    "the rebuild of the ghost layer (neighbour exchanges)"),
    "ghost": ("pdem.parallel.slab_domain", "SlabDomain.update_ghosts",
              "the ghost update of every step (sized neighbour exchange)"),
    "exact-sum": ("pdem.parallel.comm",
                  "MpiComm.exact_sum|MpiComm.exact_sum_rows|MpiComm.exact_sum_groups|MpiComm.exact_sum_accumulators",
                  "an exact sum over ranks (energies, wall, box and clump forces; allreduce of limbs)"),
    "timestep": ("pdem.timestep", "stable_dt", "the automatic time step (allreduce min)"),
    "stability": ("pdem.checks.diagnostics", "check_stability",
                  "the periodic stability check (any_flag, exact sums, the guard's domain check)"),
    "stop-poll": ("pdem.io.signals", "StopFlag.stop_requested", "the agreement on a stop signal (any_flag)"),
    "checkpoint": ("pdem.io.checkpoint", "write_checkpoint",
                   "a checkpoint write (gathers to rank 0, bcast of the outcome)"),
    "results": ("pdem.io.timeseries", "TimeSeriesWriter.append",
                "a row of the results series (its values are reductions; rank 0 writes)"),
    "results-open": ("pdem.io.timeseries", "TimeSeriesWriter.__init__",
                     "the opening of the results file (bcast of rank 0's outcome)"),
    "snapshot": ("pdem.io.snapshots", "SnapshotWriter.write",
                 "a snapshot write (gathers to rank 0, bcast of the outcome)"),
    "stage-until": ("pdem.driver.runloop", "RunLoop.advance:until",
                    "a stage machine's decision that the stage has ended (the stage's collective test)"),
    "stage-build": ("pdem.driver.stages", "StagedRun.build_stage", "the build of a stage's simulation from the tables"),
    "stage-end": ("pdem.driver.stages", "StagedRun.end_stage", "the end of a stage (its record, checkpoint)"),
}

FAULTS = {
    "RuntimeError": lambda where: RuntimeError(f"injected fault at {where}"),
    "MemoryError": lambda where: MemoryError(f"injected at {where}: cannot allocate 8 GiB"),
    "OSError": lambda where: OSError(errno.EIO, f"injected I/O error at {where}", "somewhere.h5"),
    "ENOSPC": lambda where: OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), f"results.h5 at {where}"),
    "Instability": lambda where: InstabilityError(f"step {Clock.step()}: injected instability at {where}"),
    "InputError": lambda where: InputError(f"injected.key = 1: must be injected, at {where}"),
    "CheckpointError": lambda where: CheckpointError("ckpt_injected.h5", f"injected damage at {where}"),
    "CheckpointWriteError": lambda where: CheckpointWriteError("ckpt_injected.h5",
                                                               f"injected write failure at {where}"),
    "ResultsFileError": lambda where: ResultsFileError("results.h5", f"injected damage at {where}"),
    "SnapshotWriteError": lambda where: SnapshotWriteError("snapshots.h5", f"injected write failure at {where}"),
    "KeyboardInterrupt": lambda where: KeyboardInterrupt(),
}
SIGNALS = ("SIGKILL", "SIGTERM", "none")
STARTUP = {"digest", "output", "resume", "results-open"}  # sites before the first step: STEP is ignored


class Clock:
    """The step of the simulation most recently advanced (0 before the first step)."""

    sim = None

    @classmethod
    def step(cls):
        return 0 if cls.sim is None else cls.sim.step


def _rank():
    return get_comm().rank


def fault(rank, step, kind, site):
    """The action on entry to ``site`` (it fires once, on the first entry that qualifies)."""
    fired = []

    def maybe():
        if fired or (Clock.step() < step and site not in STARTUP) or rank not in (_rank(), -1):
            return
        fired.append(True)
        where = f"{site} (step {Clock.step()})"
        if kind == "SIGKILL":  # nothing of pdem's runs after it: the tool says which rank it killed
            sys.stdout.flush()
            sys.stderr.write(f"inject_fault: rank {_rank()} (pid {os.getpid()}) killed at {where}\n")
            sys.stderr.flush()
            os.kill(os.getpid(), signal.SIGKILL)
        elif kind == "SIGTERM":
            os.kill(os.getpid(), signal.SIGTERM)
        elif kind != "none":
            raise FAULTS[kind](where)

    return maybe


def _replace_everywhere(old, new):
    """``new`` in place of ``old`` in every pdem module that imported it by name."""
    for name, mod in list(sys.modules.items()):
        if name == "pdem" or name.startswith("pdem."):
            for attr, value in list(vars(mod).items()):
                if value is old:
                    setattr(mod, attr, new)


def hook(site, maybe):
    """Call ``maybe()`` on entry to ``site`` (its functions or methods replaced by wrappers)."""
    module, targets, _ = SITES[site]
    mod = importlib.import_module(module)
    for target in targets.split("|"):
        _hook_one(mod, target, maybe)


def _hook_one(mod, target, maybe):
    target, _, arg = target.partition(":")
    owner_name, _, name = target.rpartition(".")
    owner = getattr(mod, owner_name) if owner_name else mod
    original = getattr(owner, name)

    if arg:  # a callable argument of the function (the stage's `until` test)
        @functools.wraps(original)
        def wrapper(*args, **kw):
            given = kw.get(arg)
            if given is not None:
                @functools.wraps(given)
                def wrapped_arg(*a, **k):
                    maybe()
                    return given(*a, **k)
                kw[arg] = wrapped_arg
            return original(*args, **kw)
    else:
        @functools.wraps(original)
        def wrapper(*args, **kw):
            maybe()
            return original(*args, **kw)

    setattr(owner, name, wrapper)
    if not owner_name:
        _replace_everywhere(original, wrapper)


def _import_pdem():
    """Import the modules that import sites by name, so that their names are replaced too."""
    import pdem.driver.plain  # noqa: F401
    import pdem.driver.stages  # noqa: F401
    import pdem.scenes  # noqa: F401


def main():
    if sys.argv[1:2] == ["--sites"]:
        for site, (_, _, what) in SITES.items():
            print(f"{site}: {what}")
        return 0
    rank, step, spec = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    kind, _, site = spec.partition("@")
    site = site or "step"
    if site not in SITES or (kind not in FAULTS and kind not in SIGNALS):
        sys.stderr.write(f"inject_fault: unknown KIND@SITE {spec!r}: kinds {sorted(FAULTS) + list(SIGNALS)}, "
                         f"sites {list(SITES)}\n")
        return 64
    argv = sys.argv[sys.argv.index("--") + 1:]
    _import_pdem()
    advance = Simulation.advance

    def tracked_advance(sim):
        Clock.sim = sim
        return advance(sim)

    Simulation.advance = tracked_advance
    hook(site, fault(rank, step, kind, site))
    get_comm()  # MPI up before the run, as in `python -m pdem`
    return cli.main(argv)


if __name__ == "__main__":
    sys.exit(main())
