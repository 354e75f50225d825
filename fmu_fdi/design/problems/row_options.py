"""Per-row options of a bank: the number of residuals and the design matrix of every structure row
(FaultDetectionTools.jl ``efdisyn``/``afdisyn``: ``rdim`` a vector, ``HDesign`` a vector of matrices).

Row i of a structure ``S`` is a detection problem of its own with the faults ``S_ij = 0`` taken as
unknown inputs; its residuals are combinations of the rows of a left null-space basis of
``[Gu Gd Gf_{S_i=0}; I 0 0]``, of which there are

    k_i = p − rank [Gd Gf_{S_i=0}]    (normal rank),

so at most ``k_i`` residuals in row i can be independent (Varga 2017, sec. 5.4, Procedure EFDI).
"""
from __future__ import annotations

import numpy as np

from ...errors import DesignError
from ...model import FDIModel


def per_row(value, rows: int, what: str) -> list:
    """``value`` for every one of ``rows`` structure rows: a scalar (or None) repeated, or a list with
    one entry per row (a DesignError naming the lengths otherwise)."""
    if value is None or isinstance(value, (int, np.integer, str)):
        return [value] * rows
    if isinstance(value, np.ndarray) and value.ndim == 2 and what == "HDesign":
        raise DesignError(f"HDesign of a bank is a list with one matrix (or None) per structure row, got one "
                          f"{value.shape} matrix for {rows} rows")
    out = list(value)
    if len(out) != rows:
        raise DesignError(f"{what} has {len(out)} entries but the structure has {rows} rows: give one per row")
    return out


def row_dimensions(model: FDIModel, names: list[str], S: np.ndarray, rdim, HDesign, *, atol: float = 0.0):
    """``(rdims, Hs)``: the residual count and design matrix (or None) of every row of ``S``.

    ``rdim``: a positive int or a list of them, one per row (default 1); a row's ``HDesign`` fixes
    its count (``rdim`` for that row must then be 1 or its row count). Refused (DesignError naming the
    row and the numbers) when a count exceeds the row's achievable dimension ``k_i`` (module docstring).
    """
    from ..toolkit._basis import normal_rank

    rows = S.shape[0]
    rdims, Hs = per_row(rdim, rows, "rdim"), per_row(HDesign, rows, "HDesign")
    G = model.lti("d", "f")
    cols = {f.name: list(model.nd + np.arange(model.nf)[f.columns]) for f in model.faults}
    out = []
    for i, (row, r, H) in enumerate(zip(S.astype(int), rdims, Hs)):
        if not (isinstance(r, (int, np.integer)) and not isinstance(r, bool) and r >= 1):
            raise DesignError(f"rdim of structure row {i + 1} must be a positive integer, got {r!r}")
        want = int(r)
        if H is not None:
            q = np.atleast_2d(np.asarray(H, dtype=float)).shape[0]
            if want not in (1, q):
                raise DesignError(f"structure row {i + 1}: rdim = {want} but its HDesign has {q} rows")
            want = q
        if want > 1:
            base = list(range(model.nd)) + [c for nm, s in zip(names, row) if not s for c in cols[nm]]
            k = model.ny - (normal_rank(G[:, base], atol=atol) if base else 0)
            if want > k:
                raise DesignError(
                    f"structure row {i + 1} {row.tolist()}: rdim = {want} residuals requested but at most {k} are "
                    f"achievable (p − rank [Gd Gf_0] = {model.ny} − {model.ny - k}, the faults marked 0 counted "
                    f"as d)")
        out.append(want)
    return out, Hs
