"""A thin fmpy harness for poking one FMU instance directly (state, bad input)."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from gyro_fmu.cosim.master import LogCollector, fmi2_callbacks


class Instance:
    """One instantiated FMU with name-based access and its own log."""

    def __init__(self, path: Path, name: str = "inst", parameters: dict | None = None,
                 initialize: bool = True) -> None:
        self.md = read_model_description(str(path))
        self.dir = extract(str(path))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.log = LogCollector()
        self._callbacks = fmi2_callbacks(self.log)
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                               modelIdentifier=self.md.coSimulation.modelIdentifier,
                               instanceName=name)
        self.name = name
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=True)
        self.slave.setupExperiment(startTime=0.0)
        self.set(parameters or {})
        if initialize:
            self.initialize()
        self.t = 0.0

    def initialize(self) -> None:
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def set(self, values: dict) -> None:
        for name, value in values.items():
            v = self.vars[name]
            if v.type == "Integer":
                self.slave.setInteger([v.valueReference], [int(value)])
            else:
                self.slave.setReal([v.valueReference], [float(value)])

    def get(self, names) -> list[float]:
        return self.slave.getReal([self.vars[n].valueReference for n in names])

    def step(self, h: float) -> int:
        """Do one step; returns the FMI status (0 ok, 2 discard, ...)."""
        try:
            self.slave.doStep(self.t, h)
        except FMICallException as exc:
            return exc.status
        self.t += h
        return 0

    def messages(self, min_status: int = 1) -> str:
        return "\n".join(m for _, s, _, m in self.log.messages if s >= min_status)

    def category(self, category: str) -> str:
        return "\n".join(m for _, _, c, m in self.log.messages if c == category)

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def run_steps(inst: Instance, n: int, h: float, outputs: list[str], inputs=None) -> np.ndarray:
    """n steps of h, inputs(t) set before each; the outputs after each, one row per step."""
    rows = []
    for _ in range(n):
        if inputs is not None:
            inst.set(inputs(inst.t))
        assert inst.step(h) == 0
        rows.append(inst.get(outputs))
    return np.array(rows)


def assert_state_round_trip(fmu: Path, params: dict, outputs: list[str], inputs, h: float,
                            before: int, after: int) -> None:
    """Run `before` steps, save; run `after`; restore, run again: the same bits. The same
    after serialize -> deserialize into a fresh instance with the same parameters."""
    a = Instance(fmu, "a", params)
    run_steps(a, before, h, outputs, inputs)
    state = a.slave.getFMUstate()
    t1 = a.t
    first = run_steps(a, after, h, outputs, inputs)
    a.slave.setFMUstate(state)
    a.t = t1
    assert np.array_equal(first, run_steps(a, after, h, outputs, inputs))
    blob = a.slave.serializeFMUstate(state)
    a.slave.freeFMUstate(state)
    b = Instance(fmu, "b", params)
    b.slave.setFMUstate(b.slave.deSerializeFMUstate(blob))
    b.t = t1
    assert np.array_equal(first, run_steps(b, after, h, outputs, inputs))
    assert b.messages(min_status=3) == ""
    a.close()
    b.close()


def assert_bad_input_refused(fmu: Path, params: dict, action: tuple, message: str,
                             h: float) -> None:
    """One bad value: the FMU logs `message`, the step does not advance, a bad input is
    recoverable, and the instance can still be terminated and freed. A refused input or
    value discards the next step (fmi2Discard, traceback in logDebug); a fixed parameter set
    after initialization, a step size that is not > 0, or a step of an instance whose
    initialization failed, is an illegal call refused at once (fmi2Error), as the native
    FMUs do.

    action: ("input" | "after_init", variable, value): set it after initialization;
    ("step", step size, None): a good step, then one of that size;
    ("init", None, None): the parameters alone must make every step fail.
    """
    inst = Instance(fmu, "bad", params)
    kind, what, value = action
    outputs = [v for v, x in inst.vars.items() if x.causality == "output"]
    before = inst.get(outputs)
    if kind == "step":
        inst.slave.doStep(0.0, h)  # a good step first
        inst.t = h
        assert inst.step(what) == 3
    elif kind == "init":
        assert inst.step(h) == 3  # the instance failed: refused, in error mode
    elif kind == "after_init":  # a call the standard forbids: fmi2Error, nothing changed
        try:
            inst.set({what: value})
            raise AssertionError(f"setting {what} after initialization was accepted")
        except FMICallException as exc:
            assert exc.status == 3
    else:
        inst.set({what: value})
        assert inst.step(h) == 2  # fmi2Discard, the state kept
        from gyro_fmu.pythonfmu.slave import DEBUG_CATEGORY  # a pythonfmu slave's traceback

        assert "Traceback" in inst.category(DEBUG_CATEGORY)
    text = inst.messages()
    assert message in text, text
    if kind == "input":
        assert np.array_equal(np.array(before), np.array(inst.get(outputs)))  # not advanced
        assert inst.step(h) == 0  # recoverable: the next step goes on
    inst.close()  # fmi2Terminate and fmi2FreeInstance after the error


#: Hostile archive members `hostile_archive` adds, and what validate must say of each.
HOSTILE_MEMBERS = {"dotdot": "outside the FMU's folder", "symlink": "is a symbolic link",
                   "many": "more than the 10000"}


def hostile_archive(fmu: Path, kind: str, dest: Path) -> Path:
    """A copy of fmu at dest with one hostile member added: "dotdot" (../evil.txt),
    "symlink" (resources/link to /etc/passwd) or "many" (10,001 more members)."""
    shutil.copy(fmu, dest)
    with zipfile.ZipFile(dest, "a") as z:
        if kind == "dotdot":
            z.writestr("../evil.txt", "x")
        elif kind == "symlink":
            info = zipfile.ZipInfo("resources/link")
            info.external_attr = 0o120777 << 16
            z.writestr(info, "/etc/passwd")
        elif kind == "many":
            for i in range(10_001):
                z.writestr(f"extra/f{i}", "")
        else:
            raise ValueError(f"kind={kind!r}: use one of {sorted(HOSTILE_MEMBERS)}")
    return dest
