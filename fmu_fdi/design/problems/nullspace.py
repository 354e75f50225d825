"""Null-space based synthesis: exact fault detection, approximate with noise (efdsyn/afdsyn).

Every proper residual generator that decouples the known inputs u and the unknown
inputs d is ``Q = Y(λ) N(λ)`` for a left null-space basis ``N`` of

    G(λ) = [Gu(λ) Gd(λ); I 0]

(Frank, eqs. 9-12; Varga 2017, Procedure EFD). One state-space core builds every design, as
FaultDetectionTools.jl does: a proper minimal basis ``N`` from the system pencil
(:func:`..toolkit.pencil.pencil_basis`, Varga's ``glnull``; orthogonal reductions, no powers of A),
least order through Type 1 minimum dynamic covers (:func:`..toolkit.pencil.simple_rows`: each basis
row on its own at its left minimal index ν_i), a constant combination ``Q = H N`` that sees every
fault, and a stable left coprime factorisation of the whole ``[Q R]`` that moves only the poles
violating the margin (:func:`..toolkit.stable_factor.stable_internal_form`, Varga's ``glcf``):

    Q(λ) = M(λ) H N(λ),    R(λ) = Q G_e(λ) = [0 0 Rw Rf].

A fault j is detectable once d is decoupled exactly when ``rank [Gd Gf_j] > rank Gd``
(normal ranks); when it is not, no Q exists and the error names the fault. With noise inputs
w, the combination is chosen to maximise the fault-to-noise gap after a co-outer normalisation
(:mod:`..toolkit.approximate`). The polynomial (parity) basis of :mod:`..toolkit._basis` remains
an explicit choice (``basis='polynomial'``) and the base of :func:`.parity.parity_space`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import DesignError
from ...linalg import single_blas_thread
from ...generator import ResidualGenerator
from ...lti import LTI, frequency_grid, vstack
from ...model import FDIModel
from ..toolkit._basis import (NullspaceBasis, check_poles, check_strong_options, minimal_basis, no_residual_error,
                              normal_rank, pole_chooser, realize_rows, strong_frequencies)
from ..toolkit._select import greedy_combinations, maximize_on_sphere, sensitivity_objective, visibility_gated
from ..toolkit.approximate import gap_objective, noise_normalizer, with_nonstandard_options
from ...freqresp import beside_poles, eigenvalues
from ...margin import near_poles
from ..toolkit.stable_factor import stable_internal_form, stable_joint_factor
from ..toolkit.postconditions import (DEC_TOL, NumericalDesignError, boundary_poles, _cosine, mode_decisions,
                                      _values, check_generator)
from ..toolkit.notes import keeps_notes, tentative


def _random_points(basis: NullspaceBasis, count: int = 4, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if basis.dt:
        return np.exp(1j * rng.uniform(0.2, 2.9, count)) * rng.uniform(0.6, 0.95, count)
    return basis.rho * (rng.uniform(0.3, 2.0, count) + 1j * rng.uniform(0.3, 2.0, count))


def _lam_to_mu(lam: np.ndarray, rho: float) -> np.ndarray:
    return np.asarray(lam, complex) / rho


def fault_columns(model: FDIModel) -> list[np.ndarray]:
    sl = model.group_slices()["f"]
    cols = np.arange(sl.start, sl.stop)
    return [cols[f.columns] for f in model.faults]


def row_responses(rows, basis: NullspaceBasis, Ge_vals: np.ndarray, lam: np.ndarray, cols: np.ndarray,
                  den_roots: np.ndarray | None) -> np.ndarray:
    """``N_i(μ) Ge(λ)[:, cols] / d(μ)`` for every row i at the points λ: (points, rows, len(cols))."""
    mu = _lam_to_mu(lam, basis.rho)
    Nvals = np.stack([r.at(mu) for r in rows], axis=1)  # (K, k, q)
    out = np.einsum("kiq,kqc->kic", Nvals, Ge_vals[:, :, cols])
    if den_roots is not None:
        dvals = np.prod(mu[:, None] - den_roots[None, :], axis=1) if den_roots.size else np.ones(mu.size)
        out = out / dvals[:, None, None]
    return out


def _eval_points(G: LTI, lam: np.ndarray) -> np.ndarray:
    return G.values(lam)  # one Hessenberg form of A for all points


def detectability_by_rows(model: FDIModel, basis: NullspaceBasis, FDtol: float) -> np.ndarray:
    """Relative gain of every basis row (rows) to every fault (columns) at random points.

    The gain ``||N_i Ge_f_j|| / (||N_i|| ||Ge_f_j||)`` is a cosine in [0, 1]; a fault is
    seen by a row when it exceeds ``FDtol``.
    """
    lam = _random_points(basis)
    Ge = _eval_points(model.augmented(), lam)
    mu = _lam_to_mu(lam, basis.rho)
    out = np.zeros((len(basis.rows), len(model.faults)))
    for j, cols in enumerate(fault_columns(model)):
        for i, r in enumerate(basis.rows):
            vals = r.at(mu)
            num = np.linalg.norm(np.einsum("kq,kqc->kc", vals, Ge[:, :, cols]), axis=1)
            den = np.linalg.norm(vals, axis=1) * np.linalg.norm(Ge[:, :, cols], axis=(1, 2))
            out[i, j] = np.max(num / np.where(den > 0, den, 1.0))
    return out


def undetectable_error(model: FDIModel, seen: np.ndarray, what: str = "d is decoupled",
                       gains: np.ndarray | None = None, FDtol: float | None = None,
                       numerical=DesignError) -> DesignError:
    """The error for faults no residual can see, naming each and its rank condition.

    When the rank condition *holds* (the fault is detectable in exact arithmetic) but no
    computed basis row sees it, the message says so — the basis is then numerically
    inaccurate, and looser or tighter rank tolerances may help — instead of claiming a
    failed rank condition with numbers that contradict it.
    """
    weak = (seen.max(axis=0) if seen.size else np.zeros(len(model.faults))).astype(bool)
    rd = normal_rank(model.lti("d")) if model.nd else 0
    parts = []
    for j, spec in enumerate(model.faults):
        if not weak[j]:
            G = model.lti("d", "f")
            cols = list(range(model.nd)) + list(model.nd + np.arange(model.nf)[spec.columns])
            rdf = normal_rank(G[:, cols])
            if rdf > rd:
                g = "" if gains is None or not gains.size else f" (largest relative gain {gains[:, j].max():.2e}"
                g += f" ≤ FDtol = {FDtol:g})" if g and FDtol is not None else (")" if g else "")
                parts.append(
                    f"fault '{spec.name}' satisfies the rank condition once {what} (rank [Gd Gf_{spec.name}] = "
                    f"{rdf} > rank Gd = {rd}) but no computed null-space row sees it{g}: the basis is numerically "
                    f"inaccurate for this model — pass other rank tolerances (tol/atol) or rescale the model"
                )
            else:
                parts.append(
                    f"fault '{spec.name}' is not detectable once {what}: rank condition "
                    f"rank [Gd Gf_{spec.name}] > rank Gd fails ({rdf} vs {rd})"
                )
    cls = numerical if any("numerically inaccurate" in x for x in parts) else DesignError
    return cls("; ".join(parts) + f". Achievable weak structure of the faults "
                       f"{model.fault_names}: {weak.astype(int).tolist()}")


def structural_zeros(Rf: list[np.ndarray], Rw: np.ndarray, rtol: float = 1e-9):
    """Set to exact zero every row response (per fault, and to the noise) whose peak is
    below ``rtol`` times that row's largest response: rounding noise of an exact
    decoupling must not count as sensitivity in a ratio."""
    blocks = [F.copy() for F in Rf] + [Rw.copy()]
    peaks = np.array([np.max(np.abs(B), axis=(0, 2)) if B.shape[2] else np.zeros(B.shape[1]) for B in blocks])
    top = peaks.max(axis=0)
    for b, B in enumerate(blocks):
        B[:, peaks[b] <= rtol * top, :] = 0.0
    return blocks[:-1], blocks[-1]


def _normalize_rows(Q: LTI, scale: np.ndarray) -> LTI:
    S = np.diag(1.0 / scale)
    return LTI(Q.A, Q.B, S @ Q.C, S @ Q.D, Q.dt)


@keeps_notes
@with_nonstandard_options
@single_blas_thread
def nullspace_design(model: FDIModel, *, rdim: int | str = 1, poles=None, sdeg: float | None = None,
                     freqs=None, FDtol: float = 1e-4, FDGainTol: float = 0.01, noise: str = "optimize",
                     tol: float | None = None, atol: float = 0.0, seed: int = 0, smarg: float | None = None,
                     dec_tol: float = DEC_TOL, minimal: bool = True, basis: str = "auto",
                     keep_stable_poles: bool = True, HDesign=None, simple: bool = False, nonstd: int | None = None,
                     epsreg: float = 0.1, sdegzer: float | None = None) -> ResidualGenerator:
    """Least-order residual generator from the proper minimal left null space of ``[Gu Gd; I 0]``.

    Solves the exact fault detection problem (Varga 2017, Procedure EFD; FaultDetectionTools.jl
    ``efdsyn``): ``Ru = 0``, ``Rd = 0`` and every fault column block of ``Rf`` nonzero. With
    noise inputs w and ``noise='optimize'`` it solves the approximate problem (Procedure AFD,
    ``afdsyn``): if w can be decoupled exactly too it is; otherwise the gap
    ``min_j ||Rf_j||∞ / ||Rw||∞`` is maximised.

    Parameters
    ----------
    model : FDIModel
    rdim : int or 'all'
        Number of residual outputs (default 1); 'all' returns the whole basis (full order).
    poles : array_like, optional
        Poles of the filter (a conjugate-closed set): every eigenvalue of the basis (of each simple
        row) is placed, at the given poles first and the missing ones at ``sdeg`` (repeats spread
        5 % apart, :func:`..toolkit.pencil._distinct`); given poles beyond the order are not used
        (a ``UserWarning`` says so).
    sdeg : float, optional
        Without ``poles``: the stability degree of the basis — its eigenvalues slower than ``sdeg``
        are mirrored about it, the others stay (Varga's ``sdeg`` in ``glcf``); with ``poles``: the
        pole for the rest (default -1, or 0 in discrete time). With neither, only the eigenvalues
        outside ``smarg`` move, to the plant's own stabilised eigenvalues spread from slow to fast,
        which keeps the fault response nearly flat over frequency (``_basis.pole_chooser``).
    freqs : array_like, optional
        Frequencies (rad/s) at which every fault must be *strongly* detectable
        (``|Rf_j(jω)| > 0``); the combination is chosen with these gains in its objective,
        among the combinations whose every fault is visible (:func:`visibility_gated`). At a
        pole of the plant on the stability boundary (an integrator at ω = 0) the gain is the
        limit of the stable fault response (:func:`_strong_points`). (``basis='polynomial'``, with
        neither ``poles`` nor ``sdeg``: plant poles slower than the fastest frequency are sped up to
        it, ``_basis.pole_chooser``.)
    FDtol, FDGainTol : float
        Relative thresholds for (weak) detectability and for strong detectability.
    noise : {'optimize', 'ignore'}
        How to treat noise inputs w (if any).
    tol, atol : float, optional
        Relative and absolute rank tolerances of the null-space computation (Varga's
        ``rtol``/``atol``: singular values at or below ``max(tol·||[A B; C D]||, atol)`` of the
        balanced minimal realisation of ``[Gu Gd]`` are zero; default ``tol = (n + 1)·1e3·eps``).
        One decision, never retried: a design that breaks a post-condition raises.
    seed : int
        Seed of the deterministic combination search.
    smarg : float, optional
        Stability margin the poles of the filter *and of its internal form* ``R = Q·Ge`` must
        satisfy (``Re p ≤ smarg``, or ``|p| ≤ smarg`` in discrete time); default just inside the
        stability boundary. Given ``poles`` outside it are refused. When ``R`` keeps a pole of the
        plant outside it (``Gf = [1/(s−1); 1/(s+2)]``: the basis is static and ``Q·Gf`` keeps +1),
        Q is replaced by ``M·Q``, M the stable left factor of a coprime factorisation of the whole
        ``[Q R]`` that moves only the violating poles (:func:`..toolkit.stable_factor.stable_internal_form`; Varga's
        ``glcf``): to ``poles`` first, then mirrored about ``sdeg`` when given, else to the plant's
        own speed with damping 0.7 (:func:`..toolkit.stable_factor.moved_pole_targets`). ``info['internal_form']``
        names the moved poles; the order grows, typically by their number.
    keep_stable_poles : bool
        True (default): only poles violating ``smarg`` move, the plant's stable poles stay in R.
        False: with ``sdeg`` given, the stable poles of ``[Q R]`` slower than ``sdeg`` move too, so
        that the residual's whole response has that stability degree (Varga's ``sdeg`` in ``glcf``).
    HDesign : array_like, optional
        A full-row-rank design matrix ``H`` (``q × k``, ``k = p − rank Gd``) that forms the ``q``
        residuals as ``Q = M·H·N`` from the proper stable pencil basis ``N`` (FaultDetectionTools.jl's
        ``HDesign``; :mod:`.hdesign`): the combination is the user's, not searched; with noise to
        optimise its noise response is co-outer normalised (``nonstd``), as ``afdsyn``. Fewer than ``k`` columns combine the leading basis rows; ``rdim``, if not 1, must
        equal the rows of H. Refused (DesignError) with more than ``k`` columns, rank below its rows, or
        rows that together miss a fault. ``info['HDesign']`` is the matrix used.
    simple : bool
        Synthesis from a simple basis (FaultDetectionTools.jl's ``simple = true``): every basis row of
        McMillan degree its own left minimal index ν_i (:func:`.hdesign.basis_rows`). With ``rdim='all'``
        the residuals are those rows (``info['simple_orders']``, order Σ ν_i), with ``HDesign`` H times
        them; with an integer ``rdim`` the pencil path's least-order search over the simple rows
        (``basis='pencil'``; refused with ``basis='polynomial'``).
    nonstd, epsreg, sdegzer
        With noise to optimise, how a noise response without an invertible co-outer factor (zeros at
        infinity — Gw strictly proper — or on the stability boundary) is normalised, as FaultDetectionTools.jl
        ``afdsyn``: 1 the quasi-co-outer factor with its boundary/infinite zeros moved to ``poles``/``sdeg``
        (default), 2 the factor of ``[Rw  epsreg·||Rw||∞·I]``, 3, 4, 5 the Wiener–Hopf choices (4: the zeros
        shifted by ``sdegzer``) — any number of noise rows, continuous or discrete time
        (:func:`..toolkit.approximate.noise_normalizer`). ``info['noise']`` says what was done.
    dec_tol : float
        Largest relative leakage of u and d (and w when it is decoupled) the returned filter
        may show (:mod:`..toolkit.postconditions`).
    minimal : bool
        True (default): least order. With several basis rows and ``rdim`` below their number, each
        row is taken on its own at its left minimal index ν_i (a simple basis from Type 1 minimum
        dynamic covers, :func:`..toolkit.pencil.simple_rows`; their poles drawn from one pool,
        :func:`_common_poles`, so that rows of indices ν_1 ≤ ν_2 combine at order ν_2), and the
        residual is the first set of them, in increasing order, whose constant combination sees
        every fault and passes every post-condition (``info['simple_rows']`` the indices used,
        ``info['least_order']`` when a single row proves it). Otherwise (or when the covers are too
        ill-conditioned, ``info['simple_rows_refused']``) and with False (fixed order,
        FaultDetectionTools.jl's ``minimal = false``): a combination of the whole basis, of order
        at most the sum of the indices, which gives the combination more freedom.
    basis : {'auto', 'pencil', 'polynomial'}
        'auto' (default) and 'pencil': the state-space core above, the only automatic path —
        nothing falls back to another basis. With noise and ``noise='optimize'`` it solves the
        approximate problem on the pencil bases of ``[Gu Gd; I 0]`` and ``[Gu Gd Gw; I 0 0]``
        (:func:`_approximate_pencil`). 'polynomial': an explicit choice of the minimal polynomial
        (parity) basis (:mod:`..toolkit._basis`) at the rank tolerance ``tol`` — it forms powers of
        A and loses accuracy at degrees 10-20; it raises where the post-conditions fail.
        ``info['basis']`` says which was used, ``info['left_minimal_indices']`` the degrees of a
        minimal polynomial basis, ``info['decoupling_kind']`` is 'exact'.

    Returns
    -------
    ResidualGenerator
        ``info`` holds the basis degrees, the order, poles, the combination, with noise the
        grid estimate of the gap, and ``postconditions``: the achieved decoupling, fault
        visibility and stability figures.

    Raises
    ------
    DesignError
        A fault is not detectable once d is decoupled (the message names it and the rank
        condition), no residual exists, poles are unstable, or strong detectability fails.

    References
    ----------
    A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, secs. 5.2-5.3 and 7.4.
    A. Varga, On computing least order fault detectors using rational nullspace bases,
    IFAC SAFEPROCESS 2003.
    """
    req = _Request.validated(model, rdim=rdim, poles=poles, sdeg=sdeg, freqs=freqs, FDtol=FDtol,
                             FDGainTol=FDGainTol, noise=noise, tol=tol, atol=atol, seed=seed, smarg=smarg,
                             dec_tol=dec_tol, minimal=minimal, basis=basis, keep_stable_poles=keep_stable_poles)
    if HDesign is not None or (simple and rdim == "all"):
        from .hdesign import hdesign_generator

        gen = hdesign_generator(model, HDesign, rdim=rdim, poles=poles, sdeg=sdeg, freqs=freqs, FDtol=FDtol,
                                FDGainTol=FDGainTol, smarg=smarg, dec_tol=dec_tol, tol=tol, atol=atol,
                                place=req.place, finish=_finish, gains=_pencil_gains, simple=bool(simple),
                                normalize_noise=not req.exact_only)
        gen.info["decoupling_kind"] = EXACT
        return gen
    if simple:
        if basis == "polynomial":
            raise DesignError("simple = True needs the state-space (pencil) basis: basis='polynomial' has no "
                              "simple form")
    if basis == "polynomial":
        return _polynomial(req)
    return req.pencil() if req.exact_only else req.noise_pencil()


@dataclass
class _Request:
    """The options of one :func:`nullspace_design` call, validated, as its stages pass them on;
    ``place``: where every path ends (:func:`_finish`), the poles of the internal form [Q R] to move
    and where to."""

    model: FDIModel
    rdim: int | str
    poles: object
    sdeg: float | None
    freqs: object
    FDtol: float
    FDGainTol: float
    noise: str
    tol: float | None
    atol: float
    seed: int
    smarg: float | None
    dec_tol: float
    minimal: bool
    place: dict

    @classmethod
    def validated(cls, model, *, rdim, poles, sdeg, freqs, FDtol, FDGainTol, noise, tol, atol, seed, smarg, dec_tol,
                  minimal, basis, keep_stable_poles) -> "_Request":
        if noise not in ("optimize", "ignore"):
            raise DesignError(f"noise must be 'optimize' or 'ignore', got {noise!r}")
        if not (rdim == "all" or (isinstance(rdim, (int, np.integer)) and rdim >= 1)):
            raise DesignError(f"rdim must be a positive integer or 'all', got {rdim!r}")
        check_poles(poles, model.dt, smarg)
        if sdeg is not None:
            check_poles([sdeg], model.dt)
        if basis not in ("auto", "polynomial", "pencil"):
            raise DesignError(f"basis must be 'auto', 'polynomial' or 'pencil', got {basis!r}")
        if freqs is not None:
            check_strong_options(freqs, FDGainTol)
        place = {"poles": poles, "sdeg": sdeg, "smarg": smarg, "keep_stable_poles": bool(keep_stable_poles)}
        return cls(model, rdim, poles, sdeg, strong_frequencies(freqs), FDtol, FDGainTol, noise, tol, atol, seed, smarg, dec_tol,
                   minimal, place)

    @property
    def exact_only(self) -> bool:
        """No noise to optimise: u and d are decoupled, w (if any) is ignored."""
        return not (self.model.nw and self.noise == "optimize")

    def pencil(self) -> ResidualGenerator:
        return _pencil(self.model, self.rdim, self.poles, self.sdeg, self.freqs, self.FDtol, self.FDGainTol, self.seed,
                       self.smarg, self.dec_tol, self.tol, self.atol, self.minimal, self.place)

    def noise_pencil(self) -> ResidualGenerator:
        return _noise_pencil(self.model, self.rdim, self.poles, self.sdeg, self.FDtol, self.FDGainTol, self.seed,
                             self.smarg, self.dec_tol, self.tol, self.atol, self.minimal, self.place)

    def polynomial(self) -> ResidualGenerator:
        return _design(self.model, self.rdim, self.poles, self.sdeg, self.freqs, self.FDtol, self.FDGainTol,
                       self.noise, self.tol, self.atol, self.seed, self.smarg, self.dec_tol, self.minimal, self.place)


def _polynomial(req: _Request) -> ResidualGenerator:
    """``basis='polynomial'``, an explicit choice only: the minimal polynomial (parity) basis
    (:mod:`..toolkit._basis`) at the rank tolerance ``tol``, judged by the same post-conditions; it
    raises where they fail (nothing falls back to it, and it falls back to nothing)."""
    gen = req.polynomial()
    gen.info.update({"rank_rtol": req.tol, "basis": "polynomial", "decoupling_kind": EXACT})
    return gen


#: ``info['decoupling_kind']`` of a row that annihilates ``[Gu Gd; I 0]`` identically (up to rounding)
EXACT = "exact"


def _pencil(model, rdim, poles, sdeg, freqs, FDtol, FDGainTol, seed, smarg, dec_tol, tol, atol,
            minimal: bool = True, place: dict | None = None) -> ResidualGenerator:
    """Residual from the proper stable pencil basis (:func:`..toolkit.pencil.pencil_basis`), least order first.

    With several basis rows and ``rdim`` below their number, each row is first taken on its own at
    its left minimal index ν_i (a simple basis, :func:`..toolkit.pencil.simple_rows`), and sets of rows are
    tried in increasing total order Σ ν_i (single rows first): the first set whose constant
    combination keeps every fault visible (:func:`visibility_gated`) and passes every post-condition
    is returned — a single row of index ν is least order for the faults it sees, as every null row
    of McMillan degree ν is a polynomial combination of the minimal basis rows of degree ≤ ν
    (predictable degree property; Varga 2017, sec. 7.5, Type 1 minimum dynamic covers). Otherwise
    (or with ``rdim`` = 'all' / the whole basis) the constant combination of all rows with the
    best fault sensitivity condition, realised from the basis' own state space and reduced to a
    minimal realisation — also with ``minimal=False`` (fixed order: the whole basis' freedom)."""
    from ..toolkit.pencil import pencil_basis, simple_rows

    pb = pencil_basis(model, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
    N = pb.N
    k = N.p
    if k == 0:
        raise no_residual_error(model, pb.rank_d)
    if rdim != "all" and rdim > k:
        raise DesignError(f"rdim = {rdim} residuals requested but the null space of [Gu Gd; I 0] has only "
                          f"{k} basis vectors (p - rank Gd)")
    full = rdim == "all" or rdim >= k
    rows = [] if full or k == 1 or not minimal else _common_poles(simple_rows(pb, model.dt), model.dt)
    base = {"basis": "pencil", "decoupling_kind": EXACT, "left_minimal_indices": pb.degrees, "pencil": pb.info}
    gains = _span_gains(model, N, freqs)[None, :]
    if model.faults and not np.all(gains >= FDtol):
        raise undetectable_error(model, gains >= FDtol, gains=gains, FDtol=FDtol, numerical=NumericalDesignError)
    _refuse_unseen_at(model, N, freqs)
    tried = []
    if rows:
        from itertools import combinations

        Ns = [r[0] for r in rows]
        seen = _pencil_gains(model, vstack(Ns), freqs, FDtol) >= FDtol
        # all k rows: the whole basis below, at no higher order — unless rows of one index share their poles
        shared = any(r[3] for r in rows)
        top = len(rows) if shared else min(len(rows), k - 1)

        def order(c):  # the McMillan degree of a combination: the union of the shared rows' pole sets, once
            return len(frozenset().union(*[rows[i][3] for i in c if rows[i][3]])) + \
                sum(rows[i][1] for i in c if not rows[i][3])

        sets = sorted((c for size in range(int(rdim), top + 1) for c in combinations(range(len(rows)), size)),
                      key=lambda c: (order(c), len(c)))
        for c in sets:
            sub = vstack([Ns[i] for i in c])
            if model.faults and not np.all(seen[list(c)].max(axis=0)) and \
                    not np.all(_span_gains(model, sub, freqs) >= FDtol):
                continue  # some fault is seen by no combination of these rows
            if len(tried) >= 6:
                break  # bounded search: the whole basis below
            try:
                with tentative():
                    gen = _pencil_combine(model, sub, rdim, freqs, FDtol, FDGainTol, seed, smarg, dec_tol,
                                          dict(base, simple_rows=[rows[i][1] for i in c],
                                               cover_conditioning=max(rows[i][2] for i in c)), pb.degrees, place)
            except DesignError as exc:
                tried.append(f"rows {list(c)} (order {sub.n}): {exc}"[:200])
                continue
            nu = max(rows[i][1] for i in c)
            if len(rows) == k and not tried and gen.info.get("internal_form", {}).get("order_before", gen.Q.n) == nu and (
                    len(c) == 1 or all(rows[i][1] == nu and rows[i][3] for i in c)):
                # one simple row of index ν (or rows of index ν with common poles, combined at order ν), every
                # row covered and no set refused before: least order unless the rows of lower index together
                # see every fault (a combination of them with one common denominator has their largest index)
                lower = [j for j in range(len(rows)) if rows[j][1] < nu]
                gen.info["least_order"] = not (lower and model.faults and np.all(seen[lower].max(axis=0)))
            return gen
    gen = _pencil_combine(model, N, rdim, freqs, FDtol, FDGainTol, seed, smarg, dec_tol, dict(base), pb.degrees,
                          place)
    if tried:
        gen.info["simple_rows_refused"] = tried
    return gen


def _common_poles(rows: list, dt: float) -> list:
    """Simple rows whose poles are drawn from one set: ``[(N_i, ν_i, cond_i, shared_i)]``.

    The poles of the first row of the largest index are the pool; each row ``N_i`` of index ν_i ≥ 1
    (one output, McMillan degree ν_i, observable) is replaced by ``m_i N_i``, ``m_i`` the scalar stable
    biproper left factor of the output injection that places its poles at a conjugate-closed sub-multiset
    of the pool of size ν_i (:func:`_pool_subset`: the same one for every row of that index; with given
    ``poles`` the rows already share them) — again a null-space row seeing the same faults. Rows whose
    denominators all divide one ``p(λ)`` combine as ``(Σ h_i n_i)/p``: McMillan degree ``deg p`` (the
    size of the union of their pole sets), not Σ ν_i — the least order of a constant combination over a
    common denominator, as the polynomial basis has it (``N_1/d`` padded to the degree of d). ``shared_i``
    is the set of pool positions row i uses (False: its placement failed or needed a gain above
    ``COVER_COND``, it keeps its poles).
    """
    from ..toolkit.pencil import COVER_COND, _place

    out = [(N, nu, cond, False) for N, nu, cond in rows]
    dyn = [i for i, r in enumerate(rows) if r[1] >= 1]
    if len(dyn) < 2:
        return out
    top = max(dyn, key=lambda i: (rows[i][1], -i))
    pool = np.asarray(rows[top][0].poles(), complex)
    placed = []
    for i in dyn:
        N, nu, cond = rows[i]
        sub = _pool_subset(pool, nu)
        if sub is None:
            continue
        target = pool[sorted(sub)]
        if _same_poles(N.poles(), target):
            placed.append((i, N, cond, sub))
            continue
        try:
            F = _place(N.A.T, N.C.T, target)
        except (DesignError, ValueError, np.linalg.LinAlgError):
            continue
        g = float(np.linalg.norm(F, 2))
        if g > COVER_COND:
            continue
        Nm = LTI(N.A + F.T @ N.C, N.B + F.T @ N.D, N.C, N.D, dt)
        if _same_poles(Nm.poles(), target):
            placed.append((i, Nm, max(cond, g), sub))
    if len(placed) >= 2:
        for i, Nm, cond, sub in placed:
            out[i] = (Nm, rows[i][1], cond, frozenset(sub))
    return out


def _pool_subset(pool: np.ndarray, size: int) -> list[int] | None:
    """Positions of a conjugate-closed sub-multiset of ``pool`` with ``size`` members (real poles first,
    then pairs, in the pool's order; deterministic, so every row of one index gets the same one), or None."""
    tol = lambda z: 1e-9 * max(1.0, abs(z))  # noqa: E731
    reals = [[i] for i, z in enumerate(pool) if abs(z.imag) <= tol(z)]
    pairs, used = [], set()
    for i, z in enumerate(pool):
        if z.imag > tol(z) and i not in used:
            j = next((j for j, w in enumerate(pool) if j not in used and j != i and abs(w - np.conj(z)) <= tol(z)), None)
            if j is not None:
                used |= {i, j}
                pairs.append([i, j])
    out: list[int] = []
    for unit in reals + pairs:
        if len(out) + len(unit) <= size:
            out += unit
    return out if len(out) == size else None


def _same_poles(a: np.ndarray, b: np.ndarray) -> bool:
    """The same multiset of poles, to 1e-9 relative (matched greedily)."""
    a, b = list(np.asarray(a, complex)), list(np.asarray(b, complex))
    if len(a) != len(b):
        return False
    for z in a:
        k = next((k for k, w in enumerate(b) if abs(z - w) <= 1e-9 * max(1.0, abs(w))), None)
        if k is None:
            return False
        b.pop(k)
    return True


def _grid_values(model, N: LTI, freqs):
    """``Ge = [Gu Gd Gw Gf; I 0 0 0]`` and the rows ``N`` on the design grid (:func:`_grid` with N's poles),
    the points where either is not finite left out: arrays (K, ·, ·)."""
    Ge = model.augmented()
    lam = _points(model, _grid(model, N.poles(), freqs))
    Gv, Nv = _values(Ge, lam), _values(N, lam)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Nv), axis=(1, 2))
    return Gv[ok], Nv[ok]


def _span_gains(model, N: LTI, freqs) -> np.ndarray:
    """Per fault, the largest relative gain of any constant combination of the rows of ``N`` on the
    design grid: pointwise ``max_h ||h N Ge_f|| / (||h N_y|| ||Gf||) = ||W N Ge_f||₂ / ||Gf||₂`` with
    ``W = S⁻¹ Uᴴ`` from ``N_y = U S Vᴴ`` (the rows made orthonormal at each point; singular values
    floored at 1e-8 of the largest, so rounding of an exact zero stays below 1e-8 of the gain), then
    the post-condition cosine over the grid (:func:`..toolkit.postconditions._cosine`). A property of
    the row space, not of the basis: rows that each see a fault weakly can span a combination that
    sees it well. Points are left out only where ``||Gf_j||`` is below :data:`SPAN_FLOOR` of its median."""
    Gv, Nv = _grid_values(model, N, freqs)
    p = model.ny
    out = np.zeros(len(model.faults))
    for j, (c, resp) in enumerate(_span_responses(model, Nv, Gv)):
        out[j] = _cosine(resp, np.linalg.norm(Gv[:, :p, c], 2, axis=(1, 2)), floor=SPAN_FLOOR)
    return out


def _span_responses(model, Nv: np.ndarray, Gv: np.ndarray):
    """Per fault column block ``c``, ``(c, max_h ||h N Ge_c|| / ||h N_y||)`` at every point: ``||W N Ge_c||₂``
    with ``W = S⁻¹ Uᴴ`` from ``N_y = U S Vᴴ`` (singular values floored at 1e-8 of the largest). ``Nv``, ``Gv``:
    the rows and ``Ge`` at the points, arrays (K, ·, ·)."""
    U, S, _ = np.linalg.svd(Nv[:, :, :model.ny], full_matrices=False)  # (K, k, r), (K, r)
    S = np.maximum(S, 1e-8 * S[:, :1])
    W = np.conj(np.swapaxes(U, 1, 2)) / np.where(S > 0, S, 1.0)[:, :, None]  # (K, r, k)
    return [(c, np.linalg.norm(np.einsum("kri,kiq,kqc->krc", W, Nv, Gv[:, :, c]), 2, axis=(1, 2)))
            for c in fault_columns(model)]


#: a fault whose span cosine at a strong frequency (:func:`_refuse_unseen_at`) is at most this is absent
#: there: an exact zero rounds to ~1e-15 (Boeing 747 at ω = 0: 2.6e-15 .. 2e-20); kept low, as a refusal
#: here must never refuse a row the design would pass (that is judged on the row, not decided here)
SPAN_ZERO = 1e-12


def _refuse_unseen_at(model, N: LTI, freqs) -> None:
    """Refuse at once when a required fault is absent at some ω of ``freqs`` from every combination of
    the rows of ``N``: pointwise ``max_h ||h N Ge_f|| / (||h N_y|| ||Gf||)`` at ``λ = jω`` (e^{jωT}), as
    :func:`_span_gains` at one point, at most :data:`SPAN_ZERO`. Every design is ``Q = M H N`` (a
    constant combination, reduced by minreal, times the stable factor ``M`` of the left coprime
    factorisation, finite at ω), so ``Q(λ) Ge_f(λ) = M(λ) H N(λ) Ge_f(λ)`` vanishes with ``N(λ) Ge_f(λ)``:
    no design is strongly visible there, and the judge would refuse each after a full design."""
    if freqs is None or not model.faults:
        return
    lam, Gs = _strong_points(model, model.augmented(), freqs)
    Nv = _values(N, lam)
    ok = np.all(np.isfinite(Nv), axis=(1, 2))
    if not np.any(ok):
        return
    p = model.ny
    for j, (c, resp) in enumerate(_span_responses(model, Nv[ok], Gs[ok])):
        gf = np.linalg.norm(Gs[ok][:, :p, c], 2, axis=(1, 2))
        cos = np.where(gf > 0, resp / np.where(gf > 0, gf, 1.0), 0.0)
        if np.any(cos <= SPAN_ZERO):
            w = freqs[ok][int(np.argmin(cos))]
            raise DesignError(f"fault '{model.faults[j].name}' is not seen at ω = {w:g} rad/s by any combination of "
                              f"the null-space rows (relative gain {cos.min():.3g} <= {SPAN_ZERO:g}): no design is "
                              f"strongly visible there")


#: points where ``||Gf_j||`` is below this fraction of its median are left out of :func:`_span_gains`: a
#: screen, never stricter than the judge, whose bound ``||Q_y|| ||Gf_j||`` keeps points the plain ``||Gf_j||``
#: floor of 1e-6 drops (CS1: act2 is seen at 4e-3 where ``||Gf||`` is 7e-9 of its median of 1e8, 3e-5
#: elsewhere); at 1e-12 a value still carries ~4 digits (rounding ~eps·median)
SPAN_FLOOR = 1e-12


def _pencil_gains(model, N: LTI, freqs, FDtol) -> np.ndarray:
    """Per row of ``N``, the relative gain (post-condition cosine) to every fault on the design grid."""
    Gv, Nv = _grid_values(model, N, freqs)
    p = model.ny
    nNy = np.linalg.norm(Nv[:, :, :p], axis=2)
    fcols = fault_columns(model)
    gains = np.zeros((N.p, len(fcols)))
    for j, c in enumerate(fcols):
        gfj = np.linalg.norm(Gv[:, :p, c], 2, axis=(1, 2))
        resp = np.linalg.norm(np.einsum("kiq,kqc->kic", Nv, Gv[:, :, c]), axis=2)
        gains[:, j] = [_cosine(resp[:, i], nNy[:, i] * gfj) for i in range(N.p)]
    return gains


def _pencil_combine(model, N: LTI, rdim, freqs, FDtol, FDGainTol, seed, smarg, dec_tol, info: dict,
                    degrees, place: dict | None = None) -> ResidualGenerator:
    """The constant combination ``H N`` (``rdim`` rows) with the best fault sensitivity condition among
    those keeping every fault visible, reduced to a minimal realisation and checked."""
    from types import SimpleNamespace

    k = N.p
    Ge = model.augmented()
    Gv, Nv = _grid_values(model, N, freqs)
    fcols = fault_columns(model)
    p = model.ny
    # _strong_points refuses freqs where the plant cannot be evaluated, whatever rdim is
    lam_s, Gs = _strong_points(model, Ge, freqs) if freqs is not None and model.faults else (None, None)
    if rdim == "all" or rdim >= k:
        H = np.eye(k)
        Q = N
    else:
        P = [np.einsum("kiq,kqc->kic", Nv, Gv[:, :, c]) for c in fcols]
        strong = None
        if lam_s is not None:
            Ns = _values(N, lam_s)
            strong = [np.einsum("kiq,kqc->kic", Ns, Gs[:, :, c]) for c in fcols]
        H = greedy_combinations(visibility_gated(P, Nv[:, :, :p], Gv, fcols, FDtol, strong),
                                k, int(rdim), seed) if model.faults else np.eye(k)[: int(rdim)]
        Q = (H @ N).minreal()
    info.update({"order": int(Q.n), "rdim": int(H.shape[0]), "combination": H.tolist()})
    gen = _finish(model, Q, SimpleNamespace(rho=1.0), "nullspace", info, degrees, place=place)
    check_generator(gen, decouple=("u", "d"), block=True, freqs=freqs, FDtol=FDtol, FDGainTol=FDGainTol,
                    smarg=smarg, dec_tol=dec_tol)
    return gen


def _design(model, rdim, poles, sdeg, freqs, FDtol, FDGainTol, noise, tol, atol, seed, smarg, dec_tol, minimal=True,
            place: dict | None = None):
    basis = minimal_basis(model, tol, atol)
    if not basis.rows:
        raise no_residual_error(model, basis.rank_d)
    choose = pole_chooser(model, poles, sdeg, freqs)
    seen = detectability_by_rows(model, basis, FDtol)
    if model.faults and not np.all(seen.max(axis=0) >= FDtol):
        raise undetectable_error(model, seen >= FDtol, gains=seen, FDtol=FDtol, numerical=NumericalDesignError)
    if model.nw and noise == "optimize":
        gen = _approximate(model, basis, rdim, choose, FDtol, tol, seed, atol, place)
        exact_w = gen.info.get("noise") == "decoupled exactly"
        check_generator(gen, decouple=("u", "d", "w") if exact_w else ("u", "d"), block=True, FDtol=FDtol,
                        smarg=smarg, dec_tol=dec_tol)
        return gen
    gen = _exact(model, basis, seen >= FDtol, rdim, choose, freqs, FDGainTol, seed, minimal, FDtol, place)
    check_generator(gen, decouple=("u", "d"), block=True, freqs=freqs, FDtol=FDtol, FDGainTol=FDGainTol,
                    smarg=smarg, dec_tol=dec_tol)
    return gen


def _grid(model: FDIModel, roots_lam: np.ndarray, freqs) -> np.ndarray:
    return frequency_grid([model.lti()], num=160, poles=roots_lam,
                          extra=() if freqs is None else np.atleast_1d(freqs))


def _points(model: FDIModel, omega: np.ndarray) -> np.ndarray:
    omega = np.asarray(omega, float)
    if model.dt:
        return np.exp(1j * omega * model.dt)
    return 1j * omega


def _strong_points(model: FDIModel, Ge: LTI, freqs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points of the strong-detectability frequencies and ``Ge`` there.

    At a pole of the plant on the stability boundary (an integrator at ω = 0), ``Ge`` is
    infinite, but a stable residual's fault response ``R_f = Q Ge_f`` is not: every decoupling
    row cancels the poles of ``Gu``/``Gd`` (``Q_y Gu = -Q_u``), and what it keeps there is the
    limit of ``R_f`` — the stable factor of a left coprime factorisation, as Varga's
    ``fdigenspec`` with ``FDfreq`` (Varga 2017, sec. 5.4). The limit is taken at ``λ`` moved by
    ``δ = 1e-7`` (relative) into the stability region: ``R_f`` changes by O(δ), and the
    cancellation of ``N(λ)`` against ``Ge(λ) ~ 1/δ`` costs ``eps/δ ~ 1e-9`` relative, both far
    below any FDGainTol.
    """
    lam = _points(model, freqs)
    G = _values(Ge, lam)
    bad = ~np.all(np.isfinite(G), axis=(1, 2))
    # a pole that rounding put 1e-16 off the boundary leaves G finite (~1e16) at it: the limit there too
    bad |= near_poles(lam, Ge.poles())
    if np.any(bad):
        delta = 1e-7
        lam = lam.copy()
        lam[bad] = lam[bad] * (1 - delta) if model.dt else lam[bad] - delta * np.maximum(1.0, np.abs(lam[bad]))
        G[bad] = _values(Ge, lam[bad])
        if not np.all(np.isfinite(G)):
            raise DesignError(f"freqs {freqs.tolist()}: the plant cannot be evaluated near its poles on the stability "
                              f"boundary; pass other freqs")
    return lam, G


def _exact(model, basis, seen, rdim, choose, freqs, FDGainTol, seed, minimal: bool = True,
           FDtol: float = 1e-4, place: dict | None = None) -> ResidualGenerator:
    rows = basis.rows
    order = np.argsort([r.degree for r in rows], kind="stable")
    rows = [rows[i] for i in order]
    seen = seen[order]
    degrees = [r.degree for r in rows]
    Ge = model.augmented()
    fcols = fault_columns(model)

    if rdim == "all":
        dens = [choose(r.degree) / basis.rho for r in rows]
        # Each row has its own denominator of its degree: the stacked order Σ ν_i is the
        # McMillan degree of a minimal basis, so no reduction is needed.
        Q = realize_rows([r.coef for r in rows], dens, basis.rho, model.dt)
        return _finish(model, Q, basis, "nullspace", {"order": int(sum(degrees)), "rdim": len(rows)},
                       [r.degree for r in rows], place=place)

    for nu in (sorted(set(degrees)) if minimal else [max(degrees)]):
        k = sum(1 for d in degrees if d <= nu)
        if k < rdim:
            continue
        if model.faults and not np.all(seen[:k].max(axis=0)):
            continue
        cand = rows[:k]
        roots = choose(nu)
        den_mu = roots / basis.rho
        grid = _grid(model, roots, freqs)
        lam = _points(model, grid)
        Ge_grid = _values(Ge, lam)
        finite = np.all(np.isfinite(Ge_grid), axis=(1, 2))  # plant poles on the grid (integrators at 0)
        lam, Ge_grid = lam[finite], Ge_grid[finite]
        P = [row_responses(cand, basis, Ge_grid, lam, c, den_mu) for c in fcols]
        strong = None
        # a strong frequency on a pole of the plant on the stability boundary: the rows' stable factor
        Js = _boundary_rows(model, cand, basis, nu, den_mu, freqs, place) if freqs is not None else None
        if Js is not None:
            Jv, Sv, w0 = _values(Js[0], lam), _values(Js[0], _points(model, freqs)), model.group_slices()["w"].start
            P, Y_stable = [Jv[:, :, Js[1] + c - w0] for c in fcols], Jv[:, :, :model.ny]
            strong = [Sv[:, :, Js[1] + c - w0] for c in fcols]
        elif freqs is not None and model.faults:
            lam_s, Ge_s = _strong_points(model, Ge, freqs)
            strong = [row_responses(cand, basis, Ge_s, lam_s, c, den_mu) for c in fcols]
        if strong is not None:
            # as the post-condition: each fault's gain at ω against that fault's own peak (not the
            # strongest fault's, which would refuse a weak but flat fault response)
            ok = [[np.max(np.linalg.norm(Sj[w], axis=1)) > FDGainTol * np.max(np.linalg.norm(Pj, axis=2))
                   for w in range(freqs.size)] for Sj, Pj in zip(strong, P)]
            if not all(all(o) for o in ok):
                if nu == max(degrees):
                    bad = [(model.fault_names[j], float(freqs[w])) for j, o in enumerate(ok)
                           for w in range(freqs.size) if not o[w]]
                    raise DesignError(
                        "strong detectability fails: " + "; ".join(
                            f"fault '{f}' has zero gain at ω = {w:g} rad/s in every residual that decouples "
                            f"u and d" for f, w in bad))
                continue
        if model.faults:
            mu = _lam_to_mu(lam, basis.rho)
            dvals = np.prod(mu[:, None] - den_mu[None, :], axis=1) if den_mu.size else np.ones(mu.size)
            Y = np.stack([r.at(mu)[:, :model.ny] for r in cand], axis=1) / dvals[:, None, None]
            Y = Y if Js is None else Y_stable
            objective = visibility_gated(P, Y, Ge_grid, fcols, FDtol, strong)
            H = greedy_combinations(objective, k, int(rdim), seed)
            fsc = min(objective(h) for h in H)
        else:
            H = np.eye(k)[: int(rdim)]
            fsc = None
        coefs = [sum(h[i] * cand[i].padded(nu) for i in range(k)) for h in H]
        Q = realize_rows(coefs, [den_mu] * len(coefs), basis.rho, model.dt) if Js is None else (
            H @ Js[0][:, :Js[1]]).minreal()  # the stable rows combined: R = H·N_R, as the strong test judged
        info = {"order": int(Q.n), "rdim": len(coefs), "combination": H.tolist(),
                "fault_sensitivity_estimate": fsc}
        gen = _finish(model, Q, basis, "nullspace", info, degrees, place=place)
        return gen
    raise DesignError(
        f"rdim = {rdim} residuals requested but the null space of [Gu Gd; I 0] has only "
        f"{len(rows)} basis vectors (p - rank Gd)"
    )


def _boundary_rows(model, cand, basis, nu, den_mu, freqs, place):
    """``(J, q)``: the stable factor ``[N_Q N_R]`` of the candidate rows
    (:func:`..toolkit.stable_factor.stable_joint_factor`) when a strong frequency lies on a pole
    of the plant on the stability boundary, else None. There
    ``Q·Ge`` is infinite (or, rounded, huge): what a stable residual keeps is the value of the stable
    factor, in which glcf has moved the pole (the peer's ``glnull(...; sdeg)`` before ``fdisspec``)."""
    if not model.n or not model.faults:
        return None
    if not np.any(near_poles(_points(model, np.atleast_1d(freqs)), np.linalg.eigvals(model.A))):
        return None
    Qc = realize_rows([r.padded(nu) for r in cand], [den_mu] * len(cand), basis.rho, model.dt)
    J, q, _ = stable_joint_factor(model, Qc, **(place or {}))
    return J, q


#: the largest u/d leak (relative to the weakest fault peak) that :func:`_refined` polishes: rounding
#: amplified near a boundary pole leaves ~cond·eps, 1e-6 on the Boeing 747 rows and 2e-6 on CS1_1;
#: a leak above 1e-4 is a wrong rank decision (a non-parity row, e.g. atol above every singular value)
#: that a least-squares correction of the numerator must not turn into a returned design
REFINE_MAX_LEAK = 1e-4


def _refined(model, Q: LTI, lam, Gv) -> LTI:
    """Q with its numerator refined (:func:`..toolkit.refine.refine_decoupling`) when its u/d leak on the grid
    exceeds 1e-9 of its weakest fault peak (a rounding error the plant amplifies near a pole on the
    boundary) but not :data:`REFINE_MAX_LEAK` of it, and the correction is small enough to compute (≤ 2000 numerator coefficients).

    The refined Q is kept only when the post-condition judge (its own points, the boundary modes' residues, each
    filter's rows at unit fault peak) reads it better — fewer failures, else a lower leak. A correction that lowers
    the leak on the fit's points can raise it between them (random seed 239's row [0 1 0 0 1], discrete, plant
    poles within 8e-3 of fc's z = 1: 4 % lower on its 77 points, 28 times higher on a dense grid, and ``Q(1)·c``
    from 2.5e-8 to 1.4e-5 — z = 1 back in R_fc, where numpy's judge passed the unrefined row), or shrink the
    numerator to rounding (random seed 10's actuator bank rows came back 1e-23 in size)."""
    from ..toolkit.refine import boundary_residues, refine_decoupling

    ud, fsl = slice(0, model.nu + model.nd), model.group_slices()["f"]
    if not (ud.stop and model.faults) or (Q.n + Q.p) * Q.m > 2000:
        return Q
    Qv = _values(Q, lam)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))
    if model.n:  # beside a plant pole (an integrator at ω = 0) Ge's values are rounding-dominated
        ok &= ~beside_poles(lam, eigenvalues(model.A), model.dt)[0]
    R = np.einsum("kiq,kqc->kic", Qv[ok], Gv[ok])
    weakest = min(np.max(np.linalg.norm(R[:, :, fsl][:, :, c], 2, axis=(1, 2))) for c in
                  [np.arange(model.nf)[f.columns] for f in model.faults])
    leak = np.max(np.linalg.norm(R[:, :, ud], 2, axis=(1, 2)), initial=0.0)
    if leak <= 1e-9 * weakest or leak > REFINE_MAX_LEAK * weakest:
        return Q
    Qr = refine_decoupling(Q, lam[ok], Gv[ok][:, :, ud], boundary_residues(model, every_input=True))[0]
    if Qr is Q:
        return Q
    return Q if _verdict(model, Qr, lam[ok], Gv[ok]) >= _verdict(model, Q, lam[ok], Gv[ok]) else Qr


def _verdict(model, X: LTI, lam, Gv) -> tuple[int, float]:
    """The post-condition judge's reading of the filter X, its rows first scaled to unit fault peak on the points
    ``lam`` (``Gv``: Ge there), as :func:`_finish` then scales them: ``(failures, leak)``, compared lexicographically
    (fewer failures, else a lower leak; a figure the judge could not read counts as the worst)."""
    fsl = model.group_slices()["f"]
    peaks = np.max(np.abs(np.einsum("kiq,kqc->kic", _values(X, lam), Gv[:, :, fsl])), axis=(0, 2))
    fig = check_generator(ResidualGenerator(_normalize_rows(X, np.where(peaks > 0, peaks, 1.0)), model, "nullspace"),
                          raise_error=False)
    return len(fig.get("failures", ())), float(fig.get("decoupling", np.inf))


def _boundary_modes_cancelled(model, Q: LTI, lam, Gv) -> LTI:
    """Q made to cancel the plant's modes on or beyond the stability boundary as well as its data can: tried only
    where the judge's decisions on those modes (:func:`..toolkit.postconditions.mode_decisions`) read a row that
    keeps one — its residue ``||Q_i(p) c_p||`` above its rounding bound δ_i (a pole of R) or so large that R read two
    of the judge's gaps beside p (``residue/(2·gap)``, :func:`..toolkit.postconditions.boundary_poles`) exceeds
    0.1·:data:`DEC_TOL` of the row's weakest fault peak — and among the candidates kept the one the judge reads best
    (:func:`_verdict`; Q itself on a tie):

    - Q's numerator corrected so that every such mode that some input of Ge excites is cancelled exactly in
      ``R = Q·Ge`` (:func:`..toolkit.refine.cancel_residues` on the modes and directions of the judge's table,
      :func:`..toolkit.refine.boundary_residues` with ``every_mode``; the u, d decoupling kept on the points
      ``lam``, where ``Gv`` are Ge's values);
    - Q's balanced realisation (:func:`..toolkit.stable_factor.conditioned_realisation` at any amplification), and
      that corrected likewise.

    Why: the stable factor ``M`` puts the zero ``Q(p) c_p = 0`` where R would keep a fault-only mode p, to the
    rounding of the factorisation; what follows can lose it. Random seed 307's row [0 1 1 0 1] (discrete, fc's
    z = 1, w not decouplable): after the factor (order 19) the residue was 1.2e-14 against δ_i = 6.7e-12; the
    noise normaliser's product ``fac·Q1`` (order 39) read 1.1e-13 (δ_i 5.7e-13), and its balanced re-realisation
    (:func:`..toolkit.stable_factor.conditioned_realisation`, order 24) kept that residue with a realisation
    whose bound is δ_i = 9.6e-14 — R kept z = 1 and the row was refused. Seed 319's row [1 0 1 1 1]: the
    product (order 48) kept the zero (7.4e-15 against 2.7e-12), the re-realisation (order 42) raised it to
    2.8e-13 against 2.0e-13. The correction moves ``[B_q; D_q]`` by 3.9e-15 (seed 307) and 7.1e-15 (319)
    relative and the residues to 4.5e-17 and 1.5e-16 (the row's own rounding); numpy's judge passes both rows.
    And a realisation can carry the residue in its own conditioning: seed 359's row [0 1 1 0 0] (discrete, n = 9,
    fc's undamped pair e^{±0.2j} decoupled, the row's order-8 filter with a pole pair 0.0058 from it) computes
    ``Q(p)`` = 70 from terms of size κ = 4.3e7 (:func:`..toolkit.postconditions._row_sensitivity`; amplification
    3961, below conditioned_realisation's default 1e4): residue 1.1e-12 within δ_i = 1.6e-7, but R_u read two gaps
    beside p leaked 8.0e-7 of the weakest fault gain; its balanced realisation has κ = 747 and reads 3.0e-8
    (numpy's judge passes both: its grid stays 1e-3 from the poles). As :func:`_refined`, bounded to ≤ 2000
    numerator unknowns."""
    from ..toolkit.refine import boundary_residues, cancel_residues
    from ..toolkit.stable_factor import conditioned_realisation

    if not model.n or (Q.n + Q.p) * Q.m > 2000:
        return Q
    ok = np.all(np.isfinite(Gv), axis=(1, 2))
    Qv = _values(Q, lam)
    ok &= np.all(np.isfinite(Qv), axis=(1, 2)) & ~beside_poles(lam, eigenvalues(model.A), model.dt)[0]
    boundary = boundary_poles([model.lti()], model.dt)
    if not np.any(ok) or not boundary:
        return Q
    Qv, G = Qv[ok], Gv[ok]
    decisions = mode_decisions(model, Q, [[k] for k in range(Q.p)],
                                [float(np.max(np.linalg.norm(Qv[:, k, :], axis=1))) for k in range(Q.p)])
    if decisions is None:
        return Q
    fsl = model.group_slices()["f"]
    Rf = np.einsum("kiq,kqc->kic", Qv, G[:, :, fsl])
    weakest = np.min([np.max(np.linalg.norm(Rf[:, :, c], axis=2), axis=0) for c in
                      [np.arange(model.nf)[f.columns] for f in model.faults]], axis=0)  # per row
    pole = np.isfinite(decisions["delta_i"]) & ~np.all(decisions["removed"], axis=2)  # modes × rows
    beside = decisions["residue"] / (2 * boundary[0][1]) > 0.1 * DEC_TOL * weakest[None, :]
    residues = boundary_residues(model, every_mode=True)
    if not (residues and np.any(pole | beside)):
        return Q  # every mode cancelled to rounding, unexcited or undecidable, and read below the leak bound
    nud = model.nu + model.nd
    candidates = [Q, cancel_residues(Q, residues, lam[ok], G[:, :, :nud] if nud else None)[0]]
    Qb = conditioned_realisation(model, Q, amplification_max=1.0)
    if Qb is not Q:
        candidates += [Qb, cancel_residues(Qb, residues, lam[ok], G[:, :, :nud] if nud else None)[0]]
    candidates = [X for k, X in enumerate(candidates) if all(X is not Y for Y in candidates[:k])]  # each once
    verdicts = [_verdict(model, X, lam[ok], G) for X in candidates]
    return candidates[min(range(len(candidates)), key=lambda k: verdicts[k])]


def _finish(model, Q: LTI, basis: NullspaceBasis, method: str, info: dict, degrees,
            scale_rows: bool = True, place: dict | None = None) -> ResidualGenerator:
    """Where every null-space design ends: make the whole internal form stable, then normalise
    each residual to unit peak fault gain (scale-free designs read better).

    ``Q ← M·Q`` with the stable left factor of ``[Q R]`` (:func:`..toolkit.stable_factor.stable_internal_form`)
    when ``R = Q·Ge`` keeps a pole of the plant outside the stability region (``place``: the
    design's ``poles``, ``sdeg``, ``smarg``, ``keep_stable_poles``); ``info['internal_form']``
    then names the moved poles.
    """
    Q, moved = stable_internal_form(model, Q, **(place or {}))
    if moved:
        info = dict(info, internal_form=moved, order=int(Q.n))
    gen = ResidualGenerator(Q, model, method)
    if scale_rows and model.faults:
        # peaks of R_f = Q·Gf as the judge reads them: the product of the two values point by point
        # (:func:`..toolkit.postconditions.internal_figures`), never the series realisation of order n_Q + n,
        # which is non-minimal (the modes Q cancels) and singular on the axis where the plant has poles
        dyn = [S for S in (model.lti(), Q) if S.n]
        grid = frequency_grid(dyn, num=200) if dyn else np.array([0.0])
        lam = _points(model, grid)
        fsl = model.group_slices()["f"]
        Gv = _values(model.augmented(), lam)
        Q = _boundary_modes_cancelled(model, _refined(model, Q, lam, Gv), lam, Gv)
        Rv = np.einsum("kiq,kqc->kic", _values(Q, lam), Gv[:, :, fsl])
        # (beside a plant pole on the boundary, R_f = Q·Gf is rounding/δ: approximate audit seed 13 read 1.2e5 at
        # z = 1 for a fault peak 1.0)
        ok = np.all(np.isfinite(Rv), axis=(1, 2)) & ~beside_poles(lam, eigenvalues(model.A), model.dt)[0]
        if np.any(ok):
            peaks = np.max(np.abs(Rv[ok]), axis=(0, 2))
        else:
            # no point where Q and the plant can both be evaluated: a pole of R_f = Q·Gf on the frequency axis
            # that the stable factorisation above could not move (it raises when it cannot; this is the backstop)
            poles = gen.Rf.poles()
            worst = (np.max(np.abs(poles)) if model.dt else np.max(poles.real)) if poles.size else float("nan")
            raise NumericalDesignError(f"{method} design fails its post-conditions (stability): a pole of the fault "
                              f"response R_f = Q·Gf lies on the stability boundary "
                              f"({'largest |pole|' if model.dt else 'largest Re(pole)'} = {worst:.6g}); the "
                              f"realisation of the basis rows is ill-conditioned for this model — pass other "
                              f"poles/sdeg or rank tolerances (tol)") from None
        scale = np.where(peaks > 0, peaks, 1.0)
        gen = ResidualGenerator(_normalize_rows(Q, scale), model, method)
    gen.info.update(info)
    gen.info.update({"basis_degrees": list(map(int, degrees)), "poles": np.asarray(gen.Q.poles()).tolist(),
                     "rho": basis.rho})
    return gen


def _approximate(model: FDIModel, basis: NullspaceBasis, rdim, choose, FDtol, tol, seed, atol=0.0,
                 place: dict | None = None):
    exact_w = model.with_disturbances(noise=True)
    try:
        basis2 = minimal_basis(exact_w, tol, atol)
        seen2 = detectability_by_rows(exact_w, basis2, FDtol) if basis2.rows else np.zeros((0, len(model.faults)))
    except DesignError:
        basis2, seen2 = None, np.zeros((0, len(model.faults)))
    if basis2 is not None and basis2.rows and (not model.faults or np.all(seen2.max(axis=0) >= FDtol)):
        gen = _exact(exact_w, basis2, seen2 >= FDtol, rdim, choose, None, 0.01, seed, place=place)
        gen = ResidualGenerator(gen.Q, model, "nullspace", info=gen.info)
        gen.info["gap_estimate"] = float("inf")
        gen.info["noise"] = "decoupled exactly"
        return gen

    def realize_all(b):
        dens = [choose(r.degree) / b.rho for r in b.rows]
        return realize_rows([r.coef for r in b.rows], dens, b.rho, model.dt)

    Q0 = realize_all(basis)
    Q2 = realize_all(basis2) if basis2 is not None and basis2.rows else None
    return _noise_combination(model, Q0, Q2, basis, basis.degrees, rdim, seed, place)


def _noise_combination(model: FDIModel, Q0: LTI, Q2: LTI | None, basis, degrees, rdim, seed,
                       place: dict | None) -> ResidualGenerator:
    """Procedure AFD's combination (Varga 2017, sec. 5.3) of a (u, d)-null-space basis ``Q0`` and a
    (u, d, w)-null-space basis ``Q2`` (None: w reaches every residual): the rows of Q0 completing Q2,
    their internal form made stable and ``Rw`` co-outer normalised, then the constant combination of
    all rows with the largest fault-to-noise gap (on its plateau, the most even fault sensitivity)."""
    k2 = Q2.p if Q2 is not None else 0
    # rows of Q0 that complete Q2 to a basis of the whole (u, d)-null space
    k = Q0.p
    lam = _random_points(basis, 2, seed=3)
    chosen: list[int] = []
    for i in range(k):
        trial = vstack(([Q2] if Q2 is not None else []) + [Q0[chosen + [i], :]])
        if min(np.linalg.matrix_rank(trial.evalfr(l), tol=1e-9 * max(1.0, np.abs(trial.evalfr(l)).max()))
               for l in lam) == k2 + len(chosen) + 1:
            chosen.append(i)
        if len(chosen) == k - k2:
            break
    # the rows that see w: their internal form stable first (Procedure AFD, Varga 2017 sec. 5.3: the
    # co-outer factor of Rw exists only for a stable Rw; an integrator of Gw left in Rw1 breaks it)
    Q1, moved = stable_internal_form(model, Q0[chosen, :], **(place or {}))
    sl = model.group_slices()
    Ge = model.augmented()
    Rw1 = (Q1 @ Ge)[:, sl["w"]].minreal()
    # Rw1 with a zero at infinity or on or next to the stability boundary (Varga's non-standard case: an inverse
    # would put a near-integrator into the filter, a pole at -5e-9 on random seeds 22, 28): the nonstd option
    fac, how = noise_normalizer(Rw1, **{k: (place or {}).get(k) for k in ("smarg", "poles", "sdeg")})
    if fac is not None:
        Q1 = (fac @ Q1).minreal()
    Qc = vstack([Q1] + ([Q2] if Q2 is not None else []))
    grid = frequency_grid([Qc, model.lti()], num=200)
    lam_g = _points(model, grid)
    Qv, Gv = _values(Qc, lam_g), _values(Ge, lam_g)
    finite = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))  # plant poles on the axis
    # ... and beside them: at a plant pole on the boundary computed 1e-16 off (z = 1 of a fault-only mode) Ge is
    # huge but finite and Q·Ge, which cancels the pole, reads rounding/δ (approximate audit seed 13: R_fc 1.2e5 at
    # z = 1 against its peak 1.0; the gap estimate read 1.28 for the true 0.373 and the combination chased it)
    finite &= ~beside_poles(lam_g, eigenvalues(model.A), model.dt)[0] if model.n else True
    Qv, Gv = Qv[finite], Gv[finite]
    Rv = np.einsum("kiq,kqc->kic", Qv, Gv)
    Rw = Rv[:, :, sl["w"]].copy()
    Rw[:, Q1.p:, :] = 0.0  # the Q2 rows decouple w exactly
    Rf, Rw = structural_zeros([Rv[:, :, c] for c in fault_columns(model)], Rw)
    objective = gap_objective(Rf, Rw)
    H = greedy_combinations(objective, Qc.p, 1 if rdim == "all" else int(rdim), seed)
    if H.shape[0] == 1 and Qc.p > 1:
        # The best gap is often reached on a plateau; on it, prefer the combination whose
        # faults are most evenly visible (largest fault sensitivity condition).
        best = objective(H[0])
        fsc, order = sensitivity_objective(Rf), _in_fault_order(Rf)

        def constrained(h, tie=0.0):
            g = objective(h)
            return fsc(h) + tie * order(h) if g >= best * (1 - 1e-9) else g / best - 1.0

        h, _ = maximize_on_sphere(constrained, Qc.p, seed, extra_starts=[H[0]])
        # Among equals (a symmetric plant, e.g. two sensors of one variable: mirror-image optima of
        # the same gap and condition) the one that favours the faults in the model's order
        # (:func:`_in_fault_order`), so the choice does not hang on how the basis is parametrised:
        # a second search from spread starts (the starts nearest the plateau crowd round the
        # greedy optimum) with the order as a tie-break, kept only when its condition ties.
        h2, _ = maximize_on_sphere(lambda x: constrained(x, TIE_WEIGHT * fsc(h)), Qc.p, seed, extra_starts=[h],
                                   spread=TIE_SPREAD)
        if (objective(h2) >= best * (1 - 1e-9) and abs(fsc(h2) - fsc(h)) <= TIE_RTOL * fsc(h)
                and order(h2) > order(h)):
            h = h2
        H = h[None, :]
    Q = (H @ Qc).minreal() if H.shape[0] < Qc.p else Qc
    info = {"order": int(Q.n), "rdim": int(H.shape[0]), "gap_estimate": min(objective(h) for h in H),
            "noise": how,
            "combination": H.tolist()}
    if moved:
        info["internal_form"] = moved
    gen = _finish(model, Q, basis, "nullspace", info, degrees, place=place)
    # the gap reported is the returned filter's, by H∞ norms of its internal form (what fault_noise_gap reads):
    # the 200-point grid above steps over a lightly damped resonance (approximate audit seed 20: estimate 0.488,
    # the filter's gap 1.87) and reads nothing beside a boundary pole of the plant
    from ...analysis import fault_noise_gap

    gap = float(np.min(fault_noise_gap(gen, np.ones((len(gen.groups), len(model.faults)), int))))
    if np.isfinite(gap) or np.isinf(gen.info["gap_estimate"]):
        gen.info["gap_estimate"] = gap
    return gen


