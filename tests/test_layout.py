"""The layout is the architecture: each subpackage one concern, imports running one way.

Ranks, lowest first: core (the C core through ctypes) and studies know nothing of each
other; cosim (the generic FMI master, its stepping loop in the core) and model (physics and
its FMU interfaces) build on core;
estimation (the observer and its FMU interface) and results (a run's files, written while
it goes and read back in chunks) on model; sensor (the drive, plant and observer as one
sensor FMU) on estimation; pythonfmu (that flavour's slave adapter, shipping, C loader and
upstream fixes) on those; fmu (native and pythonfmu builds of those interfaces) on all of
them; doctor on fmu; system
(scenarios, runs, SSP, container, sweeps) and selfcal on those below; cli on all; the
FMU slaves of fmu_src/ sit on top. A module may import its own subpackage and any of a
lower rank, never one of its own rank or higher.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "gyro_fmu"
RANKS = {"errors": -1, "options": -1, "extras": -0.5, "logs": -0.5, "interrupts": -0.5,
         "core": 0, "upstream": 0, "studies": 0, "outputs": 0, "cache": 0.5, "cosim": 1,
         "model": 1, "estimation": 2,
         "results": 2, "sensor": 2.5, "pythonfmu": 2.75, "fmu": 3, "doctor": 4, "system": 5,
         "selfcal": 5, "spec": 6, "cli": 7, "fmu_src": 8}
#: Left for 0.1 FMUs only: raises a message on import (see its docstring).
COMPAT = {PACKAGE / "fmi.py"}
MAX_LINES = 450
#: Modules still over MAX_LINES, each with where its split stands. An entry that is no
#: longer over the limit fails the test, so this list can only shrink.
KNOWN_BOOKS: dict[str, str] = {}


def _modules() -> list[Path]:
    files = [*PACKAGE.rglob("*.py"), *(ROOT / "fmu_src").glob("*.py")]
    return sorted(f for f in files if f not in COMPAT)


def _unit(path: Path) -> str | None:
    """The subpackage (or top-level module) a file belongs to; None for the package face."""
    if path.parent == ROOT / "fmu_src":
        return "fmu_src"
    parts = path.relative_to(PACKAGE).with_suffix("").parts
    if parts == ("__init__",):
        return None
    return parts[0]


def _imported_units(path: Path) -> set[str]:
    """Subpackages of gyro_fmu that a file imports (at module level or in functions)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    module_parts = (["gyro_fmu", "fmu_src"] if path.parent == ROOT / "fmu_src" else
                    ["gyro_fmu", *path.relative_to(PACKAGE).with_suffix("").parts])
    package = module_parts[:-1]  # for __init__.py: the package itself
    targets: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets.append(mod)
            targets += [f"{mod}.{a.name}" for a in node.names]  # from . import sub
    units = set()
    for t in targets:
        parts = t.split(".")
        if parts[0] == "gyro_fmu" and len(parts) > 1 and parts[1] in RANKS:
            units.add(parts[1])
    return units


def test_the_wheel_ships_every_subpackage():
    """pyproject.toml lists the packages by hand: a subpackage left out is missing from
    the wheel (gyro_fmu.studies was: `gyro-fmu sweep` failed when installed)."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    found = {"gyro_fmu"} | {
        ".".join(("gyro_fmu", *p.parent.relative_to(PACKAGE).parts))
        for p in PACKAGE.glob("**/__init__.py") if "fmu_src" not in p.parts}
    # folders of package data whose names are identifiers: setuptools warns about each one
    # not listed (13 warnings, 520 lines of the build's log)
    data = {"gyro_fmu.core.lib", "gyro_fmu.doctor.chost", "gyro_fmu.fmus",
            "gyro_fmu.fmus.fmi2", "gyro_fmu.fmus.fmi3", "gyro_fmu.fmu_src.core",
            "gyro_fmu.fmu_src.fmi"}
    data |= {f"gyro_fmu.fmu_src.models.{m.name}" for m in (ROOT / "fmu_src" / "models").iterdir()
             if m.is_dir()}
    assert found | data | {"gyro_fmu.fmu_src", "gyro_fmu.examples"} == listed


def test_the_ranks_name_every_subpackage():
    found = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    found |= {p.stem for p in PACKAGE.glob("*.py") if p.name != "__init__.py"} - {"fmi"}
    assert found | {"fmu_src"} == set(RANKS)


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_run_downward(path: Path):
    unit = _unit(path)
    if unit is None:
        return
    upward = sorted(u for u in _imported_units(path) - {unit} if RANKS[u] >= RANKS[unit])
    assert not upward, f"{unit} (rank {RANKS[unit]}) imports {upward}"


def test_the_check_sees_an_upward_import(tmp_path):
    """The rule can fail: a model module importing the system layer is caught."""
    bad = PACKAGE / "model" / "_probe_upward.py"
    bad.write_text("from ..system.scenario import scenario\n")
    try:
        assert _imported_units(bad) == {"system"}
    finally:
        bad.unlink()


def test_no_module_is_a_book():
    long = {str(p.relative_to(ROOT)): n for p in _modules()
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    new = {k: v for k, v in long.items() if k not in KNOWN_BOOKS}
    assert not new, f"modules over {MAX_LINES} lines: {new}"
    stale = set(KNOWN_BOOKS) - set(long)
    assert not stale, f"no longer over {MAX_LINES} lines, drop from KNOWN_BOOKS: {stale}"


def test_nothing_cites_a_file_outside_the_repository():
    cited = [str(p.relative_to(ROOT)) for p in [*_modules(), *(ROOT / "tests").glob("*.py"),
                                                 *(ROOT / "benchmarks").glob("*.py")]
             if "FIELD-NOTES" in p.read_text(encoding="utf-8") and p != Path(__file__)]
    assert not cited


def _module_imports(path: Path) -> set[str]:
    """The modules of the same folder that `path` imports at run time (at the top or inside
    a function; imports under `if TYPE_CHECKING:` are annotations, not arrows)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    typing_only = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
                   and ast.unparse(node.test).endswith("TYPE_CHECKING")
                   for n in ast.walk(node)}
    siblings = {p.stem for p in path.parent.glob("*.py")} - {"__init__", path.stem}
    found = set()
    for node in ast.walk(tree):
        if id(node) in typing_only or not isinstance(node, ast.ImportFrom) or node.level != 1:
            continue
        if node.module in siblings:
            found.add(node.module)
        elif node.module is None:
            found |= {a.name for a in node.names if a.name in siblings}
    return found


def test_no_import_circle_inside_a_folder():
    """Within a folder the modules import one way, too: no two import each other, at the
    top or inside a function (issue 47 found five such circles)."""
    circles = []
    for folder in {p.parent for p in _modules() if p.parent.name != "tests"}:
        arrows = {p.stem: _module_imports(p) for p in folder.glob("*.py")}
        circles += [f"{folder.name}/{a}.py <-> {b}.py" for a, deps in arrows.items()
                    for b in deps if a < b and a in arrows.get(b, ())]
    assert not circles, circles


def test_the_check_sees_a_circle(tmp_path):
    (tmp_path / "a.py").write_text("from .b import x\n")
    (tmp_path / "b.py").write_text("def f():\n    from .a import y\n")
    (tmp_path / "c.py").write_text("from typing import TYPE_CHECKING\n"
                                   "if TYPE_CHECKING:\n    from .a import z\n")
    assert _module_imports(tmp_path / "a.py") == {"b"}
    assert _module_imports(tmp_path / "b.py") == {"a"}
    assert _module_imports(tmp_path / "c.py") == set()
