"""The design file: a diagnoser as versioned JSON (format ``fmu-fdi-design/1``).

A design file holds everything the run-time needs and nothing executable: signal names
and units, the operating point, the discrete generator (and the continuous one when the
design has it, for exact re-discretisation at another step size), one evaluator and one
threshold per residual group, the decision logic, and the fault names. The schema is
documented in ``docs/design-file.md``. Files are read strictly: an unknown version, a
missing key or a matrix of the wrong shape is an error that names the item.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ._schema import check_format, check_keys
from .errors import ModelError

FORMAT = "fmu-fdi-design/1"
_TOP_REQUIRED = ("format", "name", "signals", "generator", "evaluation", "decision", "faults")
_TOP_ALLOWED = set(_TOP_REQUIRED) | {"units", "operating_point", "model", "created_by", "description", "report"}
_GEN_REQUIRED = ("method", "dt", "discrete", "groups", "residual_names")
_GEN_ALLOWED = set(_GEN_REQUIRED) | {"continuous", "info"}


class DesignFileError(ModelError):
    """A design file (or design dict) is malformed; the message names the item."""


def _matrix(value, where: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        M = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise DesignFileError(f"{where} is not a numeric matrix") from None
    if M.size == 0:
        M = M.reshape(rows or 0, cols or 0)
    if M.ndim != 2:
        raise DesignFileError(f"{where} must be a 2-D matrix, got shape {M.shape}")
    if rows is not None and M.shape[0] != rows or cols is not None and M.shape[1] != cols:
        raise DesignFileError(f"{where} must be {rows}x{cols}, got {M.shape[0]}x{M.shape[1]}")
    if not np.all(np.isfinite(M)):
        raise DesignFileError(f"{where} contains NaN or Inf")
    return M


def _check_lti(spec, where: str, n_in: int) -> int:
    if not isinstance(spec, dict):
        raise DesignFileError(f"{where} must be an object")
    for key in ("A", "B", "C", "D"):
        if key not in spec:
            raise DesignFileError(f"{where} is missing matrix {key}")
    A = _matrix(spec["A"], f"{where}.A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise DesignFileError(f"{where}.A must be square, got {A.shape}")
    D = _matrix(spec["D"], f"{where}.D", cols=n_in)
    _matrix(spec["B"], f"{where}.B", rows=n, cols=n_in)
    _matrix(spec["C"], f"{where}.C", rows=D.shape[0], cols=n)
    return D.shape[0]


def validate_design(d, source: str = "design") -> dict:
    """Check a design dict against the schema; returns it unchanged or raises DesignFileError."""
    check_format(d, FORMAT, source, DesignFileError, "design format")
    check_keys(d, _TOP_REQUIRED, _TOP_ALLOWED, source, DesignFileError)
    sig = d["signals"]
    if not isinstance(sig, dict) or not isinstance(sig.get("u"), list) or not isinstance(sig.get("y"), list):
        raise DesignFileError(f"{source}: signals must hold lists 'u' and 'y'")
    names = list(sig["u"]) + list(sig["y"])
    if len(set(names)) != len(names) or not all(isinstance(x, str) and x for x in names):
        raise DesignFileError(f"{source}: signal names must be distinct non-empty strings, got {names}")
    nu, ny = len(sig["u"]), len(sig["y"])
    op = d.get("operating_point") or {}
    if op:
        _matrix([op.get("u", [0.0] * nu)], f"{source}: operating_point.u", cols=nu)
        _matrix([op.get("y", [0.0] * ny)], f"{source}: operating_point.y", cols=ny)
    g = d["generator"]
    if not isinstance(g, dict):
        raise DesignFileError(f"{source}: generator must be an object")
    check_keys(g, _GEN_REQUIRED, _GEN_ALLOWED, f"{source}: generator", DesignFileError)
    dt = g["dt"]
    if not isinstance(dt, (int, float)) or not (dt > 0 and math.isfinite(dt)):
        raise DesignFileError(f"{source}: generator.dt must be a positive sample time, got {dt!r}")
    disc = g["discrete"]
    if not isinstance(disc, dict) or disc.get("kind") not in ("lti", "rls"):
        raise DesignFileError(f"{source}: generator.discrete.kind must be 'lti' or 'rls'")
    if disc["kind"] == "lti":
        nr = _check_lti(disc, f"{source}: generator.discrete", ny + nu)
    else:
        nr = len(g["residual_names"])
    if g.get("continuous") is not None:
        if _check_lti(g["continuous"], f"{source}: generator.continuous", ny + nu) != nr:
            raise DesignFileError(f"{source}: generator.continuous has a different number of residuals")
    if len(g["residual_names"]) != nr:
        raise DesignFileError(f"{source}: {len(g['residual_names'])} residual names for {nr} residuals")
    groups = g["groups"]
    if not isinstance(groups, list) or sorted(i for grp in groups for i in grp) != list(range(nr)):
        raise DesignFileError(f"{source}: generator.groups must partition the residuals 0..{nr - 1}")
    ev = d["evaluation"]
    if not isinstance(ev, list) or len(ev) != len(groups):
        raise DesignFileError(f"{source}: evaluation must list one entry per residual group ({len(groups)})")
    for i, e in enumerate(ev):
        if not isinstance(e, dict) or "evaluator" not in e or "threshold" not in e:
            raise DesignFileError(f"{source}: evaluation[{i}] needs 'evaluator' and 'threshold'")
    if not isinstance(d["faults"], list) or not all(isinstance(f, dict) and "name" in f for f in d["faults"]):
        raise DesignFileError(f"{source}: faults must be a list of objects with a 'name'")
    from .runtime.engine import DiagnoserRuntime

    try:
        DiagnoserRuntime(d)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc)
        raise DesignFileError(f"{source}: {what}") from None
    return d


def _clean(x):
    """JSON-ready copy: numpy → lists and floats, non-finite floats → None."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
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


def save_design(d: dict, path) -> Path:
    """Validate and write a design dict as JSON (floats round-trip exactly)."""
    d = _clean(d)
    validate_design(d, str(path))
    path = Path(path)
    path.write_text(json.dumps(d, indent=1, allow_nan=False), encoding="utf-8")
    return path


def load_design(path) -> dict:
    """Read and validate a design file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DesignFileError(f"cannot read design file {path}: {exc.strerror}") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DesignFileError(f"{path}: not valid JSON: {exc}") from None
    return validate_design(d, str(path))
