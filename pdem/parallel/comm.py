"""Communicators: the one place where pdem talks to MPI.

Owns: ``SerialComm`` and ``MpiComm`` (the same small interface: rank, size, barrier, bcast,
reductions, exact sums, row gathers, the neighbour exchange of a 1-D chain of slabs, abort),
``get_comm`` (MPI only when launched under mpiexec/srun with more than one rank; `LaunchError`
when the launcher announces N > 1 tasks but MPI sees one rank, instead of N silent serial runs)
and the numba thread count per rank.

Failures: ``agree_on_failure`` is how a rank that caught an error finds out whether every rank
failed too (all of them reach it within a grace time: a non-blocking barrier on a private
duplicate of the communicator, so it never pairs with a collective of the run) and then learns
every rank's (status, line); ``abort(message, status)`` prints one line and ends the whole job
(``MPI_Abort``) when a rank fails alone and the others wait in a collective.

This is the ONLY module of pdem that imports mpi4py, and it does so lazily, inside
``MpiComm``/``get_comm``, so that ``import pdem.parallel`` works without MPI. Nothing here knows
about particles: callers pass plain numpy arrays.

Bulk data always travels as numpy buffers with uppercase mpi4py calls (``Allreduce``,
``Gatherv``, ``Sendrecv``); only ``bcast`` (small configuration objects) and thread set-up
pickle.  Floating-point sums that must not depend on the rank count go through ``exact_sum``:
each rank fills a superaccumulator (``pdem.exactsum``) and the int64 limbs are summed with
``MPI_Allreduce(SUM)``, which is exact and order independent, so every rank count gives the
same bits.
"""

import os
import sys
import time

import numpy as np

from pdem import exactsum
from pdem.errors import InputError

__all__ = ["LaunchError", "MpiComm", "SerialComm", "configure_threads", "get_comm", "threads_per_rank"]

# Environment variables through which launchers announce the number of ranks.
_SIZE_VARS = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "MV2_COMM_WORLD_SIZE", "SLURM_STEP_NUM_TASKS")

_FAILURE_COMMS = {}  # communicator handle -> its duplicate for agree_on_failure
ABORT_FORWARD_S = 1.0  # [s] MpiComm.abort: time for the launcher to forward the last lines

_TAG_LO = 71  # neighbour_exchange: messages travelling towards rank - 1
_TAG_HI = 73  # ... towards rank + 1 (each uses tag and tag + 1)
_TAG_LO_SIZED = 75  # neighbour_exchange into given receive buffers (no size message): towards rank - 1
_TAG_HI_SIZED = 76  # ... towards rank + 1


# --------------------------------------------------------------------------- helpers
def _reduce_array(x, integer_only=False):
    """``x`` as a 1-D contiguous float64 or int64 copy, and its original shape."""
    a = np.asarray(x)
    if a.dtype.kind in "biu":
        dtype = np.int64
    elif a.dtype.kind == "f" and not integer_only:
        dtype = np.float64
    else:
        what = "an integer" if integer_only else "a real number"
        raise TypeError(f"expected {what} or an array of them, got dtype {a.dtype}")
    return np.array(a, dtype=dtype).reshape(-1), a.shape


def _reduce_result(a, shape):
    """A Python scalar for a scalar input, else an array of the input's shape."""
    return a[0].item() if shape == () else a.reshape(shape)


_MAX_NDIM = 4  # row arrays: 1-D .. 4-D (rows first)
_META = 3 + _MAX_NDIM  # [nrows, ndim, dtype char, trailing dims..., -1 padding]


def _rows_array(array):
    """Validate a row array (rows along axis 0); return it contiguous and its layout message."""
    a = np.ascontiguousarray(array)
    if not 1 <= a.ndim <= _MAX_NDIM:
        raise ValueError(f"row arrays must have 1 to {_MAX_NDIM} dimensions, got shape {a.shape}")
    if a.dtype.kind not in "biuf":
        raise TypeError(f"row arrays must have a numeric dtype, got {a.dtype}")
    meta = np.full(_META, -1, dtype=np.int64)
    meta[0], meta[1], meta[2] = a.shape[0], a.ndim, ord(a.dtype.char)
    meta[3 : 2 + a.ndim] = a.shape[1:]
    return a, meta


