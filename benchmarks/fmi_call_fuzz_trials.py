"""The FMI call-sequence fuzz (tests/fmi_call_fuzz.py, the fuzzer the tests run) over every
FMU, FMI version and flavour, tabulated by class.

    python benchmarks/fmi_call_fuzz_trials.py [--sequences 150] [--calls 40] [--no-pythonfmu]

Each FMU runs in a child process of its own: random legal and illegal sequences (setReal on
an output, calls after an error or a terminate, unknown value references, bad step sizes,
FMU states freed twice, instances freed twice), each status checked against the FMI 2.0 /
3.0 state machine. Classes per FMU: calls made, OK as the standard says, refused as it
says (fmi2Error / fmi3Error with a logged reason), mismatched (a status the state machine
does not allow), crash (the child died), hang (no answer within the timeout). The
pythonfmu flavour (FMI 2.0 only) is built from the sources into a temporary folder; it
is not given NaN sets, which it refuses at the next step (see tests/fmi_call_fuzz.py).
Exit 1 if any FMU mismatched, crashed or hung.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
FUZZER = HERE.parent / "tests" / "fmi_call_fuzz.py"


def trial(fmu: Path, version: int, seed: int, sequences: int, calls: int,
          folder: Path, flavour: str) -> dict:
    unzipdir = folder / f"{fmu.stem}-{version}-{fmu.parent.name}"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(unzipdir)
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, str(FUZZER), str(unzipdir), str(version),
                               str(seed), str(sequences), str(calls), flavour],
                              capture_output=True, text=True, timeout=600)
    except subprocess.TimeoutExpired:
        return {"class": "hang", "wall": time.perf_counter() - start}
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        return {"class": "crash", "code": proc.returncode, "wall": wall,
                "stderr": proc.stderr[-400:]}
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    refused = sum(v[1] for v in report["by_call"].values())
    return {"class": "mismatch" if report["n_mismatches"] else "ok", "wall": wall,
            "calls": report["calls"], "ok": report["calls"] - refused, "refused": refused,
            "mismatches": report["n_mismatches"], "first": report["mismatches"][:2]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=150)
    ap.add_argument("--calls", type=int, default=40)
    ap.add_argument("--no-pythonfmu", action="store_true", help="the native FMUs only")
    args = ap.parse_args()
    from gyro_fmu.fmu.build import FMU_NAMES, NATIVE_NAMES, build_fmu, prebuilt_fmu

    cases = [("native", name, version, prebuilt_fmu(name, version))
             for name in NATIVE_NAMES for version in (2, 3)]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if not args.no_pythonfmu:
            (root / "pythonfmu").mkdir()
            cases += [("pythonfmu", name, 2,
                       build_fmu(name, root / "pythonfmu", reference=False, flavour="pythonfmu"))
                      for name in FMU_NAMES]
        print(f"{'flavour':<10} {'FMU':<13} FMI {'calls':>6} {'ok':>6} {'refused':>7} "
              f"{'mismatch':>8}  class   wall")
        bad = 0
        totals = dict.fromkeys(("calls", "ok", "refused", "mismatches"), 0)
        for flavour, name, version, fmu in cases:
            r = trial(fmu, version, sum(name.encode()) + version, args.sequences, args.calls,
                      root, flavour)
            for k in totals:
                totals[k] += r.get(k, 0)
            bad += r["class"] != "ok"
            print(f"{flavour:<10} {name:<13} {version}.0 {r.get('calls', 0):>6} "
                  f"{r.get('ok', 0):>6} {r.get('refused', 0):>7} {r.get('mismatches', 0):>8}  "
                  f"{r['class']:<7} {r['wall']:.1f} s")
            if r["class"] != "ok":
                print(f"    {r.get('first') or r.get('stderr') or r.get('code')}")
    print(f"{len(cases)} FMUs: {totals['calls']} calls, {totals['ok']} OK, {totals['refused']} "
          f"refused, {totals['mismatches']} mismatched; {bad} FMUs crashed, hung or mismatched")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
