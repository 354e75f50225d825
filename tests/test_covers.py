"""Type 2 minimum dynamic covers (:mod:`fmu_fdi.design.toolkit.covers`): ``X = X1 + Y X2`` of least McMillan degree.

Constructed cases whose least degree is known by a hand argument: ``X2 = W [I 0] P`` with P orthogonal and
``W = [[1, w], [0, 1]]`` (det W = 1: no finite or infinite zeros, a proper stable inverse), so that
``K = Pᵀ [0; I]`` is a constant right annihilator of X2; ``X1 = Xlow + Y0 X2`` with ``Xlow = x [0 I] P``
(x of order k). Every ``X = X1 + Y X2`` has ``X K = x``, so its degree is at least ``deg x = k``; ``Xlow`` itself
(``Y = −Y0``) has degree k. Hence the least degree is k. Judged independently of the code under test: degrees by
counting Hankel singular values (scipy Lyapunov solvers on the returned realisation), the identity
``X = X1 + Y X2`` by numpy evaluation of ``C (λI − A)⁻¹ B + D`` at random points.
"""
import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi.design.toolkit.covers import left_cover2
from fmu_fdi.lti import LTI


def hankel_order(S: LTI) -> int:
    """McMillan degree of a stable system: Hankel singular values above 1e-7 of the largest one or of ||D|| (a
    mode the system has contributes at the data's scale; one left by rounding ~1e-16 in the Gramians, ~1e-8 in
    their product's square root)."""
    if S.n == 0 or not np.any(S.C) or not np.any(S.B):
        return 0
    if S.dt:
        P = sla.solve_discrete_lyapunov(S.A, S.B @ S.B.T)
        Q = sla.solve_discrete_lyapunov(S.A.T, S.C.T @ S.C)
    else:
        P = sla.solve_continuous_lyapunov(S.A, -S.B @ S.B.T)
        Q = sla.solve_continuous_lyapunov(S.A.T, -S.C.T @ S.C)
    hsv = np.sqrt(np.abs(np.linalg.eigvals(P @ Q)))
    return int(np.sum(hsv > 1e-7 * max(hsv.max(), np.linalg.norm(S.D, 2))))


def value(S: LTI, lam: complex) -> np.ndarray:
    return S.C @ np.linalg.solve(lam * np.eye(S.n) - S.A, S.B) + S.D if S.n else S.D.astype(complex)


def block_sum(X: LTI, Y: LTI) -> LTI:
    return LTI(sla.block_diag(X.A, Y.A), np.vstack([X.B, Y.B]), np.hstack([X.C, Y.C]), X.D + Y.D, X.dt)


def rss(rng, n, p, m, dt):
    A = rng.standard_normal((n, n))
    if dt:
        A = 0.8 * A / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-9) if n else A
    elif n:
        A = A - (np.max(np.linalg.eigvals(A).real) + 0.5 + rng.random()) * np.eye(n)
    return LTI(A, rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m)), dt)


def case(seed, k, ny0, dt=0.0, m=4, p2=2):
    rng = np.random.default_rng(seed)
    P = np.linalg.qr(rng.standard_normal((m, m)))[0]
    w = rss(rng, 2, 1, 1, dt)
    E12 = np.zeros((p2, p2))
    E12[0, 1] = 1.0
    # W = I + e_1 w e_2ᵀ (upper triangular, unit diagonal): det W = 1
    W = LTI(w.A, w.B @ np.eye(p2)[[1]], np.eye(p2)[:, [0]] @ w.C, np.eye(p2) + w.D[0, 0] * E12, dt)
    X2 = W @ LTI.static(np.eye(p2, m) @ P, dt)
    x = rss(rng, k, 1, m - p2, dt)
    Xlow = x @ LTI.static(np.eye(m)[p2:] @ P, dt)
    Y0 = rss(rng, ny0, 1, p2, dt)
    K = P.T @ np.eye(m)[:, p2:]
    return block_sum(Xlow, Y0 @ X2), X2, K, rng


@pytest.mark.parametrize("seed,k,ny0,dt", [(1, 1, 0, 0.0), (2, 2, 1, 0.0), (3, 3, 3, 0.0), (4, 1, 4, 0.0),
                                           (5, 2, 0, 0.1), (6, 3, 2, 0.1), (7, 0, 2, 0.0)])
def test_least_degree_and_identity(seed, k, ny0, dt):
    X1, X2, K, rng = case(seed, k, ny0, dt)
    assert hankel_order(X1 @ LTI.static(K, dt)) == k  # the lower bound of every X = X1 + Y X2
    assert hankel_order(X1) > k  # something to lower
    cv = left_cover2(X1, X2)
    assert cv.X.n == k and hankel_order(cv.X) == k
    # X = X1 + Y X2 at random points off the poles: rounding of realisations of norm ~1-10, factor 1e3 for
    # the resolvents' conditioning
    for _ in range(6):
        lam = complex(rng.uniform(-2, 2), rng.uniform(-3, 3)) if not dt else np.exp(complex(rng.uniform(-0.3, 0.3), rng.uniform(-3, 3)))
        lhs = value(cv.X, lam)
        rhs = value(X1, lam) + value(cv.Y, lam) @ value(X2, lam)
        assert np.linalg.norm(lhs - rhs) <= 1e-10 * max(1.0, np.linalg.norm(rhs))


def test_stable_cover_refuses_when_every_solution_keeps_an_unstable_pole():
    """``X1 = x [0 I] P`` with x of order 1 and pole +1: every ``X = X1 + Y X2`` has ``X K = x`` (K the constant
    annihilator of X2), so the pole +1 is in every X: no stable cover exists and None is returned."""
    from fmu_fdi.design.toolkit.covers import stable_left_cover

    _, X2, K, _ = case(21, 1, 0)
    x = LTI([[1.0]], [[1.0, 2.0]], [[1.0]], [[0.5, 0.0]])
    Xu = x @ LTI.static(K.T, 0.0)  # x [0 I] P = x Kᵀ (K = Pᵀ [0; I])
    assert np.allclose(value(Xu, 0.3j) @ K, value(x, 0.3j))
    got = stable_left_cover(Xu, X2, lambda re, im: re < 0, lambda k: [-1.0] * k)
    assert got is None


def test_stable_cover_places_free_poles():
    """``X1 = x Kᵀ + Y0 X2`` with x static and Y0 unstable (pole +2): ``X = x Kᵀ`` (order 0) is reached by
    ``Y = −Y0``; the stable cover returns order 0 — a stable row with the fault response of X1 (X K = x)."""
    from fmu_fdi.design.toolkit.covers import stable_left_cover

    _, X2, K, _ = case(22, 0, 0)
    x = LTI.static([[1.0, -0.5]])
    Y0 = LTI([[2.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]])
    X1 = block_sum(x @ LTI.static(K.T), Y0 @ X2)
    cv = stable_left_cover(X1, X2, lambda re, im: re < 0, lambda k: [-3.0] * k)
    assert cv is not None and cv.X.n == 0
    assert np.allclose(cv.X.D @ K, x.D, atol=1e-10)
