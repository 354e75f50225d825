"""approximate_model_matching, approximate audit seed 158 with ``Mr = I``: the returned error is read as the
post-conditions read R (``approximate_matching._judged_error``), not at the grid's point beside a plant integrator
where the filter's rounding-level residue reads r/δ."""
from __future__ import annotations

import numpy as np

from fmu_fdi.design import approximate_model_matching
from fmu_fdi.lti import LTI
from test_approximate_random import judge_amm, noisy_case


def test_seed_158_identity_reference_is_designed_within_reltol_of_the_zero_filter():
    """Audit seed 158 (continuous, n = 27, p = 2, 5 faults, a plant integrator at −8.8e-16), ``Mr = I``: no filter
    beats Q = 0 (γ_opt = ||M [Mr 0]||∞ = 1: rank Q·Gf ≤ 2 < 5). Before, the shipped filter (the designed one to a
    gap of 1.5e-9 on the design's points) was read 1.000425 at the grid's lowest point, 8.8e-11 rad/s, where its
    residue 3.5e-12 at the integrator (rounding: the judge's R-stability removes it) reads r/ω, and refused as worse
    than Q = 0 by more than reltol = 1e-4. Now it is designed; asserted: the independent numpy judge of check_case's ``amm_eye`` call (judge_amm: u/d
    decoupling, stability, Q ≠ 0, the reported error equal to numpy's within ERR_RTOL and no worse than Q = 0's)
    passes it, and the reported error is within the design's contract ``(1 + reltol)`` of Q = 0's (plus 1e-9 of it
    for the two refined readings' rounding) and, since γ_opt = 1, at least Q = 0's less that rounding (a figure
    below γ_opt would be a wrong reading)."""
    model = noisy_case(158)
    Mr = LTI.static(np.eye(model.nf), model.dt)
    reltol = 1e-4
    gen = approximate_model_matching(model, Mr, reltol=reltol)  # (check_case's "amm_eye" call: the default reltol)
    zero = gen.info["zero_filter_error"]
    assert zero * (1 - 1e-9) <= gen.info["error"] <= zero * (1 + reltol + 1e-9)
    assert judge_amm(gen, model, Mr, None) == []
