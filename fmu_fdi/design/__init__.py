"""Residual generator design: one function per method, each returning a ResidualGenerator."""
from .banks import dedicated_bank, generalized_bank, structured_bank
from .nullspace import nullspace_design
from .parity import parity_space

__all__ = ["nullspace_design", "parity_space", "structured_bank", "dedicated_bank", "generalized_bank"]