def _empty_rows(meta, nrows=0):
    """An uninitialised array with ``nrows`` rows and the layout (ndim, dtype, trailing) of meta."""
    ndim = int(meta[1])
    shape = (int(nrows),) + tuple(int(d) for d in meta[3 : 2 + ndim])
    return np.empty(shape, dtype=np.dtype(chr(int(meta[2]))))


def _groups_args(values, group, n_groups):
    """``values`` as float64[n, k], ``group`` as int64[n] within [0, n_groups), and k."""
    v = np.ascontiguousarray(values, dtype=np.float64)
    if v.ndim != 2:
        raise ValueError(f"exact_sum_groups needs a 2-D array, got shape {v.shape}")
    g = np.ascontiguousarray(group, dtype=np.int64).reshape(-1)
    if g.shape[0] != v.shape[0] or (g.size and (g.min() < 0 or g.max() >= n_groups)):
        raise ValueError(f"exact_sum_groups: {g.shape[0]} group ids in [0, {n_groups}) needed for {v.shape[0]} rows")
    return v, g, v.shape[1]


def _check_recv(recv_lo, recv_hi):
    """Receive buffers of `neighbor_exchange`: both given, C-contiguous, writeable."""
    for name, r in (("recv_lo", recv_lo), ("recv_hi", recv_hi)):
        if not isinstance(r, np.ndarray) or not r.flags.c_contiguous or not r.flags.writeable:
            raise TypeError(f"neighbor_exchange: {name} must be a writeable C-contiguous numpy array "
                            f"(or both None), got {type(r).__name__}")


def _ring_of_one(send_lo, send_hi, recv_lo, recv_hi):
    """`neighbor_exchange` of a ring of one rank: what it sends "lo" comes back from "hi" and
    the reverse (copies; into the receive buffers when given)."""
    if recv_lo is None and recv_hi is None:
        return np.array(send_hi, copy=True), np.array(send_lo, copy=True)
    _check_recv(recv_lo, recv_hi)
    if recv_lo.shape != np.shape(send_hi) or recv_hi.shape != np.shape(send_lo):
        raise RuntimeError(f"neighbor_exchange: a ring of one rank sends {np.shape(send_hi)} and "
                           f"{np.shape(send_lo)} rows into receive buffers of {recv_lo.shape} and {recv_hi.shape}")
    recv_lo[...] = send_hi
    recv_hi[...] = send_lo
    return recv_lo, recv_hi


