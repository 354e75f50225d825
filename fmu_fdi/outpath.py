"""Output paths checked before the work that fills them, so a long run never ends in a
failure to save its result.

A command that writes a file calls :func:`check_output_path` first: the name must have one of
the expected suffixes and must not be a folder, and its folder must exist or be creatable and
must accept a new file (tried with a temporary file, which is the only test that holds for
every user, ACLs and read-only mounts included). Missing folders are created.
"""
from __future__ import annotations

import copy
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import OutputError


def check_output_path(path, suffixes=(), what: str = "output file", error=OutputError, inputs=()) -> Path:
    """Return ``path`` as a Path once a file can be written there; create missing folders.

    Parameters
    ----------
    path : path
    suffixes : sequence of str
        Accepted suffixes, e.g. ``(".json",)`` (compared case-insensitively); empty: any.
    what : str
        What the file is, for the message ("design file").
    error : exception class
        Raised on failure (default :class:`~fmu_fdi.errors.OutputError`).
    inputs : sequence of path
        The files the command reads: the output must be none of them (the same file by any
        name, links included), else the result would overwrite what it is computed from.

    Raises
    ------
    error
        Naming the condition that failed: wrong suffix, a folder, a parent that is a file,
        a folder that cannot be created or written.
    """
    path = Path(path)
    for given in inputs:
        if given is not None and _same_file(path, Path(given)):
            raise error(f"{what} {str(path)!r} is the input file {str(given)!r}; writing it would destroy what it is "
                        f"computed from: give another output name")
    if path.is_dir():
        example = path / ("result" + (suffixes[0] if suffixes else ""))
        raise error(f"{what} {str(path)!r} is a folder; give a file name, e.g. {example}")
    if suffixes and path.suffix.lower() not in suffixes:
        raise error(f"{what} {str(path)!r} must end in {' or '.join(suffixes)}")
    folder = path.parent
    existing = next((p for p in (folder, *folder.parents) if p.exists()), Path("."))
    if not existing.is_dir():
        raise error(f"cannot write {what} {str(path)!r}: {existing} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise error(f"cannot write {what} {str(path)!r}: folder {folder} is not writable "
                    f"({exc.strerror or exc})") from None
    return path


def write_atomically(path, fill, mode: int = 0o644) -> Path:
    """Write ``path`` all at once: ``fill(part)`` writes a temporary file beside it, which is
    then given ``mode`` and renamed over ``path`` (``os.replace``, atomic on one file system).

    A failure anywhere in ``fill`` leaves the previous ``path`` exactly as it was and removes
    the temporary file, so no reader ever sees half a file.
    """
    path = Path(path)
    fd, part = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        fill(Path(part))
        os.chmod(part, mode)  # mkstemp makes it private; our files are meant to be shared
        os.replace(part, path)
    finally:
        if os.path.exists(part):
            os.remove(part)
    return path


def _same_file(a: Path, b: Path) -> bool:
    """True if ``a`` and ``b`` name one file (an existing one by device and inode)."""
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
        return a.resolve() == b.resolve()
    except OSError:
        return False


_PLAIN = frozenset({int, str, bool, type(None)})


def _clean(x):
    """JSON-ready copy: numpy → lists and floats, non-finite floats → None."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        kinds = set(map(type, x))  # a row of plain numbers (the bulk of a large design) is copied at C speed
        if kinds <= _PLAIN | {float} and (float not in kinds or all(map(math.isfinite, filter(_is_float, x)))):
            return list(x)
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        if x.dtype.kind in "iub" or (x.dtype.kind == "f" and np.isfinite(x).all()):
            return x.tolist()
        return _clean(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if math.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, complex):
        return [x.real, x.imag]
    return x


def copied(x):
    """A deep copy of JSON-like data (dicts, lists, numpy arrays, plain values) that copies a
    row of plain values at C speed (``copy.deepcopy`` visits every number: 3 s per million)."""
    if isinstance(x, dict):
        return {k: copied(v) for k, v in x.items()}
    if isinstance(x, list):
        return list(x) if _PLAIN.union({float}).issuperset(map(type, x)) else [copied(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.copy()
    return x if isinstance(x, (str, int, float, bool, type(None))) else copy.deepcopy(x)


def _is_float(v) -> bool:
    return type(v) is float


def json_text(d) -> str:
    """JSON of a JSON-ready value (:func:`_clean`), one item per line (indent 1) except that a list
    of plain values — a matrix row, a name list — takes one line: readable, and written by the
    json module's C encoder (the indenting encoder is pure Python: 1 s per million numbers).
    Floats keep Python's shortest round-trip repr; NaN and infinity are refused."""
    import json

    def lines(v, pad: str) -> str:
        if isinstance(v, dict) and v:
            inner = pad + " "
            return "{\n" + ",\n".join(f"{inner}{json.dumps(k)}: {lines(x, inner)}" for k, x in v.items()) + \
                "\n" + pad + "}"
        if isinstance(v, list) and v and not _PLAIN.union({float}).issuperset(map(type, v)):
            inner = pad + " "
            return "[\n" + ",\n".join(inner + lines(x, inner) for x in v) + "\n" + pad + "]"
        return json.dumps(v, allow_nan=False)

    return lines(d, "")
