"""FMU archives are untrusted data: what is checked before one is unpacked or read.

One place for the master (cosim.instances), `gyro-fmu validate` (fmu.reference) and the
doctor. A zip bomb would fill the disk when unpacked; a member named ../x, /x or C:x would
be written outside the folder; a symbolic link would point anywhere.
"""

from __future__ import annotations

import zipfile

MAX_MEMBERS = 10_000
MAX_INFLATED = 1 << 30  # bytes


def archive_problem(z: zipfile.ZipFile) -> str | None:
    """Why this archive is not opened (None when fine)."""
    infos = z.infolist()
    if len(infos) > MAX_MEMBERS:
        return f"{len(infos)} members, more than the {MAX_MEMBERS} an FMU may have here"
    inflated = sum(i.file_size for i in infos)
    if inflated > MAX_INFLATED:
        return (f"its members inflate to {inflated / 2**30:.1f} GiB, more than "
                f"{MAX_INFLATED >> 30} GiB")
    for i in infos:
        name = i.filename.replace("\\", "/")
        if name.startswith("/") or ".." in name.split("/") or (len(name) > 1 and name[1] == ":"):
            return f"member {i.filename!r} would be unpacked outside the FMU's folder"
        if (i.external_attr >> 16) & 0o170000 == 0o120000:
            return f"member {i.filename!r} is a symbolic link"
    return None
