"""mindeg's row pass refuses a one-row change on the row alone (``approximate_matching._row_leak_alone``) only where
the stacked filter's post-conditions refuse it too, and never accepts.

Ex. 5.16 (Varga 2017; two rows, u decoupled, Mr = I): the optimal filter's row 1 is decoupled — the pre-check leaves
it to the full verification (None). The same row with its feedthrough moved by 1e-3 of its norm leaks u: the judge
independent of the design code (numpy: ``max_ω |Q₁(jω) [Gu(jω); I]|`` on 400 log points, unscaled as the
post-conditions with ``faults=[]`` read it) reads the leak far above dec_tol, the pre-check refuses it, and the
stacked filter (the changed row beside the optimal row 2) fails ``check_generator``'s decoupling for row 1 — the
same refusal, without building and verifying it.
"""
from __future__ import annotations

import numpy as np
import pytest
from test_synthesis_ammp import ex5_16, static

from fmu_fdi import approximate_model_matching
from fmu_fdi.design.problems import approximate_matching as am
from fmu_fdi.design.toolkit.postconditions import DEC_TOL, check_generator
from fmu_fdi.errors import DesignError
from fmu_fdi.generator import ResidualGenerator
from fmu_fdi.lti import LTI, vstack


def _numpy_ud_peak(model, Qi: LTI) -> float:
    """``max_ω |Q_i [Gu Gd; I 0]|`` by numpy solves on 400 log points 1e-4 … 1e4 rad/s and 0."""
    w = np.concatenate([[0.0], np.logspace(-4, 4, 400)])
    lam = 1j * w
    B, D = np.hstack([model.Bu, model.Bd]), np.hstack([model.Du, model.Dd])
    n = model.A.shape[0]
    G = np.linalg.solve(lam[:, None, None] * np.eye(n) - model.A, np.broadcast_to(B, (w.size,) + B.shape))
    G = np.concatenate([model.C @ G + D, np.broadcast_to(np.eye(model.nu, B.shape[1]), (w.size, model.nu,
                                                                                      B.shape[1]))], axis=1)
    X = np.linalg.solve(lam[:, None, None] * np.eye(Qi.n) - Qi.A, np.broadcast_to(Qi.B, (w.size,) + Qi.B.shape))
    Q = Qi.C @ X + Qi.D
    return float(np.max(np.linalg.norm(Q @ G, 2, axis=(1, 2))))


def test_row_precheck_refuses_only_what_the_stacked_check_refuses():
    model = ex5_16()
    gen = approximate_model_matching(model, static(np.eye(2)), sdeg=-10, reltol=5e-4)
    Q = gen.Q
    rows = [am._minimal_row(Q[i, :], 0.0) for i in range(Q.p)]
    smarg = None  # (the design's default, as approximate_model_matching passes it)
    # the optimal row: decoupled (numpy reads rounding), not refused by the pre-check
    assert _numpy_ud_peak(model, rows[0]) <= DEC_TOL  # (the design's own contract, read by numpy)
    assert am._row_leak_alone(model, rows[0], smarg, DEC_TOL) is None
    # the row with its feedthrough moved by 1e-3 of its norm: u leaks ~1e-3 (numpy), far above the margin
    X = rows[0]
    bad = LTI(X.A, X.B, X.C, X.D + 1e-3 * max(1.0, float(np.linalg.norm(X.D))), X.dt)
    assert _numpy_ud_peak(model, bad) > 100 * am.ROW_LEAK_MARGIN * DEC_TOL  # (a leak ~1e-3: 1e2 beyond the margin)
    why = am._row_leak_alone(model, bad, smarg, DEC_TOL)
    assert why is not None and "read on the row alone" in why
    # ... and the stacked filter's post-conditions refuse that row too (what _verified would have found)
    stacked = vstack([bad, rows[1]]).minreal(0.0)
    with pytest.raises(DesignError, match=r"residual 1: u(\+d)? leak"):
        check_generator(ResidualGenerator(stacked, model, "approximate_model_matching"), decouple=("u", "d"),
                        faults=[], smarg=smarg, dec_tol=DEC_TOL)
