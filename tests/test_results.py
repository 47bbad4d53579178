"""A run's results streamed to disk: results.csv and results.parquet hold exactly the rows
the master made, whatever the chunking; pandas and fmpy's plotting read them; the
summary and the figures read them back in chunks with the same figures as the arrays
held whole."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gyro_fmu.cli import main
from gyro_fmu.estimation.metrics import ESTIMATED, RunMetrics, summarize
from gyro_fmu.results.columns import estimate_column, sigma_column
from gyro_fmu.results.read import ResultReadError, iter_columns, read_results, units_of
from gyro_fmu.results.writer import ROW_GROUP, ResultFiles, ResultWriteError
from gyro_fmu.system.figures import BINS_PER_DECADE, RATE_BINS, FigureData
from gyro_fmu.system.scenario import scenario

COLUMNS = ("time", "plant.x", "observer.Omega_hat")


def _awkward(n: int, rng: np.random.Generator) -> np.ndarray:
    """Rows whose text is hard to get right: subnormals, huge, negative zero, a time
    step that is not exact in binary."""
    rows = rng.normal(size=(n, len(COLUMNS))) * 10.0 ** rng.integers(-300, 300, (n, 3))
    rows[:, 0] = np.arange(n) * 5e-6
    rows[3, 1], rows[4, 1], rows[5, 2] = 5e-324, -0.0, 1.7976931348623157e308
    rows[6, 1], rows[7, 2], rows[8, 2] = np.nan, np.inf, -np.inf  # a lost filter's outputs
    return rows


def _write(folder: Path, rows: np.ndarray, chunks: list[int]) -> dict:
    with ResultFiles(folder, "a" * 32) as files:
        files.begin(COLUMNS, {"plant.x": "m", "observer.Omega_hat": "rad/s"})
        k = 0
        for size in chunks:
            files(rows[k: k + size], k)
            k += size
        return files.close()


def test_both_files_hold_the_rows_exactly_and_name_themselves(tmp_path):
    rng = np.random.default_rng(7)
    n = 2 * ROW_GROUP + 1234  # three row groups, the last one short
    rows = _awkward(n, rng)
    sizes = list(np.diff(np.r_[0, np.sort(rng.choice(n, 40, replace=False)), n]))
    record = _write(tmp_path, rows, [int(s) for s in sizes if s])
    assert record["rows"] == n and record["binary"]["file"] == "results.parquet"
    for name in ("results.csv", "results.parquet"):
        table = read_results(tmp_path / name)
        assert table.dtype.names == COLUMNS
        back = np.column_stack([table[c] for c in COLUMNS])
        assert np.array_equal(back.view(np.int64), rows.view(np.int64))  # bit for bit
    assert units_of(tmp_path / "results.parquet") == {"time": "s", "plant.x": "m",
                                                       "observer.Omega_hat": "rad/s"}
    import pyarrow.parquet as pq

    field = pq.ParquetFile(tmp_path / "results.parquet").schema_arrow.field("plant.x")
    assert field.metadata == {b"unit": b"m"}
    from gyro_fmu.outputs import file_digest

    assert record["sha256"] == file_digest(tmp_path / "results.csv")
    assert (tmp_path / "results.csv").read_text().splitlines()[0] == ",".join(COLUMNS)
    assert not list(tmp_path.glob(".*.part"))


def test_pandas_and_fmpys_plotting_read_the_parquet_file(tmp_path):
    pandas = pytest.importorskip("pandas")
    pytest.importorskip("plotly")
    from fmpy.util import create_plotly_figure

    rows = _awkward(500, np.random.default_rng(1))
    _write(tmp_path, rows, [500])
    frame = pandas.read_parquet(tmp_path / "results.parquet")
    assert list(frame.columns) == list(COLUMNS)
    assert np.array_equal(frame.to_numpy(), rows, equal_nan=True)
    # each column's unit where a pandas user looks (df.attrs), kept through a round trip
    assert frame.attrs["units"]["plant.x"] == "m" and frame.attrs["units"]["time"] == "s"
    frame.to_parquet(tmp_path / "again.parquet")
    assert pandas.read_parquet(tmp_path / "again.parquet").attrs["units"]["plant.x"] == "m"
    figure = create_plotly_figure(read_results(tmp_path / "results.parquet"))
    assert [trace.name for trace in figure.data] == list(COLUMNS[1:])


def test_without_pyarrow_the_csv_holds_the_rows_exactly(tmp_path, monkeypatch):
    """The core's writer and reader (no parquet extra): Python's repr text, numpy's
    loadtxt; the awkward rows back bit for bit, by numpy's reader and by Arrow's."""
    import gyro_fmu.results.read as read
    import gyro_fmu.results.writer as writer

    rows = _awkward(3000, np.random.default_rng(3))
    monkeypatch.setattr(writer, "has", lambda module: False)
    record = _write(tmp_path, rows, [1000, 1, 1999])
    assert "binary" not in record and not (tmp_path / "results.parquet").exists()
    from gyro_fmu.outputs import file_digest

    assert record["sha256"] == file_digest(tmp_path / "results.csv")
    arrow = read_results(tmp_path / "results.csv")
    monkeypatch.setattr(read, "has", lambda module: False)
    mine = read_results(tmp_path / "results.csv")
    for table in (arrow, mine):
        back = np.column_stack([table[c] for c in COLUMNS])
        assert np.array_equal(back.view(np.int64), rows.view(np.int64))


def test_a_result_and_a_results_file_as_pandas_and_arrow_with_units(tmp_path):
    """What a pandas or Arrow user gets: the numbers and each column's unit, from a
    results.parquet, from a results.csv with its summary.json, and from a result in
    memory (run_cosimulation's)."""
    pytest.importorskip("pandas")
    import json

    from gyro_fmu import read_arrow, read_dataframe
    from gyro_fmu.cosim.system import CoSimulationResult

    rows = _awkward(200, np.random.default_rng(5))
    record = _write(tmp_path, rows, [200])
    units = {"time": "s", "plant.x": "m", "observer.Omega_hat": "rad/s"}
    (tmp_path / "summary.json").write_text(json.dumps({"results": record}))
    result = CoSimulationResult(COLUMNS, rows, {"plant.x": "m", "observer.Omega_hat": "rad/s"})
    frames = [read_dataframe(tmp_path / "results.parquet"),
              read_dataframe(tmp_path / "results.csv"), result.to_pandas()]
    for frame in frames:
        assert list(frame.columns) == list(COLUMNS) and frame.attrs["units"] == units
        assert np.array_equal(frame.to_numpy().view(np.int64), rows.view(np.int64))
    for table in (read_arrow(tmp_path / "results.parquet"),
                  read_arrow(tmp_path / "results.csv"), result.to_arrow()):
        assert table.column_names == list(COLUMNS)
        assert {f.name: f.metadata[b"unit"].decode() for f in table.schema} == units
        assert np.array_equal(np.column_stack([table.column(c).to_numpy() for c in COLUMNS]
                                              ).view(np.int64), rows.view(np.int64))
    records = result.to_records()
    assert records.dtype.names == COLUMNS and np.array_equal(
        records["plant.x"].view(np.int64), rows[:, 1].view(np.int64))
    # a CSV whose summary describes another file: no units claimed
    (tmp_path / "other.csv").write_bytes((tmp_path / "results.csv").read_bytes())
    assert read_dataframe(tmp_path / "other.csv").attrs["units"] == dict.fromkeys(COLUMNS, "")


def test_a_failed_run_leaves_no_file_and_a_lost_folder_is_named(tmp_path):
    rows = _awkward(100, np.random.default_rng(2))
    with pytest.raises(RuntimeError), ResultFiles(tmp_path, "b" * 32) as files:
        files.begin(COLUMNS, {})
        files(rows, 0)
        raise RuntimeError("the co-simulation failed")
    assert list(tmp_path.iterdir()) == []
    gone = tmp_path / "gone"
    gone.mkdir()
    files = ResultFiles(gone, "c" * 32)
    files.begin(COLUMNS, {})
    files(rows, 0)
    for part in gone.iterdir():
        part.unlink()
    gone.rmdir()
    with pytest.raises(ResultWriteError, match=r"after 100 rows .*give another --out"):
        files.close()
    with pytest.raises(ResultWriteError, match="a chunk was lost"):
        ok = ResultFiles(tmp_path, "d" * 32)
        ok.begin(COLUMNS, {})
        ok(rows[:10], 0)
        ok(rows[20:30], 20)


@pytest.mark.parametrize(("text", "words"), [
    ("time,a\n0,1\n1,one\n", "Row #3: CSV conversion error to double: invalid value 'one'"),
    ("time,a\n0,1\n1\n", "Row #3: Expected 2 columns, got 1"),
    ("time,a\n0,1\n1,\n", "invalid value ''")])
def test_a_damaged_csv_is_named_by_its_row(tmp_path, text, words):
    (tmp_path / "r.csv").write_text(text)
    with pytest.raises(ResultReadError, match="damaged") as caught:
        list(iter_columns(tmp_path / "r.csv", ["time", "a"]))
    assert words in str(caught.value) and "rerun the scenario" in str(caught.value)


def test_a_file_that_is_not_results_is_refused(tmp_path):
    (tmp_path / "results.parquet").write_bytes(b"PAR1 not really")
    with pytest.raises(ResultReadError, match="damaged or not a Parquet file"):
        read_results(tmp_path / "results.parquet")
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ResultReadError, match=r"first column is .'a'."):
        list(iter_columns(tmp_path / "x.csv", ["a"]))


