"""fmu-fdi: model-based fault detection and isolation for linear systems, shipped as FMUs."""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the names as the static tools see them; at run time they load on first use
    from .analysis import (detectability, fault_gains, fault_noise_gap, fault_sensitivity_condition, hinf_minus,
                           isolability, leakage, structure_matrix)
    from .design import (RLSEstimator, approximate_model_matching, dedicated_bank, factorized, fault_detection_filter,
                         generalized_bank, kalman, luenberger, model_matching, nullspace_design, parity_space,
                         rls_estimator, structured_bank, unknown_input_observer)
    from .cosim import CoSimulation, Fault, InputSignals, Result, SimulationFailed, export_ssp, parse_fault
    from .diagnoser import Diagnoser
    from .evaluation import (ThresholdDesign, ThresholdEstimate, analytic_threshold, data_driven_threshold,
                             fault_size_thresholds, residual_autocovariance, sensor_gain_plants, threshold_selector)
    from .errors import DesignError, ModelError
    from .fmu import build_fmu
    from .faults import FaultSpec, actuator_fault, component_fault, parametric_fault, sensor_fault
    from .generator import ResidualBank, ResidualGenerator
    from .identify import model_from_fmu
    from .lti import LTI
    from .model import FDIModel
    from .modelset import ModelSet
    from .schedule import ScheduledDiagnoser, load_diagnoser

# ``metrics`` is also the name of its module: bound here (a light module, numpy only), so that an
# import of the submodule fmu_fdi.metrics can never rebind the package attribute to the module
from .metrics import DiagnosisMetrics, metrics  # noqa: E402

__version__ = "0.1.0"

#: every public name and the module that defines it. They load on first use (PEP 562): ``import
#: fmu_fdi`` (and so a campaign worker, the CLI, an FMU's runtime) stays cheap instead of loading the
#: design code, scipy.stats and the identification it may never call (1.4 s → 0.3 s for a campaign worker).
_PUBLIC = {
    "FDIModel": ".model", "FaultSpec": ".faults", "actuator_fault": ".faults", "sensor_fault": ".faults",
    "component_fault": ".faults", "parametric_fault": ".faults", "LTI": ".lti",
    "ResidualGenerator": ".generator", "ResidualBank": ".generator", "DesignError": ".errors",
    "ModelError": ".errors", "luenberger": ".design", "kalman": ".design", "unknown_input_observer": ".design",
    "fault_detection_filter": ".design", "factorized": ".design", "nullspace_design": ".design",
    "parity_space": ".design", "rls_estimator": ".design", "RLSEstimator": ".design",
    "structured_bank": ".design", "dedicated_bank": ".design", "generalized_bank": ".design",
    "model_matching": ".design", "approximate_model_matching": ".design", "Diagnoser": ".diagnoser",
    "build_fmu": ".fmu", "metrics": ".metrics", "DiagnosisMetrics": ".metrics",
    "analytic_threshold": ".evaluation", "data_driven_threshold": ".evaluation",
    "ThresholdEstimate": ".evaluation", "residual_autocovariance": ".evaluation",
    "threshold_selector": ".evaluation", "ThresholdDesign": ".evaluation", "sensor_gain_plants": ".evaluation",
    "fault_size_thresholds": ".evaluation", "structure_matrix": ".analysis", "fault_gains": ".analysis",
    "hinf_minus": ".analysis", "fault_sensitivity_condition": ".analysis", "fault_noise_gap": ".analysis",
    "leakage": ".analysis", "detectability": ".analysis", "isolability": ".analysis", "CoSimulation": ".cosim",
    "Result": ".cosim", "Fault": ".cosim", "parse_fault": ".cosim", "InputSignals": ".cosim",
    "export_ssp": ".cosim", "SimulationFailed": ".cosim", "ModelSet": ".modelset",
    "ScheduledDiagnoser": ".schedule", "load_diagnoser": ".schedule", "model_from_fmu": ".identify",
}

__all__ = list(_PUBLIC)


def __getattr__(name: str):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value  # once loaded, an ordinary attribute
    return value


def __dir__() -> list:
    return sorted(set(globals()) | set(_PUBLIC))
