"""Exceptions with messages that say which condition failed."""


class ModelError(ValueError):
    """An FDI model, model file or fault specification is invalid."""


class DesignError(ValueError):
    """A requested residual generator or diagnoser cannot be designed; the message says why."""
