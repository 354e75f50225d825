"""Fault models: how each named fault enters the plant (Frank, eqs. 1-5).

Additive faults enter ``x' = A x + Bu u + Bf f``, ``y = C x + Du u + Df f``:

- actuator fault on input j: ``Bf = Bu[:, j]``, ``Df = Du[:, j]`` (it enters like the input);
- sensor fault on output i: ``Bf = 0``, ``Df = e_i`` (additive on that measurement);
- component fault: explicit columns ``Bf``, ``Df`` (e.g. a leak ``-θ√(2g h)/A``).

A parametric (multiplicative) fault changes the matrices,
``x' = (A + θ dA) x + (B + θ dB) u``, ``y = (C + θ dC) x``. Frank (section 2) notes that it
acts as an *additive* fault with a time-varying coefficient. We factor the direction matrix

    [dA dB; dC 0] = L R,   L = [Lx; Ly] (n+p × k),   R (k × n+m),   k = rank,

by SVD, so the fault enters additively through ``Bf = Lx``, ``Df = Ly`` with the signal
``f(t) = θ(t) · R [x(t); u(t)]`` (see :meth:`FaultSpec.parametric_signal`). Residual
generators designed for the additive columns therefore respond to the parametric fault,
and the structure/detectability of the fault is that of its k-column block.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from .errors import ModelError
from .linalg import rank_tol
from .runtime.schema import SIGNAL_NAME

KINDS = ("actuator", "sensor", "component", "parametric")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def check_name(name, what: str) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ModelError(
            f"{what} name {name!r} is not valid: use letters, digits and '_' and start with a letter or '_'"
        )
    return name


def check_signal_name(name, what: str) -> str:
    """``name`` if it can name a signal: an identifier, or an FMI 3 array element ``y[2]``
    (:data:`fmu_fdi.runtime.schema.SIGNAL_NAME`)."""
    if not isinstance(name, str) or not SIGNAL_NAME.match(name):
        raise ModelError(f"{what} name {name!r} is not valid: use letters, digits and '_', start with a letter "
                         f"or '_', optionally an array element's indices from 1 ('y[2]', 'A[1,2]')")
    return name


def identifier_of(name: str) -> str:
    """An identifier made of a signal name, for names derived from it: ``y[2]`` → ``y_2``,
    ``A[1,2]`` → ``A_1_2`` (a fault name ``sensor_y_2``); an identifier is returned as it is (``y_`` stays
    ``y_``: only the closing bracket is dropped, not an identifier's own trailing underscores)."""
    return re.sub(r"[^A-Za-z0-9_]+", "_", name.removesuffix("]"))


@dataclass
class FaultSpec:
    """One named fault of an :class:`~fmu_fdi.model.FDIModel`.

    Use the helpers :func:`actuator_fault`, :func:`sensor_fault`, :func:`component_fault`
    and :func:`parametric_fault` rather than this constructor.
    """

    name: str
    kind: str
    input: str | None = None
    output: str | None = None
    Bf: np.ndarray | None = None
    Df: np.ndarray | None = None
    dA: np.ndarray | None = None
    dB: np.ndarray | None = None
    dC: np.ndarray | None = None
    description: str = ""
    # Filled by FDIModel: the additive columns this fault occupies and, for a
    # parametric fault, the right factor R of its direction matrix.
    columns: slice | None = field(default=None, repr=False)
    R: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self):
        check_name(self.name, "fault")
        if self.kind not in KINDS:
            raise ModelError(f"fault '{self.name}': kind must be one of {KINDS}, got {self.kind!r}")

    # -------------------------------------------------------------- resolution
    def additive_columns(self, A, Bu, C, Du, u_names, y_names) -> tuple[np.ndarray, np.ndarray]:
        """Resolve this fault to its additive columns ``(Bf, Df)`` for the given plant."""
        n, p = A.shape[0], C.shape[0]
        if self.kind == "actuator":
            if self.input not in u_names:
                raise ModelError(
                    f"actuator fault '{self.name}' refers to input {self.input!r}, which is not one of "
                    f"the model's inputs {list(u_names)}"
                )
            j = list(u_names).index(self.input)
            return Bu[:, [j]].copy(), Du[:, [j]].copy()
        if self.kind == "sensor":
            if self.output not in y_names:
                raise ModelError(
                    f"sensor fault '{self.name}' refers to output {self.output!r}, which is not one of "
                    f"the model's outputs {list(y_names)}"
                )
            i = list(y_names).index(self.output)
            Df = np.zeros((p, 1))
            Df[i, 0] = 1.0
            return np.zeros((n, 1)), Df
        if self.kind == "component":
            if n == 0 and np.size(self.Bf) == 0 and self.Df is not None:  # static plant: Df's columns
                Bf = np.zeros((0, _matrix(self.Df, f"fault '{self.name}' Df", rows=p).shape[1]))
            else:
                Bf = _matrix(self.Bf, f"fault '{self.name}' Bf", rows=n)
            k = Bf.shape[1]
            Df = np.zeros((p, k)) if self.Df is None else _matrix(self.Df, f"fault '{self.name}' Df", rows=p)
            if Df.shape[1] != k:
                raise ModelError(
                    f"fault '{self.name}': Bf has {k} columns but Df has {Df.shape[1]}"
                )
            if not np.any(Bf) and not np.any(Df):
                raise ModelError(f"fault '{self.name}': Bf and Df are both zero, the fault has no effect")
            return Bf, Df
        # parametric
        m = Bu.shape[1]
        dA = np.zeros((n, n)) if self.dA is None else _matrix(self.dA, f"fault '{self.name}' dA", rows=n, cols=n)
        dB = np.zeros((n, m)) if self.dB is None else _matrix(self.dB, f"fault '{self.name}' dB", rows=n, cols=m)
        dC = np.zeros((p, n)) if self.dC is None else _matrix(self.dC, f"fault '{self.name}' dC", rows=p, cols=n)
        M = np.block([[dA, dB], [dC, np.zeros((p, m))]])
        if not np.any(M):
            raise ModelError(f"parametric fault '{self.name}': dA, dB and dC are all zero")
        U, s, Vh = sla.svd(M, full_matrices=False)
        k = int(np.sum(s > rank_tol(s, M.shape)))
        L = U[:, :k] * np.sqrt(s[:k])
        self.R = np.sqrt(s[:k])[:, None] * Vh[:k]
        self.dA, self.dB, self.dC = dA, dB, dC
        return L[:n], L[n:]

    def parametric_signal(self, theta: float, x, u) -> np.ndarray:
        """Equivalent additive fault signal ``f = θ · R [x; u]`` of a parametric fault."""
        if self.kind != "parametric" or self.R is None:
            raise ModelError(f"fault '{self.name}' is not a parametric fault of a model")
        return theta * (self.R @ np.concatenate([np.ravel(x), np.ravel(u)]))

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict:
        d: dict = {"name": self.name, "kind": self.kind}
        if self.description:
            d["description"] = self.description
        if self.kind == "actuator":
            d["input"] = self.input
        elif self.kind == "sensor":
            d["output"] = self.output
        elif self.kind == "component":
            d["Bf"] = np.asarray(self.Bf, float).tolist()
            if self.Df is not None:
                d["Df"] = np.asarray(self.Df, float).tolist()
        else:
            for key in ("dA", "dB", "dC"):
                val = getattr(self, key)
                if val is not None and np.any(val):
                    d[key] = np.asarray(val, float).tolist()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "FaultSpec":
        if not isinstance(d, dict):
            raise ModelError(f"each fault must be a table/object, got {type(d).__name__}")
        if "name" not in d or "kind" not in d:
            raise ModelError(f"fault entry {d!r} needs 'name' and 'kind'")
        allowed = {
            "actuator": {"input"},
            "sensor": {"output"},
            "component": {"Bf", "Df"},
            "parametric": {"dA", "dB", "dC"},
        }.get(d["kind"])
        if allowed is None:
            raise ModelError(f"fault '{d['name']}': kind must be one of {KINDS}, got {d['kind']!r}")
        unknown = set(d) - allowed - {"name", "kind", "description"}
        if unknown:
            raise ModelError(
                f"fault '{d['name']}' ({d['kind']}): unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}"
            )
        kw = {k: d[k] for k in allowed if k in d}
        for key in ("Bf", "Df", "dA", "dB", "dC"):
            if key in kw:
                kw[key] = _matrix(kw[key], f"fault '{d['name']}' {key}")
        if d["kind"] == "actuator" and "input" not in d:
            raise ModelError(f"actuator fault '{d['name']}' needs 'input'")
        if d["kind"] == "sensor" and "output" not in d:
            raise ModelError(f"sensor fault '{d['name']}' needs 'output'")
        if d["kind"] == "component" and "Bf" not in d:
            raise ModelError(f"component fault '{d['name']}' needs 'Bf'")
        return cls(name=d["name"], kind=d["kind"], description=d.get("description", ""), **kw)


