"""Newton refinement of Riccati solutions (``toolkit.riccati_newton``): usable problems are designed, not refused.

Where neither scipy's QZ solver nor SLICOT SB02OD returns an answer within ``RICCATI_RTOL`` of the equation's terms,
``spectral_riccati`` refines one with a stable closed loop by Newton's method (Kleinman 1968; Hewer 1971; Mehrmann &
Tan 1988). Judged by numpy: the returned ``P`` solves the full equation, is ⪰ 0 and its closed loop is stable; the
iteration converges quadratically (scalar equations in closed form); without a stabilising start it refuses.
"""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi.design.observers._observer import filter_riccati
from fmu_fdi.design.toolkit.riccati_newton import newton_refined
from fmu_fdi.errors import DesignError

from test_kalman_riccati import _problem, assert_solves

EPS = np.finfo(float).eps


# the seeded ill-scaled problems of test_kalman_riccati.py that only the refinement designs: neither scipy's nor
# SB02OD's answer is within RICCATI_RTOL (the starts refined: 1.2e-8 … 5.6e-5 of the terms, closed loops stable); with
# newton_refined disabled every one is refused (measured). Main refused six of them (also in
# test_kalman_riccati.REFUSED_ON_MAIN); it designed (4, 1) and (52, 1) in the staircase's coordinates, which the
# reduced equation no longer uses where nothing is deflated.
REFINED = [(3, 0), (3, 1), (3, 2), (4, 1), (18, 1), (26, 1), (52, 1), (58, 2)]


@pytest.mark.parametrize("seed, trial", REFINED)
def test_refined_riccati_solution_solves_its_equation(seed, trial):
    A, C, Qx, R, dt = _problem(seed, trial)
    # residuals measured 3.6e-16 … 8.7e-10 (the bound 1e-7 and its derivation: test_kalman_riccati.assert_solves)
    assert_solves(A, C, Qx, R, dt, filter_riccati(A, C, Qx, R, np.zeros((A.shape[0], C.shape[0])), dt))


def _m(x) -> np.ndarray:
    return np.array([[float(x)]])


def test_newton_converges_quadratically_on_the_scalar_care():
    """``2aX − X² + q = 0`` (A = a, B = 1, R = 1, S = 0): X* = a + sqrt(a² + q) = 1 for a = −1, q = 3. Newton's error
    obeys exactly e_{k+1} = e_k² / (2(X_k − a)) (expand 𝓡(X* + e) = −2(X* − a)e − e² and take the step −𝓡/𝓡')."""
    a, q, xs = -1.0, 3.0, 1.0
    x0 = xs + 1e-2
    args = (_m(a), _m(1.0), _m(q), _m(1.0), _m(0.0))
    x1 = float(newton_refined(*args, _m(x0), 0.0, rtol=1.0, steps=1)[0, 0])
    e0 = x0 - xs
    pred1 = e0 ** 2 / (2 * (x0 - a))  # 2.49e-5
    # rounding of one step: the residual's terms are ~|2aX| + X² + q ≈ 6, each to a few eps, divided by |𝓡'| ≈ 4
    assert abs((x1 - xs) - pred1) <= 20 * EPS * 6
    x2 = float(newton_refined(*args, _m(x0), 0.0, rtol=1.0, steps=2)[0, 0])
    # quadratic: e2 = e1²/(2(X1 − a)) ≈ 1.5e-10, where a linearly convergent step of rate ≥ 1e-3 would leave ≥ 2.5e-8
    pred2 = pred1 ** 2 / (2 * (x1 - a))
    assert abs((x2 - xs) - pred2) <= 20 * EPS * 6
    assert 1e-11 < x2 - xs < 1e-9
    # the default iteration ends at the rounding floor, within RICCATI_RTOL
    assert abs(float(newton_refined(*args, _m(x0), 0.0, rtol=1e-8)[0, 0]) - xs) <= 20 * EPS * 6


