"""What a pythonfmu-flavour FMU ships of gyro_fmu: the modules its adapter can import, no
more (not the scenario catalogue, the CLI, the studies, the master or the doctor).

`adapter_modules(script)` follows every import statement (at module level and inside
functions, absolute and relative) from the adapter fmu_src/NAME.py through gyro_fmu, so a
lazily imported module travels too; `shipped_package_files(name)` is those modules' files
plus this platform's compiled core (core/lib/<platform>/), which the adapters call. A
module of a concern that never runs inside an FMU (NEVER_IN_AN_FMU) reached from an
adapter fails the build, naming the chain, so the layering cannot erode silently.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent.parent
#: Imported by name at run time (gyro_fmu/__init__), invisible to the import statements.
DYNAMIC_IMPORTS = ("gyro_fmu.pythonfmu.shipped_copies",)
#: Concerns above the step: never imported inside an FMU.
NEVER_IN_AN_FMU = ("gyro_fmu.cli", "gyro_fmu.studies", "gyro_fmu.spec", "gyro_fmu.system",
                   "gyro_fmu.selfcal", "gyro_fmu.doctor", "gyro_fmu.cosim",
                   "gyro_fmu.fmu.build", "gyro_fmu.fmu.native", "gyro_fmu.pythonfmu.build")


class ShippingError(RuntimeError):
    """An adapter reaches a module that must not run inside an FMU."""


def module_file(module: str) -> Path | None:
    """The source file of gyro_fmu module `module` (package or module), or None."""
    base = PACKAGE_DIR.joinpath(*module.split(".")[1:])
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None


def _imports(path: Path, module: str) -> set[str]:
    """gyro_fmu modules named by the import statements of one file."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.split(".")[0] == "gyro_fmu")
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - node.level + 1]
                target = ".".join(parts + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "gyro_fmu":
                continue
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names
                       if module_file(f"{target}.{a.name}"))
    return out


@functools.cache
def adapter_modules(script: Path) -> tuple[str, ...]:
    """Every gyro_fmu module the adapter `script` can import, with their packages."""
    reached_from: dict[str, str] = {}
    todo = [(m, script.name) for m in sorted(_imports(script, "fmu_src._adapter"))]
    todo += [("gyro_fmu", script.name)] + [(m, "gyro_fmu") for m in DYNAMIC_IMPORTS]
    while todo:
        module, parent = todo.pop()
        parts = module.split(".")
        for k in range(1, len(parts) + 1):
            name = ".".join(parts[:k])
            if name in reached_from or module_file(name) is None:
                continue
            reached_from[name] = parent
            if name.startswith(NEVER_IN_AN_FMU):
                chain = [name]
                while chain[-1] in reached_from and chain[-1] != reached_from[chain[-1]]:
                    chain.append(reached_from[chain[-1]])
                raise ShippingError(f"{script.name} reaches {name}, which must not run inside "
                                    f"an FMU: {' <- '.join(chain)}; import it lazily where "
                                    "only the library needs it")
            todo += [(m, name) for m in sorted(_imports(module_file(name), name))]
    return tuple(sorted(reached_from))


def shipped_package_files(script: Path) -> dict[str, Path]:
    """The gyro_fmu files the FMU of adapter `script` carries, by their archive path."""
    from ..core.library import library_path

    files = [module_file(m) for m in adapter_modules(script)]
    core = library_path()
    files += [core] if core.is_file() else []
    return {f"resources/gyro_fmu/{f.relative_to(PACKAGE_DIR).as_posix()}": f for f in files}
