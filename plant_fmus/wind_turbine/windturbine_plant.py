"""Wind-turbine benchmark pitch systems, drive train and converter (pythonfmu slave).

Signals (names as in wind_pitch.toml and wind_drive_train.toml): inputs ``beta_ref_1..3``
(deg), ``tau_g_ref`` (Nm) and ``tau_r`` (aerodynamic rotor torque, Nm: the unknown
input); outputs ``beta_<i>_m<j>`` (deg), ``omega_r_m1/2``, ``omega_g_m1/2`` (rad/s),
``tau_g_m`` (Nm). Faults: ``f_sensor_<y>`` for every sensor (additive), gain and stuck
channels per sensor (benchmark faults 1-5 are stuck and gain faults), ``f_pitch_<i>_
pressure_drop`` and ``f_pitch_<i>_air_in_oil`` (fault level theta in [0, 1], benchmark
faults 6 and 7), ``f_converter_offset`` (Nm, fault 8), ``f_drive_train_efficiency`` (change
of eta_dt, fault 9: -0.05), and the generic actuator channels of beta_ref_i and tau_g_ref.
Process noise ``std_w_tau_r`` adds white noise, held over each step, to tau_r.
"""
import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Slave

import windturbine_physics as phys
from windturbine_support import ExactLinear, PlantSlave

PITCH_FAULTS = tuple(f"f_pitch_{i}_{kind}" for kind in phys.PITCH_FAULT_KINDS for i in phys.BLADES)
_COMMANDS = tuple(phys.PITCH_U + phys.DT_U)


class WindTurbine(PlantSlave, Fmi2Slave):
    description = ("Wind-turbine FDI benchmark (Odgaard et al.): pitch systems, drive train and converter "
                   "with the benchmark's sensor, actuator and system faults")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=phys.STEP)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        x0, tau_r0 = phys.operating_point()
        self.common_parameters()
        for key, value in phys.PARAMS.items():
            self.parameter(key, value, f"benchmark parameter {key}")
        self.parameter("omega_r_op", phys.OMEGA_R_OP, "rotor speed of the initial steady state", "rad/s")
        self.parameter("tau_g_op", phys.TAU_G_OP, "generator torque of the initial steady state", "Nm")
        self.parameter("beta_op", phys.BETA_OP, "initial pitch angle of all blades", "deg")
        units = phys.UNITS
        actuators = phys.PITCH_U + phys.DT_U
        self.actuators(actuators, [units[u] for u in actuators], [f"actuator_{u}" for u in actuators],
                       [f"pitch reference of blade {i}" for i in phys.BLADES] + ["converter torque reference"],
                       starts=[phys.BETA_OP] * 3 + [x0[3]])
        self.real_input("tau_r", tau_r0, "aerodynamic rotor torque (unknown input)", "Nm")
        self.parameter("std_w_tau_r", 0.0, "std of white noise added to tau_r", "Nm")
        texts = [f"pitch angle of blade {y[5]}, sensor {y[-1]}" for y in phys.PITCH_Y] + \
                ["rotor speed, sensor 1", "rotor speed, sensor 2", "generator speed, sensor 1",
                 "generator speed, sensor 2", "generator torque"]
        sensors = phys.PITCH_Y + phys.DT_Y
        self.sensors(sensors, [units[y] for y in sensors], [f"sensor_{y}" for y in sensors],
                     [phys.NOISE_STD[y] for y in sensors], texts)
        for name in PITCH_FAULTS:
            blade, kind = name.split("_", 3)[2:]
            self.real_input(name, 0.0, f"pitch actuator {blade}: {kind.replace('_', ' ')} fault level, in [0, 1]")
        self.real_input("f_converter_offset", 0.0, "converter torque offset (model fault converter_offset)", "Nm")
        self.real_input("f_drive_train_efficiency", 0.0, "change of eta_dt (model fault drive_train_efficiency)")

    def _params(self):
        return {key: float(getattr(self, key)) for key in phys.PARAMS}

    def initialize(self):
        p = self._params()
        for key in ("J_g", "J_r", "N_g", "K_dt", "alpha_gc"):
            if not p[key] > 0:
                raise ValueError(f"parameter {key} must be > 0, got {p[key]}")
        self._p, self._systems = p, {}
        _, _, Cp = phys.pitch_matrices(p)
        *_, Cd = phys.drive_train_matrices(p)
        self._C = np.zeros((Cp.shape[0] + Cd.shape[0], 10))
        self._C[:Cp.shape[0], :6], self._C[Cp.shape[0]:, 6:] = Cp, Cd
        x0, _ = phys.operating_point(p, self.omega_r_op, self.tau_g_op)
        self._x = [float(self.beta_op), 0.0] * 3 + x0.tolist()
        self.measure((self._C @ np.array(self._x)).tolist())

    def _system(self, theta: tuple, eff: float) -> ExactLinear:
        """The whole plant for the pitch fault levels and the efficiency change, with the inputs
        v = (beta_ref_1..3, tau_g_ref as applied, tau_r, converter offset); built once per distinct
        fault level (the parameters are fixed after initialisation; the last 64 are kept)."""
        key = (theta, eff)
        system = self._systems.get(key)
        if system is None:
            p = self._p
            th = np.array(theta).reshape(2, 3)
            Ap, Bp, _ = phys.pitch_matrices(p, th[0], th[1])
            Ad, Bu, Bd, _ = phys.drive_train_matrices(p, eff)
            A, B = np.zeros((10, 10)), np.zeros((10, 6))
            A[:6, :6], A[6:, 6:] = Ap, Ad
            B[:6, :3], B[6:, 3], B[6:, 4] = Bp, Bu[:, 0], Bd[:, 0]
            B[7, 5] = -1.0 / p["J_g"]  # the converter offset acts on the generator
            if len(self._systems) >= 64:
                self._systems.pop(next(iter(self._systems)))
            system = self._systems[key] = ExactLinear(A, B, self._C)
        return system

    def hold(self):
        theta = tuple(min(max(v, 0.0), 1.0) for v in self._get(PITCH_FAULTS))
        self._held_system = self._system(theta, float(self.f_drive_train_efficiency))
        self._offset = float(self.f_converter_offset)
        self._u = self.actuate(self._get(_COMMANDS))

    def advance(self, t, h):
        v = self._u + [self.tau_r + self.process_noise(("std_w_tau_r",))[0], self._offset]
        self._x, y = self.step_linear(self._held_system, self._x, v, h)
        y[-1] += self._offset  # the measured torque is the one acting, offset included
        self.measure(y)
