"""Least-order rows of ``X(λ) Ge(λ) = [0 0 Mr_i(λ)]`` from the pencil null-space basis (Varga's ``glsol``, one row).

With ``Ge = [Gu Gd Gf; I 0 0]`` (from ``[u; d; f]`` to ``[y; u]``) a row ``X`` solves

    X Ge = [0  0  Mr_i]      iff      [X_y  −1  X_u]  [Gu Gd Gf; 0 0 Mr_i; I 0 0] = 0,

i.e. ``[X_y, −1, X_u]`` is a left annihilator of the *augmented* system with outputs ``[y; z]``,
``z = Mr_i f``, known inputs u and unknown inputs ``[d; f]`` — the null space
:func:`.pencil.pencil_basis` computes (the solution of a linear rational equation from the left
null space of ``[G; F]``: A. Varga, "Computation of least order solutions of linear rational
equations", MTNS 2004, the method of DescriptorSystems.jl ``glsol``). Its simple basis
(:func:`.pencil.simple_rows`: one row ``N_j`` per left minimal index ``ν_j``, each of McMillan
degree ``ν_j``, by Type 1 minimum dynamic covers) has the *predictable degree property* (Forney,
SIAM J. Control 13, 1975): the numerators ``P_j`` of ``N_j = P_j/d_j``
form a minimal polynomial basis (their degrees sum to the least total), so every polynomial null
row of degree ≤ δ is ``Σ_j p_j P_j`` with ``deg p_j ≤ δ − ν_j``. A rational row ``X`` of McMillan
degree δ is ``n/d`` with a polynomial null row ``n`` of degree ≤ δ whose z-entry is ``−d ≠ 0``;
hence the least degree of a solution is

    δ_min = min { ν_j : the z-entry of N_j is not identically zero },

reached by ``X = −N_z^{-1} [N_y N_u]`` of that row (its denominator has degree ν_j). With the row's
realisation ``N = (A, [b_y b_z b_u], c, [d_y d_z d_u])`` and a biproper ``N_z`` (``d_z ≠ 0``),

    X = (A − b_z c/d_z,  [b_y b_u] − b_z [d_y d_u]/d_z,  −c/d_z,  −[d_y d_u]/d_z),      (order ν)

whose poles are the zeros of ``N_z`` (the basis' own poles cancel). ``d_z = 0`` for every row of
least degree: the least-degree solution is improper; a stable proper pair ``(X, m) = (N_yu, −N_z)``
then solves ``X Ge = [0 0 m Mr_i]`` (Procedure EMM's updating factor), with the poles of ``N`` placed
by output injection (a biproper left factor, which keeps ``N`` a null row).

Rows of the least index ν: a single one whose solution is proper and stable is taken; otherwise
they are combined (poles placed at common targets, :func:`_combined_row`) into a row whose
Mr-entry is a nonzero constant, so that the solution has the chosen poles. When no single row or
constant combination gives a stable solution, :func:`stable_solution` gives a stable one (not of least
order) and :func:`lowered_stable_rows` lowers it: every solution is ``X1 + Y N_b`` (``N_b`` the basis of
:func:`solution_basis`), and a stable minimum dynamic cover (:func:`.covers.stable_left_cover`) of the
least-order row (when proper) or of the stable one finds the least k whose admissible characteristic
polynomials hold a stable one — this includes a combination of equal-index rows with a dynamic
Mr-entry whose zeros are stable. Guaranteed least among stable solutions when, at every lower order,
the admissible polynomials form a single point or all monic polynomials; otherwise (a proper affine
subset, whose stable members are not searched beyond its point nearest the requested poles) the order
is an upper bound of the least.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import DesignError
from ...lti import LTI
from ...model import FDIModel
from .pencil import controllable_staircase, pencil_basis, schur_feedback, simple_rows


@dataclass
class LeastRow:
    """The least-degree null row of the augmented system with a nonzero z-entry."""

    #: the null row ``[N_y N_z N_u]`` (1 × (p + 1 + m)), stable, proper, McMillan degree ``degree``
    N: LTI
    degree: int
    #: z-entry feedthrough relative to the row's scale (0: the least-order solution is improper)
    dz: float
    #: left minimal indices of the augmented system and the cover conditions of the simple rows
    indices: list
    cond: float
    p: int
    #: the whole proper stable basis of the augmented null space (k × (p + 1 + m)) and its rank tolerance
    basis: LTI | None = None
    rank_tol: float = 0.0

    def solution(self, atol: float = 0.0) -> LTI:
        """``X = −N_z^{-1} [N_y N_u]`` (requires ``dz > 0``), minimal."""
        N, p = self.N, self.p
        b, d = N.B, N.D
        bz, dz = b[:, [p]], float(d[0, p])
        keep = np.r_[np.arange(p), np.arange(p + 1, N.m)]
        byu, dyu = b[:, keep], d[:, keep]
        X = LTI(N.A - bz @ N.C / dz, byu - bz @ dyu / dz, -N.C / dz, -dyu / dz, N.dt)
        return X.minreal(atol)

    def pair(self, choose, atol: float = 0.0) -> tuple[LTI, LTI]:
        """``(X, m) = (N_yu, −N_z)`` with every pole of N at ``choose(ν)`` (output injection ``A + L c``,
        Schur method on the dual pair: :func:`.pencil.assign_poles`), both minimal."""
        N, p = self.N, self.p
        A, B, C, D = N.A, N.B, N.C, N.D
        if N.n:
            T, Z, F, _ = schur_feedback(A.T, C.T, N.dt, lambda eig: choose(eig.size), lambda re, im: False, full=True)
            A, B, C = T.T, Z.T @ B + F.T @ D, C @ Z  # A + L C in its Schur coordinates (accurate for a large L)
        keep = np.r_[np.arange(p), np.arange(p + 1, N.m)]
        X = LTI(A, B[:, keep], C, D[:, keep], N.dt)
        m = LTI(A, -B[:, [p]], C, -D[:, [p]], N.dt)
        return X.minreal(atol), m.minreal(atol)


def augmented_model(model: FDIModel, Mi: LTI, rtol: float = 0.0, atol: float = 0.0) -> FDIModel:
    """The model with the output ``z = Mr_i f`` appended and f turned into an unknown input:
    outputs ``[y; z]``, known inputs u, unknown inputs ``[d; f]``; states ``[x; x_M]`` reduced to a
    minimal realisation with the rank tolerance ``max(atol, rtol·||[A B; C D]||)`` of the balanced
    realisation (TB01ID, then TB01PD on those coordinates; a reference
    ``Q* Gf`` repeats plant modes that its product realisation cancels only to rounding: the block
    diagonal realisation holds them twice, uncontrollable to ~1e-13). The reference's modes that repeat
    plant modes are first read from the plant's own states (:func:`_on_plant_states`), so that this
    reduction has no copies to remove and the plant's rows stay exact."""
    n, p, m, nd = model.n, model.ny, model.nu, model.nd
    G = model.lti("u", "d", "f")
    Cx, Mo = _on_plant_states(model, Mi, rtol) if rtol > 0 else (None, None)
    if Mo is None:
        Cx, Mo = np.zeros((1, n)), Mi
    nM = Mo.n
    A = np.block([[model.A, np.zeros((n, nM))], [np.zeros((nM, n)), Mo.A]])
    B = np.block([[G.B], [np.zeros((nM, m + nd)), Mo.B]])
    C = np.block([[model.C, np.zeros((p, nM))], [Cx, Mo.C]])
    D = np.block([[G.D], [np.zeros((1, m + nd)), Mo.D]])
    aug = LTI(A, B, C, D, model.dt)
    if aug.n and rtol > 0:
        aug = relative_minreal(aug, rtol, atol)
    return FDIModel(aug.A, aug.B[:, :m], aug.C, aug.D[:, :m], Bd=aug.B[:, m:], Dd=aug.D[:, m:], dt=model.dt,
                    name=f"{model.name}_Mr")


