"""VTOL aircraft (COMPleib HE1) under LQR state feedback (pythonfmu slave).

Signals (names as in vtol.toml): outputs ``collective``, ``cyclic`` (feedback commands, the
model's known inputs u) and ``vh``, ``vv``, ``q``, ``y4`` (measured, y); inputs
``ref_collective``, ``ref_cyclic`` (added to the feedback: u = -K C^-1 y_meas + r).
Faults: ``f_actuator_<u>`` (added to the input the aircraft receives), ``f_sensor_<y>``
(added to the measurement, which the feedback also uses), gain and stuck channels.
Parametric uncertainty: fixed parameters ``delta_a32``, ``delta_a34``, ``delta_b21``
(relative, default 0). Process noise ``std_w_<u>`` adds white noise, held over each
communication step, to the applied inputs. The command at t_k comes from the measurement
at t_k and is applied over [t_k, t_k + h].
"""
import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Slave

import vtol_physics as phys
from vtol_support import ExactLinear, PlantSlave

_REFS = tuple(f"ref_{u}" for u in phys.U)
_PROCESS_NOISE = tuple(f"std_w_{u}" for u in phys.U)


class VTOL(PlantSlave, Fmi2Slave):
    description = "VTOL aircraft (COMPleib HE1) with LQR state feedback; 4 sensors, 2 actuators"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=phys.STEP)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.common_parameters()
        for name in phys.UNCERTAIN:
            self.parameter(name, 0.0, f"relative change of {name[6:]} (documented bound +-{phys.UNCERTAINTY_BOUND})")
        for i, x in enumerate(("vh", "vv", "q", "theta")):
            self.parameter(f"{x}_start", 0.0, f"initial state {i + 1}")
        self.actuators(phys.U, ["", ""], phys.ACTUATOR_FAULTS, ["collective pitch", "longitudinal cyclic pitch"],
                       inputs=False)
        self.sensors(phys.Y, [""] * 4, phys.SENSOR_FAULTS, phys.NOISE_STD, phys.SENSOR_TEXT)
        for u in phys.U:
            self.real_input(f"ref_{u}", 0.0, f"reference added to the {u} feedback command")
            self.parameter(f"std_w_{u}", 0.0, f"std of white noise added to the applied {u}")

    def initialize(self):
        A, B = phys.plant_matrices(*(getattr(self, n) for n in phys.UNCERTAIN))
        self._system = ExactLinear(A, B, phys.C)  # v = the inputs the aircraft receives
        self._feedback = [tuple(row) for row in (-phys.K @ np.linalg.inv(phys.C)).tolist()]  # u = F y + r
        self._x = [float(getattr(self, f"{x}_start")) for x in ("vh", "vv", "q", "theta")]
        self.hold()
        self._control(self.measure((phys.C @ np.array(self._x)).tolist()))

    def hold(self):
        self._refs = self._get(_REFS)

    def _control(self, y_meas):
        y1, y2, y3, y4 = y_meas
        self.collective, self.cyclic = [a1 * y1 + a2 * y2 + a3 * y3 + a4 * y4 + r
                                        for (a1, a2, a3, a4), r in zip(self._feedback, self._refs)]

    def advance(self, t, h):
        u = [a + w for a, w in zip(self.actuate((self.collective, self.cyclic)), self.process_noise(_PROCESS_NOISE))]
        self._x, y = self.step_linear(self._system, self._x, u, h)
        self._control(self.measure(y))