def _matrix(X, what: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        M = np.asarray(X, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{what} is not a numeric matrix: {exc}") from None
    if M.ndim == 1 and rows is not None and M.size == rows:
        M = M.reshape(rows, 1)
    if M.ndim == 0 or M.ndim > 2:
        raise ModelError(f"{what} must be a 2-D matrix, got shape {M.shape}")
    if M.ndim == 1:
        M = M.reshape(1, -1)
    if rows is not None and M.shape[0] != rows:
        raise ModelError(f"{what} must have {rows} rows, got shape {M.shape}")
    if cols is not None and M.shape[1] != cols:
        raise ModelError(f"{what} must have {cols} columns, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ModelError(f"{what} contains NaN or Inf")
    return M


def actuator_fault(name: str, input: str, description: str = "") -> FaultSpec:
    """Additive actuator fault entering like input ``input`` (``Bf = Bu e_j``, ``Df = Du e_j``)."""
    return FaultSpec(name=name, kind="actuator", input=input, description=description)


def sensor_fault(name: str, output: str, description: str = "") -> FaultSpec:
    """Additive sensor fault on output ``output`` (``Bf = 0``, ``Df = e_i``)."""
    return FaultSpec(name=name, kind="sensor", output=output, description=description)


def component_fault(name: str, Bf, Df=None, description: str = "") -> FaultSpec:
    """Component fault with explicit distribution columns ``Bf`` (n×k) and ``Df`` (p×k)."""
    return FaultSpec(name=name, kind="component", Bf=np.asarray(Bf, float),
                     Df=None if Df is None else np.asarray(Df, float), description=description)


def parametric_fault(name: str, dA=None, dB=None, dC=None, description: str = "") -> FaultSpec:
    """Multiplicative fault ``A + θ dA``, ``B + θ dB``, ``C + θ dC``; see the module docstring."""
    return FaultSpec(name=name, kind="parametric", dA=dA, dB=dB, dC=dC, description=description)
