"""Shared fixtures: FMUs freshly built from this checkout, once per test session.

GYRO_FMU_TEST_WITHOUT=pythonfmu (a comma-separated list of top-level modules) runs the
suite as if those packages were not installed: every import of them fails here, and the
tests that need them skip, naming the extra (issue 47: everything else passes without the
pythonfmu flavour)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

WITHOUT = tuple(m for m in os.environ.get("GYRO_FMU_TEST_WITHOUT", "").split(",") if m)


class _Refuse:
    """An import finder that refuses the modules of WITHOUT, as if not installed."""

    @staticmethod
    def find_spec(name, path=None, target=None):
        if name.split(".")[0] in WITHOUT:
            raise ModuleNotFoundError(f"No module named {name!r} (GYRO_FMU_TEST_WITHOUT)",
                                      name=name)


if WITHOUT:
    for loaded in [m for m in sys.modules if m.split(".")[0] in WITHOUT]:
        del sys.modules[loaded]
    sys.meta_path.insert(0, _Refuse)

from gyro_fmu.fmu.build import build_all  # noqa: E402


def needs_pythonfmu() -> None:
    """Skip the calling test or fixture where the pythonfmu extra is not installed."""
    pytest.importorskip("pythonfmu", reason="the pythonfmu flavour needs the pythonfmu extra "
                        "(pip install 'gyro_fmu[pythonfmu]')")


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

    needs_pythonfmu()
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
