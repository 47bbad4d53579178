"""The one place where gyro_fmu adapts pythonfmu: variable tables, units, safe callbacks, state.

Every FMU slave in fmu_src/ subclasses `GyroSlave`, declares a table of `Var`
and implements `setup()` and `advance()` (and, when it keeps library objects,
`model_state()` / `restore_model_state()`). This base class

- registers the variables with pythonfmu and writes what pythonfmu leaves out
  of modelDescription.xml: units with base-unit exponents, min/max/nominal,
  InitialUnknowns, output dependencies, a DefaultExperiment;
- never lets a Python exception escape a callback. pythonfmu's binary maps any
  exception to fmi2Fatal (after which fmi2Terminate crashes the importer,
  docs/fmi-notes.md) and ignores what setters return, so the only recoverable status
  it can deliver is fmi2Discard from fmi2DoStep. Bad values are therefore
  refused at set time with an error-level log message (the previous value is
  kept) and the next fmi2DoStep returns fmi2Discard without advancing; a host that
  retries that very step (fmpy.simulate_fmu re-sends the same bad value) gets it
  done with the kept value and fmi2Warning. The C loader (pythonfmu/upstream_status.py) delivers
  what pythonfmu cannot: fmi2Error for fmi2DoStep before initialization, and
  fmi2Terminated answered false after a recoverable refusal, fmi2Error once the
  instance cannot step (a failed initialization, parameter, state restore, or a step
  whose Real outputs are not finite: the message names the inputs held over it);
- saves and restores the complete state (every variable, the library objects'
  internals, the failure flags) as JSON, so get/set and serialize/deserialize
  of FMU state are exact; a state is restored only if it has exactly the structure
  this slave saves (state.py), never a crash.

Inside an FMU, the base class also installs `upstream_exit`: pythonfmu 0.7.0
frees its interpreter guard twice at process exit, which aborts non-Python hosts
(measured with `gyro-fmu doctor`: the abort is the double free and follows numpy or
scipy being loaded at all, not the place of the numpy import; docs/fmi-notes.md).
"""

from __future__ import annotations

import json
import math
import sys
import traceback
import warnings
from operator import itemgetter
from pathlib import Path
from typing import Any, ClassVar
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Integer, Real

from ..model.interfaces import Var, dataclass_parameters  # noqa: F401 (re-exported)
from ..model.units import UNITS
from . import state as fmu_state
from .upstream_status import ERROR, WARNING, HostStatus, host_library_mismatch

_FMAX = sys.float_info.max

#: Log category of the full tracebacks behind error messages.
DEBUG_CATEGORY = "logDebug"


