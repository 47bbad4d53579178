"""Every script of examples/ (the tutorials include them) runs as a user would run it,
from an empty folder, in a fresh process, with the shortest arguments that still show
its point; each checks its own result (exit code) and prints its figures."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from gyro_fmu.fmu.build import NATIVE_NAMES

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(argv: list[str], cwd: Path) -> str:
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    proc = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def test_every_example_is_run_here() -> None:
    tested = {"observer_in_fmpy_loop.py", "cosimulate_from_python.py", "self_calibrate.py",
              "validate_in_ci.sh", "read_results.py", "stabilized_platform.py"}
    assert {p.name for p in EXAMPLES.iterdir() if p.suffix in (".py", ".sh")} == tested


def test_observer_in_a_plain_fmpy_loop(tmp_path: Path) -> None:
    run([sys.executable, "-m", "gyro_fmu.cli", "fmus", "--dest", "fmus", "--fmi", "2"], tmp_path)
    out = run([sys.executable, str(EXAMPLES / "observer_in_fmpy_loop.py"), "--fmus", "fmus",
               "--rate", "0.3", "--stop-time", "0.02"], tmp_path)
    rate, sigma = map(float, re.search(r"Omega_hat (\S+) rad/s, 1-sigma (\S+),", out).groups())
    assert abs(rate - 0.3) < 4 * sigma < 0.01  # the script's own check, made visible


def test_a_stabilized_platform_with_gyrosensor_in_its_rate_loop(tmp_path: Path) -> None:
    """The system example: GyroSensor.fmu in a 1 ms rate loop, from an empty folder. The
    gate is the script's own check (its exit code: the loop stabilized, the pointing
    error within 5 times the ideal gyro's plus the sensor's mean error over the run);
    here only that the figures are printed and ordered, and a sanity bound of 20 that a
    broken sensor would cross. The ratio itself is not a stable figure: the run is
    chaotic in its last bits (the observer's re-fit test restarts it once or twice a
    second under the vehicle's sway, docs/gyro-sensor.md "What falls short"). Measured
    here: ideal 0.889 mrad; GyroSensor at seed 0 1.66 mrad before 0.4.0's observer
    changes and 3.56 after; over seeds 0-19, 1.6-6.8 times the ideal before (mean 3.3)
    and 1.1-7.5 after (mean 3.6)."""
    run([sys.executable, "-m", "gyro_fmu.cli", "fmus", "--dest", "fmus", "--fmi", "2"], tmp_path)
    out = run([sys.executable, str(EXAMPLES / "stabilized_platform.py"), "--fmus", "fmus",
               "--stop-time", "1", "--figure", "platform.png"], tmp_path)
    ideal = float(re.search(r"ideal gyro: (\S+) mrad", out).group(1))
    real = float(re.search(r"GyroSensor: (\S+) mrad", out).group(1))
    assert 0 < ideal < real < 20 * ideal  # the sensor's noise and lag cost, not a failure
    assert (tmp_path / "platform.png").stat().st_size > 10_000


def test_cosimulate_from_python(tmp_path: Path) -> None:
    out = run([sys.executable, str(EXAMPLES / "cosimulate_from_python.py"), "--stop-time",
               "0.01"], tmp_path)
    assert (tmp_path / "models" / "GyroObserver.fmu").is_file()
    rate, sigma = map(float, re.search(r"Omega_hat (\S+) rad/s \(1-sigma (\S+)\)", out).groups())
    assert abs(rate - 1.0) < 4 * sigma


def test_self_calibrate(tmp_path: Path) -> None:
    out = run([sys.executable, str(EXAMPLES / "self_calibrate.py")], tmp_path)
    d_bias = float(re.search(r"(\S+) off the rate table\n", out).group(1))
    d_sf = float(re.search(r"(\S+) ppm off the rate table", out).group(1))
    assert abs(d_bias) < 7.27e-5 and abs(d_sf) < 100.0


@pytest.mark.skipif(sys.platform == "win32", reason="a bash script")
def test_validate_in_ci(tmp_path: Path) -> None:
    out = run(["bash", str(EXAMPLES / "validate_in_ci.sh"), "my-fmus"], tmp_path)
    assert "all outputs match their reference results" in out
    assert len(list((tmp_path / "my-fmus").glob("*.fmu"))) == len(NATIVE_NAMES)


def test_read_results(tmp_path: Path) -> None:
    pytest.importorskip("pandas")
    pytest.importorskip("plotly")
    run([sys.executable, "-m", "gyro_fmu.cli", "run", "--stop-time", "0.01", "--no-figures"],
        tmp_path)
    out = run([sys.executable, str(EXAMPLES / "read_results.py")], tmp_path)
    assert "2001 rows" in out and "agree on every value: True" in out
    assert "units: Omega_hat in rad/s, x in m" in out and "units too: True" in out
    assert "['observer.Omega_hat', 'observer.sigma_Omega_z']" in out
    rms = float(re.search(r"last 20 %: (\S+) rad/s", out).group(1))
    assert rms < 1e-3


def test_the_docs_python_snippets_run_as_pasted() -> None:
    """Every ```python block of docs/ that is not an include, pasted into a fresh Python
    in an empty folder (the wheel check does the same from the wheel alone)."""
    sys.path.insert(0, str(Path(__file__).parent))
    from tutorial_snippets import run, snippets

    found = snippets(EXAMPLES.parent / "docs")
    assert len(found) >= 3
    for where, code in found:
        out = run(sys.executable, where, code)
        assert out.returncode == 0, f"{where}:\n{out.stderr[-2000:]}"


def test_gyro_fmu_examples_copies_the_scripts_the_tutorials_run(tmp_path: Path) -> None:
    out = run([sys.executable, "-m", "gyro_fmu.cli", "examples", "--dest", "ex"], tmp_path)
    copied = {p.name for p in (tmp_path / "ex").iterdir()}
    assert copied == {p.name for p in EXAMPLES.iterdir() if p.suffix in (".py", ".sh")}
    assert out.count("wrote ") == len(copied)
    (tmp_path / "ex" / "read_results.py").write_text("# mine\n")
    refused = subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "examples", "--dest",
                              "ex"], cwd=tmp_path, capture_output=True, text=True)
    assert refused.returncode == 2 and "read_results.py" in refused.stderr
    assert (tmp_path / "ex" / "read_results.py").read_text() == "# mine\n"  # kept


def test_every_tutorial_command_is_run_by_the_wheel_check_or_skipped_with_a_reason() -> None:
    """The wheel check runs the tutorials' command lines (tutorial_snippets.py --bash); the
    ones it skips are few and named (a study of minutes, a cluster, a user's own file)."""
    sys.path.insert(0, str(Path(__file__).parent))
    from tutorial_snippets import commands, skipped

    lines = [line for page in commands(EXAMPLES.parent / "docs").values() for line in page]
    run_there = [line for line in lines if not skipped(line)]
    assert len(run_there) >= 25 and len(lines) - len(run_there) <= 10, (len(lines),
                                                                         len(run_there))
    assert "tutorial_snippets.py" in (EXAMPLES.parent / ".ci" / "wheel-check").read_text()