def _observed(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    truth = scenario().params
    t = np.arange(n) * 5e-6
    chunk = {"time": t, "rate.Omega_z": np.sin(2 * np.pi * 50 * t)}
    decay = np.exp(-t / (0.2 * t[-1]))
    for name in ESTIMATED:
        true = chunk["rate.Omega_z"] if name == "Omega_z" else getattr(truth, name)
        scale = 1.0 if name == "Omega_z" else abs(true) or 1.0
        chunk[estimate_column(name)] = true + scale * (0.3 * decay + 1e-5 * rng.normal(size=n))
        chunk[sigma_column(name)] = scale * (0.2 * decay + 1e-5)
    chunk[estimate_column("kxx")][n // 2] = np.nan  # a NaN must stay visible
    for name in ("drive.ux", "plant.x", "plant.y", "plant.vx", "plant.vy", "observer.x_hat",
                 "observer.y_hat", "observer.vx_hat", "observer.vy_hat"):
        chunk[name] = rng.normal(size=n)
    return chunk


def test_run_metrics_in_chunks_equal_the_arrays_whole():
    rng = np.random.default_rng(3)
    truth = scenario().params
    for n in (2, 3, 997, 5000):
        whole = _observed(n, rng)
        expected = summarize(whole["time"], {k: whole[estimate_column(k)] for k in ESTIMATED},
                             {k: whole[sigma_column(k)] for k in ESTIMATED}, truth,
                             whole["rate.Omega_z"])
        cuts = np.sort(rng.choice(np.arange(1, n), min(n - 1, 6), replace=False))
        pieces = np.split(np.arange(n), cuts)
        metrics = RunMetrics(truth)
        for p in pieces:
            metrics.scan(whole["time"][p], whole["rate.Omega_z"][p])
        for p in pieces:
            metrics.judge(whole["time"][p],
                          {k: whole[estimate_column(k)][p] for k in ESTIMATED},
                          {k: whole[sigma_column(k)][p] for k in ESTIMATED},
                          whole["rate.Omega_z"][p])
        _same(metrics.summary(), expected)


def _same(got: object, expected: object, where: str = "") -> None:
    """Equal, floats to 1e-12 (sums taken chunk by chunk round differently), NaN to NaN."""
    if isinstance(expected, dict):
        assert isinstance(got, dict) and got.keys() == expected.keys(), where
        for key in expected:
            _same(got[key], expected[key], f"{where}/{key}")
    elif isinstance(expected, list):
        assert isinstance(got, list) and len(got) == len(expected), where
        for i, (a, b) in enumerate(zip(got, expected, strict=True)):
            _same(a, b, f"{where}[{i}]")
    elif isinstance(expected, float):
        assert isinstance(got, float), where
        assert got == pytest.approx(expected, rel=1e-12, nan_ok=True), where
    else:
        assert got == expected, where


def test_the_figure_envelope_is_each_bins_min_and_max_whatever_the_chunks():
    rng = np.random.default_rng(4)
    truth = scenario().params
    whole = _observed(20_000, rng)
    t = whole["time"]
    data = FigureData(truth, t[0], t[-1])
    for p in np.array_split(np.arange(t.size), 7):
        data.feed({k: v[p] for k, v in whole.items()})
    times, table = data.envelope()
    bins = np.floor(BINS_PER_DECADE * np.log10(t[1:])).astype(int)
    assert times.size == np.unique(bins).size
    err = np.abs(whole[estimate_column("dxy")][1:] - truth.dxy)
    sig = whole[sigma_column("dxy")][1:]
    i = list(ESTIMATED).index("dxy")
    for j, b in enumerate(np.unique(bins)):
        inside = bins == b
        assert table[j, 4 * i] == err[inside].min() and table[j, 4 * i + 1] == err[inside].max()
        assert table[j, 4 * i + 3] == sig[inside].max()
        assert t[1:][inside].min() <= times[j] <= t[1:][inside].max()
    early, late = data.window_rows(False), data.window_rows(True)
    assert np.array_equal(early["time"], t[t <= 0.002])
    assert np.array_equal(late["time"], t[t >= t[-1] - 0.002])
    # the rate figure's linear-time bins: each bin's min and max of every curve
    rate = data.rate_envelope()
    lin = np.minimum(np.floor((t - t[0]) / (t[-1] - t[0]) * RATE_BINS), RATE_BINS - 1)
    assert len(rate) == np.unique(lin).size == RATE_BINS
    est, sig = whole[estimate_column("Omega_z")], whole[sigma_column("Omega_z")]
    true = whole["rate.Omega_z"]
    for j in (0, 1, 333, RATE_BINS - 1):
        inside = lin == j
        assert rate[j, 0] == t[inside].min() and rate[j, 1] == t[inside].max()
        assert rate[j, 2] == true[inside].min() and rate[j, 5] == est[inside].max()
        assert rate[j, 6] == (est - sig)[inside].min()
        assert rate[j, 7] == (est + sig)[inside].max()
        assert rate[j, 8] == (est - true)[inside].min() and rate[j, 11] == sig[inside].max()


def test_reading_and_writing_do_not_import_pandas(tmp_path):
    """pyarrow imports pandas (if installed) on its first pa.array or to_numpy:
    gyro_fmu.results.arrow goes around it. The second half tells when pyarrow stops."""
    pytest.importorskip("pandas")
    code = f"""
import sys, numpy as np
from pathlib import Path
from gyro_fmu.results.writer import ResultFiles
from gyro_fmu.results.read import read_results
f = ResultFiles(Path({str(tmp_path)!r}), "e" * 32)
f.begin(("time", "a"), {{}})
f(np.ones((10, 2)), 0)
f.close()
assert read_results(Path({str(tmp_path)!r}) / "results.parquet")["a"].sum() == 10
assert "pandas" not in sys.modules, "our path imported pandas"
import pyarrow as pa
pa.array(np.ones(2)).to_numpy()
print("pyarrow imports pandas:", "pandas" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "pyarrow imports pandas: True" in out, (
        "pyarrow no longer imports pandas for pa.array/to_numpy: gyro_fmu.results.arrow "
        "can go")


def test_a_run_streams_both_files_and_report_redraws_from_either(models_dir, tmp_path):
    out = tmp_path / "run"
    assert main(["run", "--stop-time", "0.004", "--models", str(models_dir), "--out",
                 str(out), "--noise", "1e-5", "--rate", "sine:0.5:300"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    csv, parquet = read_results(out / "results.csv"), read_results(out / "results.parquet")
    assert summary["results"]["rows"] == len(csv) == len(parquet) == 801
    assert all(np.array_equal(csv[c], parquet[c]) for c in csv.dtype.names)
    whole = {c: csv[c] for c in csv.dtype.names}
    expected = summarize(whole["time"], {k: whole[estimate_column(k)] for k in ESTIMATED},
                         {k: whole[sigma_column(k)] for k in ESTIMATED},
                         scenario().with_(overrides={}).params, whole["rate.Omega_z"])
    _same(summary["unknowns"], json.loads(json.dumps(expected["unknowns"])))
    for name in ("fig3_states.png", "fig4_estimates.png", "rate_estimate.png"):
        (out / name).unlink()
    assert main(["report", str(out)]) == 0  # from results.parquet
    assert (out / "fig4_estimates.png").stat().st_size > 10_000
    assert (out / "rate_estimate.png").stat().st_size > 10_000
    (out / "results.parquet").unlink()  # a run of 0.3.x: the CSV alone
    del summary["results"]["binary"]
    (out / "summary.json").write_text(json.dumps(summary))
    (out / "fig3_states.png").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "fig3_states.png").stat().st_size > 10_000
