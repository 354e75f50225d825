"""Stand-in diagnostic slave (test only): the interface of the real diagnostic FMU, trivial maths.

Bundled into the FMU by ``fmu_fdi.fmu.packaging.build_slave_fmu``; imports numpy, the stdlib,
pythonfmu and (relatively) ``slave_base`` only.

Model, with ``v = [u1, u2, y1]`` the inputs as currently set and ``e = [y1 - u1, y1 - u2]``:

    step over h:     x <- a x + (1 - a) e,   a = exp(-h / tau)   (exact for e held over h)
    outputs:         residual = e - x,  evaluation = |residual|,  threshold = threshold_scale * T0,
                     alarm = evaluation > threshold,  fault_detected = any(alarm),
                     isolated_fault = k if only alarm_k else (0 if none else -1),
                     input_invalid = any(v not finite)  (then residuals 0, no alarm, no step).
"""
import math

import numpy as np
from pythonfmu import Boolean, Fmi2Causality, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

from .slave_base import FdiSlave

T0 = (0.2, 0.3)  # unscaled thresholds of the two residuals
VARIANT = 1.0    # a build-time constant that two otherwise identical FMUs can differ in


class StandIn(FdiSlave):
    """Two first-order residuals of y1 against u1 and u2 with threshold alarms."""

    author = "fmu-fdi"
    description = "Stand-in for the fmu-fdi diagnostic FMU (test only)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # the inputs live in one list that the registered getters/setters close over (the
        # pattern of the real slave template): a state restore must write into this list
        self.v = [0.0, 0.0, 0.0]
        self.threshold_scale = 1.0
        self.tau = 0.5
        self.fail_at_step = -1
        self.variant = VARIANT
        self.x = np.zeros(2)
        self.n_steps = 0
        self.alarm_count = np.zeros(2, dtype=np.int64)  # steps spent in alarm, per residual
        self.detected_last_step = False
        for k in (1, 2):
            for name in ("residual", "evaluation", "threshold"):
                setattr(self, f"{name}_{k}", 0.0)
            setattr(self, f"alarm_{k}", False)
        self.fault_detected = False
        self.isolated_fault = 0
        self.input_invalid = False

        inp, out, par = Fmi2Causality.input, Fmi2Causality.output, Fmi2Causality.parameter
        for i, name in enumerate(("u1", "u2", "y1")):
            self.register_variable(Real(name, causality=inp, description=f"plant signal {name}",
                                        getter=_item(self.v, i), setter=_set_item(self.v, i)), nested=False)
        self.register_variable(Real("threshold_scale", causality=par, variability=Fmi2Variability.tunable,
                                    description="factor on every threshold"))
        self.register_variable(Real("tau", causality=par, variability=Fmi2Variability.fixed,
                                    description="filter time constant"))
        self.register_variable(Integer("fail_at_step", causality=par, variability=Fmi2Variability.fixed,
                                       description="raise inside step number n (test hook; -1: never)"))
        for k in (1, 2):
            self.register_variable(Real(f"residual_{k}", causality=out, description=f"residual {k}"))
            self.register_variable(Real(f"evaluation_{k}", causality=out, description=f"|residual {k}|"))
            self.register_variable(Real(f"threshold_{k}", causality=out, description=f"threshold of residual {k}"))
            self.register_variable(Boolean(f"alarm_{k}", causality=out, description=f"evaluation_{k} > threshold_{k}"))
        self.register_variable(Boolean("fault_detected", causality=out, description="any alarm"))
        self.register_variable(Integer("isolated_fault", causality=out,
                                       description="0 none, k the only alarm k, -1 several"))
        self.register_variable(Boolean("input_invalid", causality=out, description="an input is not finite"))

    def _inputs(self):
        return np.array(self.v, dtype=float)

    def update_outputs(self):
        v = self._inputs()
        self.input_invalid = not bool(np.all(np.isfinite(v)))
        e = np.array([v[2] - v[0], v[2] - v[1]]) * self.variant
        r = np.zeros(2) if self.input_invalid else e - self.x
        thr = self.threshold_scale * np.asarray(T0)
        alarm = np.abs(r) > thr
        for k in (1, 2):
            setattr(self, f"residual_{k}", float(r[k - 1]))
            setattr(self, f"evaluation_{k}", float(abs(r[k - 1])))
            setattr(self, f"threshold_{k}", float(thr[k - 1]))
            setattr(self, f"alarm_{k}", bool(alarm[k - 1]))
        self.fault_detected = bool(alarm.any())
        n = int(alarm.sum())
        self.isolated_fault = 0 if n == 0 else (int(np.argmax(alarm)) + 1 if n == 1 else -1)

    def step(self, current_time, step_size):
        if self.n_steps == self.fail_at_step:
            raise RuntimeError(f"injected failure at step {self.n_steps}")
        self._ensure_outputs()  # alarms at the start of the step, for counting and logging
        if self.input_invalid:
            self.log_event(f"t={current_time:g}: input not finite, state held", category="logFdiInput",
                           status=Fmi2Status.warning)
        else:
            if self.fault_detected != self.detected_last_step:
                what = "raised" if self.fault_detected else "cleared"
                self.log_event(f"t={current_time:g}: alarm {what} (isolated_fault={self.isolated_fault})")
                self.detected_last_step = self.fault_detected
            self.alarm_count += np.array([self.alarm_1, self.alarm_2], dtype=np.int64)
            v = self._inputs()
            e = np.array([v[2] - v[0], v[2] - v[1]]) * self.variant
            a = math.exp(-step_size / self.tau)
            self.x = a * self.x + (1.0 - a) * e
        self.n_steps += 1
        return True


def _item(values, i):
    return lambda: values[i]


def _set_item(values, i):
    def set_(value):
        values[i] = value
    return set_
