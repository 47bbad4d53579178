"""The snippets the docs show, each run as a user would paste it.

- Every ```python block (not the examples they include, which tests/test_examples.py
  runs): in a fresh process, in an empty folder.
- With --bash, every command of the tutorials' ```bash blocks that starts with
  `gyro-fmu` or `python examples/`, page by page in one empty folder each (a page's later
  lines use what its earlier ones wrote), but those SKIPPED names with its reason (a
  study of many minutes, a cluster, a file of the user's own).

Used by tests/test_examples.py with this checkout's Python (the python blocks) and by the
wheel check (.ci/wheel-check) with the wheel's venv (both):

    python tests/tutorial_snippets.py PYTHON DOCS_DIR [--bash]   # exit 1 naming a failure
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

BLOCK = re.compile(r"```python\n(.*?)```", re.S)
BASH = re.compile(r"```bash\n(.*?)```", re.S)
#: Commands of the tutorials not run here, by a piece of their text, with the reason.
SKIPPED = {
    "sweep -n 200": "a Monte Carlo study of minutes (tests/test_sweep.py runs short ones)",
    "sweep -n 1000": "a user's Dask cluster",
    "selfcal-lot -n": "a lot study of minutes (tests/test_selfcal.py runs short ones)",
    "my/OwnPlant.fmu": "a file of the user's own",
    "bench.csv": "a file of the user's own",
    "python benchmarks/": "benchmarks are run by hand (their docstrings)",
}


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


def commands(docs: Path) -> dict[str, list[str]]:
    """Per tutorial page, its bash commands to run (continuation lines joined), in order."""
    pages = {}
    for page in sorted((Path(docs) / "tutorials").glob("*.md")):
        found = []
        for block in BASH.findall(page.read_text(encoding="utf-8")):
            for line in block.replace("\\\n", " ").splitlines():
                line = line.split("  #")[0].split(" # ")[0].strip()
                if line.startswith(("gyro-fmu ", "python examples/")):
                    found.append(line)
        pages[page.name] = found
    return pages


def skipped(command: str) -> str | None:
    return next((why for text, why in SKIPPED.items() if text in command), None)


def run_commands(python: str, docs: Path) -> int:
    """Each page's commands by bash in a fresh folder, with the venv of `python` first on
    PATH, as a user who ran the Quick start has it: the examples copied in (`gyro-fmu
    examples`), the FMUs in models/ and the default run in runs/default (`gyro-fmu run`)."""
    import os

    bin_dir = str(Path(python).parent)
    env = {**os.environ, "PATH": bin_dir + os.pathsep + os.environ.get("PATH", "")}
    failed = 0
    for page, lines in commands(docs).items():
        with tempfile.TemporaryDirectory(prefix="gyro_fmu-tutorial-") as folder:
            for setup in (["examples", "--dest", "examples"], ["run", "--no-figures"]):
                subprocess.run([python, "-m", "gyro_fmu.cli", *setup], cwd=folder, env=env,
                               capture_output=True, check=True)
            for line in lines:
                why = skipped(line)
                if why:
                    print(f"skipped: {page}: {line[:70]}: {why}")
                    continue
                out = subprocess.run(["bash", "-c", line], cwd=folder, env=env,
                                     capture_output=True, text=True, timeout=900)
                print(f"{'ok' if out.returncode == 0 else 'FAILED'}: {page}: {line[:80]}")
                if out.returncode:
                    print(out.stdout[-1000:] + out.stderr[-2000:])
                    failed += 1
    return failed


def main(python: str, docs: str, bash: bool = False) -> int:
    failed = 0
    for where, code in snippets(Path(docs)):
        out = run(python, where, code)
        print(f"{'ok' if out.returncode == 0 else 'FAILED'}: {where}: "
              f"{(out.stdout.strip().splitlines() or [''])[-1][:100]}")
        if out.returncode:
            print(out.stderr[-2000:])
            failed += 1
    if bash:
        failed += run_commands(python, Path(docs))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2], "--bash" in sys.argv[3:]))