def test_exact_line_search_when_the_newton_step_overshoots():
    """The scalar CARE above from X0 = −0.9 (closed loop a − X0 = −0.1, stable): Newton's step −𝓡/𝓡' =
    3.99/0.2 = 19.95 overshoots to 19.05 (residual 3.99 → −398). Benner & Byers' exact line search minimises
    ‖(1 − t)𝓡(X0) − t²Δ²‖: here a root, t = 0.0952…, where X0 + tΔ = 1 = X* — one step to the solution."""
    args = (_m(-1.0), _m(1.0), _m(3.0), _m(1.0), _m(0.0))
    x1 = float(newton_refined(*args, _m(-0.9), 0.0, rtol=1.0, steps=1)[0, 0])
    # rounding: t is a simple root of the cubic (relative error ~eps), times |Δ| ≈ 20, plus the addition
    assert abs(x1 - 1.0) <= 100 * EPS * 20


def test_newton_converges_quadratically_on_the_scalar_dare():
    """``a²X − X − a²X²/(r + X) + q = 0`` (A = a, B = 1, R = r): a = 2 (unstable), r = q = 1 give −X² + 4X + 1 = 0,
    X* = 2 + sqrt(5), closed loop a r/(r + X*) = 0.382. With 𝓡(X) = a²rX/(r + X) − X + q, Newton's error obeys
    exactly e_{k+1} = −e_k² a²r² / ((r + X*)(a²r² − (r + X_k)²))."""
    a, r, q = 2.0, 1.0, 1.0
    xs = 2.0 + np.sqrt(5.0)
    x0 = xs + 1e-2
    args = (_m(a), _m(1.0), _m(q), _m(r), _m(0.0))

    def pred(x):
        return -((x - xs) ** 2) * a * a * r * r / ((r + xs) * (a * a * r * r - (r + x) ** 2))

    x1 = float(newton_refined(*args, _m(x0), 0.1, rtol=1.0, steps=1)[0, 0])
    # rounding of one step: terms ≈ a²X ≈ 17 to a few eps each, over |𝓡'| = 1 − 0.382² ≈ 0.85
    tol = 20 * EPS * 17 / 0.85
    assert abs((x1 - xs) - pred(x0)) <= tol  # pred(x0) = 3.3e-6
    x2 = float(newton_refined(*args, _m(x0), 0.1, rtol=1.0, steps=2)[0, 0])
    assert abs((x2 - xs) - pred(x1)) <= tol  # pred(x1) ~ 3.6e-13: quadratic (a linear rate 0.15 would leave 5e-7)
    assert abs(x2 - xs) <= 1e-11


def test_refinement_without_a_stabilising_start_refuses():
    """Newton's method needs a stabilising start (the Lyapunov equation of an unstable closed loop is not the
    Newton step towards the stabilising solution): from the anti-stabilising root X = a − sqrt(a² + q) = −3 of the
    scalar CARE above (closed loop a − X = 2) it returns None. And a filter problem with an unobservable unstable
    mode has no stabilising solution: whatever the direct solvers return, no start is stabilising, and the
    refusal is a DesignError naming the condition."""
    args = (_m(-1.0), _m(1.0), _m(3.0), _m(1.0), _m(0.0))
    assert newton_refined(*args, _m(-3.0 + 1e-3), 0.0, rtol=1e-8) is None
    A = np.diag([1.5, -1.0])
    C = np.array([[0.0, 1.0]])  # the mode 1.5 is unobservable: (A, C) not detectable
    with pytest.raises(DesignError, match="no stabilising solution"):
        filter_riccati(A, C, np.eye(2), np.eye(1), np.zeros((2, 1)), 0.0)


