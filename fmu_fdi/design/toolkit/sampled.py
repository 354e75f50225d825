"""Least-order exact residual rows from frequency samples with a fixed stable denominator.

The fallback of :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` when the polynomial
(parity) basis is too ill-conditioned — high degrees, stiff or badly scaled models — to
meet the post-conditions. For a degree ν and ν chosen stable poles, every proper row with
that denominator is

    Q(λ) = C_m (λI − A_m)^{-1} B + D,

with ``A_m`` a real cascade of first/second-order sections holding the poles (exactly,
so the filter is stable by construction) and ``(C_m, A_m)`` observable; Q is *linear* in
``X = [B; D]``. The decoupling conditions ``Q(λ_k) [Gu Gd; I 0](λ_k) = 0`` at K grid points
are a linear system in X. A rational row of McMillan degree ≤ ν + n that vanishes at
K > 2(ν + n) distinct points vanishes identically, so on a dense enough grid the
solutions are exactly the degree-ν members of the left null space (Varga 2017, sec. 7.4:
``Q = Y N`` with N a proper basis).

Numerics: the basis functions ``[C_m (λI − A_m)^{-1}, 1]`` are orthonormalised on the grid
(eigen-decomposition of their Gram matrix), every column of ``[Gu Gd; I 0]`` is scaled to
unit peak over the grid and each point's equations are divided by their norm, and the null
space is read from an SVD: a right-singular direction with
singular value σ is a row whose relative leakage is σ (RMS over the grid), so the rank
decision *is* the post-condition, with the threshold ``null_tol`` (default 1e-10; exact
rows of low degree show ~1e-13, of degree 10-20 ~1e-10; nullspace_design passes
``dec_tol / 100``). The smallest ν at which the null space sees every fault gives the
least order; the combination is chosen as in the polynomial design (:mod:`._select`).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...lti import LTI, frequency_grid
from ._select import greedy_combinations, visibility_gated
from .postconditions import _cosine, _values


def cascade(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(A_m, C_m)`` holding the poles exactly: real first-order sections (real poles) and
    rotation blocks ``[a b; −b a]`` (pairs). Distinct poles: modal form, output the sum of
    the sections' first states (observable as the poles differ). Repeated poles: a cascade,
    each section driven by the previous section's first state, output the last section's
    (observable when no section's zero cancels a later pole)."""
    poles = np.asarray(poles, complex)
    units, used = [], np.zeros(poles.size, bool)
    for i, z in enumerate(poles):
        if used[i]:
            continue
        used[i] = True
        if abs(z.imag) > 1e-12 * max(1.0, abs(z)):
            j = next((k for k in range(poles.size) if not used[k] and abs(poles[k] - np.conj(z)) <= 1e-9 * max(1.0, abs(z))), None)
            if j is None:
                raise DesignError(f"pole {z} has no conjugate: filter poles must be closed under conjugation")
            used[j] = True
            units.append(np.array([[z.real, abs(z.imag)], [-abs(z.imag), z.real]]))
        else:
            units.append(np.array([[z.real]]))
    nu = sum(u.shape[0] for u in units)
    A = np.zeros((nu, nu))
    # distinct poles: a modal (partial-fraction) form, output the sum of the sections — its
    # basis functions 1/(λ - p_i) are far better conditioned than the cascade's products
    eig = np.array([complex(u[0, 0], u[0, 1] if u.shape[0] == 2 else 0.0) for u in units])
    gaps = np.abs(eig[:, None] - eig[None, :])
    np.fill_diagonal(gaps, np.inf)
    modal = eig.size <= 1 or np.min(gaps) > 1e-6 * max(1.0, float(np.max(np.abs(eig))))
    k, prev = 0, None
    C = np.zeros((1, nu))
    for u in units:
        d = u.shape[0]
        A[k:k + d, k:k + d] = u
        if modal:
            C[0, k] = 1.0
        elif prev is not None:
            A[k, prev] = 1.0  # input of this section = output (first state) of the previous one
        prev = k
        k += d
    if nu and not modal:
        C[0, prev] = 1.0
    return A, C


