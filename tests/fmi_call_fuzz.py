"""Call-sequence fuzzer of the native FMI layer, run in a child process by the tests
(tests/test_native_fmi_layer.py): random legal and illegal sequences of FMI 2.0 or 3.0 calls
straight through ctypes, each status checked against the standard's state machine.

usage: python fmi_call_fuzz.py UNZIPDIR FMI_VERSION SEED SEQUENCES CALLS [FLAVOUR]
FLAVOUR pythonfmu leaves out one call: a NaN set, which that flavour accepts and refuses at
the next step (its documented semantics, tested in test_fmu_quality.py), where the native
layer refuses the set itself.
Prints one JSON line {"calls": N, "mismatches": [...], "by_call": {...}}; a crash shows as
the child's exit code.
"""

from __future__ import annotations

import ctypes
import json
import math
import random
import sys
from ctypes import byref, c_bool, c_char_p, c_double, c_int, c_size_t, c_uint32, c_void_p
from pathlib import Path

from fmpy import read_model_description

INST, INIT, STEP, TERM, ERROR = "instantiated", "init", "step", "terminated", "error"
OK, ERR = "ok", "error"
OPS = ["setup", "enter", "exit", "step", "badstep", "set_input", "set_bad_input", "set_output",
       "set_param", "get", "get_unknown", "terminate", "reset", "get_state", "set_state",
       "free_state", "free_dead_state"]


