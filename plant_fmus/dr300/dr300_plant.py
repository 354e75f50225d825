"""DC motor DR300 in closed loop with its PI speed controller (pythonfmu slave).

Signals (names as in dr300.toml): outputs ``voltage`` (controller output V, the model's
known input u) and ``speed`` (measured, y); inputs ``speed_ref`` (reference) and
``load_torque`` (the unknown input d). Faults: ``f_actuator_voltage`` (V, added to the
voltage the motor receives, not to the reported controller output) and
``f_sensor_speed`` (added to the measured speed, which the controller also uses), plus
gain and stuck channels. Process noise ``std_w_load_torque`` adds white noise, held over
each communication step, to the load torque.

The controller output at t_k is computed from the measurement at t_k and the reference as
set for the step that ended at t_k, and is applied over [t_k, t_k + h]; so the pair
(voltage_k, speed_k) the FMU reports at t_k is what a discrete-time model x_{k+1} =
Ad x_k + Bd u_k, y_k = C x_k expects.
"""
import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Slave

import dr300_physics as phys
from dr300_support import ExactLinear, PlantSlave


class DR300(PlantSlave, Fmi2Slave):
    description = "DC motor DR300 with PI speed control; load torque, actuator and speed-sensor faults"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=phys.STEP)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.common_parameters()
        for key, text in (("k_u", "static gain voltage -> speed"), ("T1", "plant time constant 1 (s)"),
                          ("T2", "plant time constant 2 (s)"), ("T3", "plant time constant 3 (s)"),
                          ("k_d", "load torque integrator gain"), ("k_c", "PI gain: Gc = k_c (1 + T1 s)/s")):
            self.parameter(key, phys.PARAMS[key], text, "s" if key.startswith("T") else "")
        self.actuators(phys.U, ["V"], phys.ACTUATOR_FAULTS, ["motor voltage"], inputs=False)
        self.sensors(phys.Y, [""], phys.SENSOR_FAULTS, phys.NOISE_STD, ["motor speed"])
        self.real_input("speed_ref", 0.0, "speed reference of the PI controller")
        self.real_input("load_torque", 0.0, "load torque (the model's unknown input)")
        self.parameter("std_w_load_torque", 0.0, "std of white noise added to the load torque")

    def initialize(self):
        p = {k: float(getattr(self, k)) for k in phys.PARAMS}
        for key in ("T1", "T2", "T3"):
            if not p[key] > 0:
                raise ValueError(f"parameter {key} must be > 0, got {p[key]}")
        A, Bu, Bd, C = phys.matrices(p)
        self._system = ExactLinear(A, np.hstack([Bu, Bd]), C)  # v = (voltage received, load torque)
        self._kp, self._ki = phys.pi_gains(p)
        self._x = [0.0] * A.shape[0]
        self._xi = 0.0
        self._control(self.measure((C @ np.array(self._x)).tolist())[0])

    def _control(self, y_meas):
        """PI output for the coming step from the measurement at its start."""
        self._e = self.speed_ref - y_meas
        self.voltage = self._kp * self._e + self._ki * self._xi

    def advance(self, t, h):
        v = self.actuate((self.voltage,))
        v.append(self.load_torque + self.process_noise(("std_w_load_torque",))[0])
        self._x, y = self.step_linear(self._system, self._x, v, h)
        self._xi += h * self._e
        self._control(self.measure(y)[0])
