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
        "Samples discarded because a value inside the runtime became NaN/Inf (numeric_reset)."))

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
        value = float(value)
        if not (value >= 0.0 and math.isfinite(value)):
            self.log_event(f"threshold_scale must be a finite number >= 0, got {value}; kept "
                           f"{self.rt.threshold_scale}", "logStatusWarning", Fmi2Status.warning)
            return
        self.rt.threshold_scale = value

    def validate_fmu_state(self, attributes):
        if attributes.get("design_sha256") != self.design_sha256:
            raise ValueError("FMU state of another design (design fingerprint differs)")
        rt = attributes.get("rt")
        if type(rt) is not type(self.rt):
            raise ValueError(f"FMU state holds no diagnoser runtime (got {type(rt).__name__})")
        copy.deepcopy(self.rt).set_state(rt.get_state())  # shapes, lengths, finiteness; raises ValueError
        for name, n in (("u_in", self.rt.nu), ("y_in", self.rt.ny), ("out", len(self.rt.names))):
            value = attributes.get(name)
            if type(value) is not list or len(value) != n or not all(isinstance(x, float) for x in value):
                raise ValueError(f"FMU state: {name} must be {n} floats")

    def step(self, current_time, step_size):
        h_before, ratio_before = self.rt.h, self.rt.sample_ratio
        try:
            out = self.rt.advance(self.u_in, self.y_in, step_size)
        except StepSizeError as exc:
            self.log_event(f"step at t={current_time:g} refused: {exc}", "logStatusDiscard", Fmi2Status.discard)
            return False
        self.out[:] = out
        if self.rt.sample_ratio != ratio_before:
            self.log_event(f"t={current_time:g}: step size changed from {h_before:g} s to {self.rt.h:g} s "
                           f"(design Ts = {self.rt.Ts:g} s): evaluation windows and thresholds restarted "
                           f"(docs/semantics.md, step sizes)", "logStatusWarning", Fmi2Status.warning)
        if out[INPUT_INVALID]:
            self.invalid_count += 1
            self.log_event(f"t={current_time:g}: invalid input sample (NaN/Inf or outside its valid range); "
                           f"diagnosis held", "logFdiInput", Fmi2Status.warning)
        if out[NUMERIC_RESET]:
            self.numeric_reset_count += 1
            self.log_event(f"t={current_time:g}: a value inside the diagnoser became NaN/Inf; sample discarded, "
                           f"generator and evaluation restarted (numeric_reset)", "logFdiNumeric", Fmi2Status.warning)
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
    return lambda: int(values[i])


def _set_item(values, i):
    def setter(v):
        values[i] = float(v)
    return setter
'''
