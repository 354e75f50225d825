"""Strict checks of values read from the versioned JSON/TOML files (numpy and stdlib only).

Model files (``fmu-fdi-model/1``) and design files (``fmu-fdi-design/1``) are data typed by
hand or by other tools, so every value is checked for its JSON type before it is used:
nothing is coerced. A string (``"0.5"``, ``"1e-3"``) or a Boolean (``true``) where a
number belongs is an error, as is a number outside the range the computations can hold.
Each check raises the caller's error class with a one-line message naming the key.

The module lives in the runtime package because the diagnostic FMU bundles that package
as it is: the FMU checks its design with the same code as ``Diagnoser.load`` and
``fmu-fdi build`` (see :mod:`.design_check`).
"""
from __future__ import annotations

import math
import numbers
import re

import numpy as np

#: Largest magnitude accepted for a matrix entry or parameter. Residual generation and
#: design form products and squared norms (Gramians, ``||r||²``); with |x| ≤ 1e150 a
#: square stays below 1e300 < 1.8e308 (the float maximum), so no overflow comes from
#: the data alone.
MAX_ABS = 1e150


#: a signal name: an identifier, or an FMI 3 array element in FMI's structured naming,
#: ``y[2]`` / ``A[1,2]`` (indices from 1; fmu_fdi/cosim/elements.py says why this spelling)
SIGNAL_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[[1-9][0-9]*(,[1-9][0-9]*)*\])?$")


#: deepest nesting of lists/tables a file may have (the deepest legitimate value, a
#: matrix inside a fault inside the model inside a design, is 5 levels down)
MAX_DEPTH = 64


def check_depth(value, where: str, error: type[Exception], limit: int = MAX_DEPTH) -> None:
    """No list/table nests deeper than ``limit`` (checked without recursion, so a hostile
    file cannot exhaust the stack of the code that later copies or serialises it)."""
    stack = [(value, 0)]
    while stack:
        node, depth = stack.pop()
        if depth > limit:
            raise error(f"{where}: values nest deeper than {limit} levels")
        if isinstance(node, dict):
            stack.extend((v, depth + 1) for v in node.values())
        elif isinstance(node, (list, tuple)) and not _LEAF_TYPES.issuperset(map(type, node)):
            # (a row of numbers, the bulk of a large file, is passed over at C speed)
            stack.extend((v, depth + 1) for v in node if isinstance(v, (list, tuple, dict)))


_LEAF_TYPES = frozenset({int, float, str, bool, type(None)})


def type_name(value) -> str:
    """The JSON/TOML name of a value's type, for messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a Boolean"
    if isinstance(value, str):
        return f"the string {value[:40]!r}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}" if not isinstance(value, int) or abs(value) < 10**20 else "a huge integer"
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, dict):
        return "a table/object"
    return type(value).__name__


def check_format(d, expected: str, source: str, error: type[Exception], what: str = "format") -> None:
    """The object is a dict whose ``format`` is exactly ``expected``."""
    if not isinstance(d, dict):
        raise error(f"{source}: the top level must be a table/object, got {type_name(d)}")
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
        raise error(f"{where}: unknown keys {sorted(map(str, unknown))}; allowed: {sorted(allowed)}")


def table(value, where: str, error: type[Exception]) -> dict:
    if not isinstance(value, dict):
        raise error(f"{where} must be a table/object, got {type_name(value)}")
    return value


def array(value, where: str, error: type[Exception]) -> list:
    if isinstance(value, np.ndarray):  # a design dict built in-process
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise error(f"{where} must be a list, got {type_name(value)}")
    return list(value)


def text(value, where: str, error: type[Exception], empty: bool = False) -> str:
    if not isinstance(value, str) or not (empty or value):
        raise error(f"{where} must be a {'' if empty else 'non-empty '}string, got {type_name(value)}")
    return value


def names(value, where: str, error: type[Exception]) -> list[str]:
    """A list of distinct non-empty strings."""
    out = array(value, where, error)
    for i, nm in enumerate(out):
        text(nm, f"{where}[{i}]", error)
    if len(set(out)) != len(out):
        dup = sorted({n for n in out if out.count(n) > 1})
        raise error(f"{where} must be distinct, {dup} appear more than once")
    return out


def real(value, where: str, error: type[Exception], lo: float | None = None, hi: float | None = None,
         lo_open: bool = False, hi_open: bool = False, limit: float = MAX_ABS) -> float:
    """A JSON/TOML number (not a Boolean or string), finite, |x| ≤ limit, within [lo, hi].

    ``lo_open``/``hi_open`` make the bound strict: ``real(x, ..., lo=0, lo_open=True)``
    is a positive finite number. ``limit`` defaults to :data:`MAX_ABS`; a value that is
    only compared (a threshold) may use ``math.inf`` (any finite number).
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise error(f"{where} must be a number, got {type_name(value)}")
    try:
        x = float(value)
    except OverflowError:
        raise error(f"{where} is beyond the floating-point range") from None
    if not math.isfinite(x):
        raise error(f"{where} must be a finite number, got {x!r}")
    if abs(x) > limit:
        raise error(f"{where} = {x:g} is larger in magnitude than {limit:g}")
    if lo is not None and (x < lo or (lo_open and x == lo)) or hi is not None and (x > hi or (hi_open and x == hi)):
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        raise error(f"{where} must be in {left}{'-inf' if lo is None else f'{lo:g}'}, "
                    f"{'inf' if hi is None else f'{hi:g}'}{right}, got {x!r}")
    return x


