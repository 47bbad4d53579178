"""Results of pure computations kept on disk between processes, keyed on their inputs and
on the code that computes them.

`remembered(kind, inputs, code, compute)` returns compute()'s JSON-able result, from the
cache when the same inputs met the same code before. The key is the SHA-256 of the inputs
(as JSON) and of every file under `code` (the package folders the computation reads, the
C core's binaries included), so an edit of that code or a new build recomputes. The cache lives in
$GYRO_FMU_CACHE_DIR, else $XDG_CACHE_HOME/gyro_fmu, else ~/.cache/gyro_fmu; a cache that
cannot be read or written is skipped (the result is computed), never an error.
GYRO_FMU_CACHE_DIR=off turns it off.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

PACKAGE = Path(__file__).resolve().parent


def cache_dir() -> Path | None:
    """The cache's folder, or None when GYRO_FMU_CACHE_DIR=off."""
    chosen = os.environ.get("GYRO_FMU_CACHE_DIR")
    if chosen == "off":
        return None
    if chosen:
        return Path(chosen)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "gyro_fmu"


@functools.cache
def code_digest(folders: tuple[str, ...]) -> str:
    """SHA-256 of every file of the package under these folders (names and contents; the
    C core's binaries under core/ too, the byte-code caches not)."""
    sha = hashlib.sha256()
    for folder in folders:
        for path in sorted((PACKAGE / folder).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                sha.update(str(path.relative_to(PACKAGE)).encode() + b"\0" + path.read_bytes())
    return sha.hexdigest()


def remembered(kind: str, inputs: dict, code: Sequence[str], compute: Callable[[], Any]) -> Any:
    """compute()'s result (JSON-able), remembered under (kind, inputs, code)."""
    folder = cache_dir()
    if folder is None:
        return compute()
    from . import __version__

    key = hashlib.sha256(json.dumps([kind, __version__, inputs, code_digest(tuple(code))],
                                    sort_keys=True).encode()).hexdigest()
    path = folder / kind / f"{key}.json"
    try:
        return json.loads(path.read_text())["result"]
    except (OSError, ValueError, KeyError, TypeError):
        pass
    result = compute()
    try:
        from .outputs import atomic_write

        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda p: p.write_text(json.dumps({"inputs": inputs,
                                                              "result": result})))
    except OSError:
        pass
    return result


def size_and_crc(path: Path) -> tuple[int, int]:
    """A file's size and CRC-32 (what a zip archive stores of each member), remembered in
    this process on the file's modification time: a check before every run stays cheap."""
    stat = Path(path).stat()
    return _size_and_crc_of(str(path), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=1024)
def _size_and_crc_of(path: str, mtime_ns: int, size: int) -> tuple[int, int]:
    return size, zlib.crc32(Path(path).read_bytes())
