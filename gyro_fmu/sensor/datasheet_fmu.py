"""What GyroSensor.fmu carries of its datasheets: the public sheet (no curves) as JSON and
as a Markdown table per preset, measured by the build (`add_datasheet`, through
gyro_fmu.sensor.datasheet's protocol) or kept from the last build of the same FMU, and
read back (`read_fmu_datasheet`)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from . import datasheet as protocol
from .datasheet import DATASHEET, DATASHEET_TEXT, DEFAULT_PRESET, DatasheetError, measure_datasheet
from .presets import SENSOR_PRESETS


def public(datasheet: dict) -> dict:
    """The datasheet without its curves (what the FMU carries)."""
    return {k: v for k, v in datasheet.items() if k != "curves"}


def figure_text(figure: dict) -> tuple[str, str]:
    """A figure's value ("<= " before an upper bound) and uncertainty ("" for a declared
    one) as a datasheet prints them."""
    u = figure.get("uncertainty")
    bound = "<= " if figure.get("bound") == "upper" else ""
    return bound + format(figure["value"], ".4g"), "" if u is None else format(u, ".2g")


def datasheet_markdown(sheet: dict) -> str:
    """The datasheet in human form: a table of the figures, then the protocol."""
    p = sheet["protocol"]
    lines = [f"# {sheet['model']}: datasheet ({sheet.get('preset', 'custom settings')})", "",
             "Measured by the build from this FMU's own output (gyro_fmu "
             "docs/datasheet.md); the same figures in datasheet.json. Settings: "
             f"{sheet['settings'] or 'the FMU defaults'}.", "",
             "| figure | value | +- (one seed) | unit | how |", "| --- | --- | --- | --- | --- |"]
    for name, f in sheet["figures"].items():
        value, u = figure_text(f)
        lines.append(f"| {name} | {value} | {u} | {f['unit']} | {f['how']} |")
    lines += ["", f"Protocol: warm-up {p['warm_up_s']:g} s at rate 0, record {p['record_s']:g} "
              f"s at a {p['record_step_s']:g} s host step; step and sines at {p['fast_step_s']:g} "
              f"s; seeds {p['seeds']}; uncertainty: {p['uncertainty']}. Check it: "
              "`gyro-fmu datasheet --check --fmu THIS.fmu`.", ""]
    return "\n".join(lines)


def read_fmu_datasheet(fmu: Path, preset: str = DEFAULT_PRESET) -> dict:
    """The datasheet of a preset (default: the FMU's defaults) that an FMU carries."""
    import zipfile

    name = sheet_names(preset)[0]
    with zipfile.ZipFile(fmu) as z:
        try:
            return json.loads(z.read(name))
        except KeyError:
            raise DatasheetError(f"{fmu} has no {name}: measure one with "
                                 "`gyro-fmu datasheet`") from None


def fmu_key(fmu: Path) -> str:
    """What a datasheet is measured from: the FMU's model description, its sources and
    the binary this host runs (the others are not run; the darwin64 one differs from build
    to build), and the protocol (gyro_fmu.sensor.datasheet)."""
    import hashlib
    import zipfile

    from fmpy import platform

    h = hashlib.sha256(Path(protocol.__file__).read_bytes())
    with zipfile.ZipFile(fmu) as z:
        for name in sorted(z.namelist()):
            if name == "modelDescription.xml" or name.startswith(
                    ("sources/", f"binaries/{platform}/")):
                h.update(name.encode() + b"\0" + z.read(name))
    return h.hexdigest()


def sheet_names(preset: str) -> tuple[str, str]:
    """The FMU members of a preset's datasheet (JSON, text): the defaults' (consumer) are
    DATASHEET and DATASHEET_TEXT, another preset's documentation/datasheet-<name>.*."""
    if preset == DEFAULT_PRESET:
        return DATASHEET, DATASHEET_TEXT
    return f"documentation/datasheet-{preset}.json", f"documentation/datasheet-{preset}.md"


def add_datasheet(fmus: Sequence[Path], cache: Path) -> dict:
    """Measure the datasheet of fmus[0] (FMI 2.0) at every preset (SENSOR_PRESETS), or take
    them from `cache` when measured from the same FMU and presets, and write them into
    every FMU of `fmus` (FMI 2.0 and 3.0 share the binaries). Returns them by preset."""
    import hashlib
    import zipfile

    key = hashlib.sha256((fmu_key(fmus[0]) + json.dumps(SENSOR_PRESETS, sort_keys=True))
                         .encode()).hexdigest()
    sheets = None
    if cache.is_file():
        cached = json.loads(cache.read_text())
        if cached.get("key") == key:
            sheets = cached["sheets"]
    if sheets is None:
        sheets = {name: {**public(measure_datasheet(fmus[0], settings)), "preset": name}
                  for name, settings in SENSOR_PRESETS.items()}
        cache.write_text(json.dumps({"key": key, "sheets": sheets}))
    members = {}
    for name, sheet in sheets.items():
        json_name, text_name = sheet_names(name)
        members[json_name] = json.dumps(sheet, indent=1) + "\n"
        members[text_name] = datasheet_markdown(sheet)
    for fmu in fmus:
        with zipfile.ZipFile(fmu, "a") as z:
            for name, text in members.items():
                info = zipfile.ZipInfo(name, date_time=(2026, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16
                z.writestr(info, text, zipfile.ZIP_DEFLATED)
    return sheets
