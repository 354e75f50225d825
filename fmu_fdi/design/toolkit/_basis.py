"""Minimal polynomial bases of the left null space of ``G(λ) = [Gu Gd; I 0]``.

A row ``N(λ) = [V(λ)  -W(λ)]`` with ``V(λ) = Σ v_k λ^k`` is a left annihilator of
``[Gu Gd; I 0]`` exactly when its coefficients form a *parity vector* (Chow and
Willsky 1984; Frank, section 4): with the observability matrix ``O_s`` and the
block-Toeplitz matrices of Markov parameters ``H_{d,s}``, ``H_{u,s}``,

    v [O_s  H_{d,s}] = 0,        w = v H_{u,s},

because then ``Σ v_k y^(k) - Σ w_k u^(k) = v H_{d,s} D_s = 0`` for every state. (λ is the
derivative operator in continuous time and the forward shift in discrete time.)

The parity vectors of order s contain the shifts ``λ^j N_i(λ)`` of every lower-order
vector; the vectors that are new at order s — an orthonormal complement of the
shifts inside ``null([O_s H_{d,s}]^T)`` — have degree exactly s. Collecting them for
s = 0, 1, ... until ``p - rank Gd`` vectors are found gives a minimal (row-reduced,
least total degree) polynomial basis; its degrees are the left Kronecker indices of
the controllable part of ``[Gu Gd]`` (Varga 2017, sec. 7.4; Varga 2003).

Numerics: states are balanced (TB01ID), the operator is scaled ``λ = ρ μ`` with ρ a
power of two near ``||A||`` so that the block rows of ``O_s`` have comparable size, and
columns are normalised before every SVD (which leaves a left null space unchanged).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...freqresp import eigenvalues
from ...linalg import complement_rows, left_null, rank
from ...lti import LTI
from ...model import FDIModel
from .notes import note


@dataclass
class PolyRow:
    """One polynomial row ``N(μ) = Σ_k coef[k] μ^k`` acting on ``[y; u]``."""

    degree: int
    coef: np.ndarray  # (degree + 1, p + m)

    def at(self, mu: np.ndarray) -> np.ndarray:
        """Values at the points ``mu``: shape (len(mu), p + m)."""
        powers = np.power.outer(np.asarray(mu, complex), np.arange(self.degree + 1))
        return powers @ self.coef

    def padded(self, degree: int) -> np.ndarray:
        out = np.zeros((degree + 1, self.coef.shape[1]))
        out[: self.degree + 1] = self.coef
        return out


@dataclass
class NullspaceBasis:
    """A minimal polynomial left null-space basis, in the scaled operator ``μ = λ / ρ``."""

    rows: list[PolyRow]
    rho: float
    dt: float
    p: int
    m: int
    rank_d: int
    info: dict = field(default_factory=dict)

    @property
    def degrees(self) -> list[int]:
        return [r.degree for r in self.rows]


def _colnormalize(M: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """Columns scaled to unit norm (the left null space is unchanged); columns at rounding
    level — below ``rtol`` times the largest, e.g. a Markov parameter ``C A^k B_j`` that is
    exactly 0 in the model but ~1e-17 after the orthogonal reductions — are dropped, since
    normalising them would turn rounding noise into an O(1) column and destroy null vectors."""
    norms = np.linalg.norm(M, axis=0)
    keep = norms > rtol * norms.max(initial=0.0)
    return M[:, keep] / norms[keep]


def _block_toeplitz(markov: list[np.ndarray], s: int) -> np.ndarray:
    """Lower block-triangular Toeplitz matrix with blocks ``markov[i - j]``."""
    p, m = markov[0].shape
    H = np.zeros(((s + 1) * p, (s + 1) * m))
    for i in range(s + 1):
        for j in range(i + 1):
            H[i * p:(i + 1) * p, j * m:(j + 1) * m] = markov[i - j]
    return H


def normal_rank(G: LTI, rtol: float | None = None, points: int = 3, seed: int = 0, atol: float = 0.0) -> int:
    """Normal rank of a transfer matrix from its values at random complex points
    (singular values above ``max(rtol·σ_max, atol)`` count)."""
    return sampled_rank(sample_values(G, points, seed), rtol=rtol, atol=atol)


def sample_values(G: LTI, points: int = 3, seed: int = 0) -> np.ndarray:
    """``G(λ_k)`` at the ``points`` random complex points of :func:`normal_rank`: shape
    (points, p, m). The points depend only on A (its spectral radius scales them), so the
    values of all columns at once serve the normal rank of every column subset
    (:func:`sampled_rank`): one eigenvalue problem and one Hessenberg form for them all."""
    if G.m == 0 or G.p == 0:
        return np.zeros((0, G.p, G.m), complex)
    rng = np.random.default_rng(seed)
    scale = 1.0 if G.is_discrete else max(1.0, float(np.max(np.abs(G.poles()), initial=0.0)))
    lams = []
    for _ in range(points):
        lam = scale * (rng.uniform(0.5, 2.0) + 1j * rng.uniform(0.5, 2.0))
        if G.is_discrete:
            lam = np.exp(1j * rng.uniform(0.3, 2.8)) * rng.uniform(1.1, 1.5)
        lams.append(lam)
    return G.values(lams)


def sampled_rank(values: np.ndarray, cols=None, rtol: float | None = None, atol: float = 0.0) -> int:
    """Normal rank of the columns ``cols`` (default all) of a transfer matrix from its
    values (:func:`sample_values`): the largest rank over the points."""
    if cols is not None:
        values = values[:, :, list(cols)]
    if values.size == 0:
        return 0
    return max(rank(H, rtol, atol) for H in values)


class ParityData:
    """Scaled state-space data of ``[Gu Gd]`` and its parity matrices of growing order."""

    def __init__(self, model: FDIModel, reduce: bool = True):
        G = model.lti("u", "d")
        self.p, self.m, self.md = model.ny, model.nu, model.nd
        # x_data = T x_model; unknown (None) after a controllable-part reduction
        self.T: np.ndarray | None = np.eye(G.n)
        if reduce:
            if G.n and G.m:
                G = G.minreal(job="C")  # modes no u or d excites need no annihilating
            elif not G.m:
                G = LTI.static(G.D, G.dt)
            self.T = None
        if G.n and G.m:
            G, scale = G.balanced()
            if self.T is not None:
                self.T = np.diag(1.0 / scale)
        self.G = G
        normA = float(np.linalg.norm(G.A, 2)) if G.n else 0.0
        self.rho = float(2.0 ** np.round(np.log2(normA))) if normA > 0 and not G.dt else 1.0
        self.A = G.A / self.rho
        B = G.B / self.rho
        self.Bu, self.Bd = B[:, : self.m], B[:, self.m:]
        self.C = G.C
        self.Du, self.Dd = G.D[:, : self.m], G.D[:, self.m:]
        self.n = G.n
        self._O = [self.C]
        self._mu = [self.Du]
        self._md = [self.Dd]

    def markov(self, B: np.ndarray, D: np.ndarray, s: int) -> list[np.ndarray]:
        """Markov parameters ``D, C B, C A B, ...`` of another input channel ``(B, D)`` of
        the model (in model coordinates), expressed in this data's state and scaling."""
        if self.T is None:
            raise ValueError("extra channels need the unreduced parity data (reduce=False)")
        Bs = self.T @ B / self.rho
        out = [D]
        self._grow(s)
        for k in range(1, s + 1):
            out.append(self._O[k - 1] @ Bs)
        return out

    def _grow(self, s: int):
        while len(self._O) <= s:
            k = len(self._O)
            CAk1 = self._O[k - 1]  # C A^{k-1}
            self._mu.append(CAk1 @ self.Bu)
            self._md.append(CAk1 @ self.Bd)
            self._O.append(CAk1 @ self.A)

    def O(self, s: int) -> np.ndarray:
        self._grow(s)
        return np.vstack(self._O[: s + 1])

    def Hu(self, s: int) -> np.ndarray:
        self._grow(s)
        return _block_toeplitz(self._mu[: s + 1], s)

    def Hd(self, s: int) -> np.ndarray:
        self._grow(s)
        return _block_toeplitz(self._md[: s + 1], s)

    def parity_vectors(self, s: int, rtol: float | None = None, atol: float = 0.0) -> np.ndarray:
        """Orthonormal rows spanning ``{v : v [O_s H_{d,s}] = 0}`` (singular values of the
        column-normalised matrix at or below ``max(rtol·σ_max, atol)`` count as zero)."""
        M = np.hstack([self.O(s), self.Hd(s)]) if self.n or self.md else np.zeros(((s + 1) * self.p, 0))
        return left_null(_colnormalize(M), rtol, atol) if M.shape[1] else np.eye((s + 1) * self.p)

    def row(self, v: np.ndarray, s: int) -> PolyRow:
        """Polynomial row ``[V(μ), -W(μ)]`` of the parity vector ``v`` of order s."""
        W = v @ self.Hu(s) if self.m else np.zeros(0)
        coef = np.hstack([v.reshape(s + 1, self.p), -W.reshape(s + 1, self.m)])
        return PolyRow(s, coef)


