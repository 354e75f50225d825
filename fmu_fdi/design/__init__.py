"""Residual generator design: one function per method, each returning a ResidualGenerator."""
from .approximate_matching import approximate_model_matching
from .banks import afdi_bank, dedicated_bank, generalized_bank, structured_bank
from .beard_jones import fault_detection_filter
from .coprime import factorized, left_coprime_factors
from .datadriven import data_driven
from .kalman_filter import kalman
from .matching import model_matching
from .model_detection import (approximate_model_detection_bank, distance_mapping, match_model, model_detection_bank,
                              noise_gaps)
from .nullspace import nullspace_design
from .output_observer import luenberger
from .parity import parity_space
from .rls import RLSEstimator, rls_estimator
from .uio import unknown_input_observer
from .unified import unified_observer

__all__ = [
    "parity_space", "luenberger", "kalman", "unknown_input_observer", "fault_detection_filter", "factorized",
    "left_coprime_factors", "nullspace_design", "dedicated_bank", "generalized_bank", "structured_bank",
    "rls_estimator", "RLSEstimator", "data_driven", "model_matching", "approximate_model_matching",
    "unified_observer", "afdi_bank", "model_detection_bank", "approximate_model_detection_bank", "distance_mapping",
    "noise_gaps", "match_model",
]