def relative_minreal(S: LTI, rtol: float, atol: float = 0.0) -> LTI:
    """``S`` balanced (SLICOT TB01ID) and reduced to a minimal realisation (TB01PD, without balancing again) with the
    rank tolerance ``max(atol, rtol·||[A B; C D]||)`` of the *balanced* data — the core's relative decision.
    LTI.minreal balances internally, so a threshold from the unbalanced norm (up to 1e4 larger: matching seed
    14's reference at mm_tol 1e-8) judged rescaled matrices and removed every state of the reference."""
    if not S.n:
        return S
    Sb, _ = S.balanced()
    norm = float(np.linalg.norm(np.block([[Sb.A, Sb.B], [Sb.C, Sb.D]]), 2))
    return Sb.minreal(tol=max(atol, rtol * norm), equil="N")


def _on_plant_states(model: FDIModel, Mi: LTI, tol: float):
    """``(C_x, M_o)`` with ``Mr_i = C_x (λI − A)^{-1} B_f + M_o`` (and ``C_x (λI − A)^{-1} [B_u B_d] = 0``):
    the modes of the reference that are plant modes read from the plant's own states, ``M_o`` the rest; or
    ``(None, None)`` when that representation does not reproduce ``Mr_i`` to ``tol`` of its peak on a grid.

    A reference ``Q* Gf`` repeats plant modes. Realised beside the plant and reduced jointly, the copies are
    uncontrollable only to the accuracy of their eigenvalues in the reference (a mode of residue 1e-4 known
    to 1e-12 in value is ~1e-8 off in position), and removing them perturbs the *plant's* rows of the
    augmented model by the truncation — amplified near a plant pole at the stability boundary (random seed
    156 unstable, discrete: pole 1.0000856, plant rows off by 1e-7 of their peak, a matched row off by 7e-8,
    where the plant data are exact). Here the plant's realisation stays exact: with the reference's modes
    near the plant's spectrum (relative distance ≤ ``sqrt(tol)``) ordered first and decoupled (Sylvester
    ``A11 X − X A22 = −A12``, as :func:`...problems.matching._drop_cancelled`), ``T`` solves
    ``T A − A11 T = 0``, ``T [B_u B_d B_f] = [0 0 B1]`` (least squares), so that ``x1 − T x`` is
    uncontrollable and ``C1 x1 = C1 T x`` on the trajectories: ``C_x = C1 T``."""
    import scipy.linalg as sla

    from ...linalg import ordered_schur
    from ...lti import frequency_grid
    from .postconditions import _values

    n = model.n
    if not (n and Mi.n):
        return None, None
    lam_p = np.linalg.eigvals(model.A)
    near = np.sqrt(tol)

    def close(re, im):
        z = complex(re, im)
        return bool(np.min(np.abs(lam_p - z)) <= near * max(1.0, abs(z)))

    T_, Z, k = ordered_schur(Mi.A, close)
    if k == 0:
        return None, None
    nM = Mi.n
    A11, A12, A22 = T_[:k, :k], T_[:k, k:], T_[k:, k:]
    X = sla.solve_sylvester(A11, -A22, -A12) if k < nM else np.zeros((k, 0))
    Bt, Ct = Z.T @ Mi.B, Mi.C @ Z
    B1, B2 = Bt[:k] - X @ Bt[k:], Bt[k:]
    C1, C2 = Ct[:, :k], Ct[:, :k] @ X + Ct[:, k:]
    G = model.lti("u", "d", "f")
    nf = Mi.m
    rhs_B = np.hstack([np.zeros((k, G.m - nf)), B1])
    # vec(T A − A11 T) = (Aᵀ ⊗ I − I ⊗ A11) vec T, vec(T B) = (Bᵀ ⊗ I) vec T (column-major vec)
    Ik = np.eye(k)
    L = np.vstack([np.kron(model.A.T, Ik) - np.kron(np.eye(n), A11), np.kron(G.B.T, Ik)])
    r = np.concatenate([np.zeros(k * n), rhs_B.ravel(order="F")])
    T = np.linalg.lstsq(L, r, rcond=None)[0].reshape((k, n), order="F")
    Cx = C1 @ T
    Mo = LTI(A22, B2, C2, Mi.D, Mi.dt)
    # verification: z = C_x (λI − A)^{-1} B_f + M_o reproduces Mr_i, and C_x sees no u, d
    w = frequency_grid([Mi, G], num=200)
    lam = np.exp(1j * w * Mi.dt) if Mi.dt else 1j * w
    poles = np.r_[lam_p, np.asarray(Mi.poles(), complex)]
    lam = lam[np.min(np.abs(lam[:, None] - poles[None, :]), axis=1) > 1e-6 * np.maximum(1.0, np.abs(lam))]
    ref = _values(Mi, lam)
    rows = LTI(G.A, G.B, Cx, np.zeros((1, G.m)), G.dt)
    got = _values(rows, lam)
    got[:, :, G.m - nf:] += _values(Mo, lam)
    want = np.concatenate([np.zeros((lam.size, 1, G.m - nf)), ref], axis=2)
    ok = np.all(np.isfinite(got), axis=(1, 2)) & np.all(np.isfinite(want), axis=(1, 2))
    top = float(np.max(np.abs(ref[ok]), initial=0.0))
    if not (ok.any() and top > 0 and float(np.max(np.abs(got[ok] - want[ok]))) <= tol * top):
        return None, None
    return Cx, Mo


