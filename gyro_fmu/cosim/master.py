"""A fixed-step co-simulation master on fmpy: any FMI 2.0 CS FMUs, any connections.

Each communication step is a Jacobi step: read every output at t, set every
connected input, then step every FMU from t to t+h. All inputs are therefore
the values at t, held over the step, which is what GyroPlant and GyroObserver
assume. Per step and FMU there is one getReal (all needed outputs) and one
setReal (all its connected inputs): the fewest calls FMI 2.0 allows.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from ctypes import c_void_p, cast

import numpy as np
from fmpy.fmi2 import (  # type: ignore[attr-defined]
    FMU2Slave,
)

from ..interrupts import hold_signals, restore_signals
from .instances import (
    Instance,
    LogCollector,
    fmi2_callbacks,
    initialize,
    instantiate,
    release,
    split_reference,
    units_of,
    variable,
)
from .stepping import GET, SET, make_plan, step_loop
from .system import (
    Component,
    Connection,
    CoSimulationError,
    CoSimulationInterrupted,
    CoSimulationResult,
)

__all__ = [
    "CoSimulationError",
    "CoSimulationInterrupted",
    "CoSimulationResult",
    "Component",
    "Connection",
    "LogCollector",
    "fmi2_callbacks",
    "run_cosimulation",
    "whole_steps",
]


def run_cosimulation(
    components: Sequence[Component],
    connections: Sequence[Connection],
    stop_time: float,
    step: float,
    start_time: float = 0.0,
    record: Sequence[str] | None = None,
    max_result_bytes: int | None = None,
    sink: Callable[[np.ndarray, int], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
    on_columns: Callable[[tuple[str, ...], dict[str, str]], None] | None = None,
) -> CoSimulationResult:
    """Run the coupled FMUs with a fixed communication step and record signals.

    record: "instance.variable" names to keep; by default every output of every FMU.
    Returns values at the n + 1 communication points start_time + k * step.
    max_result_bytes: refuse (before allocating) a result table larger than this
    (default: half the physical memory, `result_memory_limit`).
    sink: instead of keeping them, hand the recorded rows on as they are made,
    sink(rows, k) with rows[i] the point k + i (time and the recorded columns; a view
    valid during the call), so memory does not grow with the run; the result then
    holds the final point only.
    progress: called after each chunk of steps with (points done, points in all).
    on_columns: called once before the first step with the recorded columns ("time"
    first) and their units, e.g. for a sink to write a header.
    Ctrl-C stops the run between chunks of steps and raises CoSimulationInterrupted
    (a KeyboardInterrupt) carrying the points simulated so far.
    """
    if not step > 0.0:
        raise CoSimulationError(f"communication step {step!r} s must be > 0")
    if not stop_time > start_time:
        raise CoSimulationError(f"stop time {stop_time!r} s must be after start time {start_time}")
    names = [c.name for c in components]
    if len(set(names)) != len(names):
        raise CoSimulationError(f"instance names must be unique, got {names}")
    n_steps = whole_steps(stop_time - start_time, step)
    logger = LogCollector()
    callbacks = fmi2_callbacks(logger)
    instances: dict[str, Instance] = {}
    with _interrupt_between_chunks() as interrupted:
        try:
            for comp in components:
                instances[comp.name] = instantiate(comp, callbacks)
            outputs = _OutputTable(instances)
            wiring = _wire(outputs, connections)
            columns, getters = _recording(outputs, record)
            plan = _Plan(instances, outputs, wiring, getters, n_steps, max_result_bytes, sink)
            if on_columns is not None:
                on_columns(tuple(columns), units_of(instances))
            for name, inst in instances.items():
                targets = map(split_reference, (c.dst for c in connections))
                connected = {var for inst_name, var in targets if inst_name == name}
                initialize(inst, start_time, stop_time, logger, connected)
            if interrupted():
                raise CoSimulationInterrupted("co-simulation interrupted during start-up, "
                                              "before the first step")
            k, phase, index, status = plan.run(start_time, step, interrupted, progress)
            result = CoSimulationResult(tuple(columns), plan.result(k), units_of(instances))
            if interrupted():  # Ctrl-C wins over a refusal in the same chunk
                raise CoSimulationInterrupted(
                    f"co-simulation interrupted at t = {start_time + k * step:.9g} s of "
                    f"{stop_time:g} s", result)
            if phase >= 0:
                raise plan.refusal(k, phase, index, status, start_time + k * step, logger)
            return result
        finally:
            for inst in instances.values():
                release(inst)


def whole_steps(duration: float, step: float) -> int:
    """The number of communication steps in `duration`; refuses a step that does not
    divide it (rounding would move the end of the run without a word)."""
    n = round(duration / step)
    if n < 1 or abs(n * step - duration) > 1e-9 * max(duration, step):
        lower, upper = max(1, math.floor(duration / step)), math.ceil(duration / step)
        raise CoSimulationError(
            f"the communication step {step!r} s does not divide the run of {duration!r} s "
            f"({duration / step:.6g} steps): use a stop time of {lower * step:.9g} s or "
            f"{upper * step:.9g} s, or a step that divides {duration!r} s")
    return n


def check_result_memory(points: float, signals: int, max_bytes: int | None = None, *,
                        what: str = "the results", remedy: str | None = None) -> None:
    """Refuse, before allocating, a table of `points` x `signals` floats larger than
    max_bytes (default `result_memory_limit()`): numpy would fail with a MemoryError or
    the machine would swap. `what` and `remedy` word the refusal for the caller."""
    limit = result_memory_limit() if max_bytes is None else max_bytes
    needed = float(points) * signals * 8
    if needed > limit:
        remedy = remedy or ("shorten the run or lengthen the step, record fewer signals "
                            "(run_cosimulation(record=[...])), or run it in pieces")
        raise CoSimulationError(
            f"{what} would need {needed / 2**30:.3g} GiB ({float(points):.4g} points x "
            f"{signals} signals x 8 bytes), more than the limit of {limit / 2**30:.3g} GiB "
            f"(half this machine's memory): {remedy}")


def result_memory_limit() -> int:
    """Bytes the recorded results may take: half the machine's physical memory."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2
    except (ValueError, OSError, AttributeError):
        return 8 << 30


