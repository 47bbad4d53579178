"""Fuzz fmi2DeSerializeFMUstate / fmi2SetFMUstate of real FMUs with mutated states.

For each FMU a genuine serialized state (initialized, after a few steps) is mutated:
bit flips, truncations, and for a pythonfmu FMU's JSON state JSON-aware mutations (wrong
types, extra and missing keys, the slave's method names as variable names, huge / NaN /
infinite numbers, wrong list lengths, nested garbage), for a native FMU's binary state
byte-level ones (NaN, infinite or huge doubles, zeroed or random regions, words moved,
garbage appended). Every trial runs deserialize -> set state -> doStep ->
terminate -> free on a fresh instance through fmpy, in a worker subprocess, so a crash
(a signal, an abort) is seen as the worker's exit code; the parent restarts after the
trial that crashed. "crashes" are workers killed by a signal (segfault, abort);
"fatal" are workers ended by an FMI call that failed where the host cannot expect it
(fmi2Fatal from getReal, terminate or free). A trial is "refused" when the FMU logged
that restoring the state failed, else "accepted"; for accepted ones the table says
whether the step went (acc.stepped) and whether the outputs after it are finite.
Run it with an older gyro_fmu first on PYTHONPATH (from a folder other than the
checkout) to fuzz that version: FMUs run the host's gyro_fmu when it has one.

    python benchmarks/fuzz_states.py --trials 1000               # all six FMUs
    python benchmarks/fuzz_states.py --trials 50 --fmu GyroPlant --fmu GyroObserver
"""

from __future__ import annotations

import argparse
import json
import math
import random
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

METHOD_NAMES = ("get_real", "do_step", "set_real", "log", "_set_fmu_state", "__class__",
                "__dict__", "exit_initialization_mode", "vars", "_outputs", "model")
WEIRD = (None, True, "x", [], {}, [1.0], {"a": 1}, 1e308, -1e308, float("nan"),
         float("inf"), -float("inf"), 10**40, -1, 0, 2**63, 1e-320, "NaN")


# --- mutations --------------------------------------------------------------
def _paths(node, path=()):
    yield path
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*path, k))
    elif isinstance(node, list):
        for k, v in enumerate(node):
            yield from _paths(v, (*path, k))


def _get(node, path):
    for p in path:
        node = node[p]
    return node


def _nested(rng: random.Random) -> str:
    """JSON text of garbage nested up to 5000 deep (as text: json.dumps would recurse)."""
    depth = rng.choice((3, 50, 500, 5000))
    text = json.dumps(rng.choice(WEIRD))
    for _ in range(depth):
        text = f"[{text}]" if rng.random() < 0.5 else f'{{"g": {text}}}'
    return text