def integer(value, where: str, error: type[Exception], lo: int, hi: int) -> int:
    """A JSON/TOML integer (a float with an integral value is accepted) in [lo, hi]."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise error(f"{where} must be an integer, got {type_name(value)}")
    if not isinstance(value, numbers.Integral) and not (math.isfinite(value) and value == int(value)):
        raise error(f"{where} must be an integer, got {value!r}")
    if not lo <= value <= hi:
        shown = value if abs(value) < 10**20 else f"{float(value):.3g}"
        raise error(f"{where} must be an integer in [{lo}, {hi}], got {shown}")
    return int(value)


def flag(value, where: str, error: type[Exception]) -> bool:
    if not isinstance(value, bool):
        raise error(f"{where} must be true or false, got {type_name(value)}")
    return value


_NUMBER_TYPES = {int, float}


def _fast_reals(row, bounds) -> bool:
    """True when every entry is a plain int/float, finite, within MAX_ABS and the bounds
    (vectorised; the caller falls back to :func:`real` per entry to name a failure)."""
    if not set(map(type, row)) <= _NUMBER_TYPES:
        return False
    try:
        a = np.array(row, dtype=float)
    except OverflowError:
        return False
    if not np.all(np.abs(a) <= MAX_ABS):  # NaN fails too
        return False
    lo, hi = bounds.get("lo"), bounds.get("hi")
    if lo is not None and not (np.all(a > lo) if bounds.get("lo_open") else np.all(a >= lo)):
        return False
    if hi is not None and not (np.all(a < hi) if bounds.get("hi_open") else np.all(a <= hi)):
        return False
    return True


def vector(value, where: str, error: type[Exception], size: int | None = None, **bounds) -> list:
    """A list of numbers (each as :func:`real`, with the same bounds)."""
    out = array(value, where, error)
    if size is not None and len(out) != size:
        raise error(f"{where} must have {size} entries, got {len(out)}")
    if not _fast_reals(out, bounds):
        for i, x in enumerate(out):
            real(x, f"{where}[{i}]", error, **bounds)
    return out


def matrix(value, where: str, error: type[Exception], rows: int | None = None, cols: int | None = None,
           **bounds) -> list:
    """A matrix as a list of rows (lists of numbers), every row of the same length.

    An empty list is the matrix with no rows (of any width). The message of a ragged
    matrix names the row and the length expected; ``rows``/``cols`` fix the shape.
    Returns the list of rows unchanged.
    """
    rows_ = array(value, where, error)
    if rows is not None and len(rows_) != rows and not (not rows_ and cols == 0):
        shape = f"{rows}x{cols}" if cols is not None else f"a matrix with {rows} rows"
        raise error(f"{where} must be {shape}, got {len(rows_)} rows")
    width = cols
    for i, row in enumerate(rows_):
        if isinstance(row, np.ndarray):
            row = row.tolist()
        if not isinstance(row, (list, tuple)):
            raise error(f"{where} must be a list of rows (lists of numbers); row {i + 1} is {type_name(row)}")
        if width is None:
            width = len(row)
        elif len(row) != width:
            if cols is None:
                raise error(f"{where}: row {i + 1} has {len(row)} entries, expected {width} (the length of row 1)")
            if rows is not None:
                raise error(f"{where} must be {rows}x{cols}: row {i + 1} has {len(row)} entries, expected {cols}")
            raise error(f"{where} must have {cols} columns: row {i + 1} has {len(row)} entries")
        if not _fast_reals(row, bounds):
            for j, x in enumerate(row):
                real(x, f"{where}[{i + 1}][{j + 1}]", error, **bounds)
    return rows_