def _markov_norm(N: LTI, cols) -> float:
    """``||[D, C B/ρ, C A B/ρ², …]||`` of the columns ``cols`` (ρ = max(1, ||A||)): zero iff those
    columns are identically zero (n Markov parameters decide a system of order n)."""
    B, D = N.B[:, cols], N.D[:, cols]
    out = [np.linalg.norm(D)]
    if N.n:
        rho = max(1.0, float(np.linalg.norm(N.A, 2)))
        v = B / rho
        for _ in range(N.n):
            out.append(np.linalg.norm(N.C @ v))
            v = N.A @ v / rho
    return float(np.linalg.norm(out))


def least_row(model: FDIModel, Mi: LTI, *, tol: float, atol: float = 0.0, poles=None, sdeg=None,
              smarg=None, good=None, choose=None) -> LeastRow | None:
    """The least-degree row of the augmented null space whose z-entry is nonzero (relative size
    above ``tol``, also the relative rank tolerance of the core's decisions: a reference known to
    ~1e-11, e.g. a product ``Q* Gf``, is matched by the null row it is an approximation of), or None
    when every null row has a zero z-entry (``Mr_i`` is not a fault response
    of any decoupling filter). Among the simple rows of that degree, one whose solution is proper
    (biproper ``N_z``) and, with ``good(re, im)``, stable (the zeros of ``N_z`` in the region) is
    preferred, then the largest relative z-feedthrough (the best conditioned division by ``d_z``).
    When no single row is both and ``choose`` is given, the rows of that degree are combined
    (:func:`_combined_row`): a row whose z-entry is a nonzero constant, so that the solution has
    the ``choose(ν)`` poles."""
    aug = augmented_model(model, Mi, tol, atol)
    p = model.ny
    pb = pencil_basis(aug, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
    if pb.N.p == 0:
        return None
    rows = simple_rows(pb, model.dt)
    if len(rows) < pb.N.p:
        from .postconditions import NumericalDesignError

        raise NumericalDesignError(
            f"model matching: the simple basis of the augmented null space has {len(rows)} of its {pb.N.p} rows "
            f"(indices {pb.degrees}): a minimum dynamic cover was too ill-conditioned; the least order cannot be "
            f"proven — pass other atol")
    rows = [_least_degree_row(N, nu, cond, p, tol, atol) for N, nu, cond in rows]
    best, group = None, []
    for N, nu, cond in sorted(rows, key=lambda r: r[1]):
        if best is not None and nu > best[2]:
            break
        group.append(N)
        whole = _markov_norm(N, np.arange(N.m))
        z = _markov_norm(N, [p])
        if not whole > 0 or z <= tol * whole:
            continue
        dz = abs(float(N.D[0, p])) / whole
        stable = False
        if dz > tol and good is not None:
            zeros = np.linalg.eigvals(N.A - N.B[:, [p]] @ N.C / N.D[0, p]) if N.n else np.zeros(0)
            stable = all(good(z.real, z.imag) for z in zeros)
        key = (dz > tol, stable, dz)
        if best is None or key > best[0]:
            best = (key, N, nu, dz, cond)
    if best is None:
        return None
    (proper, stable, _), N, nu, dz, cond = best
    if not (proper and stable) and choose is not None and good is not None and nu > 0 and len(group) > 1:
        comb = _combined_row(group, p, choose, good, tol)
        if comb is not None:
            N, dz = comb, 1.0 / _markov_norm(comb, np.arange(comb.m))
    if dz > tol and good is not None:
        N = _refined_row(model, Mi, N, p, good, tol)
    # the indices with those of the rows whose exact solution has a lower degree (:func:`_least_degree_row`)
    return LeastRow(N, int(nu), dz if dz > tol else 0.0, sorted(int(r[1]) for r in rows), float(cond), p, pb.N,
                    pb.rank_tol)


#: relative distance of the points beside the plant's poles outside the region at which :func:`_refined_row` reads the
#: matching equation (a residue r of R there reads r/BESIDE; 1e-4 keeps the plant's values finite, ≲ 1e4·‖Ge‖)
BESIDE = 1e-4


def _refined_row(model: FDIModel, Mi: LTI, N: LTI, p: int, good, tol: float = 0.0) -> LTI:
    """The row ``[X_y  −1  X_u]`` of the solution ``X = −N_z^{-1} [N_y N_u]`` with its numerator ``[B; D]`` refitted
    (poles and ``C`` kept) to ``X(λ) [Gu Gd Gf; I 0 0](λ) = [0 0 Mr_i(λ)]`` on a grid — the equation itself, on the
    plant's own data — when ``X`` is stable (``good``), misses the equation there by more than ``tol`` (the core's
    relative tolerance) of ``Mr_i``'s peak, and the refit lowers the equation's largest residual; otherwise ``N``
    unchanged (the fit's least squares cost 0.04 s a row: skipped where the row already meets the tolerance).

    The pencil's rank decisions at the core's relative tolerance truncate entries of about that size, and the
    null row inherits the truncation amplified by the plant's gain: exact matching seed 1149 (unstable, updating;
    discrete, plant poles 0.976 and 1.043, ‖Ge‖ 187 near z = 1; an exact reference of degree 2) had its degree-2
    row decided at rtol 1e-9 (at 1e-11 the staircase reads index 7) with ``N [Gu Gd; 0 0; I 0]`` = 6.7e-8 and a
    z-column residual 1.7e-7, so the matched filter leaked 1.03e-7 of its weakest fault gain and was refused.
    ``X(λ) = K(λ) Θ`` is linear in Θ = [B; D] (:func:`numerator_fit`: the pole-fixed step of vector fitting), so
    the least-squares Θ solves the sampled equation as well as X's poles allow; the poles are the zeros of
    ``N_z`` — exact where the reference is (seed 1149: residual 6.7e-8 → ~1e-13)."""
    from ...lti import frequency_grid
    from .postconditions import _values

    X = LeastRow(N, 0, 1.0, [], 1.0, p).solution()
    ev = np.linalg.eigvals(X.A) if X.n else np.zeros(0)
    if not all(good(z.real, z.imag) for z in ev):
        return N
    G = model.lti("u", "d", "f")
    m, k = model.nu, G.m
    Ge = LTI(G.A, G.B, np.vstack([G.C, np.zeros((m, G.n))]),
             np.vstack([G.D, np.hstack([np.eye(m), np.zeros((m, k - m))])]), model.dt)
    w = frequency_grid([Ge, Mi, X], num=400)
    lam = np.exp(1j * w * model.dt) if model.dt else 1j * w
    poles = np.concatenate([np.asarray(S.poles(), complex) for S in (Ge, Mi, X)] + [np.zeros(0)])
    if poles.size:
        lam = lam[np.min(np.abs(lam[:, None] - poles[None, :]), axis=1) > 1e-6 * np.maximum(1.0, np.abs(lam))]
    # beside each plant pole outside the region: R must cancel it exactly (the post-conditions read its residue),
    # and there a residue r of the equation reads r/δ, so the fit and the comparison weigh the cancellation
    ev_p = np.linalg.eigvals(model.A) if model.n else np.zeros(0)
    bad = np.array([z for z in ev_p if not good(z.real, z.imag)], complex)
    ring = np.exp(2j * np.pi * np.arange(4) / 4 + 0.3j)
    if bad.size:
        lam = np.concatenate([lam, (bad[:, None] + BESIDE * np.maximum(1.0, np.abs(bad))[:, None] * ring).ravel()])
    Gv, Mv = _values(Ge, lam), _values(Mi, lam)
    target = np.concatenate([np.zeros((lam.size, 1, k - Mi.m)), Mv], axis=2)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(target), axis=(1, 2))
    lam, Gv, target = lam[ok], Gv[ok], target[ok]
    if 2 * lam.size * k < X.n + X.p * X.m:
        return N
    before = float(np.max(np.abs(_values(X, lam) @ Gv - target), initial=0.0))
    if not before > tol * float(np.max(np.abs(Mv[ok]), initial=0.0)):
        return N
    th, res = numerator_fit(X.A, X.C, model.dt, lam, target, Gv)
    if not float(np.max(np.abs(res))) < before:
        return N
    Bx, Dx = th[:X.n], th[X.n:]
    B = np.hstack([Bx[:, :p], np.zeros((X.n, 1)), Bx[:, p:]])
    D = np.hstack([Dx[:, :p], -np.ones((1, 1)), Dx[:, p:]])
    return LTI(X.A, B, X.C, D, N.dt)


