"""Reading the versioned file formats (model files, design files): text, syntax, values.

The value checks (:func:`check_format`, :func:`real`, :func:`matrix`, ...) live in
:mod:`fmu_fdi.runtime.schema`, which the diagnostic FMU bundles; this module adds what
only the toolkit needs: reading a file as UTF-8 text with one-line errors for an FMU, a
binary or UTF-16 file given by mistake, and parsing JSON/TOML with the nesting depth,
syntax and number-range failures turned into the caller's error type.
"""
from __future__ import annotations

import json
from pathlib import Path

from .runtime.schema import (MAX_ABS, array, check_depth, check_format, check_keys, flag,  # noqa: F401
                             integer, matrix, names, real, table, text, type_name, vector)

#: how to get a model when the user has a plant FMU (the command of docs/plant-fmu.md)
FMU_TO_MODEL = "run 'fmu-fdi model {fmu} -o model.toml' (docs/plant-fmu.md)"


def read_text(path, what: str, error: type[Exception]) -> str:
    """The file's text (UTF-8); a one-line ``error`` for anything else.

    ``what`` names the expected kind of file in messages (``"model file"``).
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read(4096)  # look before reading all of a (possibly large binary) file
            if not _refused(data, path, what, error):
                data += fh.read()
    except IsADirectoryError:
        raise error(f"{path} is a folder, not a {what}") from None
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{path} is not UTF-8 text (invalid byte at offset {exc.start}); a {what} must be "
                    f"UTF-8") from None


def _refused(data: bytes, path: Path, what: str, error: type[Exception]) -> bool:
    """Raise ``error`` if the file's first bytes show an FMU/zip, UTF-16/32 or binary file."""
    if data[:4] == b"PK\x03\x04":
        kind = "an FMU (a zip archive)" if path.suffix.lower() == ".fmu" else "a zip archive"
        hint = (f"; to diagnose a plant FMU, write its model first: {FMU_TO_MODEL.format(fmu=path)}"
                if path.suffix.lower() == ".fmu" or "model" in what else "")
        raise error(f"{path} is {kind}, not a {what}{hint}")
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise error(f"{path} is UTF-16 or UTF-32 encoded; a {what} must be UTF-8 text (save it as UTF-8)")
    if b"\x00" in data:
        raise error(f"{path} is a binary file, not a {what} (UTF-8 text)")
    return False


def parse(text_: str, syntax: str, source: str, error: type[Exception]):
    """Parse JSON or TOML text; syntax errors, too deep nesting and out-of-range numbers
    become one-line ``error``s (non-finite numbers are left to the value checks)."""
    try:
        if syntax == "json":
            return json.loads(text_, parse_constant=float)
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            import tomli as tomllib
        return tomllib.loads(text_)
    except RecursionError:
        raise error(f"{source}: nesting too deep to be a valid file") from None
    except (ValueError, TypeError) as exc:  # JSONDecodeError, TOMLDecodeError, int overflow
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise error(f"{source}: not valid {syntax.upper()}: {msg}") from None
