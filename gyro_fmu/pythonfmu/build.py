"""The pythonfmu flavour's build: an FMU whose slave is fmu_src/NAME.py, built by
pythonfmu's FmuBuilder with the gyro_fmu modules the slave reaches (shipping.py) and our C
loader in front of pythonfmu's binary (loader.py); and whether such an FMU in a models
folder still ships this tree's sources (stale_sources). gyro_fmu.fmu.build calls it for
flavour="pythonfmu" and passes what finishes an FMU (reference results, documentation)."""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path

from ..cache import size_and_crc
from ..extras import require
from .shipping import shipped_package_files
from .slaves import source_dir


def build_flavour_fmu(name: str, dest: Path, capabilities: dict[str, str],
                      names: tuple[str, ...], finish: Callable[[Path], None]) -> Path:
    """dest/NAME.fmu built by pythonfmu from fmu_src/NAME.py (names: the product's FMUs,
    for the message of an unknown one), with `capabilities` in its model description and
    `finish` run on it before it is moved into place whole."""
    sources = source_dir()
    if sources is None:
        raise FileNotFoundError("gyro_fmu.fmu_src (the FMU slave sources) is not installed: "
                                "reinstall gyro_fmu from its wheel or checkout")
    script = sources / f"{name}.py"
    if not script.exists():
        raise FileNotFoundError(f"no FMU source {script}: the FMU names are {list(names)}")
    builder = require("pythonfmu.builder", "pythonfmu").FmuBuilder
    dest.mkdir(parents=True, exist_ok=True)
    # Built in a folder of its own and moved into place whole: a process reading
    # dest/NAME.fmu meanwhile sees the old archive or the new one, never a partial one.
    with tempfile.TemporaryDirectory(dir=dest, prefix=f".{name}-") as tmp:
        package = Path(tmp) / "stage" / "gyro_fmu"
        for archived, f in shipped_package_files(script).items():
            target = package / archived.removeprefix("resources/gyro_fmu/")
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(f, target)
        path = Path(builder.build_FMU(script, dest=tmp, project_files=[package],
                                      **capabilities))
        _install_loader(path)
        finish(path)
        final = dest / path.name
        os.replace(path, final)
    return final


def _install_loader(path: Path) -> None:
    """Our loader in front of pythonfmu's binary (loader.py), so a non-Python host needs no
    settings; without a C compiler the FMU keeps pythonfmu's binary alone."""
    from .loader import LoaderUnavailableError, install_loader

    try:
        install_loader(path)
    except LoaderUnavailableError as exc:
        warnings.warn(f"{path.stem}: no Python loader ({exc}); a non-Python host needs the "
                      "settings `gyro-fmu doctor` prints", stacklevel=4)


def stale_sources(fmu: Path, name: str) -> list[str]:
    """The Python sources FMU `fmu` (built from fmu_src/NAME.py) ships differently from
    this tree; empty when it is current. A stale FMU would run its old slave adapter on
    the host's newer gyro_fmu (modules are cached per process) and fail obscurely.
    Compares sizes and CRC-32s (the archive stores both), so nothing is decompressed.
    Without a source tree (gyro_fmu running from inside an FMU) there is nothing to
    compare with, and the FMU counts as current."""
    sources = source_dir()
    source = sources / f"{name}.py" if sources else None
    if source is None or not source.is_file():
        return []
    tree = {f"resources/{name}.py": source, **shipped_package_files(source)}
    try:
        with zipfile.ZipFile(fmu) as z:
            shipped = {i.filename: (i.file_size, i.CRC) for i in z.infolist()
                       if i.filename in tree or (i.filename.startswith("resources/gyro_fmu/")
                                                 and i.filename.endswith((".py", ".c")))}
    except (OSError, zipfile.BadZipFile):
        return [str(fmu)]
    return sorted(n for n in tree.keys() | shipped.keys()
                  if n not in tree or shipped.get(n) != size_and_crc(tree[n]))

