"""Residual generator design: one function per method, each returning a ResidualGenerator.

Laid out as the theory reads (Varga 2017): :mod:`.toolkit` holds the state-space machinery
underneath (minimal bases, pencils, stable factorisations, the judge), :mod:`.problems` one
module per synthesis problem above it, :mod:`.observers` the classical observers beside them.
"""
from .observers.beard_jones import fault_detection_filter
from .observers.kalman_filter import kalman
from .observers.output_observer import luenberger
from .observers.uio import unknown_input_observer
from .problems.approximate_matching import approximate_model_matching
from .problems.banks import afdi_bank, dedicated_bank, generalized_bank, structured_bank
from .problems.coprime import factorized, left_coprime_factors
from .problems.datadriven import data_driven
from .problems.matching import model_matching
from .problems.model_detection import (approximate_model_detection_bank, distance_mapping, match_model,
                                       model_detection_bank, noise_gaps)
from .problems.nullspace import nullspace_design
from .problems.parity import parity_space
from .problems.rls import RLSEstimator, rls_estimator
from .problems.unified import unified_observer

__all__ = [
    "parity_space", "luenberger", "kalman", "unknown_input_observer", "fault_detection_filter", "factorized",
    "left_coprime_factors", "nullspace_design", "dedicated_bank", "generalized_bank", "structured_bank",
    "rls_estimator", "RLSEstimator", "data_driven", "model_matching", "approximate_model_matching",
    "unified_observer", "afdi_bank", "model_detection_bank", "approximate_model_detection_bank", "distance_mapping",
    "noise_gaps", "match_model",
]
