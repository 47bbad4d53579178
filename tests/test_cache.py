"""Results remembered between processes (gyro_fmu.cache): the same answer as computing,
recomputed when an input changes, never an error when the cache cannot be used; and what
it buys: `gyro-fmu run` pays the drive check's bound and scipy's import once."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from gyro_fmu import cache


def test_remembered_computes_once_per_inputs_and_survives_a_bad_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("GYRO_FMU_CACHE_DIR", str(tmp_path / "c"))
    calls = []

    def compute(value):
        calls.append(value)
        return {"twice": 2 * value}

    for value in (1, 1, 2, 1):
        assert cache.remembered("t", {"v": value}, ("model",),
                                lambda v=value: compute(v)) == {"twice": 2 * value}
    assert calls == [1, 2]
    # another code folder is another key; a damaged entry is recomputed
    cache.remembered("t", {"v": 1}, ("estimation",), lambda: compute(1))
    for entry in (tmp_path / "c" / "t").iterdir():
        entry.write_text("{not json")
    cache.remembered("t", {"v": 2}, ("model",), lambda: compute(2))
    assert calls == [1, 2, 1, 2]
    # off, or a folder that cannot be made: computed every time, no error
    for setting in ("off", str(tmp_path / "file" / "below")):
        (tmp_path / "file").write_text("")
        monkeypatch.setenv("GYRO_FMU_CACHE_DIR", setting)
        cache.remembered("t", {"v": 1}, ("model",), lambda: compute(1))
    assert calls == [1, 2, 1, 2, 1, 1]


RUN = """
import sys
from gyro_fmu.cli import main
code = main(sys.argv[1:])
print("LOADED", "gyro_fmu.estimation.sensitivity" in sys.modules)
sys.exit(code)
"""


@pytest.mark.parametrize("far", [False, True])
def test_the_drive_check_is_remembered_with_its_verdict(models_dir, tmp_path, far):
    """A run with the cache gives the same warnings as a run without it: none for the
    default scenario, the drive's for a gyro whose modes are far from the tones. No run
    imports scipy's sensitivities for it (the bound is the C core's since 0.4.0; they
    cost 0.5 s of CPU of the default run before)."""
    from test_cli import FAST_GYRO

    args = ["run", "--stop-time", "0.002", "--models", str(models_dir), "--no-figures"]
    if far:
        args += [a for k, v in FAST_GYRO.items() for a in ("--set", f"{k}={v!r}")]
    seen = []
    for setting in ("off", str(tmp_path / "cache"), str(tmp_path / "cache")):
        out = subprocess.run([sys.executable, "-c", RUN, *args, "--out", "r", "--force"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=300,
                             env={**os.environ, "GYRO_FMU_CACHE_DIR": setting})
        assert out.returncode == 0, out.stderr
        warnings = json.loads((tmp_path / "r" / "summary.json").read_text())["warnings"]
        seen.append((out.stdout.split("LOADED ")[1].strip(), warnings))
    assert [s[0] for s in seen] == ["False", "False", "False"]
    assert seen[0][1] == seen[1][1] == seen[2][1]
    assert any("far from the guessed modes" in w for w in seen[0][1]) == far


def test_the_key_follows_every_file_of_the_code_but_byte_code(tmp_path, monkeypatch):
    """A changed source or binary (the C core's library) is a new key; a new byte-code
    cache file is not (it would make every second run a miss)."""
    (tmp_path / "core" / "lib").mkdir(parents=True)
    (tmp_path / "core" / "library.py").write_text("x = 1\n")
    (tmp_path / "core" / "lib" / "libgyro_core.so").write_bytes(b"\x7fELF one")
    monkeypatch.setattr(cache, "PACKAGE", tmp_path)

    def digest() -> str:
        cache.code_digest.cache_clear()
        return cache.code_digest(("core",))

    first = digest()
    (tmp_path / "core" / "__pycache__").mkdir()
    (tmp_path / "core" / "__pycache__" / "library.cpython-311.pyc").write_bytes(b"pyc")
    assert digest() == first
    (tmp_path / "core" / "lib" / "libgyro_core.so").write_bytes(b"\x7fELF two")
    second = digest()
    (tmp_path / "core" / "library.py").write_text("x = 2\n")
    assert len({first, second, digest()}) == 3
    cache.code_digest.cache_clear()