#: weight of the fault-order tie-break (a value in [0, 1)) relative to the fault sensitivity condition:
#: far above Nelder-Mead's tolerance (1e-12), far below any difference of condition worth keeping
TIE_WEIGHT = 1e-6
#: refined starts on the plateau are at least acos(0.9) ≈ 26° apart (:func:`maximize_on_sphere`'s spread)
TIE_SPREAD = 0.9
#: conditions equal to this relative tolerance tie (mirror images agree to ~1e-9; the tie-break moves
#: the condition by at most TIE_WEIGHT relative)
TIE_RTOL = 1e-5


def _in_fault_order(Rf: list[np.ndarray]):
    """Tie-break of equally good combinations ``h``: ``Σ_j 2^-(j+1) ||h Rf_j||∞ / max_i ||h Rf_i||∞``
    in [0, 1), larger when the earlier faults (model order) are seen more strongly. Equal for
    every permutation-symmetric figure (gap, condition, noise), it tells mirror images apart."""
    weights = 0.5 ** np.arange(1, len(Rf) + 1)

    def order(h: np.ndarray) -> float:
        peaks = np.array([np.max(np.linalg.norm(np.einsum("r,krc->kc", h, F), axis=1)) for F in Rf])
        top = peaks.max()
        return float(weights @ peaks / top) if top > 0 else 0.0

    return order


