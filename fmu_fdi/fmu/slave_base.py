"""Base class for fmu-fdi pythonfmu slaves (bundled into every FMU; numpy, stdlib, pythonfmu only).

What it adds to :class:`pythonfmu.Fmi2Slave`, and why:

* **No exception escapes.** pythonfmu 0.7.0 turns a Python exception in any callback into
  ``fmi2Fatal`` and, while doing so, releases its references to the instance; the master can
  then only free it. Every callback here catches everything, logs it with status ``error``
  under ``logStatusError`` and degrades: ``do_step`` returns ``False`` (pythonfmu answers
  ``fmi2Discard`` and reports ``fmi2Terminated`` true), getters return NaN / 0 / False, setters
  ignore the value. After a failure inside the model (``step``, ``update_outputs``, a state
  restore) the instance stays *failed*: every later ``do_step`` is discarded until ``fmi2Reset``.
* **The whole instance is the FMU state.** pythonfmu saves only registered variables by
  default. Here ``fmi2GetFMUstate`` deep-copies every instance attribute except pythonfmu's
  own bookkeeping (numpy arrays and nested runtime objects included), ``fmi2SetFMUstate``
  restores a fresh deep copy (so one saved state can be restored any number of times),
  in place for lists, dicts, same-shape arrays and plain objects (getters registered as
  closures over them keep working), and removes attributes created after the save. Serialization uses :mod:`.slave_state`
  (exact, pickle-free).
* **Outputs follow the current inputs.** Subclasses compute outputs in ``update_outputs`` from
  the state and the inputs as currently set; it runs lazily before the first get after any
  set or step, so an output with direct feedthrough is right whatever order the master
  uses for set/get around ``fmi2DoStep``. ``step`` only advances the state.
* **The FMI 2.0 call sequence is enforced.** ``fmi2DoStep`` is served only between
  ``fmi2ExitInitializationMode`` and ``fmi2Terminate``; setupExperiment/enter/exit
  initialisation only in their phase. pythonfmu 0.7.0 lets a Python callback return only
  OK, Discard (``do_step`` returning False) or Fatal (any exception), so a misplaced doStep is
  answered with ``fmi2Discard`` and an error-status message saying why; a misplaced
  initialisation call is ignored with such a message. The phase is not part of the FMU state.
* **A state is validated when it is set.** Foreign, truncated or corrupt bytes, a state of
  another FMU, or one :meth:`validate_fmu_state` refuses leave the instance exactly as it was,
  with an error-status message at set time; since the status cannot be fmi2Error here, the
  next ``do_step`` is discarded with the same reason (a master that ignored the log cannot go
  on silently from the wrong state) until a valid state is set or the FMU is reset.
* **Categorised logging.** :meth:`log_event` queues a message under one of
  ``log_categories``; pythonfmu forwards the queue to the FMI logger at the end of the same
  FMI call, but only if the master switched logging on (``loggingOn`` at instantiation or
  ``fmi2SetDebugLogging``; an empty category list means all categories). Errors are dropped
  too when logging is off: that is pythonfmu's logger, not this class.
"""
from __future__ import annotations

import copy
import math
import os
import sys
import traceback
from abc import abstractmethod

import numpy as np
from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

from .slave_state import StateCodecError, decode_state, encode_state

#: attributes set by pythonfmu's Fmi2Slave.__init__ that are bookkeeping, not model state.
#: ``log_queue`` must keep its identity: the C side holds a reference to that very list.
_BOOKKEEPING = frozenset({
    "vars", "instance_name", "resources", "visible", "log_queue", "guid", "author", "license",
    "version", "copyright", "modelName", "description", "default_experiment",
})
_ERROR_STATE = "__fmu_fdi_state_error__"