def binary_mutate(blob: bytes, rng: random.Random) -> bytes:
    """One mutated copy of a native FMU's binary state (fmu_src/fmi/instance_states.c: a
    header, then the model's data): bit flips, truncation, garbage appended, a double
    (8-byte aligned) made NaN, infinite, huge, tiny or negative, a region zeroed or
    random, a word copied elsewhere."""
    data = bytearray(blob)
    kind = rng.randrange(7)
    if kind == 0:
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
    elif kind == 1:
        return blob[:rng.randrange(len(blob))]
    elif kind == 2:
        data += bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
    elif kind == 3:
        weird = (float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 1e-320, -1.0, 0.0)
        for _ in range(rng.randint(1, 4)):
            i = 8 * rng.randrange(len(data) // 8)
            data[i:i + 8] = struct.pack("<d", rng.choice(weird))
    elif kind in (4, 5):
        i = rng.randrange(len(data))
        n = min(rng.randint(1, 256), len(data) - i)
        data[i:i + n] = bytes(n) if kind == 4 else bytes(rng.randrange(256) for _ in range(n))
    else:
        i, j = (8 * rng.randrange(len(data) // 8) for _ in range(2))
        data[j:j + 8] = data[i:i + 8]
    return bytes(data)


def mutate(blob: bytes, rng: random.Random) -> bytes:
    """One mutated copy of a serialized state: JSON-aware for a pythonfmu FMU's state,
    byte-level for a native FMU's binary one."""
    try:
        json.loads(blob)
    except (ValueError, UnicodeDecodeError):
        return binary_mutate(blob, rng)
    kind = rng.randrange(10)
    if kind == 0:  # bit flips
        data = bytearray(blob)
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
        return bytes(data)
    if kind == 1:  # truncation
        return blob[:rng.randrange(len(blob))]
    state = json.loads(blob)
    paths = list(_paths(state))
    path = rng.choice(paths[1:])
    parent, key = _get(state, path[:-1]), path[-1]
    if kind == 2:  # wrong type / weird value at a leaf or subtree
        parent[key] = rng.choice(WEIRD)
    elif kind == 3:  # extra key in some dict
        dicts = [p for p in paths if isinstance(_get(state, p), dict)]
        _get(state, rng.choice(dicts))[rng.choice(("extra", "invalid", "model", "s"))] = \
            rng.choice(WEIRD)
    elif kind == 4:  # missing key
        dicts = [p for p in paths if isinstance(_get(state, p), dict) and _get(state, p)]
        target = _get(state, rng.choice(dicts))
        del target[rng.choice(list(target))]
    elif kind == 5:  # method names as variable names
        for name in rng.sample(METHOD_NAMES, rng.randint(1, 3)):
            state["variables"][name] = rng.choice(WEIRD)
        if rng.random() < 0.5:  # and instead of real ones, so the count still fits
            for name in rng.sample(sorted(state["variables"]), 2):
                if name not in METHOD_NAMES:
                    del state["variables"][name]
    elif kind == 6:  # huge / NaN numbers at number leaves
        numbers = [p for p in paths if isinstance(_get(state, p), (int, float))
                   and not isinstance(_get(state, p), bool)]
        for p in rng.sample(numbers, min(len(numbers), rng.randint(1, 4))):
            _get(state, p[:-1])[p[-1]] = rng.choice(
                (1e300, -1e300, float("nan"), float("inf"), 1e-300, 10**30, -(2**70), 0))
    elif kind == 7:  # wrong list length
        lists = [p for p in paths if isinstance(_get(state, p), list)]
        target = _get(state, rng.choice(lists))
        if target and rng.random() < 0.5:
            target.pop(rng.randrange(len(target)))
        else:
            target.extend([0.0] * rng.choice((1, 2, 100)))
    elif kind == 8:  # nested garbage
        parent[key] = "@@garbage@@"
        return json.dumps(state).replace('"@@garbage@@"', _nested(rng)).encode()
    else:  # flags / times
        field = rng.choice(("flags", "times"))
        state[field] = rng.choice(([None, None, "yes"], [None, None, True, 1], ["x"],
                                   [0.0, float("nan")], [1e308, -1e308], ["a", 3, False],
                                   [None, None, 1], None, [True, False]))
    return json.dumps(state).encode()


# --- worker: trials in this process -----------------------------------------
def _worker(fmu: Path, seed: int, first: int, count: int, h: float) -> None:
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    from gyro_fmu.cosim.instances import LogCollector, fmi2_callbacks

    md = read_model_description(str(fmu))
    folder = extract(str(fmu))
    outputs = [v.valueReference for v in md.modelVariables
               if v.causality == "output" and v.type == "Real"]

    def new(name):
        log = LogCollector()
        cb = fmi2_callbacks(log)
        s = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        s.instantiate(callbacks=cb, loggingOn=True)
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        return s, log, cb

    base, _, _cb = new("base")
    t = 0.0
    for _ in range(5):
        base.doStep(t, h)
        t += h
    blob = bytes(base.serializeFMUstate(base.getFMUstate()))
    base.terminate()
    base.freeInstance()
    for i in range(first, first + count):
        rng = random.Random(f"{seed}-{fmu.stem}-{i}")
        data = mutate(blob, rng)
        print(f"start {i}", flush=True)
        s, log, _keep = new(f"trial{i}")  # the callbacks must outlive the instance
        try:
            state = s.deSerializeFMUstate(data)
            s.setFMUstate(state)
            s.freeFMUstate(state)
        except FMICallException:
            pass
        refused = any("restoring the FMU state failed" in m  # pythonfmu flavour
                      or "deserialize FMU state refused" in m  # native (instance_states.c)
                      for *_, m in log.messages)
        seen = len(log.messages)
        try:
            s.doStep(t, h)
            stepped = True
        except FMICallException:
            stepped = False
        values = s.getReal(outputs)
        finite = all(math.isfinite(v) for v in values)
        s.terminate()
        s.freeInstance()
        why = " ".join(m for *_, m in log.messages[seen:seen + 1]).replace("\n", " ")
        print(f"done {i} {'refused' if refused else 'accepted'} {int(stepped)} {int(finite)} "
              f"{why if not stepped else ''}", flush=True)


# --- parent: batches in subprocesses, crash detection -----------------------
def fuzz(fmu: Path, trials: int, seed: int, batch: int, h: float) -> dict:
    row = {"fmu": fmu.stem, "trials": 0, "refused": 0, "accepted": 0, "crashes": 0, "fatal": 0,
           "accepted_finite": 0, "accepted_stepped": 0, "crashed_trials": [],
           "not_stepped": {}}
    i = 0
    while i < trials:
        n = min(batch, trials - i)
        proc = subprocess.run([sys.executable, __file__, "--worker", str(fmu), "--seed",
                               str(seed), "--first", str(i), "--count", str(n), "--h", str(h)],
                              capture_output=True, text=True)
        last = i
        for line in proc.stdout.splitlines():
            parts = line.split()
            if parts[:1] == ["start"]:
                last = int(parts[1])
            elif parts[:1] == ["done"]:
                row["trials"] += 1
                row[parts[2]] += 1
                if parts[2] == "accepted":
                    row["accepted_stepped"] += int(parts[3])
                    row["accepted_finite"] += int(parts[4])
                    if parts[3] == "0":  # why an accepted state did not step
                        why = " ".join(parts[5:])[:100]
                        row["not_stepped"][why] = row["not_stepped"].get(why, 0) + 1
                last = int(parts[1]) + 1
        if proc.returncode != 0:
            kind = "fatal" if proc.returncode == 1 else "crashes"
            if last >= i + n:  # every trial done: the crash was at exit
                row[kind] += 1
                row["crashed_trials"].append(f"exit after {last - 1}: {proc.returncode}")
            else:
                row["trials"] += 1
                row[kind] += 1
                row["crashed_trials"].append(f"{last}: exit {proc.returncode} "
                                             f"{proc.stderr.strip()[-200:]}")
                last += 1
        i = last if last > i else i + n
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=1000, help="per FMU")
    ap.add_argument("--fmu", action="append", help="FMU name (default: all six)")
    ap.add_argument("--models", type=Path, help="folder of built FMUs (default: build now)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--batch", type=int, default=100)
    ap.add_argument("--h", type=float, default=None, help="step size (default: the FMU's)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--first", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--count", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        _worker(args.worker, args.seed, args.first, args.count, args.h)
        return
    rows = run(args.fmu, args.trials, args.seed, args.batch, args.models)
    if args.json:
        print(json.dumps(rows))
        return
    print(f"{'FMU':14} {'trials':>6} {'refused':>7} {'accepted':>8} {'crashes':>7} "
          f"{'fatal':>5} {'acc.stepped':>11} {'acc.finite':>10}")
    for r in rows:
        print(f"{r['fmu']:14} {r['trials']:6} {r['refused']:7} {r['accepted']:8} "
              f"{r['crashes']:7} {r['fatal']:5} {r['accepted_stepped']:11} "
              f"{r['accepted_finite']:10}")
        for c in r["crashed_trials"]:
            print(f"  crash at trial {c}")
        for why, n in sorted(r["not_stepped"].items(), key=lambda kv: -kv[1])[:3]:
            print(f"  accepted, then the step refused ({n}x): {why}")


def run(names, trials: int, seed: int = 0, batch: int = 100, models: Path | None = None):
    """One table row per FMU (dicts); builds the FMUs into a temp folder if not given."""
    from fmpy import read_model_description

    from gyro_fmu.fmu.build import FMU_NAMES, build_all

    names = names or list(FMU_NAMES)
    with tempfile.TemporaryDirectory() as tmp:
        if models is None:
            models = Path(tmp)
            build_all(models)
        rows = []
        for name in names:
            fmu = models / f"{name}.fmu"
            h = float(read_model_description(str(fmu)).defaultExperiment.stepSize)
            rows.append(fuzz(fmu, trials, seed, batch, h))
    return rows


if __name__ == "__main__":
    main()
