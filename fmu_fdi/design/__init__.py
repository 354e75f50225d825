"""Residual generator design: one function per method, each returning a ResidualGenerator."""
from .banks import dedicated_bank, generalized_bank, structured_bank
from .nullspace import nullspace_design

__all__ = ["nullspace_design", "structured_bank", "dedicated_bank", "generalized_bank"]
