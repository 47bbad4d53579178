"""Work around pythonfmu 0.7.0's use-after-free at process exit (Linux, non-Python hosts).

pythonfmu's export library keeps its interpreter guard in a namespace-scope
``std::shared_ptr<PyState> pyState``. At process exit the C++ runtime destroys it
(exit handler: Py_Finalize, then the control block is freed), and afterwards the
library's ``__attribute__((destructor)) onLibraryUnload`` assigns ``pyState =
nullptr`` to the destroyed object: it reads the freed control block and, when the
heap has moved on (numpy/scipy teardown), aborts with "free(): corrupted ...".
Python's atexit handlers run inside that Py_Finalize, i.e. after the shared_ptr
has been read for the last time by its destructor and before onLibraryUnload, so
zeroing the 16 bytes of the dead shared_ptr there makes onLibraryUnload a no-op.
"""

from __future__ import annotations

import atexit
import ctypes
import struct
import sys
from pathlib import Path

#: (anonymous namespace)::pyState in pythonfmu-export (PySlaveInstance.cpp).
_SYMBOL = b"_ZN12_GLOBAL__N_17pyStateE"
_done: set[str] = set()


def _symbol(path: Path) -> tuple[int, int] | None:
    """(st_value, st_size) of _SYMBOL in the ELF64 .symtab of path, or None."""
    data = path.read_bytes()
    if data[:5] != b"\x7fELF\x02":
        return None
    (shoff,) = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize)
                for i in range(shnum)]
    for sec in sections:
        if sec[1] != 2:  # SHT_SYMTAB
            continue
        strtab = sections[sec[6]][4]
        for off in range(sec[4], sec[4] + sec[5], 24):
            name, _info, _other, _shndx, value, size = struct.unpack_from("<IBBHQQ", data, off)
            start = strtab + name
            if data[start:data.index(b"\0", start)] == _SYMBOL:
                return value, size
    return None


def _mapped_base(path: Path) -> int | None:
    """Load address of path in this process (its offset-0 mapping), or None."""
    real = str(path.resolve())
    with open("/proc/self/maps") as maps:
        for line in maps:
            parts = line.split(maxsplit=5)
            if len(parts) == 6 and parts[5].rstrip("\n").removesuffix(" (deleted)") == real \
                    and int(parts[2], 16) == 0:
                return int(parts[0].split("-")[0], 16)
    return None


def _clear(path: Path, address: int) -> None:
    if _mapped_base(path) is not None:  # never write into an unloaded library
        ctypes.memset(address, 0, 16)


def install(binary: Path) -> bool:
    """Arrange for the dead shared_ptr of this FMU binary to be cleared at Py_Finalize."""
    binary = Path(binary)
    if not sys.platform.startswith("linux") or str(binary) in _done or not binary.is_file():
        return False
    try:
        sym = _symbol(binary)
        base = _mapped_base(binary)
    except (OSError, ValueError, struct.error):
        return False
    if sym is None or base is None or sym[1] != 16:
        return False
    _done.add(str(binary))
    atexit.register(_clear, binary, base + sym[0])
    return True
