"""What the wheel carries: the C core and the native FMUs prebuilt inside the package,
the stamp that says which sources they were made from, and the build `pip install` runs
(setup.py) when they are missing or stale. The building itself: gyro_fmu.fmu.native."""

from __future__ import annotations

import functools
import hashlib
import sys
from pathlib import Path

from .sources import DECLARATION_FILES, sources_root

PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: Where the build puts the prebuilt FMUs and the core inside the package.
PREBUILT_FMUS = PACKAGE_DIR / "fmus"
CORE_LIB = PACKAGE_DIR / "core" / "lib"
STAMP = "sources.sha256"


def sources_digest() -> str:
    """Hash of everything the binaries and FMUs are made from: the C sources, the
    declarations and this builder, each by its name relative to its folder (the same in a
    checkout and in an installation). Read once per process while no file changes (the
    check before every run stats the files instead of reading them)."""
    root = sources_root()
    files = {f.relative_to(root).as_posix(): f
             for f in [*root.glob("core/*"), *root.glob("fmi/*"), *root.glob("models/*/*")]
             if f.is_file()}
    for name in (*DECLARATION_FILES, "fmu/native.py", "fmu/macho.py", "model/units.py",
                 "sensor/datasheet.py", "sensor/datasheet_fmu.py", "sensor/presets.py",
                 "sensor/gyros.py"):
        files[name] = PACKAGE_DIR / name
    return _digest(tuple((name, str(files[name]), files[name].stat().st_mtime_ns,
                          files[name].stat().st_size) for name in sorted(files)))


@functools.lru_cache(maxsize=8)
def _digest(entries: tuple[tuple[str, str, int, int], ...]) -> str:
    h = hashlib.sha256()
    for name, path, _, _ in entries:
        h.update(name.encode() + b"\0" + Path(path).read_bytes())
    return h.hexdigest()


def prebuilt_problem() -> str | None:
    """Why the package's prebuilt core and FMUs cannot be used (None when current)."""
    stamp = PREBUILT_FMUS / STAMP
    if not stamp.is_file():
        return (f"the prebuilt native FMUs are missing ({PREBUILT_FMUS}): reinstall gyro_fmu "
                "(pip install gyro_fmu, or pip install -e . in a checkout)")
    if (sources_root() / "core").is_dir() and stamp.read_text().strip() != sources_digest():
        return ("the prebuilt native FMUs are older than the C sources or declarations: "
                "rebuild them with `pip install -e .` (or `python build_fmu.py --native`)")
    return None


def build_package(force: bool = False) -> bool:
    """Compile the core and the native FMUs into the package (what `pip install` runs);
    skipped when they are current. Returns whether anything was built."""
    if not force and prebuilt_problem() is None:
        return False

    from .native import TARGETS, build_core, build_native

    def say(text: str) -> None:  # pip shows it with -v; python -m build always
        print(f"gyro_fmu: {text}", file=sys.stderr, flush=True)

    say(f"compiling the C core for {len(TARGETS)} platforms with zig cc (about 3 minutes "
        "the first time on a machine, seconds once zig's cache holds it)")
    build_core(CORE_LIB)
    stamp = PREBUILT_FMUS / STAMP
    stamp.unlink(missing_ok=True)
    build_native(PREBUILT_FMUS, say=say)
    stamp.write_text(sources_digest() + "\n")
    return True
