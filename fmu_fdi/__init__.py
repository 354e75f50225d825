"""fmu-fdi: model-based fault detection and isolation for linear systems, shipped as FMUs."""
from .analysis import (detectability, fault_gains, fault_noise_gap, fault_sensitivity_condition, hinf_minus,
                       isolability, leakage, structure_matrix)
from .design import (RLSEstimator, approximate_model_matching, dedicated_bank, factorized, fault_detection_filter,
                     generalized_bank, kalman, luenberger, model_matching, nullspace_design, parity_space,
                     rls_estimator, structured_bank, unknown_input_observer)
from .cosim import CoSimulation, Fault, InputSignals, Result, SimulationFailed, export_ssp, parse_fault
from .diagnoser import Diagnoser
from .evaluation import (ThresholdDesign, ThresholdEstimate, analytic_threshold, data_driven_threshold,
                         fault_size_thresholds, residual_autocovariance, sensor_gain_plants, threshold_selector)
from .metrics import DiagnosisMetrics, metrics
from .errors import DesignError, ModelError
from .fmu import build_fmu
from .faults import FaultSpec, actuator_fault, component_fault, parametric_fault, sensor_fault
from .generator import ResidualBank, ResidualGenerator
from .identify import model_from_fmu
from .lti import LTI
from .model import FDIModel
from .modelset import ModelSet
from .schedule import ScheduledDiagnoser, load_diagnoser

__version__ = "0.1.0"

__all__ = [
    "FDIModel", "FaultSpec", "actuator_fault", "sensor_fault", "component_fault", "parametric_fault",
    "LTI", "ResidualGenerator", "ResidualBank", "DesignError", "ModelError",
    "luenberger", "kalman", "unknown_input_observer", "fault_detection_filter", "factorized",
    "nullspace_design", "parity_space", "rls_estimator", "RLSEstimator", "structured_bank", "dedicated_bank", "generalized_bank",
    "model_matching", "approximate_model_matching",
    "Diagnoser", "build_fmu", "metrics", "DiagnosisMetrics", "analytic_threshold", "data_driven_threshold",
    "ThresholdEstimate", "residual_autocovariance", "threshold_selector", "ThresholdDesign", "sensor_gain_plants", "fault_size_thresholds",
    "structure_matrix", "fault_gains", "hinf_minus", "fault_sensitivity_condition", "fault_noise_gap",
    "leakage", "detectability", "isolability",
    "CoSimulation", "Result", "Fault", "parse_fault", "InputSignals", "export_ssp", "SimulationFailed",
]
__all__ += ["ModelSet", "ScheduledDiagnoser", "load_diagnoser", "model_from_fmu"]  # the operating envelope (docs/envelope.md)
