"""MkDocs hooks: reference pages generated from the code, so they cannot drift from it.

- `<!-- generated: cli -->` becomes every `gyro-fmu` command's help, by group, from the
  parser itself (gyro_fmu.cli.parser);
- `<!-- generated: variables MODEL -->` becomes MODEL's variable table from the same
  declarations that generate its modelDescription.xml (gyro_fmu.fmu.native);
- figures: `images/platform.png` is drawn by running `examples/stabilized_platform.py`
  on the package's FMUs (3 s), so the page shows what the example prints today.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

_MARK = re.compile(r"<!-- generated: (cli|variables (\w+)) -->")


def _cli() -> str:
    import argparse

    from gyro_fmu.cli import GROUPS, parser

    p = parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    out = []
    for group, names in GROUPS.items():
        out.append(f"### {group.capitalize()}\n")
        for name in names:
            text = sub.choices[name].format_help().rstrip()
            out.append(f"#### `gyro-fmu {name}`\n\n```text\n{text}\n```\n")
    return "\n".join(out)


def _variables(model: str) -> str:
    from gyro_fmu.fmu.native import NATIVE_INTERFACES

    rows = ["| name | causality | unit | start | min | max | description |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    order = {"parameter": 0, "input": 1, "output": 2}
    for v in sorted(NATIVE_INTERFACES[model].variables,
                    key=lambda v: order.get(v.causality, 3)):
        cells = [f"`{v.name}`", v.causality, v.unit or "", _g(v.start), _g(v.min), _g(v.max),
                 (v.description or "").replace("|", "\\|")]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def _g(value: object) -> str:
    return "" if value is None else f"{value:g}" if isinstance(value, float) else str(value)


def on_page_markdown(markdown: str, **kwargs: object) -> str:
    return _MARK.sub(lambda m: _cli() if m.group(1) == "cli" else _variables(m.group(2)),
                     markdown)


def _platform_figure() -> bytes:
    from gyro_fmu.fmu.build import prebuilt_fmu

    root = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-docs-") as tmp:
        fmus = Path(tmp)
        for name in ("StabilizedPlatform", "GyroSensor"):
            (fmus / f"{name}.fmu").write_bytes(prebuilt_fmu(name).read_bytes())
        subprocess.run([sys.executable, str(root / "examples" / "stabilized_platform.py"),
                        "--fmus", str(fmus), "--stop-time", "2", "--figure",
                        str(fmus / "platform.png")], check=True, capture_output=True)
        return (fmus / "platform.png").read_bytes()


def on_files(files, config, **kwargs):
    from mkdocs.structure.files import File

    files.append(File.generated(config, "images/platform.png", content=_platform_figure()))
    return files