def no_residual_error(model: FDIModel, rank_d: int) -> DesignError:
    """The refusal when the left null space of ``[Gu Gd; I 0]`` is empty (every basis: polynomial or pencil)."""
    return DesignError(f"no residual generator exists for model '{model.name}': the unknown inputs d span every "
                       f"output direction (normal rank of Gd = {rank_d} = number of outputs {model.ny})")


def minimal_basis(model: FDIModel, rtol: float | None = None, atol: float = 0.0) -> NullspaceBasis:
    """Minimal polynomial basis of the left null space of ``[Gu Gd; I 0]``.

    Rank decisions count singular values above ``max(rtol·σ_max, atol)`` (Varga's
    ``atol``/``rtol``). The result is checked: the number of rows must be
    ``p - rank Gd`` *and* the rows must have that rational rank (:func:`basis_rank`) —
    a vector rejected at degree s whose shifts are accepted at degree s+1 would
    otherwise give a basis with more rows than its rank.
    """
    data = ParityData(model)
    p = model.ny
    rank_d = normal_rank(model.lti("d"), rtol, atol=atol) if model.nd else 0
    target = p - rank_d
    rows: list[PolyRow] = []
    vecs: list[tuple[int, np.ndarray]] = []
    s, recovered = 0, 0
    while s <= data.n + 1 and len(rows) < target:
        N = data.parity_vectors(s, rtol, atol)
        shifts = []
        for deg, v in vecs:
            for j in range(s - deg + 1):
                row = np.zeros((s + 1) * p)
                row[j * p:(j + deg + 1) * p] = v
                shifts.append(row)
        S = np.array(shifts) if shifts else np.zeros((0, (s + 1) * p))
        new = complement_rows(N, S, rtol)
        low = _lower_degree(new, p, s) if s and recovered <= target else []
        if low:
            # a vector of lower degree was rejected there (its singular value sat just above
            # the tolerance) but its shifts are accepted here: take it at its own degree and
            # redo this order, so the basis keeps its rational rank and minimal degrees
            for deg, v in low:
                vecs.append((deg, v))
                rows.append(data.row(v, deg))
                recovered += 1
            continue
        for v in new:
            vecs.append((s, v))
            rows.append(data.row(v, s))
        s += 1
    rows.sort(key=lambda r: r.degree)
    if len(rows) != target:
        from .postconditions import NumericalDesignError

        raise NumericalDesignError(
            f"the null-space computation found {len(rows)} basis vectors where the normal rank condition "
            f"p - rank(Gd) = {p} - {rank_d} = {target} requires {target}; the rank decisions are ill "
            f"conditioned for this model — scale the model or pass other rank tolerances (rtol/atol)"
        )
    r, sv_ratio = basis_rank(rows, data.rho, model.dt)
    if r < len(rows):
        from .postconditions import NumericalDesignError

        raise NumericalDesignError(
            f"the null-space basis has {len(rows)} rows (degrees {[w.degree for w in rows]}) but rational rank {r} "
            f"(smallest singular value ratio {sv_ratio:.2e} at random points): a parity vector was rejected at one "
            f"degree and its shifts accepted at a higher one — pass a looser rtol/atol"
        )
    return NullspaceBasis(rows, data.rho, model.dt, p, model.nu, rank_d,
                          info={"controllable_order": data.n, "basis_sv_ratio": sv_ratio})


