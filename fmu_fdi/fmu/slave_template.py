"""Source of the slave module bundled into every diagnostic FMU.

:func:`fmu_fdi.fmu.builder.build_fmu` writes it into the FMU's private package next to a
copy of :mod:`fmu_fdi.runtime` and the design file, with ``__CLASS__`` replaced by the
model identifier. It imports only numpy, the standard library, pythonfmu and (relatively)
its own package: the runtime and :mod:`.slave_base`, which catches every exception,
keeps the whole instance as the FMU state and logs through the FMI logger.

Timing: ``fmi2DoStep(t, h)`` consumes the inputs set for time t and makes the outputs the
diagnosis of that sample (row k of ``Diagnoser.run``); outputs do not depend on inputs
directly (no feedthrough), so a master may read them any time after the step.
"""

TEMPLATE = r'''"""fmu-fdi diagnostic FMU slave (generated): residual generation, evaluation, decision."""
import json
import math
import os

from pythonfmu import Boolean, Fmi2Causality, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from .engine import DiagnoserRuntime, StepSizeError
from .slave_base import FdiSlave

# The design is read from *this instance's* resources folder: a host may run an FMU again after
# deleting the first extraction, while pythonfmu keeps the module imported from it.
_PACKAGE = __package__


class __CLASS__(FdiSlave):
    author = "fmu-fdi"
    description = __DESCRIPTION__

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        with open(os.path.join(self.resources, _PACKAGE, "design.json"), encoding="utf-8") as fh:
            design = json.load(fh)
        self.rt = DiagnoserRuntime(design)
        self._nostate_faults = [f["name"] for f in design.get("faults", [])]
        rt = self.rt
        self.u_in = [float(v) for v in rt.u0]
        self.y_in = [float(v) for v in rt.y0]
        self.out = [0.0] * len(rt.names)
        self.last_detected = False
        self.invalid_count = 0
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
            if name.startswith("alarm_") or name in ("fault_detected", "input_invalid"):
                var = Boolean(name, start=False, getter=_bool_item(self.out, j), **common)
            elif name == "isolated_fault":
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

    def step(self, current_time, step_size):
        try:
            out = self.rt.advance(self.u_in, self.y_in, step_size)
        except StepSizeError as exc:
            self.log_event(f"step at t={current_time:g} refused: {exc}", "logStatusDiscard", Fmi2Status.discard)
            return False
        self.out[:] = out
        if out[-1]:
            self.invalid_count += 1
            self.log_event(f"t={current_time:g}: invalid (NaN/Inf) input sample; diagnosis held", "logFdiInput",
                           Fmi2Status.warning)
        detected = out[-3] != 0.0  # outputs end with fault_detected, isolated_fault, input_invalid
        if detected != self.last_detected:
            iso = int(out[-2])
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
