"""Which fault structures a residual bank can have (Varga 2017, sec. 5.4, Procedure GENSPEC;
FaultDetectionTools.jl ``fdigenspec``), decided by the same tests as the bank's design: the weak rank
test :func:`~fmu_fdi.analysis.row_test` and, for strong structures, the design itself
(:func:`~fmu_fdi.design.problems.banks.structured_bank` and its judge) — so a listed row is designed
and a refused row is not listed. It lives with the problems, above the analysis it calls, because
its strong listing runs the synthesis."""
from __future__ import annotations

import numpy as np

from ...analysis import DEFAULT_GAIN_TOL, row_test
from ...errors import DesignError
from ...linalg import single_blas_thread
from ...model import FDIModel
from .banks import structured_bank
from ..toolkit._basis import check_strong_options


@single_blas_thread  # as the designs: threaded BLAS on small matrices spin-waits (400x on a loaded machine)
def achievable_structure(model: FDIModel, faults=None, max_faults: int = 12, *, freqs=None,
                         FDGainTol: float = DEFAULT_GAIN_TOL, tol: float | None = None,
                         atol: float = 0.0) -> np.ndarray:
    """Every achievable specification: the rows ``s`` (0/1 over ``faults``, not all 0) for
    which a residual exists that sees exactly the faults with ``s_j = 1`` once u, d and the
    faults with ``s_j = 0`` are decoupled (Varga 2017, sec. 5.4, Procedure GENSPEC;
    FaultDetectionTools.jl ``fdigenspec``). Rows in lexicographic order.

    Weak (``freqs=None``): rank test per row, ``rank [Gd Gf_0 Gf_j] > rank [Gd Gf_0]`` for
    every ``j`` with ``s_j = 1`` (normal ranks at random points; :func:`~fmu_fdi.analysis.row_test`). The condition
    is necessary and sufficient for an exact design (Varga 2017, Theorem 5.2), and
    :func:`~fmu_fdi.design.problems.banks.structured_bank` refuses the rows it fails before designing.

    Strong (``freqs`` given, rad/s, e.g. 0 for constant faults; Varga's ``FDfreq``): a weakly
    achievable row is listed iff ``structured_bank(model, [row], faults=..., freqs=freqs,
    FDGainTol=FDGainTol, tol=tol, atol=atol)`` designs it — the one state-space core and its
    judge (:func:`~fmu_fdi.design.toolkit.postconditions.check_generator`): every required fault
    has gain ``||R_fj(jω_k)|| ≥ FDGainTol`` at every ω_k on the residual normalised to unit
    weakest fault peak. No cheaper test decides the same: the gain at ω relative to the peak
    depends on the denominators the core gives the basis rows and on the combination it picks
    (Boeing 747, FDGainTol = 1e-2: the minimal polynomial basis over other denominators keeps
    1.9e-3 at ω = 1, the core's rows more than 1e-2), so a projection test on another basis
    listed rows the core then refused and refused rows it designs (tests/test_designable_iff_achievable.py).
    The peer's ``fdigenspec`` judges the same way, on its own filters: ``fdisspec_(...; stabilize =
    true)`` of the ``glnull(...; sdeg = -0.05)`` rows (0.95 discrete), each row's absolute gain
    ``|R_fij(jω)| > FDGainTol`` with no normalisation, a row kept when its strong pattern equals its
    weak one at every ω. ``tol``/``atol``: rank tolerances of the basis (as in
    :func:`~fmu_fdi.design.nullspace_design`). Published results (FaultDetectionTools.jl
    ``fdigenspec``) are reproduced in tests/test_achievable_structure.py.

    Raises
    ------
    DesignError
        Too many faults (``max_faults``), a frequency that is negative or not finite, or
        ``FDGainTol`` outside (0, 1).
    """
    import itertools

    names = list(model.fault_names if faults is None else faults)
    for nm in names:
        model.fault(nm)
    if len(names) > max_faults:
        raise DesignError(f"{len(names)} faults give 2^{len(names)} candidate rows; pass max_faults to allow it")
    if freqs is not None:
        check_strong_options(freqs, FDGainTol)
    test = row_test(model, names)
    rows = [row for row in itertools.product((0, 1), repeat=len(names)) if any(row) and test(row) is None]
    if freqs is not None:
        rows = [row for row in rows if _designable(model, names, row, freqs, FDGainTol, tol, atol)]
    return np.array(rows, dtype=int).reshape(-1, len(names))


def _designable(model: FDIModel, names, row, freqs, FDGainTol, tol, atol) -> bool:
    """Does :func:`~fmu_fdi.design.problems.banks.structured_bank` design the single ``row``
    strongly at ``freqs``? (A refusal is a :class:`DesignError`; anything else propagates.)"""
    try:
        structured_bank(model, [list(row)], faults=names, freqs=freqs, FDGainTol=FDGainTol, tol=tol, atol=atol)
    except DesignError:
        return False
    return True