def _exact_residual(A, B, Q, R, S, X, dt):
    """𝓡(X) (riccati_newton's module docstring) in rational arithmetic from the doubles given: the judge. ``G`` is
    2 × 2, inverted by its adjugate."""
    from fractions import Fraction

    def fr(M):
        return [[Fraction(float(v)) for v in row] for row in np.atleast_2d(M)]

    def mul(P, Q_):
        return [[sum(P[i][k] * Q_[k][j] for k in range(len(Q_))) for j in range(len(Q_[0]))] for i in range(len(P))]

    def add(*Ms):
        return [[sum(M[i][j] for M in Ms) for j in range(len(Ms[0][0]))] for i in range(len(Ms[0]))]

    def neg(M):
        return [[-v for v in row] for row in M]

    def tr(M):
        return [list(r) for r in zip(*M)]

    A, B, Q, R, S, X = (fr(M) for M in (A, B, Q, R, S, X))
    if dt:
        K, G, quad = add(mul(mul(tr(A), X), B), S), add(R, mul(mul(tr(B), X), B)), add(mul(mul(tr(A), X), A), neg(X))
    else:
        K, G, quad = add(mul(X, B), S), R, add(mul(tr(A), X), mul(X, A))
    det = G[0][0] * G[1][1] - G[0][1] * G[1][0]
    Gi = [[G[1][1] / det, -G[0][1] / det], [-G[1][0] / det, G[0][0] / det]]
    Rx = add(quad, neg(mul(mul(K, Gi), tr(K))), Q)
    return np.array([[float(v) for v in row] for row in Rx])


@pytest.mark.parametrize("dt", [0.0, 0.1])
def test_double_double_residual_is_exact_to_its_bound(dt):
    """``riccati_newton._double_double_residual`` (the residual on hosts whose longdouble is double; callable on any
    host) against 𝓡(X) in rational arithmetic, at scipy's solution of a seeded equation with states scaled over 6
    decades, where the terms (~1e6 of 𝓡's size) cancel. Bound (its docstring): the final rounding ``eps·|𝓡|`` plus
    ``c·n²·eps²`` of the terms' size ``T = |Aᵀ||X|(|A|) + |X| + |K||G⁻¹Kᵀ| + |Q|`` (n = 4, Dot2's ``(n + 2⌈log₂ n⌉)u²``
    ≤ n²eps², κ(G) ~ 10 so the refined ``G⁻¹Kᵀ`` is ~(κ·eps)² of its size; c = 16 covers the handful of chained
    Dot2/Sum2 steps). Plain double's residual misses that bound (its rounding is ~n·eps·T), which shows the bound
    discriminates."""
    import scipy.linalg as sla

    from fmu_fdi.design.toolkit.riccati_newton import _double_double_residual

    rng = np.random.default_rng(21)
    n, m = 4, 2
    T = np.diag(10.0 ** np.array([-3, -1, 1, 3]))
    A = np.linalg.solve(T, rng.standard_normal((n, n))) @ T - (0.5 if not dt else 0.0) * np.eye(n)
    if dt:
        A = A / (1.2 * max(abs(np.linalg.eigvals(A))))
    B = np.linalg.solve(T, rng.standard_normal((n, m)))
    Q = T @ np.diag(rng.uniform(0.5, 2, n)) @ T
    R, S = np.diag([1.0, 3.0]), np.zeros((n, m))
    X = (sla.solve_discrete_are if dt else sla.solve_continuous_are)(A, B, Q, R)
    X = (X + X.T) / 2
    exact = _exact_residual(A, B, Q, R, S, X, dt)
    got, F = _double_double_residual(A, B, Q, R, S, X, dt)

    aA, aX = abs(A), abs(X)
    K = (A.T @ X @ B + S) if dt else (X @ B + S)
    G = R + B.T @ X @ B if dt else R
    terms = (aA.T @ aX @ aA if dt else 2 * aA.T @ aX) + aX + abs(K) @ abs(np.linalg.solve(G, K.T)) + abs(Q)
    eps = np.finfo(float).eps
    assert np.max(abs(exact)) < 1e-6 * np.max(terms)  # the terms cancel: the case the extended residual is for
    bound = eps * abs(exact) + 16 * n ** 2 * eps ** 2 * terms
    assert np.all(abs(got - exact) <= bound), np.max(abs(got - exact) / bound)
    np.testing.assert_allclose(F, -np.linalg.solve(G, K.T), rtol=1e-12, atol=0)

    plain = ((A.T @ X @ A - X) if dt else (A.T @ X + X @ A)) - K @ np.linalg.solve(G, K.T) + Q
    assert np.any(abs(plain - exact) > bound)
