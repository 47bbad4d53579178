"""Universal ("fat") Mach-O files: FMI 2.0 has one darwin64 folder for both macOS
architectures, so the native build joins the x86_64 and arm64 slices as lipo would."""

from __future__ import annotations

import struct
from pathlib import Path


class MachOError(RuntimeError):
    """A slice that is not a 64-bit Mach-O of x86_64 or arm64."""


def universal_macho(slices: list[Path], out: Path) -> Path:
    """A universal ("fat") Mach-O of thin slices, as lipo -create writes it: FMI 2.0 has one
    darwin64 folder for both macOS architectures. A big-endian fat header (magic, count,
    then cputype, cpusubtype, offset, size, log2 alignment per slice), each slice at a
    multiple of 2^14."""
    cpus = {0x01000007: 3, 0x0100000C: 0}  # x86_64, arm64: their "all" subtypes
    align = 14
    page = 1 << align
    blobs = [p.read_bytes() for p in slices]
    entries, offset = [], page
    for path, blob in zip(slices, blobs, strict=True):
        magic, cputype = struct.unpack("<II", blob[:8])
        if magic != 0xFEEDFACF or cputype not in cpus:
            raise MachOError(f"{path} is not a 64-bit Mach-O of x86_64 or arm64")
        entries.append((cputype, cpus[cputype], offset, len(blob), align))
        offset += -(-len(blob) // page) * page
    data = bytearray(offset)
    data[:8] = struct.pack(">II", 0xCAFEBABE, len(blobs))
    for i, (entry, blob) in enumerate(zip(entries, blobs, strict=True)):
        data[8 + 20 * i: 28 + 20 * i] = struct.pack(">IIIII", *entry)
        data[entry[2]: entry[2] + len(blob)] = blob
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(bytes(data))
    return out
