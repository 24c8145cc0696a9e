"""pdem input/output: checkpoints, results time series, particle snapshots, stop signals.

Everything pdem writes to disk goes through this package as HDF5 (plus an XDMF index for
ParaView). Submodules: `checkpoint` (full restart state), `timeseries` (results file: /series,
/cycles), `snapshots` (particles for ParaView), `signals` (SIGTERM/SIGUSR1 -> checkpoint and
exit status 3), `atomic` (temp file + fsync + rename). No module here imports mpi4py: collective
operations go through the ``comm`` object from pdem.parallel.comm. Importing this package sets up
nothing (no handlers, no logging); import the submodules you need.
"""
