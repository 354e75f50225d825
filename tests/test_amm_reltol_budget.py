"""approximate_model_matching: the γ-iteration and the stages after it share one ``reltol`` (issue 17; approximate
audit seed 122, ``approximate_matching.iteration_reltol``)."""
from __future__ import annotations

import numpy as np

from fmu_fdi.design.problems.approximate_matching import iteration_reltol
from test_approximate_random import noisy_case
from test_audit_seeds18 import refused_with_rank_bound


def test_iteration_share_composes_to_reltol():
    """``(1 + r_γ)² = 1 + reltol``: the iteration's and the later stages' factors multiply to the user's budget
    (to the rounding of one square root and one product, 4 u)."""
    for r in (1e-8, 1e-6, 1e-4, 1e-2, 0.5):
        rg = iteration_reltol(r)
        assert 0 < rg < r and abs((1 + rg) ** 2 - (1 + r)) <= 4 * np.finfo(float).eps


def test_seed_122_identity_reference_is_refused_with_its_rank_bound():
    """~1 s. Audit seed 122 (continuous, n = 9, p = 4, 5 faults, a plant integrator), ``Mr = I``: no filter beats
    Q = 0 (γ_opt = ||M [Mr 0]||∞ = 1: rank Q·Gf ≤ 4 < 5). amm12 made it designed within reltol of Q = 0's error (the
    iteration's share above); since amm21 such a reference is refused, naming the rank (numpy's, 4) and the bound
    σ_5(I) = 1 = ||I||∞ (test_audit_seeds18.refused_with_rank_bound)."""
    assert refused_with_rank_bound(noisy_case(122)) == 4
