"""results.csv and results.parquet written while the co-simulation runs.

`ResultFiles` is a sink for `run_cosimulation`: each chunk of rows is appended to both
files under temporary names in the run's folder, so a run of any length holds at most
one Parquet row group (ROW_GROUP rows) in memory. `close()` renames both into place and
returns what summary.json says of them; `discard()` (or leaving the `with` block by an
exception) removes them. The CSV's SHA-256 is taken as it is written, not read back.

Both are written by Arrow's C++ writers (the parquet extra, pyarrow); without it, the CSV
only, by `_csv_text`. Arrow's CSV writer formats a double as the shortest
text that reads back to the same double (as repr does): 3-4x faster than numpy.savetxt's
"%.17g", and shorter. Why Parquet beside the CSV: 8 bytes a value instead of about 18,
typed, columnar (a figure reads 27 of 33 columns, a summary 18), and read by pandas,
polars, MATLAB's parquetread and Arrow in every language; pyarrow writes it in row groups
as the rows come.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from pathlib import Path
from types import TracebackType

import numpy as np

from ..errors import GyroFmuError
from ..extras import has

#: Rows a Parquet row group holds (about 65,536: whole chunks of the master's), 18 MB of
#: 35 doubles. The writer keeps every group's metadata until it closes the file, so the
#: fewer groups, the flatter a long run's memory.
ROW_GROUP = 1 << 16
#: Rows of a chunk read back (the summary's and the figures' temporaries scale with it).
READ_ROWS = 1 << 14
CSV, PARQUET = "results.csv", "results.parquet"
#: Bytes a value takes in both files, to refuse before the run a run the disk cannot
#: hold: 18 in the CSV (measured: 598 MB for 1,000,001 rows of 33 columns) and 8 in
#: Parquet, with 10 % to spare.
BYTES_PER_VALUE = 29
#: Key of the Parquet schema metadata holding the run id, rows and units (JSON).
METADATA_KEY = b"gyro_fmu"


class ResultWriteError(GyroFmuError):
    """A results file could not be written while the run went (a full disk, a lost
    folder)."""


class ResultFiles:
    """Sink writing the recorded rows to folder/results.csv and folder/results.parquet.

    Call `begin(columns, units)` once (run_cosimulation's on_columns), then
    `self(rows, k)` for each chunk (its sink), then close() or discard().
    """

    def __init__(self, folder: Path, run_id: str, parquet: bool = True,
                 expected_rows: int | None = None) -> None:
        """expected_rows: the run's rows, if known, to refuse in begin() a run whose files
        the disk cannot hold (ResultWriteError) rather than fill it."""
        self.folder, self.run_id, self.parquet = Path(folder), run_id, parquet
        self.expected_rows = expected_rows
        self.columns: tuple[str, ...] = ()
        self.units: dict[str, str] = {}
        self.rows = 0
        self.finite = True
        self._sha = hashlib.sha256()
        self._csv: _HashedFile | None = None
        self._csv_writer = None
        self._writer = None
        self._pending: list = []  # pyarrow Tables of the rows not yet in a row group
        self._pending_rows = 0
        self._temps: dict[str, Path] = {}

    def __enter__(self) -> ResultFiles:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if kind is not None:
            self.discard()

    def _temp(self, name: str) -> Path:
        path = self.folder / f".{name}.{self.run_id[:12]}.part"
        self._temps[name] = path
        return path

    def begin(self, columns: tuple[str, ...], units: dict[str, str]) -> None:
        """Open both files under temporary names and write the CSV's header."""
        if self.expected_rows is not None:
            self._check_space(self.expected_rows * len(columns))
        self.columns, self.units = tuple(columns), {c: units.get(c, "") for c in columns}
        self.units["time"] = "s"
        self.arrow = has("pyarrow")
        self.parquet = self.parquet and self.arrow
        try:
            self._csv = _HashedFile(self._temp(CSV), self._sha)
            # the header as before: names unquoted (Arrow would quote each)
            self._csv.write((",".join(self.columns) + "\n").encode())
            if self.arrow:
                self._begin_arrow()
        except OSError as exc:
            raise self._error(exc) from exc

    def _begin_arrow(self) -> None:
        import pyarrow.csv as pcsv
        import pyarrow.parquet as pq

        from .arrow import units_schema

        meta = {"run_id": self.run_id, "units": self.units}
        # PANDAS_ATTRS: pandas (2.1 and later) puts it into DataFrame.attrs on
        # read_parquet, so df.attrs["units"] holds each column's unit
        self._schema = units_schema(self.columns, self.units,
                                    {METADATA_KEY: json.dumps(meta).encode(),
                                     b"PANDAS_ATTRS": json.dumps(meta).encode()})
        self._csv_writer = pcsv.CSVWriter(self._csv, self._schema,
                                          write_options=pcsv.WriteOptions(include_header=False))
        if self.parquet:
            # doubles do not repeat: a dictionary and statistics would only cost time
            self._writer = pq.ParquetWriter(self._temp(PARQUET), self._schema,
                                            compression="zstd", use_dictionary=False,
                                            write_statistics=False)

    def __call__(self, rows: np.ndarray, k: int) -> None:
        """Append rows (points k, k + 1, ...): the CSV at once, Parquet by row groups."""
        if self._csv is None:
            raise ResultWriteError("ResultFiles received rows before begin(columns)")
        if k != self.rows:
            raise ResultWriteError(f"rows from point {k} after {self.rows} points: a chunk "
                                   "was lost")
        self.finite = self.finite and bool(np.isfinite(rows).all())
        try:
            if self.arrow:
                self._write_arrow(rows)
            else:  # without the parquet extra: Python's own shortest text
                self._csv.write(_csv_text(rows))
        except OSError as exc:
            raise self._error(exc) from exc
        self.rows += len(rows)

    def _write_arrow(self, rows: np.ndarray) -> None:
        table = self._table(rows)  # copies the master's rows: they are a view
        self._csv_writer.write_table(table)  # type: ignore[union-attr]
        if self._writer is not None:
            self._pending.append(table)
            self._pending_rows += len(rows)
            if self._pending_rows >= ROW_GROUP:
                self._flush()

    def _table(self, block: np.ndarray):
        import pyarrow as pa

        from .arrow import to_arrow

        return pa.Table.from_arrays([to_arrow(block[:, j]) for j in range(block.shape[1])],
                                    schema=self._schema)

    def _flush(self) -> None:
        if not self._pending_rows:
            return
        import pyarrow as pa

        group = pa.concat_tables(self._pending)  # the chunks as they are, no copy
        self._pending, self._pending_rows = [], 0
        self._writer.write_table(group, row_group_size=len(group))  # type: ignore[union-attr]

    def close(self) -> dict:
        """Rename both files into place; returns what summary.json records of them."""
        try:
            self._flush()
            for handle in (self._writer, self._csv_writer, self._csv):
                if handle is not None:
                    handle.close()
            for name, temp in self._temps.items():
                os.chmod(temp, 0o644)
                os.replace(temp, self.folder / name)
        except OSError as exc:
            self.discard()
            raise self._error(exc) from exc
        # the units for readers of the CSV, whose header (fmpy's convention) has none
        record = {"file": CSV, "run_id": self.run_id, "rows": self.rows,
                  "sha256": self._sha.hexdigest(), "units": self.units}
        if self.parquet:
            from ..outputs import file_digest

            record["binary"] = {"file": PARQUET, "sha256": file_digest(self.folder / PARQUET)}
        self._temps = {}
        return record

    def discard(self) -> None:
        """Close and remove the temporary files (a failed run leaves nothing)."""
        for handle in (self._writer, self._csv_writer, self._csv):
            try:
                if handle is not None:
                    handle.close()
            except Exception:
                pass
        self._writer = self._csv_writer = self._csv = None
        for temp in self._temps.values():
            temp.unlink(missing_ok=True)
        self._temps = {}

    def _check_space(self, values: int) -> None:
        import shutil

        need = values * BYTES_PER_VALUE
        free = shutil.disk_usage(self.folder).free
        if need > free:
            raise ResultWriteError(
                f"the results of this run would take about {need / 2**30:.3g} GiB "
                f"(results.csv and results.parquet) where {self.folder} has "
                f"{free / 2**30:.3g} GiB free: shorten the run, or give another --out on a "
                "disk with room")

    def _error(self, exc: OSError) -> ResultWriteError:
        self.discard()
        return ResultWriteError(
            f"could not write the results into {self.folder} after {self.rows} rows "
            f"({exc.strerror or exc}): free space or fix the folder's permissions, or give "
            "another --out, and rerun")


def _csv_text(rows: np.ndarray) -> bytes:
    """CSV lines of rows of doubles, each as Python's repr (the shortest text that reads
    back to the same double): the writer without pyarrow, about 4x slower than Arrow's
    (0.45 s for 20,001 rows of 35 columns) and the same numbers in other spelling
    (1e-05 and 0.0 where Arrow writes 0.00001 and 0)."""
    return ("\n".join(",".join(map(repr, row)) for row in rows.tolist()) + "\n").encode()


class _HashedFile(io.RawIOBase):
    """A binary file that feeds every byte written to a hash (the CSV's SHA-256 without
    reading it back)."""

    def __init__(self, path: Path, sha: hashlib._Hash) -> None:
        self._file, self._sha = path.open("wb"), sha

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:  # type: ignore[override]
        self._sha.update(data)
        return self._file.write(data)

    def close(self) -> None:
        if not self.closed:
            self._file.close()
        super().close()
