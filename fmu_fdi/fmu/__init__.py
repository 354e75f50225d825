"""The diagnostic FMU: build it from a Diagnoser, and run it in FMI hosts (see docs/fmu-hosts.md and docs/fmu-internals.md)."""
from .builder import build_fmu

__all__ = ["build_fmu"]
