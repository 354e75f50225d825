"""A plant FMU for co-simulation tests of the diagnostic FMU: Varga's Ex 5.3 plant, exact.

The slave holds the zero-order-hold discretisation (Ts) of the Ex 5.3 model and drives it
with u = sin(2π t) and 0.5 step faults from t = 0.05 (both faults, as in A7); its outputs
u, y1, y2 at a communication point are functions of the state and time only, so every
host reproduces them exactly. Built with fmu_fdi.fmu.packaging (unique bundle name).
"""

from fmu_fdi.fmu.packaging import build_slave_fmu

SOURCE = '''
import math

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Variability, Real

from .slave_base import FdiSlave

AD = np.array(__AD__)
BD = np.array(__BD__)
C = np.array(__C__)
D = np.array(__D__)
TS = __TS__


class Ex53Plant(FdiSlave):
    author = "fmu-fdi tests"
    description = "Varga Ex 5.3 plant, exact ZOH at Ts, u = sin(2 pi t), faults 0.5 from t = 0.05"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = np.zeros(AD.shape[0])
        self.k = 0
        self.u = 0.0
        self.y1 = 0.0
        self.y2 = 0.0
        for name in ("u", "y1", "y2"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.discrete, description=name), nested=False)
        self.update_outputs()

    def _inputs(self, k):
        t = k * TS
        f = 0.5 if t >= 0.05 - 1e-12 else 0.0
        return np.array([math.sin(2 * math.pi * t), 0.0, f, f])  # [u, d, f_a, f_s2]

    def update_outputs(self):
        v = self._inputs(self.k)
        y = C @ self.x + D @ v
        self.u, self.y1, self.y2 = float(v[0]), float(y[0]), float(y[1])

    def step(self, current_time, step_size):
        if abs(step_size - TS) > 1e-12:
            return False
        self.x = AD @ self.x + BD @ self._inputs(self.k)
        self.k += 1
        return True
'''


def build_plant(path, Ts):
    import published as pub

    G = pub.ex5_3().lti().to_discrete(Ts)
    src = (SOURCE.replace("__AD__", repr(G.A.tolist())).replace("__BD__", repr(G.B.tolist()))
           .replace("__C__", repr(G.C.tolist())).replace("__D__", repr(G.D.tolist())).replace("__TS__", repr(Ts)))
    return build_slave_fmu({"ex53_plant.py": src}, "ex53_plant:Ex53Plant", path,
                           default_experiment={"startTime": 0.0, "stepSize": Ts})
