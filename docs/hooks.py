"""MkDocs hooks: reference pages generated from the code, so they cannot drift from it.

- `<!-- generated: cli -->` becomes every `gyro-fmu` command's help, by group, from the
  parser itself (gyro_fmu.cli.parser);
- `<!-- generated: variables MODEL -->` becomes MODEL's variable table from the same
  declarations that generate its modelDescription.xml (gyro_fmu.fmu.native);
- figures, drawn by the commands a user runs, so each page shows what they give today
  (FIGURES: about 25 s): `images/platform.png` by `examples/stabilized_platform.py` on
  the package's FMUs; the default run's three figures (`gyro-fmu run`); a
  self-calibration's (`gyro-fmu selfcal`); GyroSensor's datasheet figure measured
  again (`gyro-fmu datasheet --check`: two seeds other than the datasheet's).
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


def _platform_figure(tmp: Path) -> dict[str, Path]:
    from gyro_fmu.fmu.build import prebuilt_fmu

    for name in ("StabilizedPlatform", "GyroSensor"):
        (tmp / f"{name}.fmu").write_bytes(prebuilt_fmu(name).read_bytes())
    subprocess.run([sys.executable, str(ROOT / "examples" / "stabilized_platform.py"),
                    "--fmus", str(tmp), "--stop-time", "2", "--figure",
                    str(tmp / "platform.png")], check=True, capture_output=True)
    return {"platform.png": tmp / "platform.png"}


def _command_figures(tmp: Path) -> dict[str, Path]:
    def gyro_fmu(*args: str) -> None:
        subprocess.run([sys.executable, "-m", "gyro_fmu.cli", *args], cwd=tmp, check=True,
                       capture_output=True)

    gyro_fmu("run", "--out", "run")
    gyro_fmu("selfcal", "--out", "selfcal")
    gyro_fmu("datasheet", "--check", "--out", "datasheet")
    return {"run-fig3.png": tmp / "run" / "fig3_states.png",
            "run-fig4.png": tmp / "run" / "fig4_estimates.png",
            "run-rate.png": tmp / "run" / "rate_estimate.png",
            "selfcal-sidebands.png": tmp / "selfcal" / "sidebands.png",
            "datasheet.png": tmp / "datasheet" / "datasheet.png"}


ROOT = Path(__file__).resolve().parents[1]
#: What draws each page's figures (into a fresh folder each).
FIGURES = (_platform_figure, _command_figures)


def on_files(files, config, **kwargs):
    from mkdocs.structure.files import File

    for draw in FIGURES:
        with tempfile.TemporaryDirectory(prefix="gyro_fmu-docs-") as tmp:
            for name, path in draw(Path(tmp)).items():
                files.append(File.generated(config, f"images/{name}",
                                            content=path.read_bytes()))
    return files