def _lower_degree(new: np.ndarray, p: int, s: int, tol: float = 1e-6) -> list[tuple[int, np.ndarray]]:
    """Combinations of the new order-s vectors whose leading (μ^s) block vanishes, each
    stripped of its zero leading and trailing blocks: ``(degree, unit vector)``.

    ``tol`` is relative to the unit-norm rows: parity vectors of an ill-conditioned
    ``O_s`` are known to about sqrt(eps), so a block below 1e-6 is zero.
    """
    if new.shape[0] == 0:
        return []
    L = new[:, s * p:]
    U, sv, _ = sla.svd(L, full_matrices=True)
    sv = np.concatenate([sv, np.zeros(U.shape[0] - sv.size)])
    out = []
    for c in U[:, sv < tol].T:
        v = c @ new
        blocks = np.linalg.norm(v.reshape(s + 1, p), axis=1)
        live = np.nonzero(blocks > tol)[0]
        if not live.size:
            continue
        v = v[live[0] * p:(live[-1] + 1) * p]
        out.append((int(live[-1] - live[0]), v / np.linalg.norm(v)))
    return out


def basis_rank(rows: list[PolyRow], rho: float, dt: float, points: int = 3, seed: int = 7) -> tuple[int, float]:
    """Rational rank of the stacked rows ``N(μ)`` and the smallest ``σ_min/σ_max`` seen.

    The rows are normalised to unit norm at each point (a row's scale is no rank
    information); a rank is counted with the square root of machine precision, the
    accuracy to which parity vectors of an ill-conditioned ``O_s`` are known.
    """
    if not rows:
        return 0, 1.0
    rng = np.random.default_rng(seed)
    best, worst_ratio = 0, 1.0
    for _ in range(points):
        if dt:
            lam = np.exp(1j * rng.uniform(0.3, 2.8)) * rng.uniform(0.6, 0.95)
        else:
            lam = rho * (rng.uniform(0.3, 2.0) + 1j * rng.uniform(0.3, 2.0))
        V = np.vstack([r.at(np.array([lam / rho]))[0] for r in rows])
        V = V / np.maximum(np.linalg.norm(V, axis=1, keepdims=True), np.finfo(float).tiny)
        sv = sla.svd(V, compute_uv=False)
        ratio = float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0
        if len(rows) > V.shape[1]:
            ratio = 0.0
        worst_ratio = min(worst_ratio, ratio)
        best = max(best, int(np.sum(sv > np.sqrt(np.finfo(float).eps) * sv[0])))
    return best, worst_ratio


