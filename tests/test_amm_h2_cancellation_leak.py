"""H2 approximate model matching whose exact plant-mode cancellation leaks u/d: the filter before it is kept (issue 17;
``approximate_matching._mended``).

Approximate audit seed 240 (n = 24, p = 2, two known inputs, one disturbance, five faults, one noise input, a plant
integrator at −4.5e-16 that only faults excite), ``Mr = I₅``, ``norm = '2'``: one admissible row for five faults, so
every row of the H2 optimum is ``y_i·q``, and each row requires only its own fault i, which q sees with 1/8 … 1/3 of
its strongest fault's gain. The exact cancellation of the integrator (``_plant_mode_cancellation``: a relative change
1.9e-3 of ``[B_q; D_q]`` with u, d kept decoupled on thinned points only) leaked 5.4e-7 of fault i's gain at 7.4 rad/s,
which no refit mended: refused ("u/d leak 5.41e-07 … > dec_tol = 1e-07") after 35-82 s. The filter before the
correction leaks 3.5e-11 … 2.9e-10 and cancels the integrator to its rounding: it is returned now.

Judged by numpy on the returned Q and the model's matrices (test_approximate_random's judge: nothing of fmu_fdi's
analysis): per row i, the u/d leak at most DEC_TOL of the row's peak gain of fault i (Varga's normalisation, the
fault the row of Mr requires), R and Q stable (PBH on the series realisation, row_violations), and the reported H2
error equal to numpy's ``((1/π) ∫_0^∞ ||Q [Gf Gw; 0 0] − M [Mr 0]||_F² dω)^½`` within H2_RTOL.
"""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi.design import approximate_model_matching
from fmu_fdi.lti import LTI
from test_approximate_random import (_cols, _freqresp, _ge_values, _pbh_poles, _points, _refined_peak, _row_checks,
                                     noisy_case)

#: numpy's trapezoid on 20 000 log points over 1e-7 … 1e7 rad/s (the error is strictly proper — the reference is
#: low-passed — and its poles lie within 1e-2 … 1e2 rad/s: the truncated tails and the rule's error are ≲ 1e-5 of the
#: norm); the design's Gauss–Legendre quadrature is accurate to ~1e-10. 1e-4 covers both
H2_RTOL = 1e-4


def _numpy_h2_error(model, Q: LTI, M: LTI) -> float:
    w = np.logspace(-7, 7, 20_000)
    lam = 1j * w
    cols = _cols(model)
    fw = np.r_[np.concatenate([cols[f.name] for f in model.faults]), np.arange(cols["w"].start, cols["w"].stop)]
    R = _freqresp(Q.A, Q.B, Q.C, Q.D, lam) @ _ge_values(model, lam)[:, :, fw]
    Mv = _freqresp(M.A, M.B, M.C, M.D, lam)
    E = R.copy()
    E[:, :, :model.nf] -= Mv  # (Mr = I: M [Mr 0] = [M 0])
    f = np.sum(np.abs(E) ** 2, axis=(1, 2))
    return float(np.sqrt(np.trapezoid(f, w) / np.pi))


@pytest.mark.slow
def test_h2_identity_on_one_admissible_row_keeps_the_filter_before_a_leaking_cancellation():
    """~15 s (design ~8 s, numpy judge). Old code (7bc7918): DesignError "the returned filter leaks u/d above dec_tol
    … residual 1: u/d leak 5.41e-07"."""
    model = noisy_case(240)
    Mr = LTI.static(np.eye(model.nf), model.dt)
    gen = approximate_model_matching(model, Mr, norm="2")
    Q, M = gen.Q, gen.info["M"]
    lam = _points(model, [Q, M])
    Gv = _ge_values(model, lam)
    Qv = _freqresp(Q.A, Q.B, Q.C, Q.D, lam)
    Rv = Qv @ Gv
    cols = _cols(model)
    out = [f"Q has the unstable/marginal pole {p:.4g}" for p in _pbh_poles(Q.A, Q.B, Q.C, model.dt)]
    for i, f in enumerate(model.faults):
        gi = _refined_peak(lambda L, i=i, c=cols[f.name]: _freqresp(Q.A, Q.B, Q.C[i:i + 1], Q.D[i:i + 1], L)
                           @ _ge_values(model, L)[:, :, c], lam, model.dt)
        assert gi > 0, f"row {i}: its fault {f.name} is invisible"
        out += _row_checks(Q, [i], model, lam, Rv, Qv, 1.0 / gi, False, f"row {i}")
    assert out == []
    e = _numpy_h2_error(model, Q, M)
    assert abs(gen.info["error"] - e) <= H2_RTOL * e, (gen.info["error"], e)
