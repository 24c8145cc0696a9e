"""pdem's files, the one interface between a run and its post-processing, both ways.

pdem's driver and scenes write with this package; `analysis` reads with it (and nothing else of
pdem). Modules: `schema` (the results file, HDF5: names, units, writers), `read` (opening and
reading a results file: `open_results`, `read_results`, `ResultFileError`), `groups` (readers of
its optional groups: fragments, blast, track, forces), `campaign` (the campaign directory's
manifest and run records). Imports numpy, h5py and the standard library only: never the rest of
pdem (engine, numba, mpi4py) nor analysis.
"""