MOVED_SDEG = 0.05  # Varga's default stability degree (sdeg = -0.05) for the poles a design moves


def plant_pole_pool(A: np.ndarray, dt: float) -> list[complex]:
    """The plant's eigenvalues made stable, sorted from slow to fast.

    Unstable ones are mirrored into the stability region (``-|Re λ| + j Im λ``, or
    ``1/λ̄`` in discrete time); poles on the boundary (integrators) move just inside it —
    also when rounding computed them a hair inside (``|λ| ≥ 1 − 1e-6``, ``Re λ > -1e-6·max|λ|``):
    such a target would break the stability margin (``1 − sqrt(eps)``) it is meant to meet.
    In continuous time a pole that has to move goes at least to Varga's default stability
    degree ``sdeg = -0.05`` (``glcf``/``efdsyn``; or ``-1e-3·max|λ|`` when that is faster):
    the mirror image of a slow unstable mode (the Boeing 747's altitude mode, +3.1e-5 rad/s)
    would make a near-integrator filter whose huge low-frequency gain lifts the rounding of
    the decoupling above ``dec_tol`` of a weak fault's gain (leak 2e-5 at -3.1e-5, 1.3e-8 at -0.05).
    """
    eig = eigenvalues(A) if A.size else np.zeros(0, complex)  # the plant's: computed once (freqresp)
    scale = max(1.0, float(np.max(np.abs(eig), initial=0.0)))
    out = []
    for lam in eig:
        if dt:
            r = abs(lam)
            if r >= 1.0 - 1e-6:  # unstable or on the boundary (a computed 1 - 1e-15 too): moved
                lam = lam / r * min(1.0 / r, 0.999)
        else:
            if lam.real > -1e-6 * scale:  # unstable or on the boundary: moved
                lam = complex(-max(abs(lam.real), MOVED_SDEG, 1e-3 * scale), lam.imag)
        out.append(complex(lam))
    speed = (lambda z: -np.log(max(abs(z), 1e-300))) if dt else abs
    return sorted(out, key=lambda z: (speed(z), z.imag))


def spread_poles(pool: list[complex], count: int) -> np.ndarray:
    """``count`` poles from ``pool`` evenly spread from slow to fast, conjugate pairs kept
    together (a pair that does not fit becomes a real pole of the same speed)."""
    units, used = [], set()
    for z in pool:  # real poles, and one entry per conjugate pair (Im > 0)
        if abs(z.imag) <= 1e-12 * max(1.0, abs(z)):
            units.append([complex(z.real, 0.0)])
        elif z.imag > 0:
            units.append([z, np.conj(z)])
    if count <= 0 or not units:
        return np.zeros(0, complex) if count <= 0 else np.full(count, -1.0 + 0j)
    out: list[complex] = []
    for target in np.linspace(0, len(units) - 1, count):
        if len(out) >= count:
            break
        free = [i for i in range(len(units)) if i not in used] or list(range(len(units)))
        i = min(free, key=lambda j: abs(j - target))
        used.add(i)
        unit = units[i]
        if len(unit) == 2 and len(out) + 2 > count:
            z = unit[0]
            unit = [complex(-abs(z), 0.0) if z.real < 0 or abs(z) > 1 else complex(abs(z), 0.0)]
        out.extend(unit)
    return np.array(out[:count])


