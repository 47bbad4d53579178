"""Shared fixtures: FMUs freshly built from this checkout, once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyro_fmu.fmu.build import PACKAGE_DIR, build_all
from gyro_fmu.fmu.kernel_cache import drop_suspect_caches


def pytest_sessionstart(session: pytest.Session) -> None:
    """numba validates a cached kernel against its own file only: after an edit of a
    kernel it inlines from another file it would load old code. Drop such caches."""
    drop_suspect_caches(PACKAGE_DIR)


@pytest.fixture(scope="session")
def models_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Every FMU built by pythonfmu from fmu_src/ into a fresh folder."""
    dest = tmp_path_factory.mktemp("models")
    build_all(dest)
    return dest
