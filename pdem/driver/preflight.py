"""Checks at the start of a run, before any work, that no rank could pass alone.

Owns:

- `agree_on_input`: every rank hashes (sha256) the bytes of the scene file it reads and the
  command-line arguments that shape the run (``--out``, ``--steps``, ``--fresh``); one gather of
  the digests (`Comm.allgather_rows`, 64 bytes per rank) and every rank compares them with rank
  0's. Ranks that disagree (an MPMD launch, a file changed between two ranks reading it) would
  otherwise build different scenes and wait on each other forever in a collective; here every
  rank raises the same one-line `InputError` together (exit status 2, printed once). (The scene
  is parsed from a second read of the file: a file changed on one rank between its two reads,
  microseconds apart, is not caught.)
- `check_run_length`: a run whose requested length no run could reach is refused before it
  starts: more than `MAX_WALL_S` (100 years) at `MIN_STEP_S` per step, i.e. more than
  `MAX_STEPS` steps. `MIN_STEP_S` (10 µs) is a floor under the wall time of any pdem step: the
  smallest scene (two spheres, one core) steps in 28 µs on the 2-core development VM. The
  decision reads only numbers every rank has (a step count, or a stage's simulated time and
  time step), so every rank decides the same.
"""
import hashlib
import json

import numpy as np

from ..errors import InputError

MIN_STEP_S = 1e-5  # [s] a floor under the wall time of one step of any pdem run
MAX_WALL_S = 100 * 365.25 * 86400.0  # [s] 100 years
MAX_STEPS = int(MAX_WALL_S / MIN_STEP_S)  # 3.2e14 steps


def input_digests(path, args):
    """sha256 of the scene file's bytes (of the error, if it cannot be read: the parse reports
    it) and of ``args`` (a JSON-able dict of the arguments that shape the run), 32 bytes each."""
    try:
        with open(path, "rb") as fh:
            scene = hashlib.sha256(fh.read()).digest()
    except OSError as exc:
        scene = hashlib.sha256(f"unreadable: {type(exc).__name__}".encode()).digest()
    given = hashlib.sha256(json.dumps(args, sort_keys=True, default=str).encode()).digest()
    return scene, given


def agree_on_input(comm, path, args):
    """Raise InputError on every rank, together, if any rank's scene file bytes or arguments
    (``args``, e.g. {"out": ..., "steps": ..., "fresh": ...}) differ from rank 0's."""
    scene, given = input_digests(path, args)
    row = np.frombuffer(scene + given, dtype=np.uint8).reshape(1, 64)
    table = comm.allgather_rows(row)
    for what, cols in (("read a different scene file", slice(0, 32)),
                       ("was given different arguments (--out, --steps, --fresh)", slice(32, 64))):
        differ = [r for r in range(table.shape[0]) if not np.array_equal(table[r, cols], table[0, cols])]
        if differ:
            k = differ[0]
            mine, first = (table[r, cols].tobytes().hex()[:16] for r in (k, 0))
            more = f" (and {len(differ) - 1} more rank(s))" if len(differ) > 1 else ""
            raise InputError(f"ranks disagree on their input: rank {k} {what} (digest {mine} vs rank 0's {first})"
                             f"{more}; launch every rank with the same scene file and arguments")


def check_run_length(field, steps):
    """Refuse (one-line InputError starting with ``field``, e.g. "run.steps = 10**15") a run of
    ``steps`` steps: more than 100 years even at `MIN_STEP_S` per step."""
    if steps > MAX_STEPS:
        years = steps * MIN_STEP_S / (365.25 * 86400.0)
        raise InputError(f"{field}: {steps:.3g} steps would take at least {years:.3g} years (at {MIN_STEP_S * 1e6:g} "
                         f"µs per step, less than any pdem step costs): at most {MAX_STEPS:.3g} steps can be run")