#: Communication steps per call of the C loop (~0.1 s of the default system).
_CHUNK = 2000


@contextmanager
def _interrupt_between_chunks() -> Iterator[Callable[[], bool]]:
    """Record Ctrl-C (and SIGTERM where the caller handles it in Python, as the CLI does)
    instead of raising it, so that it stops the loop between chunks.

    Raised at once, KeyboardInterrupt would land inside an FMU's Python callback,
    where pythonfmu turns it into fmi2Fatal. Only in the main thread, and only for a
    signal whose handler is Python's (a background job's SIGINT is ignored: it stays so).
    """
    caught: list[int] = []
    replaced = hold_signals(lambda n, frame: caught.append(n))
    try:
        yield lambda: bool(caught)
    finally:
        restore_signals(replaced)


#: fmi2Status codes above fmi2Warning, as the standard names them.
_STATUS = {2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal", 5: "fmi2Pending"}


class _Plan:
    """Memory layout and raw FMI entry points of the C stepping loop (stepping.py).

    Row layout: time, then each instance's outputs as one contiguous block (the recorded
    ones first, in recording order, then those read only for connections), so each
    instance fills its block with a single fmi2GetReal straight into the result array.
    A destination whose sources sit in consecutive columns is set from the row itself;
    otherwise its values are gathered into a small buffer first. The loop makes the FMI
    calls the master always made (one getReal per FMU with outputs, one setReal per
    connected FMU, one doStep per FMU), each a direct call of the FMU's function.
    """

    def __init__(self, instances: dict[str, Instance], outputs: _OutputTable, wiring: dict,
                 getters: list[tuple[str, int]], n_steps: int,
                 max_result_bytes: int | None = None,
                 sink: Callable[[np.ndarray, int], None] | None = None) -> None:
        # outputs.add registered (instance, variable) -> position in inst.out_vrs
        recorded = [(name, instances[name].out_vrs[i]) for name, i in getters]
        column: dict[tuple[str, int], int] = {}
        gets: list[tuple[FMU2Slave, list[int], int, str]] = []
        ncol = 1
        for name, inst in instances.items():
            start = ncol
            order = [vr for n, vr in recorded if n == name]
            order += [vr for vr in inst.out_vrs if vr not in order]
            for vr in order:
                if (name, vr) not in column:
                    column[(name, vr)] = ncol
                    ncol += 1
            vrs = [vr for vr in order if column[(name, vr)] >= start]
            if vrs:
                gets.append((inst.slave, vrs, start, name))
        sets: list[tuple[FMU2Slave, list[int], list[int], str]] = []
        for dst, (in_vrs, sources) in wiring.items():
            cols = [column[(s, instances[s].out_vrs[i])] for s, i in sources]
            sets.append((instances[dst].slave, in_vrs, cols, dst))
        self._vrs = [np.array(vrs, dtype=np.uint32) for _, vrs, _, _ in gets + sets]
        self.get_names = [name for *_, name in gets]
        self.set_names = [name for *_, name in sets]
        self.step_names = list(instances)
        self.step_fmus = [inst.component.fmu.name for inst in instances.values()]
        first = np.cumsum([0] + [len(cols) for _, _, cols, _ in sets])
        self.args = (
            _entry_points([s for s, *_ in gets], "fmi2GetReal"),
            _components([s for s, *_ in gets]),
            _addresses(self._vrs[: len(gets)]),
            np.array([len(vrs) for _, vrs, _, _ in gets], dtype=np.int64),
            np.array([start for _, _, start, _ in gets], dtype=np.int64),
            _entry_points([s for s, *_ in sets], "fmi2SetReal"),
            _components([s for s, *_ in sets]),
            _addresses(self._vrs[len(gets):]),
            np.array([len(cols) for _, _, cols, _ in sets], dtype=np.int64),
            np.array([cols[0] if cols == list(range(cols[0], cols[0] + len(cols))) else -1
                      for _, _, cols, _ in sets], dtype=np.int64),
            first[:-1].astype(np.int64),
            np.array([c for _, _, cols, _ in sets for c in cols], dtype=np.int64),
            np.empty(int(first[-1])),
            _entry_points([inst.slave for inst in instances.values()], "fmi2DoStep"),
            _components([inst.slave for inst in instances.values()]),
        )
        self.plan = make_plan(*self.args)
        self.n_steps, self.sink = n_steps, sink
        rows = n_steps + 1 if sink is None else min(n_steps + 1, _CHUNK)
        check_result_memory(rows, ncol, max_result_bytes)
        self.data = np.empty((rows, ncol))
        wanted = [0] + [column[r] for r in recorded]
        self._wanted = None if wanted == list(range(ncol)) else np.array(wanted, dtype=np.intp)

    def run(self, start_time: float, step: float, interrupted: Callable[[], bool],
            progress: Callable[[int, int], None] | None = None) -> tuple[int, int, int, int]:
        """Every communication step, in chunks of _CHUNK steps, stopping after the chunk
        in which a call was refused or Ctrl-C came (`interrupted`). Returns (index of the
        last row read, phase, call index, status); phase -1 when nothing was refused."""
        n = self.n_steps
        for first in range(0, n + 1, _CHUNK):
            row0 = 0 if self.sink is None else first
            outcome = step_loop(self.data, start_time, step, first,
                                min(first + _CHUNK - 1, n), self.plan, row0, n)
            if self.sink is not None:  # the rows read, the refused one's included
                self.sink(self._recorded(self.data[: outcome[0] - first + 1]), first)
                self.last = (outcome[0], outcome[0] - first)
            if progress is not None:
                progress(outcome[0] + 1, n + 1)
            if outcome[1] >= 0 or interrupted():
                return outcome
        return outcome

    def refusal(self, k: int, phase: int, index: int, status: int, t: float,
                logger: LogCollector) -> CoSimulationError:
        """The error for call `index` of `phase` refused at step k (time t), quoting the FMU."""
        status_name = _STATUS.get(status, str(status))
        if phase == GET:
            name = self.get_names[index]
            what = f"{name} refused fmi2GetReal at t={t:.9g} s ({status_name})"
        elif phase == SET:
            name = self.set_names[index]
            what = f"{name} refused fmi2SetReal at t={t:.9g} s ({status_name})"
        else:
            name = self.step_names[index]
            what = (f"{name} ({self.step_fmus[index]}) refused the step at t={t:.9g} s "
                    f"(fmi2DoStep returned {status_name})")
        return CoSimulationError(f"{what}; it said:\n{logger.recent(name)}")

    def result(self, k: int) -> np.ndarray:
        """The recorded columns of points 0..k, in the order asked for (no copy in the
        default layout); of point k alone when a sink took the rows."""
        if self.sink is not None:
            row = self.last[1]
            return self._recorded(self.data[row: row + 1]).copy()
        return self._recorded(self.data[: k + 1])

    def _recorded(self, data: np.ndarray) -> np.ndarray:
        return data if self._wanted is None else data[:, self._wanted]


def _entry_points(slaves: Iterable[FMU2Slave], function: str) -> np.ndarray:
    """Addresses of one FMI function in each FMU's shared library."""
    return np.array([cast(getattr(s.dll, function), c_void_p).value for s in slaves],
                    dtype=np.int64)


def _components(slaves: Iterable[FMU2Slave]) -> np.ndarray:
    """The fmi2Component handle of each instance, as an integer."""
    return np.array([cast(s.component, c_void_p).value for s in slaves], dtype=np.int64)


def _addresses(arrays: Sequence[np.ndarray]) -> np.ndarray:
    return np.array([a.ctypes.data for a in arrays], dtype=np.int64)


class _OutputTable:
    """Which outputs each instance must deliver per step (one getReal each)."""

    def __init__(self, instances: dict[str, Instance]) -> None:
        self.instances = instances
        self._index: dict[tuple[str, str], int] = {}

    def instance(self, ref: str) -> tuple[str, str]:
        name, var = split_reference(ref)
        if name not in self.instances:
            raise CoSimulationError(f"{ref!r}: no instance {name!r}; have {sorted(self.instances)}")
        return name, var

    def add(self, ref: str) -> tuple[str, int]:
        """Register output `ref`; returns (instance, position in its getReal result)."""
        name, var = self.instance(ref)
        inst = self.instances[name]
        if (name, var) not in self._index:
            v = variable(inst, var, ("output",), ref)
            self._index[(name, var)] = len(inst.out_vrs)
            inst.out_vrs.append(v.valueReference)
        return name, self._index[(name, var)]


def _wire(outputs: _OutputTable, connections: Sequence[Connection]) -> dict:
    """Per destination: its input value references and (source, output index) pairs."""
    wiring: dict[str, tuple[list[int], list[tuple[str, int]]]] = {}
    seen: set[str] = set()
    for conn in connections:
        source = outputs.add(conn.src)
        dst_name, dst_var = outputs.instance(conn.dst)
        if conn.dst in seen:
            raise CoSimulationError(f"input {conn.dst!r} is connected twice")
        seen.add(conn.dst)
        v = variable(outputs.instances[dst_name], dst_var, ("input",), conn.dst)
        in_vrs, sources = wiring.setdefault(dst_name, ([], []))
        in_vrs.append(v.valueReference)
        sources.append(source)
    return wiring


def _recording(outputs: _OutputTable, record: Sequence[str] | None):
    if record is None:
        record = [f"{n}.{v.name}" for n, inst in outputs.instances.items()
                  for v in inst.variables.values() if v.causality == "output" and v.type == "Real"]
    return ["time", *record], [outputs.add(ref) for ref in record]
