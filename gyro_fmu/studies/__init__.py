"""Studies over many runs: the Dask plumbing the lot studies share (tasks.py)."""
