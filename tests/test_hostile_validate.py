"""Hostile FMUs for `gyro-fmu validate`: a manifest that climbs out of the archive, a
cut reference, broken archives and descriptions, each on a copy of a real built FMU."""

from __future__ import annotations

import os
import random
import struct
import zipfile
from pathlib import Path

import pytest

from gyro_fmu.cli import main
from gyro_fmu.fmu.reference import LS_REF_DIR, MANIFEST

OUT = f"{LS_REF_DIR}/GyroPlant_out.csv"


def _copy(src: Path, dst: Path, edit) -> Path:
    """Copy src to dst; edit(name, data) gives bytes, None (drop) or [(name, data), ...]."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            out = edit(item.filename, zin.read(item))
            if out is not None:
                for name, data in out if isinstance(out, list) else [(item.filename, out)]:
                    zout.writestr(name, data)
    return dst


def test_a_manifest_source_that_climbs_out_is_refused_and_nothing_is_written(
        models_dir, tmp_path, capsys, monkeypatch):
    target = tmp_path / "ESCAPED.csv"
    source = "../" * 12 + str(target).lstrip("/")
    fmu = _copy(models_dir / "GyroPlant.fmu", tmp_path / "t.fmu", lambda n, d: (
        d.replace(b'source="GyroPlant_out.csv"', f'source="{source}"'.encode())
        if n == MANIFEST else [(n, d), (f"{LS_REF_DIR}/{source}", d)] if n == OUT else d))
    monkeypatch.chdir(tmp_path)
    assert main(["validate", str(fmu)]) == 1  # was: writes ESCAPED.csv, "all outputs match"
    # the member climbing out is refused before the archive is opened at all
    assert "would be unpacked outside the FMU's folder" in capsys.readouterr().out
    assert not target.exists()
    named_only = _copy(models_dir / "GyroPlant.fmu", tmp_path / "n.fmu", lambda n, d: (
        d.replace(b'source="GyroPlant_out.csv"', b'source="../x.csv"') if n == MANIFEST else d))
    assert main(["validate", str(named_only)]) == 1  # the manifest's name alone: refused too
    assert "a reference must be a plain file name" in capsys.readouterr().out


def test_a_cut_reference_or_a_missing_column_fails(models_dir, tmp_path, capsys):
    cut = _copy(models_dir / "GyroPlant.fmu", tmp_path / "cut.fmu", lambda n, d: (
        b"\n".join(d.split(b"\n")[:4]) + b"\n" if n == OUT else d))
    drop = _copy(models_dir / "GyroPlant.fmu", tmp_path / "drop.fmu", lambda n, d: (
        b"\n".join(b",".join(line.split(b",")[:-1]) for line in d.split(b"\n")) if n == OUT
        else d))
    assert main(["validate", str(cut), str(drop)]) == 1  # cut was: exit 0, deviation inf
    out = capsys.readouterr().out
    assert "3 rows for the 2001 communication points" in out and "missing ['ay']" in out


def _bad_crc(src: Path, dst: Path) -> Path:
    raw = bytearray(src.read_bytes())
    info = zipfile.ZipFile(src).getinfo("modelDescription.xml")
    n, e = struct.unpack("<HH", raw[info.header_offset + 26:info.header_offset + 30])
    raw[info.header_offset + 30 + n + e + info.compress_size // 2] ^= 0xFF
    dst.write_bytes(bytes(raw))
    return dst


def test_broken_files_are_one_fail_line_each_and_later_fmus_are_still_checked(
        models_dir, tmp_path, capsys):
    plant = models_dir / "GyroPlant.fmu"
    (tmp_path / "notzip.fmu").write_bytes(b"not a zip")
    (tmp_path / "trunc.fmu").write_bytes(plant.read_bytes()[:100000])
    (tmp_path / "folder.fmu").mkdir()
    bad = [tmp_path / "notzip.fmu", tmp_path / "trunc.fmu", tmp_path / "folder.fmu",
           tmp_path / "missing.fmu", _bad_crc(plant, tmp_path / "crc.fmu"),
           _copy(plant, tmp_path / "nomd.fmu", lambda n, d: None
                 if n == "modelDescription.xml" else d),
           _copy(plant, tmp_path / "xml.fmu", lambda n, d: d[:200]
                 if n == "modelDescription.xml" else d),
           _copy(plant, tmp_path / "csv.fmu", lambda n, d: d.replace(b"0.0,", b"zz,", 1)
                 if n == OUT else d),
           _copy(plant, tmp_path / "refused.fmu", lambda n, d: d.replace(b",1.0\n", b",1e300\n")
                 if n.endswith("_in.csv") else d)]
    assert main(["validate", *map(str, bad), str(models_dir / "RateProfile.fmu")]) == 1
    out = capsys.readouterr().out
    for path in bad:
        assert f"{path}: FAIL: " in out, path
    assert f"{tmp_path / 'refused.fmu'}: FAIL: the simulation of the default experiment " \
        "failed: fmi2DoStep failed with status 3" in out, out
    assert "Omega_z=1e+300 rad/s is not a rate this gyro can sense" in out  # the FMU's reason
    assert "pass  Omega_z" in out and "Traceback" not in out


def _mutate(rng: random.Random, kind: str, data: bytes) -> tuple[bytes, bool]:
    """(mutated reference CSV, damaging?)"""
    lines = data.decode().splitlines()
    if kind == "rows":
        del lines[rng.randrange(1, len(lines))]
        return ("\n".join(lines) + "\n").encode(), True
    if kind == "nan":
        i = rng.randrange(1, len(lines))
        lines[i] = ",".join([lines[i].split(",")[0], "nan", *lines[i].split(",")[2:]])
        return ("\n".join(lines) + "\n").encode(), True
    if kind == "shift":
        lines[1:] = [",".join([repr(float(line.split(",")[0]) + 5e-6), *line.split(",")[1:]])
                     for line in lines[1:]]
        return ("\n".join(lines) + "\n").encode(), True
    if kind == "rename":
        return ("\n".join([lines[0].replace('"x"', '"xx"'), *lines[1:]]) + "\n").encode(), True
    return data.replace(b"\n", b"\r\n"), False  # line endings: the same table


@pytest.mark.parametrize("seed", range(20))
def test_short_fuzz_of_the_reference_no_crash_no_write_no_damaged_pass(
        models_dir, tmp_path, seed, monkeypatch, capsys):
    rng = random.Random(seed)
    kind = ["rows", "nan", "shift", "rename", "crlf"][seed % 5]
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    fmu = tmp_path / "m.fmu"
    damaging = []

    def edit(n, d):
        if n == OUT:
            d, bad = _mutate(rng, kind, d)
            damaging.append(bad)
        return d
    _copy(models_dir / "GyroPlant.fmu", fmu, edit)
    code = main(["validate", str(fmu)])
    assert code in (0, 1) and os.listdir(work) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cwd", "m.fmu"]
    if damaging[0]:
        assert code == 1, capsys.readouterr().out
