"""Shared fixtures: FMUs freshly built from this checkout, once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyro_fmu.build import build_all


@pytest.fixture(scope="session")
def models_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Every FMU built by pythonfmu from fmu_src/ into a fresh folder."""
    dest = tmp_path_factory.mktemp("models")
    build_all(dest)
    return dest
