"""benchmarks/ as three suites (benchmarks/suites.py): every script in exactly one, each a
command with a docstring that says what it measures, none left outside."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _suites():
    spec = importlib.util.spec_from_file_location("benchmark_suites", BENCHMARKS / "suites.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_script_is_in_exactly_one_suite() -> None:
    suites = _suites()
    listed = [stem for scripts in suites.SUITES.values() for stem in scripts]
    assert len(listed) == len(set(listed)), "a script in two suites"
    scripts = {p.stem for p in BENCHMARKS.glob("*.py")}
    assert set(listed) | set(suites.HELPERS) == scripts, (
        f"outside every suite: {sorted(scripts - set(listed) - set(suites.HELPERS))}; "
        f"listed but missing: {sorted(set(listed) - scripts)}")


def test_every_script_says_what_it_measures_and_runs_as_a_command() -> None:
    suites = _suites()
    for scripts in suites.SUITES.values():
        for stem in scripts:
            tree = ast.parse((BENCHMARKS / f"{stem}.py").read_text(encoding="utf-8"))
            assert ast.get_docstring(tree), f"{stem}.py has no docstring"
            guards = [n for n in tree.body if isinstance(n, ast.If)
                      and "__main__" in ast.unparse(n.test)]
            assert guards, f"{stem}.py does not run as a command"
