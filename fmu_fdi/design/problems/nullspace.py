"""Null-space based synthesis: exact fault detection, approximate with noise (efdsyn/afdsyn).

Every proper residual generator that decouples the known inputs u and the unknown
inputs d is ``Q = Y(λ) N(λ)`` for a left null-space basis ``N`` of

    G(λ) = [Gu(λ) Gd(λ); I 0]

(Frank, eqs. 9-12; Varga 2017, Procedure EFD). We compute a minimal polynomial basis
(:mod:`..toolkit._basis`), and the least-order stable filter is a constant combination of the
basis rows of the smallest degree ν that detect every fault, divided by a monic
polynomial of degree ν whose roots are the requested poles:

    Q(λ) = h [N_1(λ); ...; N_k(λ)] / d(λ),    R(λ) = Q G_e(λ) = [0 0 Rw Rf].

A fault j is detectable once d is decoupled exactly when
``rank [Gd Gf_j] > rank Gd`` (normal ranks); when it is not, no Q exists and the error
names the fault. With noise inputs w, the combination is chosen to maximise the
fault-to-noise gap after a co-outer normalisation (:mod:`..toolkit.approximate`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import DesignError
from ...linalg import single_blas_thread
from ...generator import ResidualGenerator
from ...lti import LTI, frequency_grid, vstack
from ...model import FDIModel
from ..toolkit._basis import NullspaceBasis, check_poles, minimal_basis, normal_rank, pole_chooser, realize_rows
from ..toolkit._select import greedy_combinations, maximize_on_sphere, sensitivity_objective, visibility_gated
from ..toolkit.approximate import coouter_inverse, gap_objective
from ...margin import near_poles
from ..toolkit.stable_factor import stable_internal_form, stable_joint_factor
from ..toolkit.postconditions import DEC_TOL, NumericalDesignError, _cosine, _values, check_generator


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


@single_blas_thread
def nullspace_design(model: FDIModel, *, rdim: int | str = 1, poles=None, sdeg: float | None = None,
                     freqs=None, FDtol: float = 1e-4, FDGainTol: float = 0.01, noise: str = "optimize",
                     tol: float | None = None, atol: float = 0.0, seed: int = 0, smarg: float | None = None,
                     dec_tol: float = DEC_TOL, minimal: bool = True, basis: str = "auto",
                     keep_stable_poles: bool = True) -> ResidualGenerator:
    """Least-order residual generator from a minimal proper stable left null space of ``[Gu Gd; I 0]``.

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
        Poles of the filter (a conjugate-closed set); missing ones are placed at ``sdeg``.
    sdeg : float, optional
        Pole for the rows beyond the given ``poles`` (default -1, or 0 in discrete time).
        With neither ``poles`` nor ``sdeg`` each row takes poles from the plant's own
        stabilised eigenvalues, spread from slow to fast, which keeps its fault response
        nearly flat over frequency (``_basis.pole_chooser``).
    freqs : array_like, optional
        Frequencies (rad/s) at which every fault must be *strongly* detectable
        (``|Rf_j(jω)| > 0``); the combination is chosen with these gains in its objective,
        among the combinations whose every fault is visible (:func:`visibility_gated`). At a
        pole of the plant on the stability boundary (an integrator at ω = 0) the gain is the
        limit of the stable fault response (:func:`_strong_points`). With neither ``poles`` nor
        ``sdeg``, plant poles slower than the fastest frequency are sped up to it
        (``_basis.pole_chooser``).
    FDtol, FDGainTol : float
        Relative thresholds for (weak) detectability and for strong detectability.
    noise : {'optimize', 'ignore'}
        How to treat noise inputs w (if any).
    tol, atol : float, optional
        Relative and absolute rank tolerances of the null-space computation (Varga's
        ``rtol``/``atol``: singular values at or below ``max(tol·σ_max, atol)`` are zero).
        When neither is given and the design breaks a numerical post-condition
        (decoupling, basis rank, stability of the realisation), the rank decisions are
        retried with a tighter (1e-15) and then a looser (1e-9) relative tolerance; the
        tolerance used is ``info['rank_rtol']``.
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
    dec_tol : float
        Largest relative leakage of u and d (and w when it is decoupled) the returned filter
        may show (:mod:`..toolkit.postconditions`).
    minimal : bool
        True (default): least order — the smallest degree ν whose basis rows meet the
        requirements. False: fixed (full) order — a combination of *all* basis rows at the
        largest basis degree (FaultDetectionTools.jl's ``minimal = false``), which gives the
        combination more freedom (e.g. for strong detectability or sensitivity) at a higher order.
    basis : {'auto', 'polynomial', 'pencil'}
        Which left null-space basis the design starts from. 'polynomial': the minimal
        polynomial (parity) basis (:mod:`..toolkit._basis`, least order), with the frequency-sampled
        least-order fallback (:mod:`..toolkit.sampled`). 'pencil': the proper state-space basis from
        the system pencil (:mod:`..toolkit.pencil`, Varga's ``glnull``), accurate at any degree. With
        several basis rows each row is first taken on its own at its left minimal index ν_i
        (a simple basis from Type 1 minimum dynamic covers, :func:`..toolkit.pencil.simple_rows`) and the
        residual is the first set of them, in increasing total order (single rows first), whose
        combination sees every fault and passes every post-condition — least order when one row
        suffices (``info['simple_rows']`` the indices used); otherwise (or when the covers are
        too ill-conditioned, ``info['simple_rows_refused']``) a combination of the whole basis,
        of order at most the sum of the indices. Its poles are the basis' own, except those
        outside the stability region (``smarg``, and ``sdeg`` when given), which move to
        ``poles`` first and then to their mirror image about ``sdeg``. Simple rows of one index
        get common poles (:func:`_common_poles`), so that a combination of them keeps that order.
        'auto' (default): the pencil row first when it is least order and passes every
        post-condition — ``rdim = 1`` (or one basis row), no ``poles``/``sdeg``/``tol``/``atol``, no
        noise to optimise (``info['least_order']`` when a simple row proves it); else the
        polynomial, and the pencil basis when neither polynomial nor sampled rows meet the
        post-conditions, or when the sampled row's order is below the smallest left minimal
        index — such a row cannot annihilate ``[Gu Gd; I 0]`` exactly, it only decouples to the
        peak-relative ``dec_tol`` (pointwise leaks up to 1e-2 where |G| is small) — and the pencil
        row passes every post-condition (``info['basis']`` says which was used;
        ``info['left_minimal_indices']`` the degrees of a minimal polynomial basis;
        ``info['replaces']`` the approximate row a pencil row replaced).
        ``info['decoupling_kind']`` is 'exact' or, for a sampled row below the smallest index
        returned because no exact row was found (or with ``basis='polynomial'``), starts with
        'approximate' — and a ``UserWarning`` says so. With noise and ``noise='optimize'``,
        'pencil' solves the approximate problem on the pencil bases of ``[Gu Gd; I 0]`` and
        ``[Gu Gd Gw; I 0 0]`` (:func:`_approximate_pencil`); 'auto' does so when every rank
        tolerance of the polynomial ladder breaks a post-condition (``info['fallback_from']``).

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
    if basis == "pencil":
        return req.pencil() if req.exact_only else req.noise_pencil()
    auto = basis == "auto" and req.exact_only
    pencil_gen, pencil_failed = _pencil_first(req) if auto else (None, None)
    if pencil_gen is not None and _least_order(pencil_gen, rdim):
        return pencil_gen
    gen, first = _polynomial_ladder(req)
    if gen is not None:
        return gen
    if not req.exact_only:
        if basis != "auto":
            raise first
        return _noise_fallback(req, first)
    return _exact_fallbacks(req, auto, first, pencil_gen, pencil_failed)


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
        place = {"poles": poles, "sdeg": sdeg, "smarg": smarg, "keep_stable_poles": bool(keep_stable_poles)}
        return cls(model, rdim, poles, sdeg, freqs, FDtol, FDGainTol, noise, tol, atol, seed, smarg, dec_tol,
                   minimal, place)

    @property
    def exact_only(self) -> bool:
        """No noise to optimise: u and d are decoupled, w (if any) is ignored."""
        return not (self.model.nw and self.noise == "optimize")

    @property
    def default_rank_tolerances(self) -> bool:
        return self.tol is None and not self.atol

    def pencil(self) -> ResidualGenerator:
        return _pencil(self.model, self.rdim, self.poles, self.sdeg, self.freqs, self.FDtol, self.FDGainTol, self.seed,
                       self.smarg, self.dec_tol, self.tol, self.atol, self.minimal, self.place)

    def noise_pencil(self) -> ResidualGenerator:
        return _noise_pencil(self.model, self.rdim, self.poles, self.sdeg, self.FDtol, self.FDGainTol, self.seed,
                             self.smarg, self.dec_tol, self.tol, self.atol, self.minimal, self.place)

    def polynomial(self, rtol: float | None, target: float) -> ResidualGenerator:
        return _design(self.model, self.rdim, self.poles, self.sdeg, self.freqs, self.FDtol, self.FDGainTol,
                       self.noise, rtol, self.atol, self.seed, self.smarg, target, self.minimal, self.place)

    def sampled(self, degrees) -> ResidualGenerator:
        return _sampled(self.model, int(self.rdim), self.poles, self.sdeg, self.freqs, self.FDtol, self.FDGainTol,
                        self.seed, self.smarg, self.dec_tol, degrees, self.place)


def _pencil_first(req: _Request):
    """Stage 1 of 'auto' (exact problem): the state-space core first, ``(gen, None)`` or ``(None, error)``.

    A pencil row at the smallest left minimal index is least order and exact (orthogonal reductions,
    no powers of A); the polynomial ladder and the sampled rows remain for what it does not settle —
    given poles/sdeg (a polynomial row's denominator is exactly them, the pencil moves only its
    basis' unstable eigenvalues), rank tolerances, several rows."""
    if req.rdim == "all" or req.poles is not None or req.sdeg is not None or not req.default_rank_tolerances:
        return None, None
    try:
        return req.pencil(), None
    except DesignError as exc:
        return None, exc


def _polynomial_ladder(req: _Request):
    """Stage 2: the polynomial basis over a ladder of rank tolerances, ``(gen, None)`` or ``(None, first error)``.

    It aims at a tenth of dec_tol over the whole ladder first, so that a rank tolerance that gives a
    clean basis wins over one that only just passes; then accepts dec_tol itself (the failures are
    reported against dec_tol itself)."""
    ladder = [req.tol] if not req.default_rank_tolerances else [None, 1e-15, 1e-9]
    first = None
    for target in (req.dec_tol / 10, req.dec_tol):
        first = None
        for rtol in ladder:
            try:
                gen = req.polynomial(rtol, target)
            except NumericalDesignError as exc:
                first = first or exc
                continue
            gen.info["rank_rtol"] = rtol
            gen.info["basis"] = "polynomial"
            gen.info["decoupling_kind"] = EXACT
            gen.info["postconditions"]["dec_tol"] = req.dec_tol
            return gen, None
    return None, first


def _noise_fallback(req: _Request, first: Exception) -> ResidualGenerator:
    """Stage 3 of 'auto' with noise to optimise: the approximate problem on the state-space core, where
    the polynomial basis of an ill-scaled or clustered plant leaks far above dec_tol (random seeds 3, 22,
    30, 37)."""
    try:
        gen = req.noise_pencil()
    except DesignError as exc:
        raise type(first)(f"{first} | the pencil (state-space) basis failed too: {exc}") from None
    gen.info["fallback_from"] = str(first)[:300]
    return gen


def _exact_fallbacks(req: _Request, auto: bool, first: Exception, pencil_gen, pencil_failed) -> ResidualGenerator:
    """Stage 3 of the exact problem, when the polynomial ladder failed: the pencil row (if stage 1 did
    not run), the frequency-sampled row, and the pencil basis at a higher order (see
    :func:`nullspace_design`, ``basis``)."""
    model, rdim = req.model, req.rdim

    def pencil():
        gen = req.pencil()
        gen.info["fallback_from"] = str(first)[:300]
        return gen

    if auto and rdim != "all" and pencil_gen is None and pencil_failed is None:
        # a pencil row at the smallest left minimal index (one basis row: its index; several: a simple row,
        # nullspace._pencil) is the least order of any exact row, and a sampled row can only be approximate
        # (below it) or of that order — skip its search
        try:
            pencil_gen = pencil()
        except DesignError as exc:
            pencil_failed = exc
        else:
            if _least_order(pencil_gen, rdim):
                return pencil_gen
    elif pencil_gen is not None:
        pencil_gen.info["fallback_from"] = str(first)[:300]
    approximate = None  # a sampled row below the smallest left minimal index: returned only without an exact one
    if rdim != "all":
        # the polynomial basis is too ill-conditioned here: design from frequency samples
        # with a fixed stable denominator (exact poles, rank decision = post-condition)
        try:
            # the pencil row's left minimal indices are those _exactness would compute again when that
            # pencil_basis call had exactly its own arguments (all defaults)
            same_call = pencil_gen is not None and req.default_rank_tolerances and req.poles is None \
                and req.sdeg is None and req.smarg is None
            degrees = list(pencil_gen.info["left_minimal_indices"]) if same_call else None
            gen = req.sampled(degrees)
            gen.info["fallback_from"] = str(first)[:300]
            if not auto or not gen.info["decoupling_kind"].startswith("approximate"):
                return _announce(model, gen)
            approximate = gen
        except DesignError as exc:
            first = type(first)(f"{first} | the frequency-sampled fallback failed too: {exc}")
    if auto:
        # no least-order row could be made accurate (or the sampled one is below the smallest left
        # minimal index, i.e. approximate): the state-space (pencil) basis never forms powers of A
        # and keeps ~1e-13 leakage at any degree, at the price of a higher order
        try:
            if pencil_failed is not None:
                raise pencil_failed
            gen = pencil_gen if pencil_gen is not None else pencil()
        except DesignError as exc:
            if approximate is not None:
                approximate.info["exact_alternative"] = f"the pencil (state-space) basis failed: {exc}"[:300]
                return _announce(model, approximate)
            raise type(first)(f"{first} | the pencil (state-space) basis failed too: {exc}") from None
        if approximate is not None:
            gen.info["replaces"] = (f"an approximate frequency-sampled row of order {approximate.Q.n} (below the "
                                    f"smallest left minimal index {min(approximate.info['left_minimal_indices'])})")
        return gen
    raise first


def _least_order(gen: ResidualGenerator, rdim) -> bool:
    """A pencil design is least order: one basis row (its index), or one residual at the smallest left
    minimal index — counted before the stable factorisation of the internal form added the moved poles —
    or one simple row whose lower-index rows cannot see every fault (``info['least_order']``, :func:`_pencil`)."""
    idx = gen.info["left_minimal_indices"]
    order = gen.info.get("internal_form", {}).get("order_before", gen.Q.n)
    return len(idx) == 1 or (rdim == 1 and (order == min(idx) or gen.info.get("least_order", False)))


#: ``info['decoupling_kind']`` of a row that annihilates ``[Gu Gd; I 0]`` identically (up to rounding)
EXACT = "exact"


def _announce(model: FDIModel, gen: ResidualGenerator) -> ResidualGenerator:
    """Warn when a returned row decouples only approximately (its ``info['decoupling_kind']``)."""
    import warnings

    kind = gen.info.setdefault("decoupling_kind", EXACT)
    if not kind.startswith(EXACT):
        warnings.warn(f"model '{model.name}': the residual generator decouples u and d {kind} (order {gen.Q.n}, "
                      f"left minimal indices {gen.info.get('left_minimal_indices', '?')}); "
                      f"{gen.info.get('exact_alternative', 'no exact row was found')}", UserWarning, stacklevel=3)
    return gen


def _sampled(model, rdim, poles, sdeg, freqs, FDtol, FDGainTol, seed, smarg, dec_tol,
             degrees: list[int] | None = None, place: dict | None = None) -> ResidualGenerator:
    from types import SimpleNamespace

    from ..toolkit.sampled import sampled_rows

    choose = pole_chooser(model, poles, sdeg, freqs)
    # a direction whose RMS relative leak is 1/100 of dec_tol passes the post-condition's peak test
    Q, info = sampled_rows(model, choose, fault_columns(model), rdim, freqs=freqs, FDtol=FDtol,
                           FDGainTol=FDGainTol, seed=seed, null_tol=1e-2 * dec_tol)
    gen = _finish(model, Q, SimpleNamespace(rho=1.0), "nullspace", info, [info["degree"]], place=place)
    check_generator(gen, decouple=("u", "d"), block=True, freqs=freqs, FDtol=FDtol, FDGainTol=FDGainTol,
                    smarg=smarg, dec_tol=dec_tol)
    _exactness(model, gen, degrees)
    return gen


def _exactness(model: FDIModel, gen: ResidualGenerator, degrees: list[int] | None = None) -> None:
    """Record the left minimal indices (pencil basis, ms) next to a sampled row's order: a row whose
    order is below the smallest index cannot annihilate ``[Gu Gd; I 0]`` exactly — it decouples to the
    post-condition's peak-relative tolerance only (on the random set: orders 9-18 against indices
    13-26, pointwise relative leak up to 1e-2 where |G| is 1e-7 of its peak). ``degrees``: those
    indices when already known from ``pencil_basis(model)`` itself (not computed again)."""
    from ..toolkit.pencil import pencil_basis

    if degrees is None:
        try:
            degrees = pencil_basis(model).degrees
        except DesignError as exc:
            gen.info["decoupling_kind"] = (f"unverified: the left minimal indices are not available ({exc}"[:200]
                                           + "); decoupled to the post-condition tolerance (dec_tol, peak-relative)")
            return
    gen.info["left_minimal_indices"] = degrees
    exact = bool(degrees) and gen.Q.n >= min(degrees)
    gen.info["decoupling_kind"] = ("exact (order ≥ the smallest left minimal index)" if exact else
                                   "approximate: order below the smallest left minimal index, decoupled to the "
                                   "post-condition tolerance (dec_tol, peak-relative) only")


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
        raise DesignError(
            f"no residual generator exists for model '{model.name}': the unknown inputs d span every "
            f"output direction (normal rank of Gd = {pb.rank_d} = number of outputs {model.ny})")
    if rdim != "all" and rdim > k:
        raise DesignError(f"rdim = {rdim} residuals requested but the null space of [Gu Gd; I 0] has only "
                          f"{k} basis vectors (p - rank Gd)")
    freqs = None if freqs is None else np.atleast_1d(np.asarray(freqs, float))
    if freqs is not None and (np.any(freqs < 0) or not np.all(np.isfinite(freqs))):
        raise DesignError(f"freqs must be finite non-negative frequencies in rad/s, got {freqs.tolist()}")
    full = rdim == "all" or rdim >= k
    rows = [] if full or k == 1 or not minimal else _common_poles(simple_rows(pb, model.dt), model.dt)
    base = {"basis": "pencil", "decoupling_kind": EXACT, "left_minimal_indices": pb.degrees, "pencil": pb.info}
    gains = _pencil_gains(model, N, freqs, FDtol)
    if model.faults and not np.all(gains.max(axis=0) >= FDtol):
        raise undetectable_error(model, gains >= FDtol, gains=gains, FDtol=FDtol, numerical=NumericalDesignError)
    tried = []
    if rows:
        from itertools import combinations

        Ns = [r[0] for r in rows]
        seen = _pencil_gains(model, vstack(Ns), freqs, FDtol) >= FDtol
        # all k rows: the whole basis below, at no higher order — unless rows of one index share their poles
        shared = any(r[3] for r in rows)
        top = len(rows) if shared else min(len(rows), k - 1)

        def order(c):  # the McMillan degree of a combination: rows of one index with common poles count once
            return sum({rows[i][1] for i in c if rows[i][3]}) + sum(rows[i][1] for i in c if not rows[i][3])

        sets = sorted((c for size in range(int(rdim), top + 1) for c in combinations(range(len(rows)), size)),
                      key=lambda c: (order(c), len(c)))
        for c in sets:
            if model.faults and not np.all(seen[list(c)].max(axis=0)):
                continue  # some fault is seen by none of these rows: no combination of them sees it
            if len(tried) >= 6:
                break  # bounded search: the whole basis below
            sub = vstack([Ns[i] for i in c])
            try:
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
    """Simple rows of one index ν ≥ 1 with the same poles: ``[(N_i, ν_i, cond_i, shared_i)]``.

    Each row ``N_i`` (one output, McMillan degree ν, observable) is replaced by ``m_i N_i``, ``m_i`` the
    scalar stable biproper left factor of the output injection that places all its poles at those of
    the first row of its index (:func:`..toolkit.pencil._place` on the dual pair) — again a null-space row
    seeing the same faults. Rows with one denominator ``p(λ)`` combine as ``(Σ h_i n_i)/p``: McMillan
    degree ν, not Σ ν (the least order of a constant combination, as the polynomial basis has it). A row
    whose placement fails or needs a gain above ``COVER_COND`` keeps its poles (``shared_i`` False).
    """
    from ..toolkit.pencil import COVER_COND, _place

    out = [(N, nu, cond, False) for N, nu, cond in rows]
    for nu in sorted({r[1] for r in rows if r[1] >= 1}):
        group = [i for i, r in enumerate(rows) if r[1] == nu]
        if len(group) < 2:
            continue
        target = rows[group[0]][0].poles()
        placed = []
        for i in group:
            N, _, cond = rows[i]
            try:
                F = _place(N.A.T, N.C.T, target)
            except (DesignError, ValueError, np.linalg.LinAlgError):
                continue
            g = float(np.linalg.norm(F, 2))
            if g > COVER_COND:
                continue
            Nm = LTI(N.A + F.T @ N.C, N.B + F.T @ N.D, N.C, N.D, dt)
            placed.append((i, Nm, max(cond, g)))
        if len(placed) >= 2:
            for i, Nm, cond in placed:
                out[i] = (Nm, nu, cond, True)
    return out


def _pencil_gains(model, N: LTI, freqs, FDtol) -> np.ndarray:
    """Per row of ``N``, the relative gain (post-condition cosine) to every fault on the design grid."""
    Ge = model.augmented()
    lam = _points(model, _grid(model, N.poles(), freqs))
    Gv, Nv = _values(Ge, lam), _values(N, lam)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Nv), axis=(1, 2))
    Gv, Nv = Gv[ok], Nv[ok]
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
    lam = _points(model, _grid(model, N.poles(), freqs))
    Gv, Nv = _values(Ge, lam), _values(N, lam)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Nv), axis=(1, 2))
    Gv, Nv = Gv[ok], Nv[ok]
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
        raise DesignError(
            f"no residual generator exists for model '{model.name}': the unknown inputs d span every "
            f"output direction (normal rank of Gd = {basis.rank_d} = number of outputs {model.ny})"
        )
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

    freqs = None if freqs is None else np.atleast_1d(np.asarray(freqs, float))
    if freqs is not None and (np.any(freqs < 0) or not np.all(np.isfinite(freqs))):
        raise DesignError(f"freqs must be finite non-negative frequencies in rad/s, got {freqs.tolist()}")
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
    boundary) but not :data:`REFINE_MAX_LEAK` of it, and the correction is small enough to compute (≤ 2000 numerator coefficients)."""
    from ..toolkit.refine import boundary_residues, refine_decoupling

    ud, fsl = slice(0, model.nu + model.nd), model.group_slices()["f"]
    if not (ud.stop and model.faults) or (Q.n + Q.p) * Q.m > 2000:
        return Q
    Qv = _values(Q, lam)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))
    if model.n:  # beside a plant pole (an integrator at ω = 0) Ge's values are rounding-dominated
        ok &= ~near_poles(lam, np.linalg.eigvals(model.A), 1e-6)
    R = np.einsum("kiq,kqc->kic", Qv[ok], Gv[ok])
    weakest = min(np.max(np.linalg.norm(R[:, :, fsl][:, :, c], 2, axis=(1, 2))) for c in
                  [np.arange(model.nf)[f.columns] for f in model.faults])
    leak = np.max(np.linalg.norm(R[:, :, ud], 2, axis=(1, 2)), initial=0.0)
    if leak <= 1e-9 * weakest or leak > REFINE_MAX_LEAK * weakest:
        return Q
    return refine_decoupling(Q, lam[ok], Gv[ok][:, :, ud], boundary_residues(model))[0]


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
        Q = _refined(model, Q, lam, Gv)
        Rv = np.einsum("kiq,kqc->kic", _values(Q, lam), Gv[:, :, fsl])
        ok = np.all(np.isfinite(Rv), axis=(1, 2))
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
    normalized = False
    fac = coouter_inverse(Rw1) if Rw1.n else None
    if fac is not None and not _clear_of_boundary(fac[0].poles(), model.dt, (place or {}).get("smarg")):
        # Rw1 has a zero on or next to the stability boundary (Varga's non-standard case): its inverse
        # would put a near-integrator into the filter (a pole at -5e-9, random seeds 22, 28); the
        # filter poles set the frequency weighting instead
        fac = None
    if fac is not None:
        Q1 = (fac[0] @ Q1).minreal()
        normalized = True
    Qc = vstack([Q1] + ([Q2] if Q2 is not None else []))
    grid = frequency_grid([Qc, model.lti()], num=200)
    lam_g = _points(model, grid)
    Qv, Gv = _values(Qc, lam_g), _values(Ge, lam_g)
    finite = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))  # plant poles on the axis
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
        fsc = sensitivity_objective(Rf)

        def constrained(h):
            g = objective(h)
            return fsc(h) if g >= best * (1 - 1e-9) else g / best - 1.0

        h, _ = maximize_on_sphere(constrained, Qc.p, seed, extra_starts=[H[0]])
        H = h[None, :]
    Q = (H @ Qc).minreal() if H.shape[0] < Qc.p else Qc
    info = {"order": int(Q.n), "rdim": int(H.shape[0]), "gap_estimate": min(objective(h) for h in H),
            "noise": "co-outer normalised" if normalized else "weighted by the filter poles",
            "combination": H.tolist()}
    if moved:
        info["internal_form"] = moved
    return _finish(model, Q, basis, "nullspace", info, degrees, place=place)


#: a co-outer inverse pole within this relative distance of the stability boundary counts as on it
BOUNDARY_RTOL = 1e-6


def _clear_of_boundary(poles: np.ndarray, dt: float, smarg: float | None) -> bool:
    """Every pole inside the margin (``smarg``, default just inside the boundary) and at least
    :data:`BOUNDARY_RTOL` (relative to its modulus, at least 1) away from the boundary itself."""
    from ...margin import default_smarg

    poles = np.asarray(poles, complex)
    margin = default_smarg(dt) if smarg is None else float(smarg)
    if dt:
        return bool(np.all(np.abs(poles) <= min(margin, 1.0 - BOUNDARY_RTOL)))
    return bool(np.all(poles.real <= np.minimum(margin, -BOUNDARY_RTOL * np.maximum(1.0, np.abs(poles)))))


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
    A) combined by :func:`_noise_combination`."""
    from types import SimpleNamespace

    from ..toolkit.pencil import pencil_basis

    exact_w = model.with_disturbances(noise=True)
    try:
        gen = _pencil(exact_w, rdim, poles, sdeg, None, FDtol, FDGainTol, seed, smarg, dec_tol, tol, atol, minimal,
                      place)
    except DesignError:
        gen = None
    if gen is not None:
        gen = ResidualGenerator(gen.Q, model, "nullspace", info=gen.info)
        gen.info.update({"gap_estimate": float("inf"), "noise": "decoupled exactly"})
        return gen
    pb = pencil_basis(model, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
    if pb.N.p == 0:
        raise DesignError(
            f"no residual generator exists for model '{model.name}': the unknown inputs d span every "
            f"output direction (normal rank of Gd = {pb.rank_d} = number of outputs {model.ny})")
    try:
        pb2 = pencil_basis(exact_w, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
        Q2 = pb2.N if pb2.N.p else None
    except DesignError:
        Q2 = None
    gains = _pencil_gains(model, pb.N, None, FDtol)
    if model.faults and not np.all(gains.max(axis=0) >= FDtol):
        raise undetectable_error(model, gains >= FDtol, gains=gains, FDtol=FDtol, numerical=NumericalDesignError)
    gen = _noise_combination(model, pb.N, Q2, SimpleNamespace(rho=1.0, dt=model.dt), pb.degrees, rdim, seed, place)
    gen.info.update({"left_minimal_indices": pb.degrees, "pencil": pb.info})
    return gen
