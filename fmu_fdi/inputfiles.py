"""Input files checked before they are parsed: present, a file, readable, UTF-8 text.

Loaders of text formats (TOML/JSON model and design files, CSV logs) otherwise fail deep in
a decoder with a message that names neither the file nor the problem. The content checks
(an FMU or other zip archive, UTF-16/32, binary, not UTF-8) are the library loaders' own
(:func:`fmu_fdi._schema.read_text`), so the CLI and the Python API say the same thing.
"""
from __future__ import annotations

from pathlib import Path

from ._schema import read_text
from .errors import InputFileError


def check_input_file(path, what: str = "input file") -> Path:
    """Return ``path`` as a Path if it is a readable UTF-8 text file, else raise.

    Raises
    ------
    InputFileError
        Naming the file and the condition: missing, a folder, unreadable, an FMU or other zip
        archive (an FMU where a model belongs points to ``fmu-fdi model``), UTF-16/32, binary
        (NUL bytes), or not UTF-8 (with the byte offset).
    """
    path = Path(path)
    if not path.exists():
        raise InputFileError(f"{what} {str(path)!r} does not exist")
    if path.is_dir():
        raise InputFileError(f"{what} {str(path)!r} is a folder, not a file")
    read_text(path, what, InputFileError)
    return path