class GyroSlave(Fmi2Slave):
    """Base of all gyro_fmu slaves: declares VARIABLES, guards every callback."""

    VARIABLES: ClassVar[tuple[Var, ...]] = ()
    author = "gyro_fmu"
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=0.01, step_size=5e-6)
    log_categories: ClassVar[dict[str, str]] = {
        **Fmi2Slave.log_categories,
        DEBUG_CATEGORY: "Full Python tracebacks behind error messages.",
    }

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.failed: str | None = None  #: set when initialization failed; every step refused
        self.pending_error: str | None = None  #: refused set; the next step is discarded
        self.initialized = False
        self.discarded_at: tuple[float, str] | None = None  #: (t, refusal) of that discard
        self.start_time = 0.0
        self.time = 0.0
        self._spec = {v.name: v for v in self.VARIABLES}
        for var in self.VARIABLES:
            setattr(self, var.name, var.start)
            self.register_variable(self._pythonfmu_variable(var))
        # Fast paths of get_real / set_real (one dict lookup per value; see those methods)
        self._real_names = {vr: v.name for vr, v in self.vars.items() if isinstance(v, Real)}
        self._input_bounds = {
            vr: (name, -_FMAX if spec.min is None else spec.min,
                 _FMAX if spec.max is None else spec.max)
            for vr, name in self._real_names.items()
            if self.vars[vr].causality == Fmi2Causality.input
            and not (spec := self._spec[name]).is_parameter
        }
        self._getters: dict[tuple[int, ...], Any] = {}
        outs = [v.name for v in self.VARIABLES if v.causality == "output" and not v.integer]
        self._outputs = itemgetter(*outs) if len(outs) > 1 else (lambda d, n=outs: [d[n[0]]])
        self._host = HostStatus(self.resources, self.modelName)
        self._host_failed: str | None = None  #: what the loader was last told
        if self.resources:  # inside an FMU: defuse pythonfmu 0.7.0's exit-time double free
            mismatch = host_library_mismatch(Path(self.resources))
            if mismatch:
                self.log(f"{self.modelName}: {mismatch}", Fmi2Status.warning)
            from . import upstream_exit

            platform = Path(self.resources).parent / "binaries" / "linux64"
            binary = platform / f"{self.modelName}_pythonfmu.so"  # behind our loader
            upstream_exit.install(binary if binary.is_file() else
                                   platform / f"{self.modelName}.so")

    @staticmethod
    def _pythonfmu_variable(var: Var) -> Real | Integer:
        causality = Fmi2Causality[var.causality]
        if var.is_parameter:
            variability, initial = Fmi2Variability.fixed, None
        elif var.integer:
            variability, initial = Fmi2Variability.discrete, None
        else:
            variability, initial = Fmi2Variability.continuous, None
        if causality == Fmi2Causality.output:
            initial = Fmi2Initial.calculated  # computed from the parameters at initialization
        cls = Integer if var.integer else Real
        return cls(var.name, causality=causality, description=var.description,
                   variability=variability, initial=initial)

    # --- hooks for subclasses ------------------------------------------------
    def setup(self) -> None:
        """Build the library objects from the parameters (end of initialization)."""

    def advance(self, t: float, h: float) -> None:
        """Advance from t to t+h and update the outputs."""
        raise NotImplementedError

    #: Name of the attribute holding the library model built by setup(); its
    #: get_state()/set_state() make the FMU state (None: no internal state).
    state_holder: ClassVar[str | None] = "model"

    def model_state(self) -> Any:
        """JSON-ready internal state of the library objects (beyond the variables)."""
        holder = getattr(self, self.state_holder, None) if self.state_holder else None
        return None if holder is None else holder.get_state()

    def restore_model_state(self, state: Any) -> None:
        """Inverse of model_state, called after setup() on the restored parameters."""
        if state is not None and self.state_holder:
            getattr(self, self.state_holder).set_state(state)

    #: Keys of the model state that follow from the parameters: must equal a fresh setup's.
    fixed_model_keys: ClassVar[tuple[str, ...]] = ()

    def model_state_problem(self, state: Any) -> str | None:
        """What is wrong with a structurally fitting model state (values, e.g. an index
        into a buffer), None if fine; called before restore_model_state."""
        return None

    # --- FMI callbacks -------------------------------------------------------
    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        self.start_time = self.time = start_time

    def exit_initialization_mode(self) -> None:
        if self.failed is not None:  # a refused parameter: do not set up on the kept value
            self._outputs_not_a_number()
            return
        try:
            problems = [p for v in self.VARIABLES if v.is_parameter
                        and (p := v.range_problem(getattr(self, v.name)))]
            if problems:
                raise ValueError("; ".join(problems))
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                self.setup()
            for w in caught:  # e.g. a growing mode: the importer's log must show it
                self.log(f"{self.modelName}: {w.message}", Fmi2Status.warning)
            self.initialized = True
        except Exception as exc:
            self._fail("initialization", exc)
        self._sync_host()

    def do_step(self, current_time: float, step_size: float) -> bool:
        status = 0
        try:
            if self.failed is not None:
                raise ValueError(f"cannot step: {self.failed}")
            if not self.initialized:
                status = ERROR  # an illegal call sequence, not a refusal to retry
                raise ValueError("fmi2DoStep before fmi2ExitInitializationMode: initialize "
                                 "the instance (or restore an initialized FMU state) first")
            if self.pending_error is not None:
                message, self.pending_error = self.pending_error, None
                if self.discarded_at != (current_time, message):
                    self.discarded_at = (current_time, message)
                    raise ValueError(f"step refused: {message}")
                status = WARNING  # the host retried the same step with the same value
                self.log(f"{self.modelName}: step at t={current_time:.9g} s done with the "
                         f"kept value after the same refusal again: {message}",
                         Fmi2Status.warning)
            if not (math.isfinite(step_size) and step_size > 0.0):
                raise ValueError(
                    f"communication step size {step_size!r} s must be > 0 and finite"
                )
            self.advance(current_time, step_size)
            if not math.isfinite(sum(self._outputs(self.__dict__))):
                self._not_finite(current_time, step_size)
            self.time = current_time + step_size
            self.discarded_at = None
        except Exception as exc:
            self.log(f"{self.modelName}: step at t={current_time:.9g} s discarded: {exc}",
                     Fmi2Status.discard)
            self._log_traceback()
            self._sync_host(status)
            return False
        if status:
            self._sync_host(status)
        return True

    def _not_finite(self, t: float, h: float) -> None:
        """Fail the instance after a step that made a Real output inf or NaN (the state has
        advanced into it: only a restore of an earlier FMU state goes on), naming the
        outputs and the inputs held over the step, so the error is this FMU's."""
        bad = ", ".join(f"{v.name}={getattr(self, v.name)!r}" for v in self.VARIABLES
                        if v.causality == "output" and not v.integer
                        and not math.isfinite(getattr(self, v.name)))
        held = ", ".join(f"{v.name}={getattr(self, v.name)!r}" for v in self.VARIABLES
                         if v.causality == "input") or "no inputs"
        self.failed = (f"the step from t={t:.9g} s over {h!r} s gave non-finite outputs "
                       f"({bad}) with {held} held over the step: the inputs or parameters "
                       "are out of this model's numeric range; restore an earlier FMU state "
                       "with other inputs, or instantiate anew")
        self.log(f"{self.modelName}: {self.failed}", Fmi2Status.error)
        self._outputs_not_a_number()
        raise ValueError(self.failed)

    def _sync_host(self, call_status: int = 0) -> None:
        """Tell the C loader this call's status and whether the instance can still step."""
        if call_status or self.failed != self._host_failed:
            self._host.report(call_status, self.failed)
            self._host_failed = self.failed

    def get_real(self, vrs: list[int]) -> list[float]:
        """Values of the Real variables vrs: one C-level gather per call (pythonfmu's own
        get_real calls a Python getter per value; 24 outputs cost 10 us there)."""
        key = tuple(vrs)
        getter = self._getters.get(key)
        if getter is None:
            if not all(vr in self._real_names for vr in key):
                return self._refused_get(key, "Real", math.nan)
            names = [self._real_names[vr] for vr in key]
            getter = itemgetter(*names) if len(names) > 1 else (lambda d, n=names: [d[n[0]]])
            self._getters[key] = getter
        return list(map(float, getter(self.__dict__)))

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        """Inputs that are finite and within their min/max are stored directly; anything
        else (parameters, non-finite or out-of-range values, unknown references) takes the
        guarded path of _set, with its message and refusal. The bounds default to +-max
        float, so the comparison also rejects inf and nan."""
        bounds = self._input_bounds
        d = self.__dict__
        for vr, value in zip(vrs, values, strict=False):
            b = bounds.get(vr)
            if b is not None and b[1] <= value <= b[2]:
                d[b[0]] = float(value)
            else:
                self._set([vr], [value], float)

    def get_integer(self, vrs: list[int]) -> list[int]:
        if not all(isinstance(self.vars.get(vr), Integer) for vr in vrs):
            return self._refused_get(tuple(vrs), "Integer", 0)
        return super().get_integer(vrs)

    def _refused_get(self, vrs: tuple[int, ...], kind: str, fill: float) -> list:
        """A get of a reference that is not a variable of this kind: fmi2Error with the
        reason (pythonfmu 0.7.0 let the exception through and crashed the host)."""
        bad = next(vr for vr in vrs if not (
            vr in self._real_names if kind == "Real" else isinstance(self.vars.get(vr), Integer)))
        what = (f"is {self.vars[bad].name}, not a {kind} variable" if bad in self.vars
                else "is no variable of this FMU")
        self.log(f"{self.modelName}: value reference {bad} {what}: refused", Fmi2Status.error)
        self._sync_host(ERROR)
        return [fill] * len(vrs)

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._set(vrs, values, int)

    def _set(self, vrs: list[int], values: list, cast: type) -> None:
        for vr, value in zip(vrs, values, strict=False):
            try:
                var = self.vars.get(vr)
                if var is None:
                    raise IllegalCallError(f"value reference {vr} is no variable of this FMU "
                                     f"(refused {value!r})")
                spec = self._spec[var.name]
                if var.causality == Fmi2Causality.output:
                    raise IllegalCallError(f"{spec.name} is an output: the FMI standard forbids "
                                     f"setting it (refused {value!r})")
                if spec.is_parameter and self.initialized:
                    raise IllegalCallError(
                        f"{spec.name} is a fixed parameter and cannot change after "
                        f"initialization (kept {getattr(self, spec.name)!r}, refused {value!r}): "
                        "set it before fmi2ExitInitializationMode, or instantiate anew"
                    )
                problem = spec.range_problem(value)
                if problem is not None:
                    raise ValueError(problem + f" (kept {getattr(self, spec.name)!r})")
                setattr(self, spec.name, cast(value))
            except Exception as exc:
                message = f"{self.modelName}: {exc}"
                if isinstance(exc, IllegalCallError):  # fmi2Error now, nothing changed
                    self.log(message, Fmi2Status.error)
                    self._sync_host(ERROR)
                    continue
                # a refused value: the next step is discarded (a parameter: the instance
                # fails), so a host that retries goes on with the kept value
                if spec_is_parameter(self, vr) and not self.initialized:
                    self.failed = f"refused parameter value: {exc}"
                    self._outputs_not_a_number()
                else:
                    self.pending_error = str(exc)
                self.log(message, Fmi2Status.error)
                self._log_traceback()
                self._sync_host()

    # --- FMU state -----------------------------------------------------------
    def _get_fmu_state(self) -> dict[str, Any]:
        try:
            return {
                "variables": {v.name: getattr(self, v.name) for v in self.VARIABLES},
                "flags": [self.failed, self.pending_error, self.initialized],
                "times": [self.start_time, self.time],
                "model": self.model_state() if self.initialized else None,
            }
        except Exception as exc:
            self.log(f"{self.modelName}: could not save the state: {exc}", Fmi2Status.error)
            self._log_traceback()
            return {"invalid": str(exc)}

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore a saved state; anything this slave did not save is refused (state.py)."""
        status = 0
        try:
            fmu_state.restore(self, state)
        except Exception as exc:
            self._fail("restoring the FMU state", exc)
            status = ERROR  # through the loader: fmi2SetFMUstate returns fmi2Error
        self._sync_host(status)

    @staticmethod
    def _fmu_state_to_bytes(state: dict[str, Any]) -> bytes:
        return json.dumps(state).encode("utf-8")  # repr floats: exact round trip

    @staticmethod
    def _fmu_state_from_bytes(state: bytes) -> dict[str, Any]:
        try:
            return json.loads(state.decode("utf-8"))
        except Exception as exc:  # an exception here would be fmi2Fatal
            return {"invalid": f"serialized state unreadable: {exc}"}

    # --- failure reporting ---------------------------------------------------
    def _fail(self, where: str, exc: Exception) -> None:
        self.failed = f"{where} failed: {exc}"
        self.log(f"{self.modelName}: {self.failed}", Fmi2Status.error)
        self._log_traceback()
        self._outputs_not_a_number()

    def _outputs_not_a_number(self) -> None:
        """Every Real output NaN once the FMU cannot step at all (initialization, a
        parameter or a state restore refused): a host that ignores fmi2Discard and the
        error log must not read its outputs (the zeros of before initialization) as
        plausible values. A recoverable refusal (a bad input) keeps the outputs of the
        last good step, since the state is kept and the next step goes on."""
        for v in self.VARIABLES:
            if v.causality == "output" and not v.integer:
                setattr(self, v.name, math.nan)

    def _log_traceback(self) -> None:
        self.log(traceback.format_exc(), Fmi2Status.ok, category=DEBUG_CATEGORY)

    # --- model description: what pythonfmu leaves out ------------------------
    def to_xml(self, model_options: dict[str, str] | None = None) -> Element:
        root = super().to_xml(model_options or {})
        used_units: list[str] = []
        for node in root.iter("ScalarVariable"):
            var = self._spec[node.get("name")]
            type_node = node[0]
            if not var.integer:
                unit = var.unit or "1"
                type_node.set("unit", unit)
                if unit not in used_units:
                    used_units.append(unit)
            for attr in ("min", "max", "nominal"):
                value = getattr(var, attr)
                if value is not None:
                    type_node.set(attr, str(int(value)) if var.integer else f"{value:.16g}")
        unit_defs = Element("UnitDefinitions")
        for unit in used_units:
            u = SubElement(unit_defs, "Unit", name=unit)
            SubElement(u, "BaseUnit", {k: str(v) for k, v in UNITS[unit].items()})
        root.insert(list(root).index(root.find("CoSimulation")) + 1, unit_defs)
        structure = root.find("ModelStructure")
        outputs = structure.find("Outputs")
        if outputs is not None:
            initial = SubElement(structure, "InitialUnknowns")
            for unknown in outputs:
                # an output changes only in fmi2DoStep: no direct feedthrough of inputs
                unknown.set("dependencies", "")
                SubElement(initial, "Unknown", index=unknown.get("index"))
        return root


class IllegalCallError(ValueError):
    """A set the FMI standard forbids whatever the value (an output, an unknown value
    reference, a fixed parameter after initialization): refused with fmi2Error at once,
    through the loader, and nothing changes."""


def spec_is_parameter(slave: GyroSlave, vr: int) -> bool:
    var = slave.vars.get(vr)
    return var is not None and slave._spec[var.name].is_parameter


def dataclass_from_parameters(cls: type, slave: object) -> object:
    """Instance of a tuning dataclass from the slave's parameters of the same names."""
    import dataclasses

    casts = {"int": int, "bool": bool, "float": float, int: int, bool: bool, float: float}
    return cls(**{f.name: casts.get(f.type, float)(getattr(slave, f.name))
                  for f in dataclasses.fields(cls)})
