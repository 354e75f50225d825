"""impulse_norms (fmu_fdi/evaluation/selector.py), computed in batches of taps: every tap's norm is
that of the impulse response computed independently (Markov parameters by repeated products,
2-norm as the largest singular value), and the returned tail bounds the true tail."""
import numpy as np
import pytest

from fmu_fdi.evaluation.selector import impulse_norms
from fmu_fdi.lti import LTI


@pytest.mark.parametrize("n, rho, max_taps", [(1, 0.5, 10_000), (4, 0.99, 10_000), (6, 0.9, 70), (3, 0.0, 10)])
def test_taps_and_tail_against_an_independent_impulse_response(n, rho, max_taps):
    rng = np.random.default_rng(7 + n)
    A = rng.standard_normal((n, n))
    A *= rho / max(abs(np.linalg.eigvals(A))) if rho else 0.0
    B, C, D = rng.standard_normal((n, 2)), rng.standard_normal((3, n)), rng.standard_normal((3, 2))
    norms, tail = impulse_norms(LTI(A, B, C, D, dt=1.0), 1e-6, max_taps)
    K = max(len(norms), 1) + 4000  # far beyond the settling length: the rest is below 1e-12 of the sum
    h, X = [np.linalg.svd(D, compute_uv=False)[0]], B
    for _ in range(K):
        h.append(np.linalg.svd(C @ X, compute_uv=False)[0])
        X = A @ X
    h = np.array(h)
    # the same products in the same order, a different norm call: equal to rounding (1e-13 of the largest)
    assert np.allclose(norms, h[:len(norms)], rtol=0, atol=1e-13 * h.max())
    assert h[len(norms):].sum() <= tail * (1 + 1e-9) + 1e-300  # a bound on what was left out
    if len(norms) < max_taps:  # settled: the tail is within the tolerance of the ℓ1 norm
        assert tail <= 1e-6 * (h.sum() + tail)
