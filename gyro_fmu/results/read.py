"""A run's results read back: whole, or a few columns in chunks of rows.

`read_results(path)` returns a NumPy structured array with a "time" field, the form
fmpy's `fmpy.util.plot_result` and `create_plotly_figure` take; pandas reads the same
file with `pandas.read_parquet(path)`. `iter_columns` streams chunks of rows so that a
summary or a figure of a run of any length needs memory for one chunk only.
"""

from __future__ import annotations

import itertools
import json
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from ..errors import GyroFmuError
from .writer import METADATA_KEY, ROW_GROUP


class ResultReadError(GyroFmuError):
    """A results file that is not one `gyro-fmu run` wrote, or a damaged one."""


def _parquet(path: Path):
    import pyarrow.parquet as pq

    try:
        return pq.ParquetFile(path)
    except (OSError, ValueError) as exc:  # ArrowInvalid is a ValueError
        raise ResultReadError(f"{path} is damaged or not a Parquet file ({exc}): rerun "
                              "the scenario") from None


def columns_of(path: Path) -> tuple[str, ...]:
    """The recorded columns of results.parquet or results.csv, "time" first."""
    path = Path(path)
    if path.suffix == ".parquet":
        names = tuple(_parquet(path).schema_arrow.names)
    else:
        with path.open() as f:
            names = tuple(f.readline().strip().split(","))
    if names[:1] != ("time",):
        raise ResultReadError(f"{path} is not a results file of `gyro-fmu run`: its first "
                              f"column is {names[:1]}, not 'time'; rerun the scenario")
    return names


def units_of(path: Path) -> dict[str, str]:
    """The units results.parquet records for its columns (empty for a CSV)."""
    path = Path(path)
    if path.suffix != ".parquet":
        return {}
    meta = _parquet(path).schema_arrow.metadata or {}
    return json.loads(meta.get(METADATA_KEY, b"{}")).get("units", {})


def iter_columns(path: Path, names: Sequence[str], rows: int = ROW_GROUP
                 ) -> Iterator[dict[str, np.ndarray]]:
    """Chunks of at most `rows` rows of the named columns, in order, as {name: array}."""
    path = Path(path)
    known = columns_of(path)
    missing = [n for n in names if n not in known]
    if missing:
        raise ResultReadError(f"{path} has no column(s) {missing}: it was not written by "
                              "`gyro-fmu run` of this system; rerun the scenario")
    if path.suffix == ".parquet":
        # row group by row group: iter_batches' memory grew with the file (pyarrow 26:
        # +186 MB over a 5 s run's 142 MB file) where this stays flat
        from .arrow import to_numpy

        parquet = _parquet(path)
        try:
            for group in range(parquet.num_row_groups):
                table = parquet.read_row_group(group, columns=list(names), use_threads=False)
                for start in range(0, table.num_rows, rows):
                    part = table.slice(start, rows)
                    yield {n: to_numpy(part.column(n)) for n in names}
        except OSError as exc:
            raise ResultReadError(f"{path} is damaged ({exc}): rerun the scenario") from None
        return
    index = [known.index(n) for n in names]
    with path.open() as f:
        f.readline()
        while True:
            lines = list(itertools.islice(f, rows))
            if not lines:
                return
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UserWarning)
                    block = np.loadtxt(lines, delimiter=",", ndmin=2)
            except ValueError as exc:
                raise ResultReadError(f"{path} is damaged ({exc}): rerun the "
                                      "scenario") from None
            if block.shape[1] != len(known):
                raise ResultReadError(f"{path} has rows of {block.shape[1]} values for "
                                      f"{len(known)} columns: rerun the scenario")
            yield {n: block[:, i] for n, i in zip(names, index, strict=True)}


def read_results(path: Path) -> np.ndarray:
    """The whole table as a structured array (fields named as the columns, "time"
    first): what fmpy's plotting takes, e.g. fmpy.util.plot_result(read_results(p))."""
    path = Path(path)
    names = columns_of(path)
    chunks = list(iter_columns(path, names))
    out = np.empty(sum(len(c["time"]) for c in chunks), dtype=[(n, "f8") for n in names])
    row = 0
    for c in chunks:
        m = len(c["time"])
        for n in names:
            out[n][row: row + m] = c[n]
        row += m
    return out
