"""NumPy <-> Arrow for columns of doubles, without pyarrow's pandas shim.

pyarrow (26.0.1, and since at least 14) imports pandas on the first `pa.array(ndarray)`
or `Array.to_numpy()` when pandas is installed: 0.15 s and about 30 MB on every run, for
nothing a float column needs. Going through the buffers avoids it; the test
`test_results.py::test_reading_and_writing_do_not_import_pandas` watches both this and
whether pyarrow still does so.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa


def to_arrow(values: np.ndarray) -> pa.Array:
    """A float64 Arrow array viewing (or, if strided, copying) `values`."""
    data = np.ascontiguousarray(values, dtype=np.float64)
    return pa.Array.from_buffers(pa.float64(), len(data), [None, pa.py_buffer(data)])


def to_numpy(column: pa.ChunkedArray | pa.Array) -> np.ndarray:
    """A float64 column without nulls as a NumPy array (a view when in one chunk)."""
    chunks = column.chunks if isinstance(column, pa.ChunkedArray) else [column]
    parts = []
    for chunk in chunks:
        if chunk.null_count:
            raise ValueError(f"a column with {chunk.null_count} missing values")
        parts.append(np.frombuffer(chunk.buffers()[1], dtype=np.float64, count=len(chunk),
                                   offset=8 * chunk.offset))
    if len(parts) == 1:
        return parts[0]
    return np.concatenate(parts) if parts else np.empty(0)


def units_schema(columns: tuple[str, ...] | list[str], units: dict[str, str],
                 metadata: dict[bytes, bytes] | None = None) -> pa.Schema:
    """Float64 fields without nulls, each with its unit in the field's metadata ("unit"),
    as results.parquet holds them."""
    return pa.schema([pa.field(c, pa.float64(), nullable=False,
                               metadata={"unit": units.get(c, "")}) for c in columns],
                     metadata=metadata)