def pole_chooser(model: FDIModel, poles, sdeg, freqs=None):
    """``count ↦ poles`` for a filter row of that degree.

    With neither ``poles`` nor ``sdeg`` the rows take the plant's own (stabilised)
    eigenvalues, spread from slow to fast (:func:`plant_pole_pool`): a row
    ``N(λ)/d(λ)`` whose denominator shares the plant's dynamics responds to faults with a
    nearly flat gain (for a row of full degree n, ``r = y_i - G_i u`` exactly), instead of a
    spike that dies away (a much faster filter) or a sluggish integral.

    With ``freqs`` (strong detectability at those frequencies) the pool's poles slower than the
    fastest requested frequency ω are sped up to it: a pole of speed a < ω attenuates the
    residual at ω by ~a/ω against its low-frequency peak (the Boeing 747's altitude mode,
    3.1e-5 rad/s, makes the ω = 1 gain 3e-5 of the peak: every FDGainTol above fails).
    """
    if poles is None and sdeg is None:
        pool = plant_pole_pool(model.A, model.dt)
        wmax = float(np.max(freqs, initial=0.0)) if freqs is not None else 0.0
        if wmax > 0:
            if model.dt:
                rmax = float(np.exp(-wmax * model.dt))
                pool = [z if abs(z) <= rmax else z / abs(z) * rmax for z in pool]
            else:
                pool = [complex(min(z.real, -wmax), z.imag) for z in pool]
            speed = (lambda z: -np.log(max(abs(z), 1e-300))) if model.dt else abs
            pool = sorted(pool, key=lambda z: (speed(z), z.imag))
        return lambda count: spread_poles(pool, count)
    s = (0.0 if model.dt else -1.0) if sdeg is None else float(sdeg)
    return lambda count: pick_poles(poles, s, count)


def pick_poles(poles, sdeg: float, count: int) -> np.ndarray:
    """``count`` poles closed under conjugation: the given ones first, then ``sdeg``."""
    poles = [] if poles is None else list(np.atleast_1d(np.asarray(poles, complex)))
    out: list[complex] = []
    i = 0
    while len(out) < count and i < len(poles):
        pole = poles[i]
        if abs(pole.imag) > 1e-12 * max(1.0, abs(pole)):
            if len(out) + 2 > count:
                i += 1
                continue
            out.extend([pole, np.conj(pole)])
            # skip the conjugate if it is listed next
            if i + 1 < len(poles) and abs(poles[i + 1] - np.conj(pole)) < 1e-9 * max(1.0, abs(pole)):
                i += 1
        else:
            out.append(complex(pole.real, 0.0))
        i += 1
    out.extend([complex(sdeg, 0.0)] * (count - len(out)))
    unused = [p for p in poles if not np.any(np.isclose(np.array(out, complex), p))]
    if unused and count:
        why = " (a complex pole needs its conjugate and two states)" if any(np.iscomplex(unused)) else ""
        note(f"poles {[complex(p) for p in unused]} not used: the filter has order {count}{why}")
    return np.array(out[:count])


def strong_frequencies(freqs) -> np.ndarray | None:
    """``freqs`` (rad/s, Varga's ``FDfreq``) as a 1-D array, or None; refused unless a non-empty list of
    finite non-negative numbers. The one check of every design and analysis that takes ``freqs``."""
    if freqs is None:
        return None
    omega = np.atleast_1d(np.asarray(freqs, float))
    if omega.ndim != 1 or not omega.size or np.any(omega < 0) or not np.all(np.isfinite(omega)):
        raise DesignError(f"freqs must be finite non-negative frequencies in rad/s, got {np.ravel(freqs).tolist()}")
    return omega


def check_strong_options(freqs, FDGainTol: float) -> None:
    """Refuse ``freqs`` that are not finite non-negative rad/s (:func:`strong_frequencies`) and ``FDGainTol``
    outside (0, 1): the strong options of :func:`~fmu_fdi.design.problems.achievable.achievable_structure`,
    :func:`~fmu_fdi.design.problems.banks.structured_bank` and :func:`~fmu_fdi.design.nullspace_design`,
    checked in one place."""
    strong_frequencies(freqs)
    if not np.isfinite(FDGainTol) or not 0 < FDGainTol < 1:
        raise DesignError(f"FDGainTol must be in (0, 1), got {FDGainTol!r}")


