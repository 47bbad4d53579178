"""Read a run's results as a user would: pandas (or polars, MATLAB's parquetread) on
results.parquet, gyro_fmu.read_dataframe with each column's unit, and
gyro_fmu.read_results for fmpy's plotting.

    pip install 'gyro_fmu[parquet,pandas]' plotly   # plotly: fmpy's plotting needs it
    gyro-fmu run --stop-time 0.01 --no-figures      # writes runs/default/
    python read_results.py [runs/default]
"""

import sys
from pathlib import Path

import pandas as pd
from fmpy.util import create_plotly_figure  # plot_result(...) shows the same in a browser

from gyro_fmu import read_dataframe, read_results

run = Path(sys.argv[1] if len(sys.argv) > 1 else "runs/default")
frame = pd.read_parquet(run / "results.parquet")  # each column's unit in frame.attrs
units = frame.attrs["units"]
print(f"units: Omega_hat in {units['observer.Omega_hat']}, x in {units['plant.x']}")
# the same from the CSV: gyro_fmu reads the units from the summary.json beside it
same_units = read_dataframe(run / "results.csv").attrs["units"] == units
tail = frame[frame["time"] >= 0.8 * frame["time"].iloc[-1]]
error = tail["observer.Omega_hat"] - tail["rate.Omega_z"]
print(f"{len(frame)} rows, {len(frame.columns)} columns; Omega_hat RMS error over the last "
      f"20 %: {(error**2).mean() ** 0.5:.3g} rad/s")

table = read_results(run / "results.parquet")  # a NumPy structured array, "time" first
same = all((table[c] == frame[c].to_numpy()).all() for c in table.dtype.names)
# a copy: fmpy 0.3.32's plotting rescales the time column of the array it is given (to ms)
figure = create_plotly_figure(table.copy(),
                              names=["observer.Omega_hat", "observer.sigma_Omega_z"])
print(f"fmpy's figure: {[trace.name for trace in figure.data]}")
print(f"read_results and pandas agree on every value: {same}; the CSV's units too: "
      f"{same_units}")
sys.exit(0 if same and same_units else 1)
