"""The inner-product rounding constants of approximate_matching._shipped_filter (issue 17, approximate audit seeds 119,
120, 131): the probabilistic ``_gamma(n) = √n·u`` is an estimate the rounding can exceed, the deterministic
``_gamma(n, worst=True) = n·u/(1 − n·u)`` (Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed., Lemma 3.1,
Thm 3.4: a recursive sum of n terms errs by at most γ_{n−1} Σ|x_i|) bounds it. Judged against exact rational
arithmetic (fractions), not against the code under test."""
from fractions import Fraction

import numpy as np

from fmu_fdi.design.problems.approximate_matching import _gamma


def _recursive_sum_error(x) -> float:
    """|fl(Σ x_i) − Σ x_i| / Σ|x_i| of the left-to-right double-precision sum, the exact sum in rationals."""
    s = 0.0
    for v in x:
        s += v
    exact = sum(Fraction(v) for v in x)
    return float(abs(Fraction(s) - exact) / sum(Fraction(abs(v)) for v in x))


def test_the_worst_case_constant_bounds_what_the_estimate_does_not():
    # 1000 copies of 0.1 (0.1's representation error is no rounding of the sum: the exact sum is of the doubles):
    # every partial sum rounds the same way, the error is 127 u of Σ|x| — four times √n·u, within (n − 1)·u
    x = [0.1] * 1000
    err = _recursive_sum_error(x)
    assert err > _gamma(len(x))
    assert err <= _gamma(len(x) - 1, worst=True)
    # and the worst-case constant is never below the estimate (β ≤ β_w term by term), n·u/(1 − n·u) exactly
    u = np.finfo(float).eps / 2
    for n in (1, 2, 10, 258, 10 ** 6):
        assert _gamma(n, worst=True) >= _gamma(n)
        assert _gamma(n, worst=True) == n * u / (1 - n * u)
