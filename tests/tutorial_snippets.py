"""The Python snippets the docs show (not the examples they include, which
tests/test_examples.py runs), each run as a user would paste it: in a fresh process, in
an empty folder. Used by tests/test_examples.py with this checkout's Python and by the
wheel check (.ci/wheel-check) with a venv that has the wheel alone:

    python tests/tutorial_snippets.py PYTHON DOCS_DIR    # exit 1 naming a failing one
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

BLOCK = re.compile(r"```python\n(.*?)```", re.S)


def snippets(docs: Path) -> list[tuple[str, str]]:
    """(where, code) of every ```python block of docs/ that is not an include."""
    found = []
    for page in sorted(Path(docs).rglob("*.md")):
        text = page.read_text(encoding="utf-8")
        for m in BLOCK.finditer(text):
            if "--8<--" not in m.group(1):
                line = text.count("\n", 0, m.start()) + 1
                found.append((f"{page.relative_to(docs)}:{line}", m.group(1)))
    return found


def run(python: str, where: str, code: str) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-snippet-") as empty:
        return subprocess.run([python, "-c", code], cwd=empty, capture_output=True,
                              text=True, timeout=600)


def main(python: str, docs: str) -> int:
    failed = 0
    for where, code in snippets(Path(docs)):
        out = run(python, where, code)
        print(f"{'ok' if out.returncode == 0 else 'FAILED'}: {where}: "
              f"{(out.stdout.strip().splitlines() or [''])[-1][:100]}")
        if out.returncode:
            print(out.stderr[-2000:])
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