class FdiSlave(Fmi2Slave):
    """pythonfmu slave base: catch-all callbacks, whole-instance FMU state, lazy outputs.

    Subclasses register variables in ``__init__`` (after ``super().__init__(**kwargs)``) and
    implement :meth:`step` and :meth:`update_outputs`. Any attribute they set is FMU state;
    attributes whose name starts with ``_nostate_`` are excluded (caches that can be rebuilt).
    """

    log_categories = {
        "logStatusWarning": "Messages with status fmi2Warning.",
        "logStatusDiscard": "Messages with status fmi2Discard.",
        "logStatusError": "Messages with status fmi2Error: exceptions caught in a callback.",
        "logStatusFatal": "Messages with status fmi2Fatal.",
        "logAll": "All messages without a more specific category.",
        "logFdiEvents": "Diagnostic events: alarms raised and cleared, isolation changes.",
        "logFdiInput": "Inputs rejected as invalid (not finite).",
        "logFdiState": "FMU state saved, restored, serialized.",
    }

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.failed_reason = ""        # non-empty once the model failed; cleared by fmi2Reset only
        self._outputs_current = False  # outputs match state and inputs
        self._nostate_phase = "instantiated"  # FMI 2.0: instantiated, initialization, stepping, terminated
        self._nostate_state_error = ""        # why the last fmi2SetFMUstate was refused ("" if it was not)
        # which interpreter and numpy the host gave us: the first thing to check when an FMU
        # behaves differently in another host (flushed to the logger at the next FMI call)
        self.log(f"{type(self).__qualname__}: Python {sys.version.split()[0]} prefix={sys.prefix} "
                 f"numpy {np.__version__} at {os.path.dirname(np.__file__)}", category="logAll")

    # ---- to implement -------------------------------------------------------------------
    @abstractmethod
    def step(self, current_time: float, step_size: float) -> bool:
        """Advance the state over ``[current_time, current_time + step_size)``; False discards."""

    def update_outputs(self) -> None:
        """Compute every output attribute from the state and the inputs as currently set."""

    def validate_fmu_state(self, attributes: dict) -> None:
        """Raise ValueError if ``attributes`` (a decoded FMU state of this class) cannot be this
        instance's state; called before anything is restored. The default accepts all."""

    # ---- logging --------------------------------------------------------------------------
    def log_event(self, msg: str, category: str = "logFdiEvents", status: Fmi2Status = Fmi2Status.ok):
        """Queue ``msg`` for the FMI logger under ``category`` (one of ``log_categories``)."""
        if category not in self.log_categories:
            category = "logAll"
        self.log(msg, status=status, category=category)

    def log(self, msg, status=Fmi2Status.ok, category=None, debug=None):
        # pythonfmu hands msg to the FMI logger as its printf-style *format*: a stray "%s"
        # would make a C logger read arguments that are not there. ('#' also has a meaning in
        # FMI 2.0 messages, #r12# names a variable, but hosts rarely expand it; left alone.)
        super().log(str(msg).replace("%", "%%"), status=status, category=category)

    def _log_exception(self, where: str, exc: BaseException):
        tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__, limit=-3))
        self.log(f"{where}: {type(exc).__name__}: {exc}\n{tb}", status=Fmi2Status.error,
                 category="logStatusError")

    def _fail(self, where: str, exc: BaseException):
        self._log_exception(where, exc)
        if not self.failed_reason:
            self.failed_reason = f"{where}: {type(exc).__name__}: {exc}"

    def _ensure_outputs(self):
        if not self._outputs_current:
            self.update_outputs()
            self._outputs_current = True

    # ---- FMI callbacks (called from pythonfmu's C++ layer) --------------------------------
    def _misplaced(self, call: str, allowed: str) -> bool:
        """True (and an error-status message) if ``call`` is not allowed in the current phase."""
        if self._nostate_phase == allowed:
            return False
        self.log(f"{call} refused: allowed only in phase '{allowed}', the instance is in phase "
                 f"'{self._nostate_phase}' (FMI 2.0 co-simulation state machine)",
                 status=Fmi2Status.error, category="logStatusError")
        return True

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        if self._misplaced("fmi2SetupExperiment", "instantiated"):
            return
        try:
            if not math.isfinite(float(start_time)):  # times are finite (docs/semantics.md §9)
                self.log(f"fmi2SetupExperiment refused: startTime {start_time!r} is not a finite number",
                         status=Fmi2Status.error, category="logStatusError")
                return
            self.start_time = float(start_time)
        except BaseException as exc:
            self._fail("setup_experiment", exc)

    def enter_initialization_mode(self):
        if not self._misplaced("fmi2EnterInitializationMode", "instantiated"):
            self._nostate_phase = "initialization"

    def exit_initialization_mode(self):
        if self._misplaced("fmi2ExitInitializationMode", "initialization"):
            return
        self._nostate_phase = "stepping"
        try:
            self._outputs_current = False
            self._ensure_outputs()
        except BaseException as exc:
            self._fail("exit_initialization_mode", exc)

    def terminate(self):
        if not self._misplaced("fmi2Terminate", "stepping"):
            self._nostate_phase = "terminated"

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._misplaced("fmi2DoStep", "stepping"):
            return False
        if self._nostate_state_error:
            self.log(f"do_step refused: the last fmi2SetFMUstate was refused ({self._nostate_state_error}); "
                     f"set a valid state or reset the FMU", status=Fmi2Status.error, category="logStatusError")
            return False
        if self.failed_reason:
            self.log(f"do_step refused: instance failed earlier ({self.failed_reason})",
                     status=Fmi2Status.error, category="logStatusError")
            return False
        try:
            ok = bool(self.step(current_time, step_size))
            self._outputs_current = False
            return ok
        except BaseException as exc:
            self._fail("do_step", exc)
            return False

    def _get(self, where, getter, vrs, fallback):
        try:
            self._ensure_outputs()
        except BaseException as exc:
            self._fail(f"{where} (update_outputs)", exc)
            return [fallback] * len(vrs)
        try:
            return getter(vrs)
        except BaseException as exc:  # e.g. a value reference of another type: the master's error
            self._log_exception(where, exc)
            return [fallback] * len(vrs)

    def get_real(self, vrs):
        return self._get("get_real", super().get_real, vrs, math.nan)

    def get_integer(self, vrs):
        return self._get("get_integer", super().get_integer, vrs, 0)

    def get_boolean(self, vrs):
        return self._get("get_boolean", super().get_boolean, vrs, False)

    def get_string(self, vrs):
        return self._get("get_string", super().get_string, vrs, "")

    def _set(self, where, setter, vrs, values):
        try:
            setter(vrs, values)
        except BaseException as exc:
            self._log_exception(where, exc)
        self._outputs_current = False

    def set_real(self, vrs, values):
        self._set("set_real", super().set_real, vrs, values)

    def set_integer(self, vrs, values):
        self._set("set_integer", super().set_integer, vrs, values)

    def set_boolean(self, vrs, values):
        self._set("set_boolean", super().set_boolean, vrs, values)

    def set_string(self, vrs, values):
        self._set("set_string", super().set_string, vrs, values)

    # ---- FMU state ------------------------------------------------------------------------
    def _model_state(self) -> dict:
        return {k: v for k, v in vars(self).items()
                if k not in _BOOKKEEPING and not k.startswith("_nostate_")}

    def _get_fmu_state(self):
        try:
            return {"class": type(self).__qualname__, "attributes": copy.deepcopy(self._model_state())}
        except BaseException as exc:
            self._log_exception("fmi2GetFMUstate", exc)
            return {_ERROR_STATE: f"{type(exc).__name__}: {exc}"}

    def _set_fmu_state(self, state):
        try:
            if not isinstance(state, dict) or _ERROR_STATE in state:
                reason = state.get(_ERROR_STATE) if isinstance(state, dict) else type(state).__name__
                raise StateCodecError(f"unusable FMU state ({reason})")
            if state.get("class") != type(self).__qualname__:
                raise StateCodecError(f"FMU state of {state.get('class')!r} given to {type(self).__qualname__!r}")
            if not isinstance(state.get("attributes"), dict):
                raise StateCodecError("FMU state without attributes")
            restored = copy.deepcopy(state["attributes"])  # the saved state stays reusable
            self.validate_fmu_state(restored)
        except BaseException as exc:  # refused before anything changed: the instance is as it was
            self._nostate_state_error = f"{type(exc).__name__}: {exc}"
            self.log(f"fmi2SetFMUstate refused, instance unchanged: {self._nostate_state_error}",
                     status=Fmi2Status.error, category="logStatusError")
            return
        self._nostate_state_error = ""
        try:
            for name in [k for k in self._model_state() if k not in restored]:
                delattr(self, name)
            for name, value in restored.items():
                _restore_attribute(self, name, value)
            self.log_event("FMU state restored", category="logFdiState")
        except BaseException as exc:
            self._fail("fmi2SetFMUstate", exc)

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        # a static method: pythonfmu calls it on the class, so no instance to log with; an
        # unencodable state becomes an error state that fmi2SetFMUstate reports.
        try:
            return encode_state(state)
        except BaseException as exc:
            return encode_state({_ERROR_STATE: f"serialization failed: {type(exc).__name__}: {exc}"})

    @staticmethod
    def _fmu_state_from_bytes(data: bytes):
        try:
            return decode_state(data)
        except BaseException as exc:
            return {_ERROR_STATE: f"deserialization failed: {type(exc).__name__}: {exc}"}


def _restore_attribute(owner, name, value):
    """Set ``owner.name = value``, in place where the current object allows it.

    Registered getters/setters are often closures over a list or array taken in ``__init__``
    (``getter=lambda: self._u[i]`` is safe, ``getter=partial(getitem, self._u, i)`` is not):
    rebinding the attribute would leave them on the old object. So containers and plain
    objects of the same kind (and arrays of the same shape and dtype) are overwritten in place.
    """
    current = owner.__dict__.get(name, None)
    if type(current) is not type(value) or current is None:
        owner.__dict__[name] = value
    elif isinstance(value, np.ndarray):
        if current.shape == value.shape and current.dtype == value.dtype and current.flags.writeable:
            np.copyto(current, value)
        else:
            owner.__dict__[name] = value
    elif type(value) is list:
        current[:] = value
    elif type(value) is dict:
        current.clear()
        current.update(value)
    elif hasattr(value, "__dict__") and not isinstance(value, type) and not callable(value):
        current.__dict__.clear()
        current.__dict__.update(value.__dict__)
    else:
        owner.__dict__[name] = value
