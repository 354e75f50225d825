"""Checks shared by the versioned file formats (model files, design files)."""
from __future__ import annotations


def check_format(d, expected: str, source: str, error: type[Exception], what: str = "format") -> None:
    """The object is a dict whose ``format`` is exactly ``expected``."""
    if not isinstance(d, dict):
        raise error(f"{source}: the top level must be a table/object")
    fmt = d.get("format")
    if fmt is None:
        raise error(f"{source}: missing key 'format' (expected {expected!r})")
    if fmt != expected:
        raise error(f"{source}: unsupported {what} {fmt!r}; this version reads {expected!r}")


def check_keys(d: dict, required, allowed, where: str, error: type[Exception]) -> None:
    """Every required key is present and no key outside ``allowed`` is."""
    missing = [k for k in required if k not in d]
    if missing:
        raise error(f"{where}: missing keys {missing}")
    unknown = set(d) - set(allowed)
    if unknown:
        raise error(f"{where}: unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}")
