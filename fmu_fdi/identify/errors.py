"""The one exception of identify/: a ModelError, so every entry point reports it as one line."""
from ..errors import ModelError


class IdentificationError(ModelError):
    """A plant FMU cannot be linearised or identified as asked; the message names the cause and the fix."""
