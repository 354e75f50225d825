"""The Kalman filter keeps the process noise of states scaled over many decades: the rank of ``Q̄ = Qx − S R⁻¹ Sᵀ``
is decided against the rounding of how it was formed (componentwise, ``_observer.noise_factor``), not against ``‖Qx‖``.

Constructed cases: a well-conditioned filter ``ξ' = Ã ξ + w``, ``y = Σ ξ_i + v`` (unit intensities) seen in the
coordinates ``x = T ξ``, ``T = diag(1, s)``: ``A = T Ã T⁻¹``, ``C = C̃ T⁻¹``, ``Qx = T Tᵀ`` — the noise on x₂ has
intensity ``s²`` of ``‖Qx‖``. The data is exact and the equation, in ξ, is as well-conditioned as any; the old rank
decision (eigenvalues of ``Q̄`` below ``1e3·n·eps·‖Qx‖`` dropped) treated that noise as rounding below ``s ≈ 1e-7``.

The judge is independent of the design code: the filter run with the returned ``L`` has the error covariance ``P_K``
(scipy's Lyapunov/Stein of ``A − LC`` with ``Qx + L R Lᵀ``, diagonally balanced), and the true stabilising solution
``P* = T P̃ Tᵀ`` is scipy's CARE/DARE in ξ (a 2×2 equation of condition O(1)). They are compared per state —
``max |P_K − P*|_ij / √(P*_ii P*_jj)``, invariant under the scaling ``T`` — so the small state's block counts as much
as the large one's (a normwise figure relative to ``‖P‖`` cannot see an error of x₂'s variance, which is ``s²`` of it).
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi.design.observers._observer import filter_riccati
from fmu_fdi.errors import DesignError

#: per-state line for P_K against P*: both are solved by scipy in well-conditioned coordinates (the per-state measure
#: is invariant under T; in ξ the CARE/DARE and the Lyapunov equation are 2×2 with condition O(1), accurate to
#: ~1e2·eps), and the design promises FORWARD_RTOL = 1e-6 normwise; 1e-5 is the line of tests/test_riccati_forward.py
#: (JUDGE_LINE). Measured on the new code: ≤ 1.5e-15.
PER_STATE_LINE = 1e-5


def scaled_pair(modes, s: float, dt: float):
    """``(A, C, Qx, R, P*)`` of the module docstring for ``Ã = diag(modes)``."""
    At = np.diag(np.asarray(modes, float))
    n = At.shape[0]
    T = np.diag([1.0] * (n - 1) + [s])
    Ct, Qt, R = np.ones((1, n)), np.eye(n), np.eye(1)
    A, C, Qx = T @ At @ np.linalg.inv(T), Ct @ np.linalg.inv(T), T @ Qt @ T
    Pt = (sla.solve_discrete_are if dt else sla.solve_continuous_are)(At.T, Ct.T, Qt, R)
    return A, C, Qx, R, T @ Pt @ T


def per_state_error(A, C, Qx, R, L, dt, Pstar) -> float:
    """``max |P_K − P*|_ij / √(P*_ii P*_jj)``, ``P_K`` by scipy (module docstring)."""
    Acl, W = A - L @ C, Qx + L @ R @ L.T
    t = sla.matrix_balance(Acl, permute=False, separate=True)[1][0]
    Ab, Wb = Acl / t[:, None] * t[None, :], W / t[:, None] / t[None, :]
    Pb = sla.solve_discrete_lyapunov(Ab, Wb) if dt else sla.solve_continuous_lyapunov(Ab, -Wb)
    PK = Pb * t[:, None] * t[None, :]
    d = np.sqrt(np.diag(Pstar))
    return float(np.max(np.abs(PK - Pstar) / np.outer(d, d)))


def _designed(A, C, Qx, R, dt):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return filter_riccati(A, C, Qx, R, np.zeros((A.shape[0], C.shape[0])), dt)


# an integrator (random walk; discrete: a mode at z = 1) driven by noise on a state scaled by s: the old code dropped
# that noise and refused, "the filter Riccati equation has no stabilising solution (the modes [0] lie on the stability
# boundary and no process noise reaches them)" — for s = 1e-7 and 1e-8 both time domains (s = 1e-6 was designed)
@pytest.mark.parametrize("dt, modes", [(0.0, [-1.0, 0.0]), (1.0, [0.5, 1.0])])
@pytest.mark.parametrize("s", [1e-7, 1e-8])
def test_noise_on_a_scaled_integrator_is_kept(dt, modes, s):
    A, C, Qx, R, Pstar = scaled_pair(modes, s, dt)
    f = _designed(A, C, Qx, R, dt)
    assert per_state_error(A, C, Qx, R, f.L, dt, Pstar) <= PER_STATE_LINE
    ev = np.linalg.eigvals(A - f.L @ C)
    assert np.all(np.abs(ev) < 1.0) if dt else np.all(ev.real < 0.0)


# a slow stable mode (−1e-6) driven by noise on a state scaled by 1e-8: the old code deflated x₂ (P = 0 there, the
# filter's loop keeps the mode at −1e-6) and the forward refinement, Kleinman's iteration from that gain, halves the
# correction per step from ~1/(2·1e-6): it was refused as "too ill-conditioned for an accurate gain" after 16 steps —
# the one natural case met of the forward line's refusal, caused by the rank decision. (Mode −1e-4: designed after
# 16 Newton steps before, none now.)
@pytest.mark.parametrize("slow", [-1e-6, -1e-4])
def test_noise_on_a_scaled_slow_mode_is_kept(slow):
    A, C, Qx, R, Pstar = scaled_pair([-1.0, slow], 1e-8, 0.0)
    f = _designed(A, C, Qx, R, 0.0)
    assert per_state_error(A, C, Qx, R, f.L, 0.0, Pstar) <= PER_STATE_LINE
    assert f.accuracy["newton_steps"] <= 1  # the direct answer is the solution's (before: 16 steps, or refused)


def test_fully_correlated_noise_leaves_no_noise_on_a_boundary_mode():
    """Where ``Qx − S R⁻¹ Sᵀ`` vanishes in exact arithmetic (process and measurement noise from one source,
    ``Bw Dw⁻¹``) its computed value is rounding, and a decision relative to that value (rather than to the terms it
    was formed from) would take it for noise: here it would invent a solution for a mode that, after the noise is
    decorrelated (``Ā = A − S R⁻¹ C``), lies on the axis with no noise reaching it — which has none (Chan, Goodwin &
    Sin 1984). The states are scaled by 1e-8 as above, so a decision relative to ‖Qx‖ is not what keeps it right."""
    s = 1e-8
    bw, dw = np.array([[0.7], [0.3 * s]]), np.array([[0.9]])
    # Ā = A − Bw Dw⁻¹ C with Ā's second mode at 0: A = Ā + Bw Dw⁻¹ C
    C = np.array([[1.3, 0.6 / s]])
    Abar = np.array([[-1.0, 0.0], [0.0, 0.0]])
    A = Abar + bw @ np.linalg.solve(dw, C)
    Qx, R, S = bw @ bw.T, dw @ dw.T, bw @ dw.T
    Qbar = Qx - S @ np.linalg.solve(R, S.T)
    assert np.any(Qbar != 0.0)  # rounding, not zero: the case the decision must see through
    with pytest.raises(DesignError, match="no stabilising solution"):
        filter_riccati(A, C, Qx, R, S, 0.0)


def test_noise_factor_reproduces_graded_covariances_and_drops_rounding():
    """``noise_factor``'s ``G Gᵀ`` equals ``Q̄`` per entry relative to ``√(Q̄_ii Q̄_jj)`` (the graded measure its
    derivation uses) for covariances of rank k with rows scaled over 16 decades, and its rank is k: numpy's rank of
    the unscaled factor ``W`` (rows of unit scale, condition ~10) is the reference."""
    from fmu_fdi.design.observers._observer import noise_factor

    rng = np.random.default_rng(3)
    for n, k in ((4, 2), (6, 6), (5, 1)):
        W = rng.standard_normal((n, k))
        D = np.diag(10.0 ** -rng.uniform(0, 16, n))
        Qx = D @ W @ W.T @ D
        G = noise_factor(Qx, np.zeros_like(Qx), Qx)
        assert G.shape[1] == np.linalg.matrix_rank(W)
        d = np.sqrt(np.diag(Qx))
        # eigh's backward error on the unit-diagonal H is ~n·eps, times the square root's rounding: 1e-12 is 1e3 above
        assert np.max(np.abs(G @ G.T - Qx) / np.outer(d, d)) <= 1e-12


# random detectable problems scaled over nine decades (tests/test_riccati_failure_messages.scaled_random_case) that
# kalman() on b237635 refused, "(A, C) is not detectable: the modes [0.243537] are unobservable … and unstable" (23 of
# 300; the modes named are not even eigenvalues of A: the staircase read the pair in the caller's coordinates)
DETECTABLE_REFUSED_ON_OLD = [11, 57, 69, 102]


@pytest.mark.parametrize("seed", DETECTABLE_REFUSED_ON_OLD)
def test_kalman_reads_detectability_in_balanced_coordinates(seed):
    from fmu_fdi import FDIModel
    from fmu_fdi.design.observers.kalman_filter import kalman
    from test_riccati_failure_messages import scaled_random_case

    A, C, Qx, R, dt, Pstar, (At, Ct, Qt, Pt) = scaled_random_case(seed)
    n, p = A.shape[0], C.shape[0]
    # the judge that (A, C) is detectable: numpy's PBH rank of the unscaled pair at every eigenvalue of Ã (Ct random:
    # observable, smallest singular value far above rounding)
    for lam in np.linalg.eigvals(At):
        assert np.linalg.svd(np.vstack([At - lam * np.eye(n), Ct]), compute_uv=False)[-1] > 1e-8
    lam, V = np.linalg.eigh(Qt)
    Bw = np.diag(np.sqrt(np.diag(Qx) / np.diag(Qt))) @ V * np.sqrt(np.clip(lam, 0.0, None))  # Bw Bwᵀ = Qx
    model = FDIModel.from_matrices(A, np.zeros((n, 1)), C, np.zeros((p, 1)), Bw=Bw, dt=dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        gen = kalman(model, 1.0, R)
    assert per_state_error(A, C, Bw @ Bw.T, R, np.array(gen.info["gain"]), dt, Pstar) <= PER_STATE_LINE
