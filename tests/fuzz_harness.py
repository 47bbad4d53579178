"""Coverage-guided fuzzing of the native FMUs: build one libFuzzer target per FMU from its
own sources (tests/fuzz/fuzz_fmu.c over the model.c, the FMI layer and the core it ships),
with address and undefined-behaviour sanitizers, and run it on a corpus.

Used by tests/test_fuzz.py (a short run on the checked-in corpus, tests/fuzz/corpus/)
and benchmarks/fuzz_native.py (long runs that print executions, coverage and findings).
Needs clang with libFuzzer (Debian: clang and libclang-rt-14-dev); `problem()` says why
not where it cannot be had."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from gyro_fmu.fmu.native import (
    NATIVE_INTERFACES,
    fmi_header_dir,
    generated_headers,
    model_sources,
    sources_root,
)

HERE = Path(__file__).resolve().parent / "fuzz"
DRIVER = HERE / "fuzz_fmu.c"
CORPUS = HERE / "corpus"
#: Inputs that found a defect (a sanitizer report, crash or time-out), one folder per FMU:
#: replayed by the tests on the fixed sources.
REGRESSIONS = HERE / "regressions"
MODELS = tuple(NATIVE_INTERFACES)
FLAGS = ["-g", "-O1", "-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all",
         "-fno-omit-frame-pointer", "-ffp-contract=off"]


def clang() -> str | None:
    for name in ("clang", "clang-16", "clang-15", "clang-14"):
        path = shutil.which(name)
        if path:
            return path
    return None


def problem() -> str | None:
    """Why no fuzz target can be built here (None: it can)."""
    cc = clang()
    if cc is None:
        return "no clang on PATH (Debian: apt-get install clang libclang-rt-14-dev)"
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "probe.c"
        src.write_text("#include <stdint.h>\n#include <stddef.h>\n"
                       "int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n)"
                       "{(void)d; (void)n; return 0;}\n")
        proc = subprocess.run([cc, *FLAGS, str(src), "-o", str(Path(tmp) / "probe")],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            return (f"{cc} cannot link a libFuzzer target with sanitizers (Debian: apt-get "
                    f"install libclang-rt-14-dev): {proc.stderr.strip()[-300:]}")
    return None


def build(model: str, dest: Path, root: Path | None = None,
          variables: str | None = None) -> Path:
    """The fuzz target of one FMU: dest/fuzz_<model>, from the C sources under root
    (fmu_src/ of this checkout by default; another checkout's, with its variables.h text,
    to fuzz an older version)."""
    interface = NATIVE_INTERFACES[model]
    gen = generated_headers(dest / "generated" / model, interface)
    if variables is not None:
        (gen / "variables.h").write_text(variables)
    here = sources_root()
    root = root or here
    sources = [str(root / p.relative_to(here)) for p in model_sources(interface)
               if p.suffix == ".c"]
    out = dest / f"fuzz_{model}"
    cmd = [clang(), *FLAGS, f"-I{gen}", f"-I{root / 'fmi'}", f"-I{root / 'core'}",
           f"-I{fmi_header_dir()}", str(DRIVER), *sources, "-lm", "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"building the fuzz target of {model} failed:\n{' '.join(cmd)}\n"
                           f"{proc.stderr}")
    return out


@dataclass
class FuzzRun:
    """What one libFuzzer run did."""

    model: str
    seconds: float
    executions: int
    edges: int  #: coverage: edges reached ("cov:" of libFuzzer's last line)
    returncode: int
    finding: str  #: the sanitizer or libFuzzer report ("" when none)
    artifact: Path | None  #: the input that found it


def run(target: Path, model: str, seconds: float, corpus: list[Path], work: Path,
        timeout: float = 10.0, jobs: int = 1) -> FuzzRun:
    """Fuzz `target` for `seconds` from the corpus folders (the first one grows), with a
    per-input time-out (s): a step that does unbounded work is a finding."""
    work.mkdir(parents=True, exist_ok=True)
    for c in corpus:
        c.mkdir(parents=True, exist_ok=True)
    cmd = [str(target), f"-max_total_time={int(max(seconds, 1))}", f"-timeout={int(timeout)}",
           "-rss_limit_mb=2048", "-max_len=512", "-print_final_stats=1",
           f"-artifact_prefix={work}/", *map(str, corpus)]
    if jobs > 1:
        cmd += [f"-jobs={jobs}", f"-workers={jobs}"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=work,
                          timeout=seconds + 120)
    text = proc.stderr
    execs = re.findall(r"stat::number_of_executed_units:\s*(\d+)", text)
    covs = re.findall(r"cov: (\d+)", text)
    elapsed = re.findall(r"stat::average_exec_per_sec:\s*(\d+)", text)
    del elapsed
    artifact = re.search(r"Test unit written to (\S+)", text)
    finding = ""
    if proc.returncode != 0:
        m = re.search(r"(==\d+==ERROR.*|.*runtime error.*|ALARM: .*|.*deadly signal.*)", text)
        finding = m.group(0) if m else text[-2000:]
    return FuzzRun(model, seconds, int(execs[-1]) if execs else 0,
                   int(covs[-1]) if covs else 0, proc.returncode, finding,
                   Path(artifact.group(1)) if artifact else None)


def replay(target: Path, inputs: list[Path]) -> subprocess.CompletedProcess:
    """Run the target once on each input (no fuzzing): the regression check."""
    return subprocess.run([str(target), "-runs=0", *map(str, inputs)], capture_output=True,
                          text=True, timeout=600)