def _least_degree_row(N: LTI, nu: int, cond: float, p: int, tol: float, atol: float) -> tuple:
    """``(N, ν, cond)`` of a simple row, or the row ``[X_y  −1  X_u]`` of lower degree when its solution
    ``X = −N_z^{-1} [N_y N_u]`` (``N_z`` biproper) has a realisation of lower order.

    A minimal basis has no zeros, so its row of index ν gives a solution of McMillan degree ν. The
    pencil's staircase decides the indices after an output-nulling deflation whose feedback (norm
    ``fnorm``) amplifies the data's rounding by about ``fnorm²``: a reference ``Q* Gf`` known to ~1e-12
    gives a sub-diagonal entry of ~1e-7 where the exact structure has 0 (random seed 197: fnorm 790,
    index 6 computed for 2), so the row carries near-common zeros of all its entries (there 3.16) —
    poles of no solution, which every solution from this row would appear to have. The solution is
    reduced at the core's relative tolerance (balanced, TB01PD) and, since that truncation moves the
    kept poles by about the dropped entry, refitted: ``A`` by Gauss–Newton (variable projection:
    ``B, D`` linear least squares for each ``A``, ``C`` kept) to the unreduced solution's values on a
    grid; the lower degree is taken only when the refit matches them to ``tol`` of their peak."""
    if not nu or not N.n:
        return N, nu, cond
    whole = _markov_norm(N, np.arange(N.m))
    dz = float(N.D[0, p])
    if not (whole > 0 and abs(dz) > tol * whole):
        return N, nu, cond
    X = LeastRow(N, nu, abs(dz) / whole, [], cond, p).solution()
    X = _refitted(X, tol, atol)
    if X is None or X.n >= nu:
        return N, nu, cond
    B = np.hstack([X.B[:, :p], np.zeros((X.n, 1)), X.B[:, p:]])
    D = np.hstack([X.D[:, :p], -np.ones((1, 1)), X.D[:, p:]])
    return LTI(X.A, B, X.C, D, N.dt), int(X.n), cond


