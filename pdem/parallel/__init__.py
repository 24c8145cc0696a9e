"""Parallel layer: slab decomposition (pure functions) and the communicator interface.

Owns: ``comm`` (SerialComm/MpiComm, the only mpi4py import in pdem, imported lazily) and
``slabs`` (edges, owners, ghost destinations, load balance; pure numpy).  Importing this
package does not import mpi4py.
"""

from pdem.parallel.comm import MpiComm, SerialComm, configure_threads, get_comm, threads_per_rank
from pdem.parallel.slabs import balanced_edges, ghost_destinations, imbalance, owner, uniform_edges

__all__ = [
    "MpiComm",
    "SerialComm",
    "configure_threads",
    "get_comm",
    "threads_per_rank",
    "balanced_edges",
    "ghost_destinations",
    "imbalance",
    "owner",
    "uniform_edges",
]