def main() -> None:
    unzipdir, version, seed, n_seq, n_calls = (sys.argv[1], int(sys.argv[2]), int(sys.argv[3]),
                                               int(sys.argv[4]), int(sys.argv[5]))
    flavour = sys.argv[6] if len(sys.argv) > 6 else "native"
    md = read_model_description(unzipdir)
    ident = md.coSimulation.modelIdentifier
    folder = "linux64" if version == 2 else "x86_64-linux"
    lib = ctypes.CDLL(str(Path(unzipdir) / "binaries" / folder / f"{ident}.so"))
    variables = [v for v in md.modelVariables if v.name != "time"]
    reals = [v for v in variables if v.type in ("Real", "Float64")]
    # steps every FMU takes: 5 and 10 us, or for one whose default step is 1e-4 s or more
    # (GyroSensor: a host's step, at least its internal one) that step and twice it
    default_step = float(md.defaultExperiment.stepSize)
    good_steps = [default_step, 2 * default_step] if default_step >= 1e-4 else [5e-6, 1e-5]
    rng = random.Random(seed)
    LOG = ctypes.CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p)
    LOG3 = ctypes.CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
    log2, log3 = LOG(lambda *a: None), LOG3(lambda *a: None)

    class Callbacks(ctypes.Structure):
        _fields_ = [("logger", LOG), ("allocateMemory", c_void_p), ("freeMemory", c_void_p),
                    ("stepFinished", c_void_p), ("componentEnvironment", c_void_p)]

    libc = ctypes.CDLL(None)  # FMI 2.0 hosts must give allocateMemory and freeMemory
    callbacks = Callbacks(log2, ctypes.cast(libc.calloc, c_void_p),
                          ctypes.cast(libc.free, c_void_p), None, None)
    p = "fmi2" if version == 2 else "fmi3"
    f = {name: getattr(lib, p + name) for name in (
        "FreeInstance", "Terminate", "Reset", "GetFMUstate" if version == 2 else "GetFMUState",
        "SetFMUstate" if version == 2 else "SetFMUState",
        "FreeFMUstate" if version == 2 else "FreeFMUState", "DoStep", "ExitInitializationMode",
        "EnterInitializationMode")}
    for fn in f.values():
        fn.restype = c_int if fn is not f["FreeInstance"] else None
    f["FreeInstance"].argtypes = [c_void_p]
    get_real = getattr(lib, p + ("GetReal" if version == 2 else "GetFloat64"))
    set_real = getattr(lib, p + ("SetReal" if version == 2 else "SetFloat64"))
    set_int = getattr(lib, p + ("SetInteger" if version == 2 else "SetInt32"))
    for fn in (get_real, set_real, set_int):
        fn.restype = c_int

    def instantiate():
        if version == 2:
            fn = lib.fmi2Instantiate
            fn.restype = c_void_p
            fn.argtypes = [c_char_p, c_int, c_char_p, c_char_p, c_void_p, c_int, c_int]
            resources = (Path(unzipdir) / "resources").as_uri().encode()
            return fn(b"fuzz", 1, md.guid.encode(), resources, ctypes.addressof(callbacks), 0, 0)
        fn = lib.fmi3InstantiateCoSimulation
        fn.restype = c_void_p
        fn.argtypes = [c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_bool, c_bool, c_void_p,
                       c_size_t, c_void_p, LOG3, c_void_p]
        return fn(b"fuzz", md.guid.encode(), unzipdir.encode(), False, False, False, False,
                  None, 0, None, log3, None)

    def refs(vs):
        return (c_uint32 * len(vs))(*vs)

    calls, mismatches, by_call = 0, [], {}
    for _ in range(n_seq):
        c = c_void_p(instantiate())
        mode, saved, live_states, dead_states = INST, {}, [], []
        history = []
        for _ in range(n_calls):
            op = rng.choice(OPS if flavour == "native" else
                            [o for o in OPS if o != "set_bad_input"])
            history.append(op)
            expect, new_mode = ERR, mode
            if op == "setup":
                if version == 2:
                    lib.fmi2SetupExperiment.restype = c_int
                    s = lib.fmi2SetupExperiment(c, 0, c_double(0), c_double(0.0), 0, c_double(0))
                    expect = OK if mode == INST else ERR
                else:
                    continue
            elif op == "enter":
                if version == 2:
                    s = f["EnterInitializationMode"](c)
                else:
                    s = lib.fmi3EnterInitializationMode(c, c_bool(False), c_double(0),
                                                        c_double(0.0), c_bool(False), c_double(0))
                expect, new_mode = (OK, INIT) if mode == INST else (ERR, mode)
            elif op == "exit":
                s = f["ExitInitializationMode"](c)
                expect, new_mode = (OK, STEP) if mode == INIT else (ERR, mode)
            elif op in ("step", "badstep"):
                h = rng.choice(good_steps) if op == "step" else rng.choice(
                    [0.0, -1e-6, math.nan, math.inf])
                if version == 2:
                    s = f["DoStep"](c, c_double(0.0), c_double(h), 1)
                else:
                    b = c_bool()
                    t = c_double()
                    s = f["DoStep"](c, c_double(0.0), c_double(h), c_bool(True), byref(b),
                                    byref(b), byref(b), byref(t))
                expect = OK if (mode == STEP and op == "step") else ERR
            elif op in ("set_input", "set_bad_input", "set_output", "set_param"):
                kind = op[4:]
                pool = {"input": [v for v in reals if v.causality == "input"],
                        "bad_input": [v for v in reals if v.causality != "output"],
                        "output": [v for v in reals if v.causality == "output"],
                        "param": [v for v in variables if v.causality == "parameter"]}[kind]
                if not pool:
                    continue
                v = rng.choice(pool)
                value = {"bad_input": math.nan}.get(kind, float(v.start or 0.0))
                vr = refs([v.valueReference])
                if v.type in ("Integer", "Int32"):
                    arr = (ctypes.c_int32 * 1)(int(value))
                    s = set_int(c, vr, c_size_t(1), arr, *([c_size_t(1)] if version == 3 else []))
                else:
                    arr = (c_double * 1)(value)
                    s = set_real(c, vr, c_size_t(1), arr, *([c_size_t(1)] if version == 3 else []))
                settable = {INST, INIT, STEP} if v.causality == "input" else {INST, INIT}
                expect = OK if (kind in ("input", "param") and mode in settable) else ERR
            elif op in ("get", "get_unknown"):
                vr = refs([reals[0].valueReference if op == "get" else 9999])
                out = (c_double * 1)()
                s = get_real(c, vr, c_size_t(1), out, *([c_size_t(1)] if version == 3 else []))
                expect = OK if (op == "get" and mode in (INIT, STEP, TERM, ERROR)) else ERR
            elif op == "terminate":
                s = f["Terminate"](c)
                expect, new_mode = (OK, TERM) if mode in (STEP, ERROR) else (ERR, mode)
            elif op == "reset":
                s = f["Reset"](c)
                expect, new_mode = OK, INST
            elif op == "get_state":
                st = c_void_p()
                s = f["GetFMUstate" if version == 2 else "GetFMUState"](c, byref(st))
                expect = OK
                live_states.append(st.value)
                saved[st.value] = mode
                if st.value in dead_states:  # malloc gave a freed address again
                    dead_states.remove(st.value)
            elif op == "set_state":
                if not live_states:
                    continue
                st = rng.choice(live_states)
                s = f["SetFMUstate" if version == 2 else "SetFMUState"](c, c_void_p(st))
                expect, new_mode = OK, saved[st]
            elif op == "free_state":
                if not live_states:
                    continue
                st = live_states.pop(rng.randrange(len(live_states)))
                ptr = c_void_p(st)
                s = f["FreeFMUstate" if version == 2 else "FreeFMUState"](c, byref(ptr))
                expect = OK
                dead_states.append(st)
            else:  # a state freed already: refused, never used
                if not dead_states:
                    continue
                ptr = c_void_p(rng.choice(dead_states))
                s = f["FreeFMUstate" if version == 2 else "FreeFMUState"](c, byref(ptr))
                expect = ERR
            calls += 1
            got = OK if s in (0, 1) else ERR if s == 3 else f"status {s}"
            by_call.setdefault(op, [0, 0])[0 if got == OK else 1] += 1
            if got != expect:
                mismatches.append({"call": op, "mode": mode, "expected": expect, "got": got,
                                   "history": history[-6:]})
            if got == OK:
                mode = new_mode
        f["FreeInstance"](c)
        f["FreeInstance"](c)  # a double free: ignored
    print(json.dumps({"calls": calls, "mismatches": mismatches[:20],
                      "n_mismatches": len(mismatches), "by_call": by_call}))


if __name__ == "__main__":
    main()
