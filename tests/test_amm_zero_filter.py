"""approximate_model_matching against the zero filter (issue 17, approximate audit seed 110).

Q = 0 decouples u and d, so it is admissible and its error ``||M [Mr 0]||∞`` bounds the optimum. Where
``Mr = I`` has more faults than the decoupled residuals reach (nf > p − rank Gd), some direction v of Mr is
never matched: ``Q(λ) Gf(λ)`` has rank ≤ p − rank Gd < nf, so ``||(Q Gf − I) v|| = ||v||`` for v in its null
space and every filter's H∞ error is ≥ 1 = Q = 0's: the optimum is the zero filter. Until amm21 the design
returned a filter within ``reltol`` above Q = 0's error with a note; now it is refused, naming the rank and the
bound (``approximate_matching._unapproachable_reference``). Judged by numpy.
"""
from test_approximate_random import noisy_case
from test_audit_seeds18 import refused_with_rank_bound


def test_seed_110_eye_reference_is_refused_with_its_rank_bound():
    """< 1 s. Seed 110 (continuous, n 9, p 3, m 4, nf 5, a marginal fault-only pair ±2j): a DesignError naming
    the admissible fault response's normal rank 3 (numpy, test_audit_seeds18.refused_with_rank_bound: the SVD of
    the left null space of [Gu; I](λ) times [Gf; 0](λ) at 40 grid points) and the bound σ_4(I) = 1 = ||I||∞.
    Old code (ac7dadb): designed, error 1.0000777 with a note 'the reference cannot be approached'."""
    assert refused_with_rank_bound(noisy_case(110)) == 3
