"""Shared fixtures: FMUs freshly built from this checkout, once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyro_fmu.fmu.build import build_all


@pytest.fixture(scope="session")
def models_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Every FMU (the native ones, prebuilt in the package) copied into a fresh folder."""
    dest = tmp_path_factory.mktemp("models")
    build_all(dest)
    return dest


@pytest.fixture(scope="session")
def pythonfmu_models(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The pythonfmu flavour of every FMU: thin adapters over the same C core, built on
    request."""
    from gyro_fmu.fmu.build import PYTHONFMU_NAMES

    dest = tmp_path_factory.mktemp("pythonfmu")
    build_all(dest, PYTHONFMU_NAMES, flavour="pythonfmu")
    return dest


@pytest.fixture(scope="session")
def pythonfmu_all(models_dir: Path, pythonfmu_models: Path,
                  tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Every FMU in its pythonfmu flavour, in one folder: for the tests that hold the
    pythonfmu adapter's own semantics (a refused value discarded at the next step, JSON
    FMU states, the loader). The native FMUs' semantics: test_native_fmi_layer.py."""
    import shutil

    from gyro_fmu.fmu.build import PYTHONFMU_NAMES

    dest = tmp_path_factory.mktemp("pythonfmu_all")
    for name in PYTHONFMU_NAMES:
        shutil.copy2(pythonfmu_models / f"{name}.fmu", dest / f"{name}.fmu")
    return dest


@pytest.fixture
def terminal_sigint():
    """SIGINT raising KeyboardInterrupt, as in a terminal's process, for the tests that send
    one. A suite started in the background of a non-interactive shell (`cmd &`, nohup)
    inherits SIGINT ignored, and Python keeps it so: a Ctrl-C test then saw its run finish
    (exit 0; stop 39's unexplained failure). Restored afterwards."""
    import signal

    before = signal.getsignal(signal.SIGINT)
    if before is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)
