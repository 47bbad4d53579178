"""Coverage-guided fuzzing of every native FMU's own C sources with address and
undefined-behaviour sanitizers (tests/fuzz_harness.py): a short run per FMU from the
checked-in corpus (tests/fuzz/corpus/), and every input that ever found a defect
(tests/fuzz/regressions/) replayed. Long runs: benchmarks/fuzz_native.py. Skipped, with
the reason, where clang with libFuzzer cannot be had."""

from __future__ import annotations

import shutil
from pathlib import Path

import fuzz_harness
import pytest

#: Seconds of fuzzing per FMU in the suite (the corpus replays first); the benchmark
#: runs minutes.
SECONDS = 4


class Targets:
    """Each FMU's fuzz target, built once per session on first use."""

    def __init__(self, folder: Path) -> None:
        self.folder, self.built = folder, {}

    def __getitem__(self, model: str) -> Path:
        if model not in self.built:
            self.built[model] = fuzz_harness.build(model, self.folder)
        return self.built[model]


@pytest.fixture(scope="module")
def targets(tmp_path_factory: pytest.TempPathFactory) -> Targets:
    why = fuzz_harness.problem()
    if why:
        pytest.skip(f"no libFuzzer here: {why}")
    return Targets(tmp_path_factory.mktemp("fuzz"))


@pytest.mark.parametrize("model", fuzz_harness.MODELS)
def test_a_short_fuzz_run_finds_nothing(targets, model, tmp_path):
    target = targets[model]
    corpus = tmp_path / "corpus"
    shutil.copytree(fuzz_harness.CORPUS / model, corpus)  # the checked-in one stays as is
    assert len(list(corpus.iterdir())) >= 10, "the checked-in corpus is missing"
    run = fuzz_harness.run(target, model, SECONDS, [corpus], tmp_path / "work")
    assert run.returncode == 0 and not run.finding, (
        f"{model}: {run.finding}\ninput: {run.artifact} (copy it into "
        f"tests/fuzz/regressions/{model}/ once fixed)")
    assert run.executions > 100 and run.edges > 100


def test_every_input_that_found_a_defect_replays_clean(targets):
    """The defects the fuzzer found in 0.4.0 (unbounded held-step sub-steps, the sideband
    loop, inf norms, unchecked restored states) stay fixed."""
    found = sorted(p for p in fuzz_harness.REGRESSIONS.glob("*/*") if p.is_file())
    models = sorted({p.parent.name for p in found})
    assert {"GyroObserver", "GyroLoops", "GyroResonator"} <= set(models)
    for model in models:
        target = targets[model]
        proc = fuzz_harness.replay(target, [p for p in found if p.parent.name == model])
        assert proc.returncode == 0, f"{model}: {proc.stderr[-3000:]}"