def check_poles(poles, dt: float, smarg: float | None = None) -> None:
    """Refuse non-finite or unstable filter poles, and (with ``smarg``) poles outside the margin."""
    poles = np.atleast_1d(np.asarray(poles, complex)) if poles is not None else np.zeros(0)
    if poles.size and not np.all(np.isfinite(poles)):
        raise DesignError("poles must be finite numbers")
    bad = poles[np.abs(poles) >= 1.0] if dt else poles[poles.real >= 0]
    if bad.size:
        region = "inside the unit circle" if dt else "in the open left half-plane"
        raise DesignError(f"poles {bad.tolist()} are not stable: residual generator poles must lie {region}")
    if smarg is not None:
        bad = poles[np.abs(poles) > smarg] if dt else poles[poles.real > smarg]  # inclusive, as the peer's
        if bad.size:
            what = "|pole|" if dt else "Re(pole)"
            raise DesignError(f"poles {bad.tolist()} break the stability margin smarg = {smarg:g} (every {what} "
                              f"must be at or below it): pass faster poles or relax smarg")


def realize_fir(coefs: list[np.ndarray], rho: float, dt: float) -> LTI:
    """Shift-register realisation of FIR rows ``N_i(μ) / μ^s`` (discrete, ``z = ρ μ``).

    The state holds the past inputs ``[v(k-1); ...; v(k-s)]``, so A is an exact 0/1
    shift matrix (all poles exactly at 0) and the order is ``q s`` whatever the number
    of rows: ``r(k) = Σ_i c_{s-i} ρ^i v(k-i)``.
    """
    s = coefs[0].shape[0] - 1
    q = coefs[0].shape[1]
    taps = [np.vstack([c[s - i] for c in coefs]) * rho**i for i in range(s + 1)]
    A = np.zeros((q * s, q * s))
    if s > 1:
        A[q:, :-q] = np.eye(q * (s - 1))
    B = np.zeros((q * s, q))
    if s:
        B[:q] = np.eye(q)
    C = np.hstack(taps[1:]) if s else np.zeros((len(coefs), 0))
    return LTI(A, B, C, taps[0], dt)


def realize_rows(coefs: list[np.ndarray], dens: list[np.ndarray], rho: float, dt: float) -> LTI:
    """State-space realisation of rows ``N_i(μ) / d_i(μ)`` in the operator ``λ = ρ μ``.

    Row i has numerator coefficients ``coefs[i]`` (ν+1, q) in ascending powers of μ
    and monic denominator with roots ``dens[i]`` (ν of them, in μ). Each row is an
    observer-canonical block; ``A_λ = ρ A_μ``, ``B_λ = ρ B_μ`` undo the scaling. Several
    discrete FIR rows of one order (all roots 0) share a shift register when that is
    smaller.
    """
    q = coefs[0].shape[1]
    degs = {c.shape[0] - 1 for c in coefs}
    if (dt and len(degs) == 1 and len(coefs) > q and all(not np.any(d) for d in dens)):
        return realize_fir(coefs, rho, dt)
    As, Bs, Cs, Ds = [], [], [], []
    for N, roots in zip(coefs, dens):
        nu = N.shape[0] - 1
        a = np.real_if_close(np.poly(roots)) if nu else np.array([1.0])  # [1, a_{ν-1}, ..., a_0]
        a = np.real(a)
        a_asc = a[::-1]  # a_0 ... a_{ν-1}, 1
        Dq = N[nu:nu + 1, :]
        A = np.zeros((nu, nu))
        if nu:
            A[1:, :-1] = np.eye(nu - 1)
            A[:, -1] = -a_asc[:nu]
        B = N[:nu, :] - np.outer(a_asc[:nu], Dq[0])
        C = np.zeros((1, nu))
        if nu:
            C[0, -1] = 1.0
        As.append(A * rho)
        Bs.append(B * rho)
        Cs.append(C)
        Ds.append(Dq)
    n_tot = sum(A.shape[0] for A in As)
    return LTI(sla.block_diag(*As) if n_tot else np.zeros((0, 0)),
               np.vstack(Bs) if n_tot else np.zeros((0, q)),
               sla.block_diag(*Cs) if n_tot else np.zeros((len(coefs), 0)),
               np.vstack(Ds), dt)
