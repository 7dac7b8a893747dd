"""Fleet scale: batch analysis on Dask, simulated fleets, certificates."""
