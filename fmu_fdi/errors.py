"""Exceptions with messages that say which condition failed."""


class ModelError(ValueError):
    """An FDI model, model file or fault specification is invalid."""


class DesignError(ValueError):
    """A requested residual generator or diagnoser cannot be designed; the message says why."""


class BuildError(ValueError):
    """An FMU cannot be written where asked, or the archive written is not a loadable FMU."""


class OutputError(ValueError):
    """An output file cannot be written where asked (checked before any work is done)."""


class InputFileError(ValueError):
    """A file given to read is missing, unreadable, binary, or not the kind of file expected."""


def one_line(exc) -> str:
    """An error's message on one line (the CLI's and the model child's replies)."""
    return " ".join(str(exc).split())