def _basis_values(A: np.ndarray, C: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``[C (λI − A)^{-1}, 1]`` at every point: (K, ν + 1)."""
    nu = A.shape[0]
    out = np.ones((lam.size, nu + 1), complex)
    if nu:
        eye = np.eye(nu)
        for k, l in enumerate(lam):
            out[k, :nu] = sla.solve((l * eye - A).T, C.ravel().astype(complex))
    return out


def sampled_rows(model, choose, fault_cols: list[np.ndarray], rdim: int, *, freqs=None, FDtol: float = 1e-4,
                 FDGainTol: float = 0.01, null_tol: float = 1e-10, seed: int = 0, max_degree: int | None = None):
    """Least-order rows decoupling u and d of ``model``; returns ``(Q, info)``.

    ``choose(ν)`` gives ν stable poles; ``fault_cols`` the columns of each fault in
    ``model.augmented()``.
    """
    Ge = model.augmented()
    sl = model.group_slices()
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    q = model.ny + model.nu
    n = model.n
    max_degree = n + 1 if max_degree is None else max_degree
    freqs_arr = None if freqs is None else np.atleast_1d(np.asarray(freqs, float))
    last = "no degree up to n + 1 gives a row that decouples u and d"
    for nu in range(0, max_degree + 1):
        poles = np.asarray(choose(nu), complex) if nu else np.zeros(0, complex)
        A, C = cascade(poles)
        K = max(160, 3 * (n + nu) + 40)
        omega = frequency_grid([model.lti()], num=K, poles=poles,
                               extra=() if freqs_arr is None else freqs_arr)
        lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
        G = _values(Ge, lam)
        ok = np.all(np.isfinite(G), axis=(1, 2))
        lam, omega, G = lam[ok], omega[ok], G[ok]
        Phi = _basis_values(A, C, lam)  # (K, ν+1)
        gram = np.real(Phi.conj().T @ Phi)
        w, V = sla.eigh(gram)
        keep = w > 1e-13 * w[-1]
        T = V[:, keep] / np.sqrt(w[keep])  # basis ψ = Φ T, orthonormal on the grid
        Psi = Phi @ T  # (K, r)
        r = Psi.shape[1]
        # every column of [Gu Gd; I 0] scaled to unit peak over the grid (the exact rows are unchanged), so
        # that a weak column — a fault decoupled as d in a bank row, 1e3 below the strongest input — is
        # decoupled to the same relative accuracy as the others: the bank checks each fault's own leak
        Gud = G[:, :, ud]
        Gud = Gud / np.maximum(np.max(np.linalg.norm(Gud, axis=1), axis=0), 1e-300)[None, None, :]
        Gn = Gud / np.maximum(np.linalg.norm(Gud, 2, axis=(1, 2)), 1e-300)[:, None, None] if ud.size else Gud
        # equations: y (r·q) -> Σ_{i,a} Ψ_k[i] Y[i,a] Gn_k[a, c] for c in ud
        L = np.einsum("ki,kac->iakc", Psi, Gn).reshape(r * q, -1)
        L = np.hstack([L.real, L.imag])
        # only U is needed: thin SVD unless there are fewer equations than unknowns
        U, s, _ = sla.svd(L, full_matrices=L.shape[0] > L.shape[1])
        s = np.concatenate([s, np.zeros(U.shape[1] - s.size)])
        Z = U[:, s <= null_tol].T  # rows: coefficient vectors y of exact rows
        if Z.shape[0] < rdim:
            continue
        # responses of each null row to each fault on the grid: (K, k, cols)
        Qz = np.einsum("ki,jia->kja", Psi, Z.reshape(-1, r, q))  # (K, k, q)
        P = [np.einsum("kja,kac->kjc", Qz, G[:, :, c]) for c in fault_cols]
        # a fault is seen by the null space when some row sees it (pointwise cosine, as the
        # post-condition: _cosine)
        nqy = np.linalg.norm(Qz[:, :, :model.ny], axis=2)  # (K, k)
        seen = []
        for Pj, c in zip(P, fault_cols):
            gfk = np.linalg.norm(G[:, :model.ny, c], 2, axis=(1, 2))  # (K,)
            resp = np.linalg.norm(Pj, axis=2)  # (K, k)
            seen.append(max(_cosine(resp[:, i], nqy[:, i] * gfk) for i in range(Z.shape[0])) >= FDtol)
        if fault_cols and not all(seen):
            last = (f"at degree {nu} the exact rows miss faults {[j for j, sj in enumerate(seen) if not sj]}")
            continue
        strong = None
        if freqs_arr is not None and fault_cols:
            idx = [int(np.argmin(np.abs(omega - f))) for f in freqs_arr]
            strong = [Pj[idx] for Pj in P]
        if fault_cols:
            objective = visibility_gated(P, Qz[:, :, :model.ny], G, fault_cols, FDtol, strong)
            H = greedy_combinations(objective, Z.shape[0], rdim, seed)
            if strong is not None and min(objective(h) for h in H) <= FDGainTol:
                last = f"at degree {nu} no exact row is strongly sensitive at {freqs_arr.tolist()}"
                continue
        else:
            H = np.eye(Z.shape[0])[:rdim]
        rows = []
        for h in H:
            X = T @ (h @ Z).reshape(r, q)  # (ν+1, q) in the Φ basis
            rows.append(LTI(A, X[:nu], C, X[nu:], model.dt))
        from ...lti import vstack

        Q = vstack(rows) if len(rows) > 1 else rows[0]
        info = {"order": int(Q.n), "rdim": len(rows), "degree": nu, "combination": H.tolist(),
                "null_dimension": int(Z.shape[0]), "null_sv": float(s[s <= null_tol].max(initial=0.0)),
                "next_sv": float(s[s > null_tol].min(initial=np.inf)), "synthesis": "frequency-sampled"}
        return Q, info
    raise DesignError(f"frequency-sampled design: {last}")