def _cpu_set():
    try:
        return frozenset(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return frozenset(range(os.cpu_count() or 1))


# --------------------------------------------------------------------------- serial
class SerialComm:
    """One rank, no MPI: collectives return their local result.

    ``neighbor_exchange`` receives nothing (a single non-periodic slab); ``gather_rows`` and
    ``allgather_rows`` return a copy.  Results have the same types as with ``MpiComm``.
    """

    rank = 0
    size = 1

    def __repr__(self):
        return "SerialComm()"

    def barrier(self):
        pass

    def bcast(self, obj, root=0):
        return obj

    def allreduce_max(self, x):
        a, shape = _reduce_array(x)
        return _reduce_result(a, shape)

    def allreduce_min(self, x):
        a, shape = _reduce_array(x)
        return _reduce_result(a, shape)

    def allreduce_sum_int(self, x):
        a, shape = _reduce_array(x, integer_only=True)
        return _reduce_result(a, shape)

    def any_flag(self, flag):
        return bool(flag)

    def exact_sum(self, values):
        v = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
        return float(exactsum.exact_sum(v))

    def exact_sum_rows(self, values):
        v = np.ascontiguousarray(values, dtype=np.float64)
        if v.ndim != 2:
            raise ValueError(f"exact_sum_rows needs a 2-D array, got shape {v.shape}")
        return exactsum.exact_sum_rows(v)

    def exact_sum_groups(self, values, group, n_groups):
        v, g, k = _groups_args(values, group, n_groups)
        return exactsum.acc_values(exactsum.exact_sum_groups_acc(v, g, n_groups)).reshape(n_groups, k)

    def exact_sum_accumulators(self, accs):
        return exactsum.acc_values(accs)

    def gather_rows(self, array, root=0):
        a, _ = _rows_array(array)
        return a.copy()

    def allgather_rows(self, array):
        a, _ = _rows_array(array)
        return a.copy()

    def neighbor_exchange(self, send_lo, send_hi, recv_lo=None, recv_hi=None, ring=False):
        if ring:  # one slab closed into a ring (periodic ends): it is its own lo and hi neighbour
            return _ring_of_one(send_lo, send_hi, recv_lo, recv_hi)
        if recv_lo is not None or recv_hi is not None:
            _check_recv(recv_lo, recv_hi)
            for r in (recv_lo, recv_hi):
                if r.shape[0]:
                    raise RuntimeError(f"neighbor_exchange: a receive buffer of {r.shape[0]} rows on a single "
                                       "slab (no neighbour sends anything)")
            return recv_lo, recv_hi
        lo, mlo = _rows_array(send_lo)
        hi, mhi = _rows_array(send_hi)
        return _empty_rows(mlo), _empty_rows(mhi)

    def node_allgather(self, obj):
        """Objects from every rank on this node (pickled; set-up only)."""
        return [obj]

    def agree_on_failure(self, status, line, timeout):
        """[(status, line)] of every rank that failed: here, this one."""
        return [(int(status), str(line))]

    def abort(self, message, status=1):
        """Print ``message`` on stderr and exit with ``status`` (``SystemExit``)."""
        sys.stderr.write(f"{message}\n")
        sys.stderr.flush()
        raise SystemExit(status)


# --------------------------------------------------------------------------- MPI
class MpiComm:
    """Wrap an mpi4py communicator (e.g. ``MPI.COMM_WORLD``) in the pdem interface.

    Ranks form a 1-D chain for ``neighbor_exchange``: rank - 1 is "lo", rank + 1 is "hi".
    """

    def __init__(self, mpi4py_comm):
        from mpi4py import MPI  # the only mpi4py import in pdem

        self._MPI = MPI
        self.comm = mpi4py_comm
        self.rank = mpi4py_comm.Get_rank()
        self.size = mpi4py_comm.Get_size()
        null = MPI.PROC_NULL
        self._lo = self.rank - 1 if self.rank > 0 else null
        self._hi = self.rank + 1 if self.rank < self.size - 1 else null
        self._node = None
        self._failure_comm()

    def __repr__(self):
        return f"MpiComm(rank={self.rank}, size={self.size})"

    # ---- simple collectives
    def barrier(self):
        self.comm.Barrier()

    def bcast(self, obj, root=0):
        """Broadcast a small picklable object (configuration, paths) from ``root``."""
        return self.comm.bcast(obj, root=root)

    def _allreduce(self, x, op, integer_only=False):
        a, shape = _reduce_array(x, integer_only)
        out = np.empty_like(a)
        self.comm.Allreduce(a, out, op=op)
        return _reduce_result(out, shape)

    def allreduce_max(self, x):
        """Element-wise maximum over ranks (float64 for reals, int64 for integers/bools)."""
        return self._allreduce(x, self._MPI.MAX)

    def allreduce_min(self, x):
        """Element-wise minimum over ranks."""
        return self._allreduce(x, self._MPI.MIN)

    def allreduce_sum_int(self, x):
        """Sum of integers over ranks (int64; floats are refused: use ``exact_sum``)."""
        return self._allreduce(x, self._MPI.SUM, integer_only=True)

    def any_flag(self, flag):
        """True on every rank if ``flag`` is true on any rank."""
        return bool(self._allreduce(int(bool(flag)), self._MPI.MAX))

    # ---- exact sums
    def exact_sum(self, values):
        """Correctly rounded sum of all ranks' ``values``; the same bits on any rank count."""
        v = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
        acc = exactsum.exact_sum_acc(v)
        total = np.empty_like(acc)
        self.comm.Allreduce(acc, total, op=self._MPI.SUM)
        return float(exactsum.acc_value(total))

    def exact_sum_rows(self, values):
        """Column sums of all ranks' ``values[n_local, k]`` (same ``k`` everywhere): ``[k]``."""
        v = np.ascontiguousarray(values, dtype=np.float64)
        if v.ndim != 2:
            raise ValueError(f"exact_sum_rows needs a 2-D array, got shape {v.shape}")
        accs = exactsum.exact_sum_rows_acc(v)
        total = np.empty_like(accs)
        self.comm.Allreduce(accs, total, op=self._MPI.SUM)
        return exactsum.acc_values(total)

    def exact_sum_groups(self, values, group, n_groups):
        """Column sums of all ranks' ``values[n_local, k]`` per group (row i in group ``group[i]``,
        0 <= group < n_groups, the same n_groups and k everywhere): ``[n_groups, k]``, exact and
        order-independent like `exact_sum_rows`, in O(n_local k) whatever n_groups."""
        v, g, k = _groups_args(values, group, n_groups)
        accs = exactsum.exact_sum_groups_acc(v, g, n_groups)
        total = np.empty_like(accs)
        self.comm.Allreduce(accs, total, op=self._MPI.SUM)
        return exactsum.acc_values(total).reshape(n_groups, k)

    def exact_sum_accumulators(self, accs):
        """The correctly rounded values of the sums over all ranks of exact accumulators
        (`pdem.exactsum`, int64[k, NLIMBS], normalised, the same k everywhere): ``[k]``."""
        total = np.empty_like(accs)
        self.comm.Allreduce(accs, total, op=self._MPI.SUM)
        return exactsum.acc_values(total)

    # ---- gathers
    def _row_layout(self, array):
        a, meta = _rows_array(array)
        metas = np.empty((self.size, _META), dtype=np.int64)
        self.comm.Allgather(meta, metas)
        if not np.all(metas[:, 1:] == metas[0, 1:]):
            # Every rank sees the same table, so every rank raises: no rank is left waiting.
            layouts = [(_empty_rows(m, m[0]).shape, chr(int(m[2]))) for m in metas]
            raise ValueError(f"row arrays differ in trailing shape or dtype over ranks: {layouts}")
        rowsize = int(np.prod(a.shape[1:], dtype=np.int64))
        counts = metas[:, 0] * rowsize
        return a, meta, metas[:, 0], counts

    def gather_rows(self, array, root=0):
        """Rows of every rank concatenated in rank order on ``root``; ``None`` elsewhere.

        ``array`` has rows along axis 0 (1-D to 4-D) and any numeric dtype; the trailing shape
        and dtype must agree on all ranks (an empty array still needs them), else every rank
        raises ``ValueError``.
        """
        a, meta, nrows, counts = self._row_layout(array)
        if self.rank == root:
            out = _empty_rows(meta, nrows.sum())
            self.comm.Gatherv(a, [out, counts], root=root)
            return out
        self.comm.Gatherv(a, None, root=root)
        return None

    def allgather_rows(self, array):
        """Rows of every rank concatenated in rank order, on every rank."""
        a, meta, nrows, counts = self._row_layout(array)
        out = _empty_rows(meta, nrows.sum())
        self.comm.Allgatherv(a, [out, counts])
        return out

    # ---- neighbours
    def _shift(self, send, dest, source, tag):
        """Send ``send`` to ``dest`` and receive the array ``source`` sends: size message first."""
        a, meta = _rows_array(send)
        rmeta = meta.copy()
        rmeta[0] = 0  # kept if source is PROC_NULL: no rows, this rank's own layout
        self.comm.Sendrecv(meta, dest, tag, rmeta, source, tag)
        recv = _empty_rows(rmeta, rmeta[0])
        self.comm.Sendrecv(a, dest, tag + 1, recv, source, tag + 1)
        return recv

    def _shift_into(self, send, dest, recv, source, tag):
        """Send ``send`` to ``dest`` and receive into ``recv`` from ``source``: the number of
        values received, or None if that is ``recv.size``."""
        status = self._MPI.Status()
        self.comm.Sendrecv(send, dest, tag, recv, source, tag, status=status)
        got = status.Get_count(self._datatype(recv.dtype)) if source != self._MPI.PROC_NULL else 0
        return None if got == recv.size else got

    def _datatype(self, dtype):
        """The predefined MPI datatype mpi4py uses for a numpy buffer of this dtype."""
        return self._MPI.Datatype.fromcode(dtype.char)

    def neighbor_exchange(self, send_lo, send_hi, recv_lo=None, recv_hi=None, ring=False):
        """Exchange rows with the neighbouring slabs of a 1-D chain of ranks (``ring``: closed
        into a ring, rank 0's lo neighbour is rank size - 1 and the reverse; periodic ends).

        Parameters
        ----------
        send_lo, send_hi : numeric arrays, rows along axis 0 (typically 2-D float64 or int64)
            Rows for rank - 1 and rank + 1 (ignored at the ends of the chain).
        recv_lo, recv_hi : C-contiguous arrays, optional (both or neither)
            Receive into these (the dtype and row shape the neighbours send, exactly as many
            rows as they send; 0 rows at the ends of the chain): one message per direction, no
            size message and no allocation. Each pair of neighbours must both use this form (the
            slab domain's ghost update, whose counts are known from the last ghost-layer
            rebuild). A count that differs from the buffer's raises (RuntimeError, or MPI's
            truncation error for more).

        Returns
        -------
        recv_from_lo, recv_from_hi : arrays
            What rank - 1 sent as its ``send_hi`` and rank + 1 as its ``send_lo``; empty arrays
            (with this rank's own column count and dtype) at the ends of the chain. With
            ``recv_lo``/``recv_hi``: those arrays, filled.
        """
        if ring and self.size == 1:
            return _ring_of_one(send_lo, send_hi, recv_lo, recv_hi)
        lo_rank, hi_rank = ((self.rank - 1) % self.size, (self.rank + 1) % self.size) if ring else (self._lo, self._hi)
        if recv_lo is not None or recv_hi is not None:
            _check_recv(recv_lo, recv_hi)
            bad_hi = self._shift_into(np.ascontiguousarray(send_lo), lo_rank, recv_hi, hi_rank, _TAG_LO_SIZED)
            bad_lo = self._shift_into(np.ascontiguousarray(send_hi), hi_rank, recv_lo, lo_rank, _TAG_HI_SIZED)
            for got, recv, source in ((bad_lo, recv_lo, lo_rank), (bad_hi, recv_hi, hi_rank)):
                if got is not None:  # raised after both messages: the neighbours are not left waiting
                    raise RuntimeError(
                        f"neighbor_exchange: received {got} values from rank {source}, expected {recv.size} "
                        f"({recv.shape[0]} rows of the receive buffer): the two ranks' row counts disagree")
            return recv_lo, recv_hi
        recv_from_hi = self._shift(send_lo, lo_rank, hi_rank, _TAG_LO)
        recv_from_lo = self._shift(send_hi, hi_rank, lo_rank, _TAG_HI)
        return recv_from_lo, recv_from_hi

    # ---- node, abort
    def node_allgather(self, obj):
        """Objects from every rank on this node (shared-memory split; pickled, set-up only)."""
        if self._node is None:
            self._node = self.comm.Split_type(self._MPI.COMM_TYPE_SHARED, key=self.rank)
        return self._node.allgather(obj)

    def _failure_comm(self):
        """A duplicate of the communicator for `agree_on_failure` (one per communicator and
        process, made at the first `MpiComm` of it: ``Dup`` is collective)."""
        key = self.comm.py2f()
        if key not in _FAILURE_COMMS:
            _FAILURE_COMMS[key] = self.comm.Dup()
        return _FAILURE_COMMS[key]

    def agree_on_failure(self, status, line, timeout):
        """Called by a rank that failed: if every rank calls it within ``timeout`` seconds (they
        all failed: e.g. the same bad input, or an error after a collective decision), returns
        [(status, line)] of every rank, in rank order, on every rank. Else (a rank is still
        running, or waits in a collective of the run) returns None: the caller then aborts.

        A non-blocking barrier on a private duplicate of the communicator, polled every 5 ms,
        so it never pairs with a collective of the run that other ranks are blocked in."""
        fc = self._failure_comm()
        request = fc.Ibarrier()
        deadline = time.monotonic() + float(timeout)
        while not request.Test():
            if time.monotonic() > deadline:
                return None  # the request stays pending: the job is aborted next
            time.sleep(0.005)
        return [(int(s), str(x)) for s, x in fc.allgather((int(status), str(line)))]

    def abort(self, message, status=1):
        """Print ``message`` on stderr, flush, and ``MPI_Abort(status)`` the whole job (every
        rank ends, including those blocked in a collective). Between the flush and the abort,
        `ABORT_FORWARD_S` for the launcher to forward what was written: Hydra's proxy reads the
        rank's pipes asynchronously and the abort kills it, so on a loaded machine the line was
        lost (seen: exit 1, empty stderr, 3 ranks at load average 3)."""
        sys.stderr.write(f"{message}\n")
        sys.stderr.flush()
        sys.stdout.flush()
        time.sleep(ABORT_FORWARD_S)
        self.comm.Abort(int(status))


# --------------------------------------------------------------------------- factory
class LaunchError(InputError):
    """The launcher started N > 1 tasks but MPI sees one rank in each (exit status 2)."""


def _launched_size():
    """(variable, rank count) announced by the launcher's environment; (None, 1) if none."""
    for var in _SIZE_VARS:
        value = os.environ.get(var)
        if value:
            try:
                return var, int(value)
            except ValueError:
                continue
    return None, 1


def _launch_mismatch(var, n, why, fix):
    return LaunchError(f"{var}={n}: the launcher started {n} tasks but {why}, so each would run the whole job alone; "
                       f"refused ({fix})")


def get_comm(comm=None):
    """The communicator to run on.

    Parameters
    ----------
    comm : None, SerialComm, MpiComm or an mpi4py communicator
        ``None`` detects: ``MpiComm(MPI.COMM_WORLD)`` if mpi4py is already initialised (e.g.
        ``python -m mpi4py``) or a launcher (MPICH Hydra ``PMI_SIZE``, Open MPI, MVAPICH, srun's
        ``SLURM_STEP_NUM_TASKS``) announces more than one rank, and that world has more than one
        rank; otherwise ``SerialComm()``.  mpi4py is imported only in those cases. A launcher
        that announces N > 1 ranks to a world of one (or without mpi4py) raises `LaunchError`.
        (Not SLURM_NTASKS: a batch script has it and may run serial processes on purpose.)
    """
    if isinstance(comm, (SerialComm, MpiComm)):
        return comm
    if comm is not None:
        return MpiComm(comm)
    var, announced = _launched_size()
    mpi = sys.modules.get("mpi4py.MPI")
    if mpi is None:
        if announced <= 1:
            return SerialComm()
        try:
            from mpi4py import MPI as mpi
        except ImportError:
            raise _launch_mismatch(var, announced, "mpi4py is not installed", "pip install pdem[mpi]") from None
    world = mpi.COMM_WORLD
    if world.Get_size() > 1:
        return MpiComm(world)
    if announced > 1:
        mpiexec = os.path.join(os.path.dirname(sys.executable), "mpiexec")
        raise _launch_mismatch(var, announced, "MPI sees 1 rank", "likely srun with a PMI this MPI does not speak: "
                               f"launch with {mpiexec} -n {announced}")
    return SerialComm()


def threads_per_rank(comm=None):
    """Numba threads for this rank: its cores divided among the ranks of the node sharing them.

    Cores are this process's CPU affinity set (``os.sched_getaffinity``).  Ranks on the same
    node (MPI shared-memory split) whose affinity sets overlap this one share it evenly, so an
    unbound launch of P ranks on C cores gives C // P and a launch binding each rank to its own
    cores gives all of them.  At least 1.
    """
    comm = get_comm(comm)
    mine = _cpu_set()
    sets = comm.node_allgather(mine)
    sharers = max(1, sum(1 for s in sets if s & mine))
    return max(1, len(mine) // sharers)


def configure_threads(comm=None):
    """``numba.set_num_threads(threads_per_rank(comm))``, capped at NUMBA_NUM_THREADS.

    Returns the number set.  (Job scripts should also export NUMBA_NUM_THREADS so that idle
    pool threads are not started; see TOOLCHAIN.md.)
    """
    import numba

    n = min(threads_per_rank(comm), int(numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(max(1, n))
    return max(1, n)
