"""A run's recorded signals on disk: written while the run goes, read back in chunks.

- `writer.ResultFiles`: the master's sink; results.csv and results.parquet grow as the
  run goes, so memory stays flat in the run's length, and are renamed into place whole.
- `read`: the same table back, whole (a structured array for fmpy's plotting, or via
  pandas.read_parquet) or in chunks of rows (`iter_columns`) for summaries and figures.
"""
