"""approximate_matching.stable_reduced_system: the stable pair ``(N_Q, N_G) = M (Q0, G1)`` is one factorisation —
``N_G = N_Q [Gf Gw; 0 0]`` at every frequency, read by numpy (issue 17, approximate audit seeds 98 and 102).

With u and d decoupled by ``Q0 = [I −Gu]`` and a fault-only boundary mode in ``G1 = [Gf Gw]`` (seed 98: ±2j,
seed 102: an integrator), G1 is factored ``G1 = M2⁻¹ N_G`` and the filters are ``Y (M2 Q0)``: their error is read
on ``M2 Q0 [Gf Gw]`` while the synthesis designs it on ``N_G``. Factored on G1's raw realisation (seed 102:
‖A‖ = 1.3e7, the integrator's output direction |C v| = 5.4e-4) the two differed by 0.995 relative, and
approximate_model_matching refused the design ('error response differs from the designed one by 24.2').
"""
import numpy as np
import pytest

from fmu_fdi.design.problems.approximate_matching import reduced_system, stable_reduced_system
from test_approximate_random import _points, noisy_case
from test_synthesis_random import _freqresp

# The factorisation is exact in exact arithmetic (N = (A + LC, B + LD, C, D), M = (A + LC, L, C, I)); computed on
# a balanced minimal realisation (‖A‖ ~ 10) its gap is the rounding of the factors, ~eps times their gains
# (≤ 1e3) over the distance δ ≥ 1e-7·max(1, |λ|) that _points keeps from the boundary mode: ≤ ~1e-6 relative
# beside it, ~1e-13 elsewhere (measured by this test: 2.0e-10 at 2.000002j, seed 98; 9.8e-11 at 1.2e-6j, seed
# 102). On the raw realisation (old code) this test read 2.4e-4 and 0.60.
FACTOR_RTOL = 1e-6


@pytest.mark.parametrize("seed", [98, 102])
def test_stable_pair_is_one_factorisation(seed):
    model = noisy_case(seed)
    Q0, G1, _ = reduced_system(model, 0.0, rows=1)
    NQ, NG = stable_reduced_system(model, Q0, G1)
    assert NG.n and max(np.real(np.linalg.eigvals(NG.A))) < 0  # G1's boundary mode was moved
    lam = _points(model, [NQ, NG])
    fnm = np.concatenate([_freqresp(model.A, model.Bf, model.C, model.Df, lam),
                          _freqresp(model.A, model.Bw, model.C, model.Dw, lam)], axis=2)
    fnm = np.concatenate([fnm, np.zeros((lam.size, model.nu, fnm.shape[2]))], axis=1)  # [Gf Gw; 0 0]
    shipped = _freqresp(NQ.A, NQ.B, NQ.C, NQ.D, lam) @ fnm
    designed = _freqresp(NG.A, NG.B, NG.C, NG.D, lam)
    gap = np.linalg.norm(shipped - designed, 2, axis=(1, 2))
    size = np.linalg.norm(designed, 2, axis=(1, 2))
    assert np.max(gap / size) <= FACTOR_RTOL, (float(np.max(gap / size)), lam[int(np.argmax(gap / size))])
