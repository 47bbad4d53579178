"""Coverage-guided fuzzing of every native FMU, long runs, with a table per FMU: seconds,
executions, coverage (edges), findings (sanitizer reports, crashes, time-outs).

    python benchmarks/fuzz_native.py [--seconds 120] [--grow] [--old CHECKOUT] [MODEL ...]

Each FMU's target is built from its own sources (tests/fuzz_harness.py). Every finding
is kept in runs/fuzz/<MODEL>/ (libFuzzer's artifact): once fixed, copy it into
tests/fuzz/regressions/<MODEL>/, where the test suite replays it. --grow merges what the
run learned into tests/fuzz/corpus/<MODEL>/ (minimized). --old fuzzes another checkout's
sources (fmu_src/ and its declarations), e.g. the last release, to count what a fix
fixed. Fork mode goes on past a finding, so one run counts them all.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import fuzz_harness


def _old_variables(checkout: Path, model: str) -> str:
    """variables.h as `checkout`'s declarations generate it."""
    code = ("from gyro_fmu.fmu.native import NATIVE_INTERFACES, variables_header; "
            f"print(variables_header(NATIVE_INTERFACES[{model!r}]), end='')")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=checkout, env={"PYTHONPATH": str(checkout)}).stdout


def fuzz(model: str, seconds: float, out: Path, work: Path, old: Path | None,
         grow: bool) -> dict:
    target = (fuzz_harness.build(model, work, checkout_root(old),
                                 _old_variables(old, model)) if old
              else fuzz_harness.build(model, work))
    corpus = work / "corpus" / model
    corpus.mkdir(parents=True, exist_ok=True)
    seeds = fuzz_harness.CORPUS / model
    findings = out / model
    findings.mkdir(parents=True, exist_ok=True)
    before = set(findings.iterdir())
    start = time.perf_counter()
    proc = subprocess.run([str(target), "-fork=1", "-ignore_crashes=1", "-ignore_timeouts=1",
                           "-ignore_ooms=1", f"-max_total_time={int(seconds)}", "-timeout=10",
                           "-max_len=512", "-rss_limit_mb=2048",
                           f"-artifact_prefix={findings}/", str(corpus), str(seeds)],
                          capture_output=True, text=True, cwd=work)
    elapsed = time.perf_counter() - start
    text = proc.stderr
    execs = re.findall(r"#(\d+): cov: (\d+)", text)
    new = sorted(set(findings.iterdir()) - before)
    kinds = [p.name.split("-")[0] for p in new]
    if grow and not old:
        subprocess.run([str(target), "-merge=1", str(seeds), str(corpus)], capture_output=True,
                       cwd=work)
    return {"model": model, "seconds": elapsed,
            "executions": int(execs[-1][0]) if execs else 0,
            "edges": int(execs[-1][1]) if execs else 0,
            "crashes": kinds.count("crash"), "timeouts": kinds.count("timeout"),
            "ooms": kinds.count("oom"), "files": new}


def checkout_root(old: Path | None) -> Path | None:
    return None if old is None else old / "fmu_src"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="*", default=list(fuzz_harness.MODELS))
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--grow", action="store_true", help="merge new coverage into the corpus")
    ap.add_argument("--old", type=Path, help="fuzz this checkout's C sources instead")
    ap.add_argument("--out", type=Path, default=Path("runs/fuzz"))
    args = ap.parse_args()
    why = fuzz_harness.problem()
    if why:
        print(f"cannot fuzz here: {why}")
        return 2
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for model in args.models:
            rows.append(fuzz(model, args.seconds, args.out.resolve(), Path(tmp), args.old,
                             args.grow))
            r = rows[-1]
            print(f"{r['model']:<14} {r['seconds']:6.0f} s {r['executions']:>10} execs "
                  f"{r['edges']:>5} edges  crashes {r['crashes']}  time-outs "
                  f"{r['timeouts']}  out-of-memory {r['ooms']}", flush=True)
    found = sum(r["crashes"] + r["timeouts"] + r["ooms"] for r in rows)
    print(f"{found} finding(s)" + (f", kept in {args.out}/<MODEL>/" if found else ""))
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