def numerator_fit(A: np.ndarray, C: np.ndarray, dt: float, lam: np.ndarray, target: np.ndarray,
                  Ge: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The numerator ``Θ = [B; D]`` of ``X = (A, B, C, D)`` (k outputs) fitted on points, with ``(A, C)`` fixed:
    ``(Θ, residual)``, Θ minimising ``Σ_j ||X(λ_j) Ge(λ_j) − target_j||_F²`` (``Ge`` None: the identity), the
    residual ``X(λ_j) Ge(λ_j) − target_j`` (points × k × columns).

    ``X(λ) = K(λ) Θ`` with ``K = [C (λI − A)^{-1}  I_k]`` is linear in Θ (Gustavsen & Semlyen's pole-fixed step
    of vector fitting), so ``(Ge(λ_j)ᵀ ⊗ K(λ_j)) vec Θ = vec(target_j)``, stacked over the points, real and
    imaginary parts, is solved in the least-squares sense (QR-based ``lstsq``; without ``Ge`` one
    ``K``-matrix with ``target``'s columns as right-hand sides). Used by the refit of a reduced row to its own
    values (:func:`_refitted`) and of a cover's numerator to the row's response ``Q_i Ge``
    (:func:`...problems.approximate_matching._refit_numerator`)."""
    n, k = A.shape[0], C.shape[0]
    if n:  # K = C (λI − A)^{-1} on the TB01ID-balanced triple (A, I, C): A_b = S⁻¹ A S, C_b = C S, I_b = S⁻¹
        bal, sc = LTI(A, np.eye(n), C, np.zeros((k, n)), dt).balanced()
        M = lam[:, None, None] * np.eye(n) - bal.A
        K = np.swapaxes(np.linalg.solve(np.swapaxes(M, 1, 2), np.broadcast_to(bal.C.T, (lam.size, n, k))), 1, 2)
        K = K / sc[None, None, :]
    else:
        K = np.zeros((lam.size, k, 0))
    K = np.concatenate([K, np.broadcast_to(np.eye(k), (lam.size, k, k))], axis=2)
    if Ge is None:
        P, R = K.reshape(-1, n + k), target.reshape(-1, target.shape[2])
        Theta = np.linalg.lstsq(np.vstack([P.real, P.imag]), np.vstack([R.real, R.imag]), rcond=None)[0]
        return Theta, (P @ Theta - R).reshape(target.shape)
    Phi = np.concatenate([np.kron(Ge[j].T, K[j]) for j in range(lam.size)])
    rhs = np.concatenate([target[j].T.reshape(-1) for j in range(lam.size)])
    theta = np.linalg.lstsq(np.vstack([Phi.real, Phi.imag]), np.concatenate([rhs.real, rhs.imag]), rcond=None)[0]
    Theta = theta.reshape((n + k, -1), order="F")
    return Theta, np.einsum("kij,kjl->kil", np.einsum("kij,jl->kil", K, Theta), Ge) - target


#: largest n²·k (order n, k rows) refitted by Gauss–Newton on A (a finite-difference Jacobian of n² columns, each
#: an (n + k)-unknown fit on 2·k·L equations): above it only the reduced A with its numerator fit is tried. Unbounded,
#: the re-solve of mindeg's random seed 16 spent 174 s in one refit (the whole stage now 2 s)
REFIT_MAX_UNKNOWNS = 144
#: Gauss–Newton budget, in finite-difference Jacobians (scipy counts the residual calls of MINPACK, about two per
#: Jacobian: max_nfev = 2·this): the refits that succeed converge in a few (seed 197), and a
#: refit that cannot match (mindeg's random seed 6: 60 Jacobians, 10 s, then refused) stops early
REFIT_JACOBIANS = 10


def _refitted(X: LTI, tol: float, atol: float, polish: bool = True, reduce_rtol: float | None = None) -> LTI | None:
    """A realisation of ``X`` (any number of rows) of lower order that matches ``X``'s values on a grid to ``tol`` of
    their peak (see :func:`_least_degree_row`), or None: :func:`relative_minreal` at ``tol``, then ``A`` by
    Gauss–Newton (variable projection: ``[B; D]`` by :func:`numerator_fit` for each ``A``, ``C`` kept; only up
    to ``REFIT_MAX_UNKNOWNS``; above it the reduced ``A`` as it is). With ``polish=False`` the reduced ``A`` is kept
    when its numerator fit already matches. ``reduce_rtol``
    (default ``tol``) is the relative tolerance of the reduction alone."""
    from ...lti import frequency_grid
    from .postconditions import _values

    if not X.n:
        return None
    Xr = relative_minreal(X, tol if reduce_rtol is None else reduce_rtol, atol)
    if Xr.n >= X.n:
        return None
    w = frequency_grid([X], num=200)
    lam = np.exp(1j * w * X.dt) if X.dt else 1j * w
    poles = np.asarray(X.poles(), complex)
    lam = lam[np.min(np.abs(lam[:, None] - poles[None, :]), axis=1) > 1e-6 * np.maximum(1.0, np.abs(lam))]
    V = _values(X, lam)
    ok = np.all(np.isfinite(V), axis=(1, 2))
    lam, V = lam[ok], V[ok]
    top = float(np.max(np.abs(np.concatenate([V.real.ravel(), V.imag.ravel()])), initial=0.0))
    n, C = Xr.n, Xr.C
    if not top > 0 or 2 * lam.size * X.p < 2 * (n + X.p) + n * n:
        return None

    A, th, res = Xr.A, *numerator_fit(Xr.A, C, X.dt, lam, V)
    if n and n * n * X.p <= REFIT_MAX_UNKNOWNS and (polish or not float(np.max(np.abs(res))) <= tol * top):
        refit = pole_refit(Xr.A, C, X.dt, lam, V)
        if refit is None:
            return None
        A, th, res = refit
    if not float(np.max(np.abs(res))) <= tol * top:
        return None
    return LTI(A, th[:n], C, th[n:], X.dt)


def pole_refit(A0: np.ndarray, C: np.ndarray, dt: float, lam: np.ndarray, target: np.ndarray,
               Ge: np.ndarray | None = None, free: np.ndarray | None = None):
    """``(A, Θ, residual)``: ``A`` (``C`` fixed) by Gauss–Newton from ``A0`` on the residual of :func:`numerator_fit`
    (variable projection, Golub & Pereyra: ``Θ = [B; D]`` eliminated by its linear least squares for each A;
    Levenberg–Marquardt, at most ``REFIT_JACOBIANS`` Jacobians), scaled by the target's largest entry; None when
    the iteration fails. Used where a reduction or a cover's rank decisions moved the kept poles by about their
    tolerance: the reduced exact-matching row (:func:`_refitted`) and mindeg's cover candidates
    (:func:`...problems.approximate_matching._refit_numerator`). ``free`` (boolean, n × n) limits the unknowns to
    those entries of A (the others keep A0's): a real modal A0 refits its poles alone, about 2n unknowns for n²."""
    from scipy.optimize import least_squares

    n = A0.shape[0]
    mask = np.ones((n, n), bool) if free is None else np.asarray(free, bool)

    def full(a):
        A = A0.copy()
        A[mask] = a
        return A

    top = max(float(np.max(np.abs(np.concatenate([target.real.ravel(), target.imag.ravel()])), initial=0.0)),
              1e-300)

    def residual(a):
        res = numerator_fit(full(a), C, dt, lam, target, Ge)[1]
        return np.concatenate([res.real.ravel(), res.imag.ravel()]) / top

    try:
        a = least_squares(residual, A0[mask], xtol=1e-15, ftol=1e-15, gtol=1e-15, method="lm",
                          max_nfev=2 * REFIT_JACOBIANS).x
    except (np.linalg.LinAlgError, ValueError):
        return None
    A = full(a)
    return (A, *numerator_fit(A, C, dt, lam, target, Ge))


#: largest condition number of an observability matrix used to bring rows to common coordinates
#: (the accuracy lost is about cond·eps: 1e8 keeps ~1e-8, the scale of mm_tol's decisions)
OBS_COND = 1e8


def _combined_row(group: list, p: int, choose, good, tol: float) -> LTI | None:
    """A combination ``Σ h_j N_j`` of null rows of equal McMillan degree ν with a constant nonzero
    z-entry, or None.

    Every row's ν poles are placed at the same targets ``choose(ν)`` by output injection (a biproper
    left factor: still a null row of degree ν, :func:`.pencil.assign_poles`); the rows, with one
    characteristic polynomial and observable single-output pairs, are similar to the first one by
    ``T_j = O_1^{-1} O_j`` (observability matrices), so in common coordinates ``(A, c)`` a combination
    is ``(A, Σ h_j B_j, c, Σ h_j D_j)``, and its z-entry is the constant 1 iff
    ``[B_z; D_z] h = [0; 1]`` — a linear system, solved in the least-squares sense and accepted when
    its relative residual is ≤ ``tol``. The solution ``−[N_y N_u]`` then has the targets as poles."""
    placed, rho = [], None
    for N in group:
        A, B, C, D = N.A, N.B, N.C, N.D
        T, Z, F, _ = schur_feedback(A.T, C.T, N.dt, lambda eig: choose(eig.size), lambda re, im: False, full=True)
        A, B, C = T.T, Z.T @ B + F.T @ D, C @ Z  # A + L C in its Schur coordinates (accurate for a large L)
        if not all(good(z.real, z.imag) for z in np.linalg.eigvals(A)):
            return None
        w = _markov_norm(LTI(A, B, C, D, N.dt), np.arange(N.m))  # each row at unit size: h measures conditioning
        B, D = B / w, D / w
        rho = max(1.0, float(np.linalg.norm(A, 2))) if rho is None else rho  # one scaling for every O_j
        O = np.vstack([C @ np.linalg.matrix_power(A / rho, k) for k in range(A.shape[0])])
        if np.linalg.cond(O) > OBS_COND:
            return None
        placed.append((A, B, C, D, O))
    A1, _, C1, _, O1 = placed[0]
    Bs, Ds = [], []
    for A, B, C, D, O in placed:
        T = np.linalg.solve(O1, O)  # x_1 = T x_j: T A_j = A_1 T, C_j = C_1 T
        if np.linalg.norm(T @ A - A1 @ T) > 1e-8 * max(1.0, np.linalg.norm(A1)) * np.linalg.norm(T):
            return None  # the placed poles differ (a defective target the placement spread): no common form
        Bs.append(T @ B)
        Ds.append(D)
    Z = np.vstack([np.column_stack([B[:, p] for B in Bs]), [[D[0, p] for D in Ds]]])
    rhs = np.zeros(Z.shape[0])
    rhs[-1] = 1.0
    h = np.linalg.lstsq(Z, rhs, rcond=None)[0]
    # exact (to the rank tolerance) and not by cancellation of huge multiples of the rows
    if not (np.linalg.norm(Z @ h - rhs) <= tol * np.linalg.norm(Z, 2) * np.linalg.norm(h)
            and np.linalg.norm(h) <= 1.0 / np.sqrt(tol)):
        return None
    B = sum(hj * Bj for hj, Bj in zip(h, Bs))
    D = sum(hj * Dj for hj, Dj in zip(h, Ds))
    B[:, p] = 0.0  # zero to the residual's size: the z-entry is the constant 1
    return LTI(A1, B, C1, D, group[0].dt)


def stable_solution(row: LeastRow, choose, good, tol: float, atol: float = 0.0) -> LTI:
    """A stable proper ``X`` with ``X Ge = [0 0 Mr_i]`` (no updating factor), or a DesignError naming the
    unstable or infinite zeros that forbid one.

    Every null row of the augmented system is ``w = Y N`` with the core's basis ``N`` (k rows, stable,
    proper, minimal: no finite or infinite zeros, so ``w`` stable proper iff ``Y`` is), and ``X`` solves
    the equation iff ``Y N_z = −1``. A stable proper left inverse ``Y`` of the column ``N_z = (A, b, C, d)``
    exists iff ``d ≠ 0`` (no zero at infinity) and the invariant zeros of ``N_z`` lie in the stability
    region: with ``h = dᵀ/|d|²`` the observer-based left inverse

        Y = (A − b h C − L (I − d h) C,  b h + L (I − d h),  −h C,  h),      Y N_z = 1,

    has as poles the zeros of ``N_z`` (the unobservable eigenvalues of ``(A − b h C, (I − d h) C)``) and
    the eigenvalues that L assigns (:func:`.pencil.assign_poles` on the observable part of the dual pair,
    moving only those outside ``good``). Then ``X = −(Y N)_{y,u}``, minimal.

    The zeros are decided on the basis *reduced at the core's rank tolerance* (the pencil's, on balanced data:
    :func:`reduced_basis`; ``N_z`` and X likewise, :func:`relative_minreal`), not on the pencil's realisation: its
    output-nulling deflation can leave modes unobservable only to rounding (matching seed 197: a feedback of
    norm 790, four modes with ``|C v| ~ 1e-13``, one at +3.16), which an absolute minimal realisation keeps
    and which then appear as unstable zeros of ``N_z`` that no solution has. Each zero still outside the
    region is then checked to be a zero of ``N_z`` alone: if the whole basis nearly loses rank there
    (``σ_min(N(z)) ≤ sqrt(tol)`` of the basis' size, the accuracy a returned row is held to) the zero is a
    rounding artefact that cannot be decided, and a NumericalDesignError says so instead of a claim about
    every exact solution.
    """
    from .postconditions import NumericalDesignError, _values

    N, p = reduced_basis(row.basis, tol, row.rank_tol, atol), row.p
    core_tol = max(atol, row.rank_tol)  # the pencil's rank tolerance, on balanced data
    Nz = relative_minreal(LTI(N.A, N.B[:, [p]], N.C, N.D[:, [p]], N.dt), 0.0, core_tol)
    A, b, C, d = Nz.A, Nz.B, Nz.C, Nz.D
    scale = max(float(np.linalg.norm(np.block([[A, b], [C, d]]), 2)) if Nz.n else float(np.linalg.norm(d)), 1e-300)
    if not np.linalg.norm(d) > tol * scale:
        raise DesignError(f"no stable proper filter matches this row without an updating factor: the Mr-column "
                          f"of the null-space basis of [Gu Gd Gf; 0 0 Mr_i; I 0 0] vanishes at infinity (feedthrough "
                          f"{np.linalg.norm(d):.3g}), so every exact solution is improper; pass updating=True")
    h = d.T / float(np.sum(d * d))
    P = np.eye(d.shape[0]) - d @ h
    Ah, Ch = A - b @ h @ C, P @ C
    n = A.shape[0]
    if n:
        T, taus = controllable_staircase(Ah.T, Ch.T, max(atol, row.rank_tol, 1e3 * np.finfo(float).eps * scale))
        no = sum(taus)
        at, bt = T.T @ Ah.T @ T, T.T @ Ch.T
        zeros = np.linalg.eigvals(at[no:, no:]) if no < n else np.zeros(0, complex)
        bad = [z for z in zeros if not good(z.real, z.imag)]
        size = max(_markov_norm(N, np.arange(N.m)), 1e-300)
        for z in bad:  # a zero of N_z must leave the basis itself of full row rank
            sv = np.linalg.svd(_values(N, np.array([z]))[0], compute_uv=False)
            if not sv[-1] > np.sqrt(tol) * size:
                raise NumericalDesignError(
                    f"no stable proper filter matches this row without an updating factor, or none can be decided: "
                    f"the Mr-column of the null-space basis of [Gu Gd Gf; 0 0 Mr_i; I 0 0] vanishes at "
                    f"{complex(z):.6g} outside the stability region, where the whole basis nearly loses rank too "
                    f"(σ_min {sv[-1]:.3g} ≤ sqrt(mm_tol) × its size {size:.3g}): a zero of the basis' rounding, not "
                    f"of the problem; pass another atol or mm_tol")
        if bad:
            raise DesignError(f"no stable proper filter matches this row without an updating factor: every exact "
                              f"solution has the poles {np.round(np.asarray(bad, complex), 10).tolist()} (zeros of "
                              f"the Mr-column of the null-space basis outside the stability region); pass "
                              f"updating=True")
        # L on the observable part, and Y realised in that closed loop's Schur coordinates x = S x̃ (Ah − L Ch is
        # not formed: its eigenvalues would cancel out of entries ‖L‖‖Ch‖ where the gain is large, pencil.schur_feedback)
        T1, Z1, F1, _ = schur_feedback(at[:no, :no], bt[:no], N.dt, lambda eig: choose(eig.size), good)
        S = T @ np.block([[Z1, np.zeros((no, n - no))], [np.zeros((n - no, no)), np.eye(n - no)]])
        a_cl = np.block([[T1, Z1.T @ at[:no, no:]], [at[no:, :no] @ Z1 + bt[no:] @ F1, at[no:, no:]]])  # Sᵀ(Ahᵀ + Chᵀ F)S
        L = -np.vstack([F1.T, np.zeros((n - no, F1.shape[0]))])  # Sᵀ L
        Y = LTI(a_cl.T, S.T @ b @ h + L @ P, -h @ C @ S, h, N.dt)
    else:
        Y = LTI(Ah, b @ h, -h @ C, h, N.dt)
    W = Y @ N
    keep = np.r_[np.arange(p), np.arange(p + 1, N.m)]
    X = LTI(W.A, W.B[:, keep], -W.C, -W.D[:, keep], N.dt)
    # minimal at the same tolerance: where the basis could not be reduced (its numerator fit missed tol), its
    # rounding-unobservable modes are unobservable in Y N too and go here
    return relative_minreal(X, 0.0, core_tol)


def reduced_basis(N: LTI, tol: float, rank_tol: float, atol: float = 0.0) -> LTI:
    """The null-space basis ``N`` without the modes its realisation holds only to rounding: :func:`relative_minreal`
    with the pencil's own rank tolerance ``rank_tol`` (absolute, on the balanced data), kept when its values
    (numerator refitted, :func:`_refitted`) match ``N``'s to ``tol`` of their peak on a grid — still a basis of
    the null space to that accuracy; otherwise ``N`` itself. The reduction at ``tol`` relative (2e-6 absolute on
    seed 197's basis) would move the kept poles by ~1e-7; the pencil's tolerance (6.8e-9 there) removes the
    rounding modes (``|C v| ~ 1e-13``), but still moves the kept poles by ~1e-7 there, so ``A`` is refitted by
    Gauss–Newton where the numerator fit alone misses ``tol`` (within ``REFIT_MAX_UNKNOWNS``)."""
    R = _refitted(N, tol, max(atol, rank_tol), polish=False, reduce_rtol=0.0)
    return N if R is None else R


def solution_basis(model: FDIModel, *, noise: bool = False, atol: float = 0.0, smarg=None) -> LTI:
    """The proper stable left null-space basis ``N`` of ``[Gu Gd Gf; I 0 0]`` (with ``noise``: of
    ``[Gu Gd Gf Gw; I 0 0 0]``), acting on ``[y; u]``: the pencil basis of the model whose unknown inputs are
    ``[d f]`` (``[d f w]``). Two rows ``X``, ``X'`` have one fault (and noise) response and decouple u, d alike
    iff ``X' = X + Y N`` — the freedom a minimum dynamic cover (:mod:`.covers`) uses."""
    Bd = [model.Bd, model.Bf] + ([model.Bw] if noise else [])
    Dd = [model.Dd, model.Df] + ([model.Dw] if noise else [])
    whole = FDIModel(model.A, model.Bu, model.C, model.Du, Bd=np.hstack(Bd), Dd=np.hstack(Dd), dt=model.dt,
                     name=f"{model.name}_df" + ("w" if noise else ""))
    return pencil_basis(whole, atol=atol, smarg=smarg).N


def lowered_stable_rows(model: FDIModel, starts: list, top: int, good, choose, atol: float = 0.0,
                        smarg=None) -> list[LTI]:
    """Stable rows ``X = X1 + Y N`` of order below ``top`` from each proper solution ``X1`` in ``starts`` (the
    least-order, unstable solution first when it is proper; the stable solution of :func:`stable_solution`),
    ``N`` = :func:`solution_basis`, by :func:`.covers.stable_left_cover` (its poles where free at ``choose``),
    lowest order first. Each has the fault response of its start, to the covers' rounding (the caller
    verifies)."""
    from .covers import stable_left_cover

    if not starts:
        return []
    N = solution_basis(model, atol=atol, smarg=smarg)
    out = []
    for X1 in starts:
        if X1 is None or N.p == 0:
            continue
        try:
            cv = stable_left_cover(X1, N, good, choose, atol=atol, max_order=top - 1)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if cv is not None and cv.X.n < top:
            out.append(cv.X)
    return sorted(out, key=lambda X: X.n)
