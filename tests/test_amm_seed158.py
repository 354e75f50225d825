"""approximate_model_matching, approximate audit seed 158 with ``Mr = I`` (issue 17): once refused for a reading
beside a plant integrator, then designed within reltol of Q = 0's error (amm12: the returned error read as the
post-conditions read R, ``approximate_matching._judged_error``), now refused with the true condition (amm21)."""
from __future__ import annotations

from test_approximate_random import noisy_case
from test_audit_seeds18 import refused_with_rank_bound


def test_seed_158_identity_reference_is_refused_with_its_rank_bound():
    """~1 s. Audit seed 158 (continuous, n = 27, p = 2, 5 faults, a plant integrator at −8.8e-16), ``Mr = I``: no
    filter beats Q = 0 (γ_opt = ||M [Mr 0]||∞ = 1: rank Q·Gf ≤ 1 < 5). Before amm21 a filter within reltol of
    Q = 0's error was returned; now a DesignError names the admissible fault response's normal rank (numpy's, 1) and
    the bound σ_2(I) = 1 = ||I||∞ (test_audit_seeds18.refused_with_rank_bound)."""
    assert refused_with_rank_bound(noisy_case(158)) == 1
