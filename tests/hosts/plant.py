"""Plant-like stand-in slave (test only) that drives the diagnostic stand-in in a co-simulation.

Outputs are functions of time and one state, so any host reproduces them exactly:

    u1 = sin(2 t),  u2 = cos(t),  z <- b z + (1 - b) u1 over a step,  b = exp(-h / 0.3),
    y1 = z + bias (bias = 0.6 from t >= 1, a sensor fault),
with t the time reached (start time after initialization, end of the last step).
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Variability, Real

from .slave_base import FdiSlave


class Plant(FdiSlave):
    """First-order plant with a sensor bias fault at t = 1."""

    author = "fmu-fdi"
    description = "Plant stand-in (test only)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time = 0.0
        self.z = 0.0
        self.bias = 0.6
        self.u1 = 0.0
        self.u2 = 0.0
        self.y1 = 0.0
        out = Fmi2Causality.output
        for name in ("u1", "u2", "y1"):
            self.register_variable(Real(name, causality=out, description=f"plant signal {name}"))
        self.register_variable(Real("bias", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed, description="sensor fault size"))

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        super().setup_experiment(start_time, stop_time, tolerance)  # guarded; sets start_time
        self.time = getattr(self, "start_time", 0.0)

    def update_outputs(self):
        t = self.time
        self.u1 = math.sin(2.0 * t)
        self.u2 = math.cos(t)
        self.y1 = self.z + (self.bias if t >= 1.0 else 0.0)

    def step(self, current_time, step_size):
        b = math.exp(-step_size / 0.3)
        self.z = b * self.z + (1.0 - b) * math.sin(2.0 * current_time)
        self.time = current_time + step_size
        return True
