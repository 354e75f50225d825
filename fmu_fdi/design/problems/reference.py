"""The reference model ``Mr`` of the model-matching problems, validated in one place.

Exact (:mod:`.matching`, Varga 2017 sec. 5.6) and approximate (:mod:`.approximate_matching`,
sec. 5.7) model matching take the same reference: a fault-to-residual map with one column per
fault column of the model, in the model's time base, proper, and (unless the exact problem may
update it) stable.
"""
from __future__ import annotations

import numpy as np

from ...errors import DesignError
from ...lti import LTI
from ...model import FDIModel


def reference(model: FDIModel, Mr, stable: bool = True, minimal: bool = True, atol: float = 0.0) -> LTI:
    """Mr as an LTI in the model's time base, validated (shape, proper, and stable unless
    ``stable=False``), minimal unless ``minimal=False``; a matrix is a constant reference."""
    if isinstance(Mr, (np.ndarray, list, tuple, int, float)):
        D = np.atleast_2d(np.asarray(Mr, dtype=float))
        if D.ndim != 2 or not np.all(np.isfinite(D)):
            raise DesignError(f"a constant Mr must be a finite matrix, got shape {np.shape(Mr)}")
        Mr = LTI.static(D, model.dt)
    if not isinstance(Mr, LTI):
        try:
            Mr = LTI.from_control(Mr)
        except ValueError as exc:
            raise DesignError(f"Mr must be a proper system: {exc}") from None
        except TypeError as exc:
            raise DesignError(f"Mr: {exc}") from None
    if Mr.m != model.nf:
        raise DesignError(f"Mr must have {model.nf} inputs (the fault columns {model.fault_names}), got {Mr.m}")
    if Mr.p < 1:
        raise DesignError("Mr must have at least one output (residual)")
    if Mr.n and abs(Mr.dt - model.dt) > 1e-12 * max(1.0, model.dt):
        raise DesignError(f"Mr has sample time {Mr.dt} but the model has {model.dt}")
    Mr = LTI(Mr.A, Mr.B, Mr.C, Mr.D, model.dt)
    if Mr.n and minimal:
        Mr = Mr.minreal(atol)
        if stable and not Mr.is_stable():
            bad = Mr.poles()
            worst = float(np.max(np.abs(bad))) if model.dt else float(np.max(bad.real))
            what = "largest |pole|" if model.dt else "largest Re(pole)"
            raise DesignError(f"Mr must be stable ({what} = {worst:.6g}): every filter's fault response Q Gf is")
    return Mr
