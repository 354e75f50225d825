"""approximate_model_matching: the γ-iteration and the stages after it share one ``reltol`` (issue 17; approximate
audit seed 122, ``approximate_matching.iteration_reltol``)."""
from __future__ import annotations

import numpy as np

from fmu_fdi.design import approximate_model_matching
from fmu_fdi.design.problems.approximate_matching import iteration_reltol
from fmu_fdi.lti import LTI
from test_approximate_random import check_case, judge_amm, noisy_case


def test_iteration_share_composes_to_reltol():
    """``(1 + r_γ)² = 1 + reltol``: the iteration's and the later stages' factors multiply to the user's budget
    (to the rounding of one square root and one product, 4 u)."""
    for r in (1e-8, 1e-6, 1e-4, 1e-2, 0.5):
        rg = iteration_reltol(r)
        assert 0 < rg < r and abs((1 + rg) ** 2 - (1 + r)) <= 4 * np.finfo(float).eps


def test_seed_122_identity_reference_is_designed_within_reltol_of_the_zero_filter():
    """Audit seed 122 (continuous, n = 9, p = 4, 5 faults, a plant integrator), ``Mr = I``: no filter beats Q = 0
    (γ_opt = ||M [Mr 0]||∞ = 1: rank Q·Gf ≤ 4 < 5). Before, the iteration stopped at 1.0000777 (its whole reltol)
    and the shipped filter read 1.000102, refused as worse than Q = 0 by more than reltol = 1e-4. Now it is
    designed, its reported error within (1 + reltol) of Q = 0's (the contract, 1e-9 of it for the two refined
    readings' rounding), and the independent numpy judge (judge_amm: u/d decoupling, stability, Q ≠ 0, the error
    equal to numpy's within ERR_RTOL and no worse than Q = 0's) passes it."""
    assert check_case(122, calls=("amm_eye",)) == [("amm(Mr=I)", "ok", "")]
    model = noisy_case(122)
    Mr = LTI.static(np.eye(model.nf), model.dt)
    reltol = 1e-4
    gen = approximate_model_matching(model, Mr, reltol=reltol)
    zero = gen.info["zero_filter_error"]
    assert gen.info["error"] <= zero * (1 + reltol + 1e-9)
    assert judge_amm(gen, model, Mr, None) == []
