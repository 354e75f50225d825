"""Lateral aircraft with loss-of-effectiveness actuator faults (pythonfmu slave).

Signals (names as in lateral_aircraft.toml): inputs ``u1``, ``u2`` (control surface
commands); outputs ``beta``, ``phi`` (rad), ``p``, ``r`` (rad/s). LOE faults: the inputs
act through Gamma = diag(1 - gamma_1, 1 - gamma_2) with gamma_j = ``gamma_<j>`` (tunable
parameter, Varga's multiple-model campaign) + ``f_loe_u<j>`` (input, the model file's
parametric fault loe_u<j>, for scheduled faults), clipped to [0, 1]. Also additive and
gain/stuck channels per sensor and actuator, and process noise ``std_w_<x>`` on each state
derivative (held over each communication step).
"""
import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Slave

import lateral_physics as phys
from lateral_support import ExactLinear, PlantSlave

_GAMMA = ("gamma_1", "gamma_2")
_LOE = tuple(f"f_{n}" for n in phys.LOE_FAULTS)
_PROCESS_NOISE = tuple(f"std_w_{y}" for y in phys.Y)


class LateralAircraft(PlantSlave, Fmi2Slave):
    description = "Lateral aircraft (Varga, Ex. 6.1/6.2) with loss-of-effectiveness actuator faults"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=phys.STEP)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.common_parameters()
        for j in (1, 2):
            self.parameter(f"gamma_{j}", 0.0, f"loss of effectiveness of input u{j}, in [0, 1]", tunable=True)
        for y, text, unit in zip(phys.Y, phys.SENSOR_TEXT, (phys.UNITS[y] for y in phys.Y)):
            self.parameter(f"{y}_start", 0.0, f"initial {text}", unit)
            self.parameter(f"std_w_{y}", phys.PROCESS_NOISE_STD[phys.Y.index(y)],
                           f"std of white noise on the derivative of {text}", unit + "/s" if unit else "")
        self.actuators(phys.U, ["", ""], phys.ACTUATOR_FAULTS, ["control surface 1", "control surface 2"])
        self.sensors(phys.Y, [phys.UNITS[y] for y in phys.Y], phys.SENSOR_FAULTS, phys.NOISE_STD, phys.SENSOR_TEXT)
        for j, name in enumerate(phys.LOE_FAULTS, start=1):
            self.real_input(f"f_{name}", 0.0, f"loss of effectiveness of u{j} added to gamma_{j} "
                                              f"(model fault {name})")

    def initialize(self):
        # v = (Gamma u_applied, w): the effective inputs and the process noise on every derivative
        self._system = ExactLinear(phys.A, np.hstack([phys.BU, np.eye(len(phys.Y))]), phys.C)
        self._x = [float(getattr(self, f"{y}_start")) for y in phys.Y]
        self.measure((phys.C @ np.array(self._x)).tolist())

    def hold(self):
        effectiveness = [1.0 - min(max(g + f, 0.0), 1.0) for g, f in zip(self._get(_GAMMA), self._get(_LOE))]
        self._u = [e * a for e, a in zip(effectiveness, self.actuate(self._get(phys.U)))]  # Gamma u_applied

    def advance(self, t, h):
        self._x, y = self.step_linear(self._system, self._x, self._u + self.process_noise(_PROCESS_NOISE), h)
        self.measure(y)