def _noise_pencil(model, rdim, poles, sdeg, FDtol, FDGainTol, seed, smarg, dec_tol, tol, atol, minimal,
                  place) -> ResidualGenerator:
    """:func:`_approximate_pencil` judged as :func:`_design` judges the polynomial one."""
    gen = _approximate_pencil(model, rdim, poles, sdeg, FDtol, FDGainTol, seed, smarg, dec_tol, tol, atol, minimal,
                              place)
    exact_w = gen.info.get("noise") == "decoupled exactly"
    check_generator(gen, decouple=("u", "d", "w") if exact_w else ("u", "d"), block=True, FDtol=FDtol,
                    smarg=smarg, dec_tol=dec_tol)
    gen.info.update({"basis": "pencil", "decoupling_kind": EXACT})
    return gen


def _approximate_pencil(model: FDIModel, rdim, poles, sdeg, FDtol, FDGainTol, seed, smarg, dec_tol, tol, atol,
                        minimal: bool, place: dict | None) -> ResidualGenerator:
    """Procedure AFD on the state-space core (FaultDetectionTools.jl ``afdsyn``): w decoupled
    exactly when a least-order pencil row of ``[Gu Gd Gw; I 0 0]`` sees every fault
    (:func:`_pencil` on the model with w as unknown inputs); otherwise the proper stable pencil
    bases of ``[Gu Gd; I 0]`` and ``[Gu Gd Gw; I 0 0]`` (:func:`..toolkit.pencil.pencil_basis`, no powers of
    A) combined by :func:`_noise_combination` — without the latter when the exact attempt failed its decoupling
    post-condition (those rows leak on their own; ``info['noise_decoupling_refused']`` says so)."""
    from types import SimpleNamespace

    from ..toolkit.pencil import pencil_basis

    exact_w = model.with_disturbances(noise=True)
    w_leaks = False
    try:
        with tentative():
            gen = _pencil(exact_w, rdim, poles, sdeg, None, FDtol, FDGainTol, seed, smarg, dec_tol, tol, atol,
                          minimal, place)
    except DesignError as exc:
        gen = None
        w_leaks = "decoupling" in getattr(exc, "conditions", ())
    if gen is not None:
        gen = ResidualGenerator(gen.Q, model, "nullspace", info=gen.info)
        gen.info.update({"gap_estimate": float("inf"), "noise": "decoupled exactly"})
        return gen
    pb = pencil_basis(model, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
    if pb.N.p == 0:
        raise no_residual_error(model, pb.rank_d)
    try:
        with tentative():
            pb2 = pencil_basis(exact_w, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
        Q2 = pb2.N if pb2.N.p else None
    except DesignError:
        Q2 = None
    if w_leaks:
        # the (u, d, w) null-space rows were just designed and leak u, d or w above dec_tol on their own: combined
        # with the others they would carry that leak (their gap is infinite, so the combination takes them). Noise
        # is then attenuated, not decoupled (random seed 207's row [1 1 0 1 0]: the one w-decoupling row, of order
        # 12, needs a feedback of norm 2.4e5 to move a basis pole 48 whose controllability is 2e-4; its rounding
        # leaks 1.9e-6 of the weakest fault gain)
        Q2 = None
    gains = _span_gains(model, pb.N, None)[None, :]
    if model.faults and not np.all(gains >= FDtol):
        raise undetectable_error(model, gains >= FDtol, gains=gains, FDtol=FDtol, numerical=NumericalDesignError)
    gen = _noise_combination(model, pb.N, Q2, SimpleNamespace(rho=1.0, dt=model.dt), pb.degrees, rdim, seed, place)
    gen.info.update({"left_minimal_indices": pb.degrees, "pencil": pb.info})
    if w_leaks:
        gen.info["noise_decoupling_refused"] = "the rows decoupling w exactly leak u, d or w above dec_tol"
    return gen
