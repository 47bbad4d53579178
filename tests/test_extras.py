"""The core without its extras: numpy, scipy and fmpy run the default scenario, and a
command that needs an extra names the pip line that installs it.

A user's environment without the extras is made here by a meta-path finder that refuses
their packages (a venv per test would take a minute); the wheel check (.ci/wheel-check)
installs the core wheel into a fresh venv, as a user would, and runs it there.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from gyro_fmu.extras import EXTRAS, MissingExtraError, install_line, require
from gyro_fmu.results.read import read_results

ROOT = Path(__file__).resolve().parents[1]
#: The top-level modules of every extra (and pandas, which the tests bring).
EXTRA_MODULES = ("pyarrow", "matplotlib", "dask", "distributed", "libcosimpy",
                 "fmu_manipulation_toolbox", "pythonfmu", "ecospy", "threadpoolctl", "pandas")
#: `gyro-fmu ARGS` in a Python that cannot import any extra's module.
WITHOUT_EXTRAS = f"""
import sys
class Refuse:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name.split(".")[0] in {EXTRA_MODULES!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Refuse)
from gyro_fmu.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def _without_extras(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", WITHOUT_EXTRAS, *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_extras_table_is_pyproject_s_and_the_core_has_no_pin():
    project = _pyproject()["project"]
    optional = project["optional-dependencies"]
    assert set(EXTRAS) == set(optional) - {"all", "test", "docs"}
    assert optional["all"] == [f"gyro_fmu[{','.join(EXTRAS)}]"]
    for extra, (dists, _) in EXTRAS.items():
        names = {re.split(r"[<>=\[ ]", d)[0] for d in optional[extra]}
        assert {d.split("[")[0] for d in dists.split(", ")} <= names, extra
    core = {re.split(r"[<>=]", d)[0] for d in project["dependencies"]}
    assert core == {"numpy", "scipy", "fmpy", "tqdm"}, core
    assert not [d for d in project["dependencies"] if "==" in d]


def test_import_and_the_parser_load_no_extra():
    code = ("import sys, gyro_fmu, gyro_fmu.cli; gyro_fmu.cli.parser(); "
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {EXTRA_MODULES!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", out


def test_run_without_extras_writes_the_same_numbers_and_says_what_it_skipped(models_dir,
                                                                            tmp_path):
    """The default scenario (2 ms) without pyarrow and matplotlib: results.csv in Python's
    own number text, the same doubles bit for bit as Arrow's file of the same run, read
    back by the core's reader as by Arrow's; no figures, with the line that installs
    them; exit 0 (the verdict)."""
    common = ["run", "--stop-time", "0.002", "--models", str(models_dir)]
    core = _without_extras([*common, "--out", "core"], tmp_path)
    assert core.returncode == 0, core.stderr
    assert "wrote core/results.csv, summary.json\n" in core.stdout, core.stdout
    assert f"no figures: they need matplotlib, which is not installed here: " \
           f"{install_line('figures')}" in core.stderr
    assert sorted(p.name for p in (tmp_path / "core").iterdir()) == ["results.csv",
                                                                      "summary.json"]
    summary = json.loads((tmp_path / "core" / "summary.json").read_text())
    assert "binary" not in summary["results"] and summary["verdict"]["passed"]
    from gyro_fmu.cli import main

    assert main([*common, "--out", str(tmp_path / "full"), "--no-figures"]) == 0
    full = read_results(tmp_path / "full" / "results.parquet")
    mine = read_results(tmp_path / "core" / "results.csv")  # Arrow's CSV reader
    assert full.dtype == mine.dtype and len(full) == 401
    for name in full.dtype.names:
        assert np.array_equal(full[name], mine[name]), name
    # the core's own reader (numpy) on the core's file: `gyro-fmu report` without pyarrow
    # reads it, and says what drawing needs
    report = _without_extras(["report", "core"], tmp_path)
    assert report.returncode == 2 and "Traceback" not in report.stderr
    assert f"matplotlib is needed for the figures and is not installed here: " \
           f"{install_line('figures')}" in report.stderr, report.stderr
    assert "Omega_z" in report.stdout


@pytest.mark.parametrize(("argv", "extra"), [
    (["sweep", "-n", "2", "--stop-time", "0.001"], "lots"),
    (["container"], "container"),
    (["build", "--flavour", "pythonfmu", "--dest", "pf"], "pythonfmu"),
    (["ssp", "--run", "--stop-time", "0.001"], "ssp"),
    (["selfcal-lot", "-n", "2"], "lots"),
])
def test_a_command_that_needs_a_missing_extra_names_it(argv, extra, models_dir, tmp_path):
    out = _without_extras([*argv, "--models", str(models_dir)] if argv[0] in ("sweep", "ssp")
                          else argv, tmp_path)
    assert out.returncode == 2, (out.stdout, out.stderr)
    assert install_line(extra) in out.stderr and "Traceback" not in out.stderr, out.stderr


def test_require_raises_only_for_the_missing_package_itself(monkeypatch, tmp_path):
    with pytest.raises(MissingExtraError, match=re.escape(install_line("figures"))):
        require("no_such_module_of_gyro_fmu", "figures")
    # a package that is there but fails to import what it needs is not "missing": its
    # own error reaches the user
    (tmp_path / "gyro_fmu_present_pkg.py").write_text("import gyro_fmu_absent_dep\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="gyro_fmu_absent_dep"):
        require("gyro_fmu_present_pkg", "figures")
