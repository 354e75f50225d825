"""Helpers the plant packages share to state their linear models (design side: may use
fmu_fdi and scipy; never bundled into an FMU)."""
from __future__ import annotations

import numpy as np


def measurement_noise(y_names, stds) -> dict:
    """Noise channels ``n_<y>`` with ``Dw = diag(std)``: unit-variance white sequences at the
    sample instants, scaled to the FMU's default sensor noise (zero stds are left out)."""
    keep = [i for i, s in enumerate(stds) if s > 0]
    Dw = np.zeros((len(y_names), len(keep)))
    for col, i in enumerate(keep):
        Dw[i, col] = stds[i]
    return {"w_names": [f"n_{y_names[i]}" for i in keep], "Dw": Dw}


def sensor_and_actuator_faults(sensor_faults, actuator_faults):
    """Additive sensor and actuator faults as ``(name, output/input)`` pairs."""
    from fmu_fdi.faults import actuator_fault, sensor_fault

    out = [sensor_fault(name, y, f"additive bias of sensor {y} (FMU input f_{name})")
           for name, y in sensor_faults]
    out += [actuator_fault(name, u, f"additive bias of actuator {u} (FMU input f_{name})")
            for name, u in actuator_faults]
    return out
