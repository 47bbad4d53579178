"""FMU state checks: only what the slave itself saves may be restored into it.

fmi2DeSerializeFMUstate takes bytes from anywhere. A state naming the
slave's own methods as `variables` used to be setattr'ed onto it (fmi2Fatal, then a crash at
fmi2Terminate), and a library model state of the wrong shape would have reached numba
kernels, which have no bounds checks. So `restore` accepts exactly the structure that
GyroSlave._get_fmu_state writes: the declared variables with their types and ranges, the
flags [str|None, str|None, bool], two finite times, and a library model state with the
structure (dict keys, list lengths, leaf types, finite numbers) of the one a freshly set
up model has. Nothing is changed unless all of it fits; the caller reports the
StateError (fmi2Error log, the instance failed, outputs NaN).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

from ..errors import GyroFmuError

KEYS = ("variables", "flags", "times", "model")


class StateError(GyroFmuError, ValueError):
    """A state that this FMU did not save, or saved by another FMU / parameter set."""


def _kind(value: Any) -> str:
    return "null" if value is None else type(value).__name__


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_state(slave: Any, state: Any) -> dict[str, Any]:
    """The state with its variables as the slave's types; StateError naming what is wrong."""
    if not isinstance(state, dict):
        raise StateError(f"the state is a JSON {_kind(state)}, not the object this FMU saves")
    if set(state) == {"invalid"}:
        raise StateError(f"that state was not saved: {state['invalid']}")
    if set(state) != set(KEYS):
        missing, extra = sorted(set(KEYS) - set(state)), sorted(set(state) - set(KEYS))
        raise StateError(f"the state must have exactly the keys {list(KEYS)} "
                         f"(missing {missing}, unexpected {extra[:5]})")
    flags, times = state["flags"], state["times"]
    if not (isinstance(flags, list) and len(flags) == 3
            and all(f is None or isinstance(f, str) for f in flags[:2])
            and isinstance(flags[2], bool)):
        raise StateError(f"flags must be [str|null, str|null, bool], got {_short(flags)}")
    if not (isinstance(times, list) and len(times) == 2
            and all(_number(t) and math.isfinite(t) for t in times)):
        raise StateError(f"times must be two finite numbers [start, now], got {_short(times)}")
    variables = state["variables"]
    if not isinstance(variables, dict):
        raise StateError(f"variables must be an object, got a JSON {_kind(variables)}")
    declared = {v.name: v for v in slave.VARIABLES}
    if set(variables) != set(declared):
        extra = sorted(set(variables) - set(declared))
        missing = sorted(set(declared) - set(variables))
        raise StateError(f"variables must be exactly the {len(declared)} declared ones "
                         f"(unknown {_short(extra[:5])}, missing {_short(missing[:5])})")
    failed = flags[0]
    values = {}
    for name, spec in declared.items():
        value = variables[name]
        if spec.integer:
            if type(value) is not int:
                raise StateError(f"Integer variable {name} must be an integer, got "
                                 f"{_kind(value)} {_short(value)}")
        elif not _number(value):
            raise StateError(f"Real variable {name} must be a number, got {_kind(value)} "
                             f"{_short(value)}")
        else:
            value = float(value)
        if spec.causality == "output":
            if not (math.isfinite(value) or (failed is not None and math.isnan(value))):
                raise StateError(f"output {name}={value!r} is not finite (only a failed "
                                 "instance saves NaN outputs)")
        else:
            problem = spec.range_problem(value)
            if problem:
                raise StateError(problem)
        values[name] = value
    if not flags[2] and state["model"] is not None:
        raise StateError("an un-initialized state has no library model state (model must "
                         f"be null, got a JSON {_kind(state['model'])})")
    return {**state, "variables": values}


def structure_problem(value: Any, template: Any, path: str = "model") -> str | None:
    """Where `value` differs in structure from `template` (keys, lengths, leaf types,
    finite floats), or None. The template bounds the recursion depth."""
    if isinstance(template, dict):
        if not isinstance(value, dict):
            return f"{path} must be an object, got a JSON {_kind(value)}"
        if set(value) != set(template):
            return (f"{path} must have the keys {sorted(template)}, got "
                    f"{_short(sorted(map(str, value))[:8])}")
        for key in template:
            problem = structure_problem(value[key], template[key], f"{path}.{key}")
            if problem:
                return problem
        return None
    if isinstance(template, list):
        if not isinstance(value, list) or len(value) != len(template):
            got = f"length {len(value)}" if isinstance(value, list) else f"a JSON {_kind(value)}"
            return f"{path} must be a list of length {len(template)}, got {got}"
        for k, (v, t) in enumerate(zip(value, template, strict=True)):
            problem = structure_problem(v, t, f"{path}[{k}]")
            if problem:
                return problem
        return None
    if type(value) is not type(template):
        return f"{path} must be {_kind(template)}, got {_kind(value)} {_short(value)}"
    if isinstance(value, float) and not math.isfinite(value):
        return f"{path}={value!r} is not finite"
    return None


def restore(slave: Any, raw: Any) -> None:
    """Set the slave to a state it saved: all of it, or (StateError) nothing."""
    state = check_state(slave, raw)
    saved = dict(slave.__dict__)
    try:
        _apply(slave, state)
    except Exception:
        slave.__dict__.clear()
        slave.__dict__.update(saved)
        raise


def _apply(slave: Any, state: dict[str, Any]) -> None:
    variables = state["variables"]
    failed, pending, initialized = state["flags"]
    slave.__dict__.update(variables)
    slave.failed, slave.pending_error = failed, pending
    slave.start_time, slave.time = (float(t) for t in state["times"])
    slave.discarded_at = None
    if initialized and failed is None:
        with warnings.catch_warnings():  # already reported at initialization
            warnings.simplefilter("ignore")
            slave.setup()  # the library objects from the restored parameters
        template = slave.model_state()
        model = state["model"]
        problem = structure_problem(model, template)
        for key in getattr(slave, "fixed_model_keys", ()):
            if problem is None and model[key] != template[key]:
                problem = (f"model.{key}={_short(model[key])} does not match this "
                           f"instance's parameters ({_short(template[key])})")
        if problem is None:
            problem = slave.model_state_problem(model)
        if problem:
            raise StateError(f"the library model state does not fit this FMU: {problem}")
        slave.restore_model_state(model)
        slave.__dict__.update(variables)  # outputs as saved
    elif slave.state_holder:  # nothing to step with until initialized (or failed)
        slave.__dict__.pop(slave.state_holder, None)
    slave.initialized = initialized


def _short(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."
