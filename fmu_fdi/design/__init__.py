"""Residual generator design: one function per method, each returning a ResidualGenerator."""
from .banks import dedicated_bank, generalized_bank, structured_bank
from .nullspace import nullspace_design
from .parity import parity_space
from .rls import RLSEstimator, rls_estimator

__all__ = ["nullspace_design", "parity_space", "rls_estimator", "RLSEstimator", "structured_bank", "dedicated_bank", "generalized_bank"]
