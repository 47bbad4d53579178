"""Run outputs written whole or not at all, and known to belong together.

- Every file goes to a temporary name in its folder and is renamed into place, so a kill,
  a full disk or a lost folder never leaves a partial file under its final name.
- summary.json names the results it belongs to: the run id, the row count and the SHA-256
  of results.csv. `gyro-fmu report` refuses a pair that does not match, for example the
  results of a new run beside the summary of an old one. The old summary is removed
  before the new results go in, so that no such pair is left even by a kill between them.
- A lock file keeps a second run out of a folder a live run is writing into; the lock of
  a dead run (its process gone) is taken over.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import json
import os
import tempfile
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

from .errors import GyroFmuError

LOCK = ".gyro-fmu.lock"


class RunFolderBusyError(GyroFmuError):
    """Another live run writes into the folder."""


class MismatchedOutputsError(GyroFmuError):
    """A summary.json and a results.csv that do not belong together."""


def atomic_write(path: Path, write: Callable[[Path], object]) -> Path:
    """write(temporary path in path's folder), then rename it to path."""
    path = Path(path)
    fd, temp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        write(Path(temp))
        os.chmod(temp, 0o644)  # mkstemp's 0600 would hide the results from other users
        os.replace(temp, path)
    except BaseException:
        Path(temp).unlink(missing_ok=True)
        raise
    return path


def file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with Path(path).open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def run_lock(folder: Path) -> Iterator[None]:
    """Hold folder/.gyro-fmu.lock for the run; refuse if a live process holds it."""
    lock = Path(folder) / LOCK
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            break
        except FileExistsError:
            try:
                pid = int(lock.read_text().strip() or "0")
            except (OSError, ValueError):
                pid = 0
            if pid and pid != os.getpid() and _alive(pid):
                raise RunFolderBusyError(
                    f"{folder} is being written by another gyro-fmu run (process {pid}): wait "
                    "for it, or give another --out") from None
            lock.unlink(missing_ok=True)  # a dead run's lock
    else:
        raise RunFolderBusyError(f"cannot take the lock {lock}: give another --out")
    try:
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        yield
    finally:
        lock.unlink(missing_ok=True)


@contextlib.contextmanager
def out_folder(folder: Path) -> Iterator[Path]:
    """Make folder (and its parents) and hold its lock for the block.

    A block that fails leaves no empty folder it made behind; a live run's folder is
    refused with RunFolderBusyError (`run_lock`).
    """
    folder = Path(folder)
    created = [d for d in (folder, *folder.parents) if not d.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    try:
        with run_lock(folder):
            yield folder
    except BaseException:
        for made in created:  # nothing to keep: no empty folders left behind
            if made.is_dir() and any(made.iterdir()):
                break
            with contextlib.suppress(OSError):
                made.rmdir()
        raise


def holds_out_folder(default: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate a CLI command so that `args.out` (or default) is made and locked for it."""
    def wrap(command: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(command)
        def locked(args) -> int:
            with out_folder(Path(args.out or default)):
                return command(args)
        return locked
    return wrap


def results_record(results: Path, run_id: str, rows: int) -> dict:
    """What summary.json says of the results it belongs to."""
    return {"file": results.name, "run_id": run_id, "rows": rows,
            "sha256": file_digest(results)}


def check_pair(summary: dict, results: Path) -> None:
    """Refuse a results.csv that is not the one summary.json was written with."""
    record = summary.get("results")
    if not isinstance(record, dict) or "sha256" not in record:
        raise MismatchedOutputsError(
            f"{results.parent / 'summary.json'} names no results (written before gyro_fmu "
            "0.3.0, or damaged): rerun the scenario")
    binary = record.get("binary")
    pairs = [(results, record["sha256"])]
    if isinstance(binary, dict):
        pairs.append((results.parent / str(binary.get("file")), binary.get("sha256")))
    for path, digest in pairs:
        if not path.is_file():
            raise MismatchedOutputsError(f"{path} is missing: the run did not finish "
                                         "writing; rerun the scenario")
        if file_digest(path) != digest:
            raise MismatchedOutputsError(
                f"{path} is not the {path.name} of run {record.get('run_id')} that "
                f"summary.json describes ({record.get('rows')} rows): they belong to "
                "different runs, or one was changed; rerun the scenario")


def table_columns(rows: list[dict]) -> list[str]:
    """Every key any row has, in the order first seen."""
    columns: list[str] = []
    for r in rows:
        columns += [c for c in r if c not in columns]
    return columns


def csv_writer(rows: list[dict]) -> Callable[[Path], int]:
    """write(path): the rows as a CSV with every column any row has (table_columns; a
    missing or None value empty); returns the number of rows (for write_table_and_summary)."""
    columns = table_columns(rows)

    def write(path: Path) -> int:
        with path.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            w.writerows({c: r.get(c) for c in columns} for r in rows)
        return len(rows)

    return write


def write_json(path: Path, data: dict, **dumps: object) -> Path:
    """data as indented JSON (json.dumps keywords: default=, allow_nan=), whole or not at
    all."""
    text = json.dumps(data, indent=2, **dumps)  # type: ignore[arg-type]
    return atomic_write(path, lambda p: p.write_text(text))


def write_table_and_summary(folder: Path, table: str, write_table: Callable[[Path], int],
                            summary: dict, derived: tuple[str, ...] = ()) -> tuple[Path, Path]:
    """Replace folder/table and folder/summary.json as a pair: the old summary goes first
    (no old summary beside a new table, even after a kill between them), the table is
    written whole (write_table(path) returns its row count), then the summary, naming
    it (results_record) under summary["run_id"] (made if absent). `derived` (figures
    drawn from the table afterwards) are removed first too: an old run's figure never
    sits beside a new table."""
    folder = Path(folder)
    run_id = summary.setdefault("run_id", uuid.uuid4().hex)
    for name in ("summary.json", *derived):
        (folder / name).unlink(missing_ok=True)
    rows: list[int] = []
    path = atomic_write(folder / table, lambda p: rows.append(write_table(p)))
    summary["results"] = results_record(path, run_id, rows[0])
    return path, write_json(folder / "summary.json", summary)


def save_figure(fig: object, path: Path, **savefig: object) -> Path:
    """fig.savefig whole under path or not at all (the format from path's suffix)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = path.suffix.lstrip(".") or "png"

    def write(p: Path) -> None:
        # the file is opened here, not by savefig: Pillow 13.0's Image.save (matplotlib's
        # PNG writer) closes a file it opened only on an Exception, so a Ctrl-C inside it
        # left the file open (a ResourceWarning, and a handle held until collected).
        # Canary: tests/test_upstream.py::test_pillow_still_leaks_its_file_on_an_interrupt
        with p.open("wb") as f:
            fig.savefig(f, format=fmt, **savefig)  # type: ignore[attr-defined]

    return atomic_write(path, write)
