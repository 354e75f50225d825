"""Source of the slave module bundled into every diagnostic FMU.

:func:`fmu_fdi.fmu.builder.build_fmu` writes it into the FMU's private package next to a
copy of :mod:`fmu_fdi.runtime` and the design file, with ``__CLASS__`` replaced by the
model identifier. It imports only numpy, the standard library, pythonfmu and (relatively)
its own package: the runtime and :mod:`.slave_base`, which catches every exception,
keeps the whole instance as the FMU state and logs through the FMI logger.

Timing: ``fmi2DoStep(t, h)`` consumes the inputs set for time t and makes the outputs the
diagnosis of that sample (row k of ``Diagnoser.run``); outputs do not depend on inputs
directly (no feedthrough), so a master may read them any time after the step. The semantics
of one step (step sizes, invalid samples, ``numeric_reset``) are in docs/semantics.md; a step
the runtime cannot serve is answered with fmi2Discard and its reason under logStatusDiscard,
and leaves the instance exactly as before.
"""

TEMPLATE = r'''"""fmu-fdi diagnostic FMU slave (generated): residual generation, evaluation, decision."""
import copy
import hashlib
import json
import math
import os

from pythonfmu import Boolean, Fmi2Causality, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from .engine import (FAULT_DETECTED, INPUT_INVALID, ISOLATED_FAULT, NUMERIC_RESET, DiagnoserRuntime, StepSizeError,
                     output_type)
from .schedule import runtime_for  # a plain or a scheduled design (schedule.py)
from .slave_base import FdiSlave

# The design is read from *this instance's* resources folder: a host may run an FMU again after
# deleting the first extraction, while pythonfmu keeps the module imported from it.
_PACKAGE = __package__


class __CLASS__(FdiSlave):
    author = "fmu-fdi"
    description = __DESCRIPTION__

    log_categories = dict(FdiSlave.log_categories, logFdiNumeric=(
        "Samples that overflowed the evaluation (a value became NaN/Inf): fault evidence, sample discarded, "
        "generator and evaluation restarted (numeric_reset, input_invalid)."))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        with open(os.path.join(self.resources, _PACKAGE, "design.json"), "rb") as fh:
            raw = fh.read()
        design = json.loads(raw.decode("utf-8"))
        self.design_sha256 = hashlib.sha256(raw).hexdigest()  # an FMU state names the design it belongs to
        self.rt = runtime_for(design)
        self._nostate_faults = [f["name"] for f in design.get("faults", [])]
        rt = self.rt
        self.u_in = [float(v) for v in rt.u0]
        self.y_in = [float(v) for v in rt.y0]
        self.out = [0.0] * len(rt.names)
        self.last_detected = False
        self._nostate_scale_error = ""  # why the last threshold_scale was refused ("" if it was not)
        self.invalid_count = 0
        self.numeric_reset_count = 0
        inp = Fmi2Causality.input
        for values, names in ((self.u_in, rt.u_names), (self.y_in, rt.y_names)):
            for i, name in enumerate(names):
                self.register_variable(Real(name, causality=inp, variability=Fmi2Variability.continuous,
                                            start=values[i], getter=_item(values, i), setter=_set_item(values, i)),
                                       nested=False)
        self.register_variable(Real("threshold_scale", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable, start=1.0,
                                    getter=lambda: self.rt.threshold_scale, setter=self._set_scale), nested=False)
        out = Fmi2Causality.output
        for j, name in enumerate(rt.names):
            common = dict(causality=out, variability=Fmi2Variability.discrete, initial=Fmi2Initial.exact)
            kind = output_type(name)
            if kind == "Boolean":
                var = Boolean(name, start=False, getter=_bool_item(self.out, j), **common)
            elif kind == "Integer":
                var = Integer(name, start=0, getter=_int_item(self.out, j), **common)
            else:
                var = Real(name, start=0.0, getter=_item(self.out, j), **common)
            self.register_variable(var, nested=False)

    def _set_scale(self, value):
        # docs/semantics.md §6: a value that is not a finite number >= 0 is refused, the scale kept.
        # pythonfmu cannot return fmi2Error from a setter: the refusal is an error-status message and
        # the following doSteps are discarded with it until a valid value is set or the FMU is reset
        # (the native FMU returns fmi2Error), so a master that ignored the log cannot go on silently.
        try:
            self.rt.set_threshold_scale(value)
        except ValueError as exc:
            self._nostate_scale_error = f"{exc}; it stays {self.rt.threshold_scale!r}"
            self.log(f"threshold_scale refused: {self._nostate_scale_error}", status=Fmi2Status.error,
                     category="logStatusError")
            return
        self._nostate_scale_error = ""

    def validate_fmu_state(self, attributes):
        if attributes.get("design_sha256") != self.design_sha256:
            raise ValueError("FMU state of another design (design fingerprint differs)")
        rt = attributes.get("rt")
        if type(rt) is not type(self.rt):
            raise ValueError(f"FMU state holds no diagnoser runtime (got {type(rt).__name__})")
        # Only the state is taken from the bytes, into a copy of this FMU's own runtime (its design
        # constants are never read from a state); set_state validates it (docs/semantics.md §10).
        fresh = copy.deepcopy(self.rt)
        fresh.set_state(rt.get_state())
        attributes["rt"] = fresh
        for name, n in (("u_in", self.rt.nu), ("y_in", self.rt.ny), ("out", len(self.rt.names))):
            value = attributes.get(name)
            if type(value) is not list or len(value) != n or not all(isinstance(x, float) for x in value):
                raise ValueError(f"FMU state: {name} must be {n} floats")
        if attributes["out"] != fresh.outputs:
            raise ValueError("FMU state: the outputs differ from the runtime's")
        for name in ("invalid_count", "numeric_reset_count"):
            if type(attributes.get(name)) is not int or not 0 <= attributes[name] < 2 ** 53:
                raise ValueError(f"FMU state: {name} must be a count")
        if type(attributes.get("last_detected")) is not bool:
            raise ValueError("FMU state: last_detected must be a bool")

    def step(self, current_time, step_size):
        if self._nostate_scale_error:
            self.log(f"do_step refused: threshold_scale was refused ({self._nostate_scale_error}); set a valid "
                     f"value or reset the FMU", status=Fmi2Status.error, category="logStatusError")
            return False
        if not math.isfinite(current_time) or (math.isfinite(step_size) and not math.isfinite(current_time + step_size)):
            # docs/semantics.md §9: times are finite (the native FMU answers fmi2Error); a non-finite
            # step is the runtime's to refuse (Discard)
            self.log(f"fmi2DoStep: communication point t={current_time!r} with step {step_size!r}: the time must be "
                     f"a finite number and stay one (refused, nothing changed)", status=Fmi2Status.error,
                     category="logStatusError")
            return False
        h_before, ratio_before = self.rt.h, self.rt.sample_ratio
        try:
            out = self.rt.advance(self.u_in, self.y_in, step_size)
        except StepSizeError as exc:
            self.log_event(f"step at t={current_time:g} refused: {exc}", "logStatusDiscard", Fmi2Status.discard)
            return False
        self.out[:] = out
        if self.rt.sample_ratio != ratio_before:
            self.log_event(f"step size changed from {h_before:g} s to {self.rt.h:g} s "
                           f"(design Ts = {self.rt.Ts:g} s): evaluation windows and thresholds restarted "
                           f"(docs/semantics.md, step sizes)", "logStatusWarning", Fmi2Status.warning)
        if out[NUMERIC_RESET]:
            self.numeric_reset_count += 1
            self.log_event(f"the sample overflowed the evaluation (a value became NaN/Inf); "
                           f"counted as fault evidence, sample discarded, generator and evaluation restarted "
                           f"(numeric_reset, input_invalid)", "logFdiNumeric", Fmi2Status.warning)
        elif out[INPUT_INVALID]:
            self.invalid_count += 1
            self.log_event(f"invalid input sample (NaN/Inf or outside its valid range); "
                           f"diagnosis held", "logFdiInput", Fmi2Status.warning)
        detected = out[FAULT_DETECTED] != 0.0
        if detected != self.last_detected:
            iso = int(out[ISOLATED_FAULT])
            what = "fault detected" if detected else "alarm cleared"
            if detected and iso > 0:
                what += f", isolated as '{self._nostate_faults[iso - 1]}'"
            elif detected and iso < 0:
                what += ", not isolated (unknown or several faults)"
            self.log_event(f"t={current_time:g}: {what}")
            self.last_detected = detected
        return True


def _item(values, i):
    return lambda: values[i]


def _bool_item(values, i):
    return lambda: values[i] != 0.0


def _int_item(values, i):
    # an FMI Integer is 32 bits: clamped (the outputs are validated, this is the last guard)
    return lambda: max(-2147483648, min(2147483647, int(values[i]))) if math.isfinite(values[i]) else 0


def _set_item(values, i):
    def setter(v):
        values[i] = float(v)
    return setter
'''
