"""Exact model detection (EMDP) for multiplicative faults: one filter per model of a set.

A multiple-model set ``{(Gu_j, Gd_j)}`` (e.g. the plant with each loss-of-effectiveness
pattern) is monitored by a bank: filter i decouples model i exactly and responds to every
other model,

    Q_i [Gu_i Gd_i; I 0] = 0,      R_ij = Q_i [Gu_j; I] ≠ 0  (j ≠ i),

so the residual of the true model's filter is the one that stays at zero (Varga 2017,
sec. 6.2, Procedure EMD; FaultDetectionTools.jl ``emdsyn``). Filter i is the least-order
detector of :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` on model i with one fault
channel per other model, ``f_j ↦ (Gu_j − Gu_i) f_j`` (the u-response filter i sees when
model j is true), appended as extra states. The distance-mapping performance is the
matrix ``MDperf[i, j] = ||R_ij||∞`` (zero diagonal), each row scaled to a largest entry 1.

Approximate model detection (AMDP; Varga 2017, sec. 6.3, Procedure AMD; FaultDetectionTools.jl
``amdsyn``). With noise inputs w_i in model i the filter still decouples u and d of model i
exactly, and among those filters maximises the noise gap

    gap_i = β_i / γ_i,    β_i = min_{j≠i} ||R_ij^u||,    γ_i = ||R_ii^w||∞,

where ``R_ij^u = Q_i [Gu_j; I]`` is the distance mapping (``Q_i [Gu_j - Gu_i; 0]``) and
``R_ii^w = Q_i [Gw_i; 0]`` the residual's noise response when model i is true. Step 1 is the
left null space ``Q1`` of ``[Gu_i Gd_i; I 0]``; step 2 the co-outer–co-inner factorisation
``Q1 [Gw_i; 0] = Ro Ri`` and ``Q_i = Ro^{-1} Q1`` (:mod:`..toolkit.approximate`), after which every
``h Q_i`` has ``||h R_ii^w||∞ = |h|``. Keeping all rows (``rdim='all'``) is then optimal: for any
other admissible filter ``Q4 Q_i``, ``||Q4 X||∞ ≤ ||Q4||∞ ||X||∞ = ||Q4 Ri||∞ ||X||∞``, so no filter
has a larger gap (when ``Q1 [Gw_i; 0]`` has zeros at infinity or on the stability boundary the
factor does not exist; the normaliser of the peer's ``nonstd`` choice is tried, see :func:`_full_order`). With ``rdim = 1``
the gap-maximising combination of the normalised rows is
chosen on a grid, as in Procedure AFD (:func:`~fmu_fdi.design.problems.nullspace.nullspace_design`).
Each filter is finally scaled so that ``β_i = 1`` (``amdsyn``'s default): the rows of
``MDperf`` have a zero diagonal and off-diagonal minimum 1, and ``γ_i = 1 / gap_i``.

The evaluation functions follow FaultDetectionTools.jl: :func:`distance_mapping`
(``mdperf``: H∞, H2, or the peak over given frequencies), :func:`noise_gaps` (``mdgap``) and
:func:`match_model` (``mdmatch``: the filter with the smallest distance names the model).
Model detection picks the model whose filter's residual is smallest.

References: A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, ch. 6 (EMDP, AMDP,
Examples 6.1 and 6.2); A. Varga, Least order fault and model detection using multi-models,
IEEE CDC 2009.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ...errors import DesignError
from ...faults import component_fault
from ...generator import ResidualBank, ResidualGenerator
from ...linalg import single_blas_thread
from ...lti import LTI
from ...model import FDIModel
from .nullspace import nullspace_design
from ..toolkit._basis import strong_frequencies
from ..toolkit.postconditions import DEC_TOL, check_generator
from ..toolkit.approximate import with_nonstandard_options
from ..toolkit.notes import keeps_notes


def _with_model_faults(models: Sequence[FDIModel], i: int, atol: float = 0.0) -> FDIModel:
    base = models[i]
    n0 = base.n
    blocks_A, blocks_B, blocks_C, faults = [base.A], [], [base.C], []
    k = n0
    for j, mj in enumerate(models):
        if j == i:
            continue
        diff = LTI(np.block([[base.A, np.zeros((n0, mj.n))], [np.zeros((mj.n, n0)), mj.A]]),
                   np.vstack([-base.Bu, mj.Bu]), np.hstack([base.C, mj.C]), mj.Du - base.Du,
                   base.dt).minreal(atol)
        blocks_A.append(diff.A)
        blocks_C.append(diff.C)
        blocks_B.append((k, diff))
        k += diff.n
    import scipy.linalg as sla

    A = sla.block_diag(*blocks_A)
    C = np.hstack(blocks_C)
    j_names = [mj.name for j, mj in enumerate(models) if j != i]
    for (start, diff), nm in zip(blocks_B, j_names):
        Bf = np.zeros((k, base.nu))
        Bf[start:start + diff.n] = diff.B
        faults.append(component_fault(f"model_{nm}", Bf, diff.D))
    pad = lambda B: np.vstack([B, np.zeros((k - n0, B.shape[1]))])  # noqa: E731
    return FDIModel(A, pad(base.Bu), C, base.Du, Bd=pad(base.Bd), Dd=base.Dd, faults=faults, dt=base.dt,
                    u_names=base.u_names, y_names=base.y_names, d_names=base.d_names, name=f"{base.name}_md")


@keeps_notes
@single_blas_thread
def model_detection_bank(models: Sequence[FDIModel], *, poles=None, sdeg=None, FDtol: float = 1e-4,
                         atol: float = 0.0, rdim=1, HDesign=None, **kwargs) -> ResidualBank:
    """A bank of least-order filters, filter i exact for model i and sensitive to all others.

    Parameters
    ----------
    models : sequence of FDIModel
        The model set: same outputs, known inputs and sample time, each stable (the distances
        are H∞ norms); unknown inputs d of each model are decoupled by its own filter; faults
        and noise of the models are ignored.
    poles, sdeg, FDtol, **kwargs
        Passed to :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` for each filter.
    atol : float
        Absolute rank tolerance (Varga's ``atol``): passed to ``nullspace_design`` and to the
        minimal realisations of the model differences ``Gu_j − Gu_i``.
    rdim, HDesign
        Per filter (FaultDetectionTools.jl ``emdsyn``): the number of residuals of filter i (an int for
        all, or a list with one per model; at most ``p − rank Gd_i``) and its design matrix (a list with
        one matrix or None per model), as ``rdim``/``HDesign`` of ``nullspace_design``.

    Returns
    -------
    ResidualBank
        Designed against ``models[0]``. Each filter is normalised as ``emdsyn`` does by default
        (the normalised internal form: its smallest required "fault" gain — the distance to
        the nearest other model — is 1): ``Q_i ← Q_i / β_i``, ``β_i = min_{j≠i} ||R_ij||∞``.
        ``info['MDperf']``: the distance mapping ``||Q_i [Gu_j; I]||∞`` of the returned
        filters (zero diagonal, off-diagonal row minimum 1); ``info['MDperf_abs']`` the same
        before the normalisation (filters as designed); ``info['beta']`` the β_i divided out;
        ``info['models']`` the names.

    Raises
    ------
    DesignError
        Fewer than two models, models that do not form a set (outputs, inputs, sample time,
        unique names), an unstable model, a model no filter exact for another can see (the rank
        condition, with numbers), or a filter that cannot be designed.
    """
    if not (np.isfinite(atol) and atol >= 0):
        raise DesignError(f"atol must be a finite non-negative number, got {atol!r}")
    models = _check_set(models)
    _check_distinguishable(models, rtol=np.sqrt(np.finfo(float).eps))
    bare = [mj._replace(faults=[], Bw=np.zeros((mj.n, 0)), Dw=np.zeros((mj.ny, 0)), w_names=[]) for mj in models]
    umaps = [_u_map(mj) for mj in bare]
    from .row_options import per_row

    rdims, Hs = per_row(rdim, len(bare), "rdim"), per_row(HDesign, len(bare), "HDesign")
    members, perf_abs, betas = [], [], []
    for i in range(len(bare)):
        mi = _with_model_faults(bare, i, atol)
        try:
            g = nullspace_design(mi, rdim=rdims[i], HDesign=Hs[i], poles=poles, sdeg=sdeg, FDtol=FDtol, atol=atol,
                                 **kwargs)
        except DesignError as exc:
            msg = str(exc).replace("fault 'model_", "model '")  # the fault channels stand for the other models
            raise type(exc)(f"filter {i + 1} (model '{models[i].name}'): {msg}") from None
        row = np.array([_gain(g.Q @ Gj) for Gj in umaps])
        beta = float(np.min(np.delete(row, i)))
        if not (np.isfinite(beta) and beta > 0):
            raise DesignError(f"filter {i + 1} (model '{models[i].name}'): the nearest other model has distance "
                              f"β = {beta:.3g}: it cannot be told apart")
        info = dict(g.info, scale=1.0 / beta)
        members.append(ResidualGenerator(g.Q * (1.0 / beta), bare[0], "model_detection", info=info))
        perf_abs.append(row)
        betas.append(beta)
    perf_abs = np.array(perf_abs)
    perf = perf_abs / np.array(betas)[:, None]  # ||(Q_i / β_i) G_j|| = ||Q_i G_j|| / β_i
    return ResidualBank(members, "model_detection", info={"MDperf": perf.tolist(), "MDperf_abs": perf_abs.tolist(),
                                                            "beta": betas, "models": [mj.name for mj in models]})


def nu_gap_siso(G1: LTI, G2: LTI, omega) -> float:
    """Chordal distance ``sup_ω |G1 − G2| / sqrt((1 + |G1|²)(1 + |G2|²))`` on a grid: the ν-gap of
    two SISO systems when Vinnicombe's winding-number condition holds (e.g. both stable and
    minimum phase), the model distance ``mddist`` of FaultDetectionTools.jl."""
    a, b = G1.freqresp(omega)[:, 0, 0], G2.freqresp(omega)[:, 0, 0]
    return float(np.max(np.abs(a - b) / np.sqrt((1 + np.abs(a) ** 2) * (1 + np.abs(b) ** 2))))


# --------------------------------------------------------------------------------------------
# approximate model detection (AMDP) and the evaluation of model detection filters

def _check_set(models: Sequence[FDIModel]) -> list[FDIModel]:
    """Same outputs, known inputs and sample time; stable (the distances are H∞ norms)."""
    models = list(models)
    if len(models) < 2:
        raise DesignError(f"model detection needs at least two models, got {len(models)}")
    m0 = models[0]
    for mj in models:
        if (mj.ny, mj.nu) != (m0.ny, m0.nu) or abs(mj.dt - m0.dt) > 1e-12 * max(1.0, m0.dt):
            raise DesignError(f"model '{mj.name}' has {mj.ny} outputs, {mj.nu} known inputs and dt = {mj.dt:g}; "
                              f"model '{m0.name}' has {m0.ny}, {m0.nu} and dt = {m0.dt:g}: a model set must agree")
        if not mj.lti().is_stable():
            poles = np.linalg.eigvals(mj.A)
            worst = float(np.max(np.abs(poles))) if mj.dt else float(np.max(poles.real))
            what = "largest |pole|" if mj.dt else "largest Re(pole)"
            raise DesignError(f"model '{mj.name}' is not stable ({what} = {worst:.6g}): the distance mapping "
                              f"||Q_i [Gu_j; I]|| of an unstable model is unbounded; stabilise the plant "
                              f"(e.g. FDIModel.feedback) and detect the closed-loop models")
    names = [mj.name for mj in models]
    if len(set(names)) != len(names):
        raise DesignError(f"model names must be unique (they name the filters and faults), got {names}")
    return models


def _probe_points(models: Sequence[FDIModel], count: int = 3, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if models[0].dt:
        return np.exp(1j * rng.uniform(0.3, 2.8, count)) * rng.uniform(1.1, 1.5, count)
    eig = [np.abs(np.linalg.eigvals(mj.A)) for mj in models if mj.n]
    scale = max(1.0, max((float(e.max()) for e in eig), default=1.0))
    return scale * (rng.uniform(0.5, 2.0, count) + 1j * rng.uniform(0.5, 2.0, count))


def _check_distinguishable(models: list[FDIModel], rtol: float) -> None:
    """Model j is detectable by a filter exact for model i iff ``rank [Gd_i Gu_j - Gu_i] > rank Gd_i``
    (normal ranks; Varga 2017, sec. 6.2): the u-difference must leave the directions of d_i."""
    lam = _probe_points(models)
    vals = [[(mj.lti("u").evalfr(l), mj.lti("d").evalfr(l)) for l in lam] for mj in models]
    bad = []
    for i, mi in enumerate(models):
        for j, mj in enumerate(models):
            if i == j:
                continue
            size, rd = 0.0, 0
            for k in range(lam.size):
                Gu_i, Gd_i = vals[i][k]
                Gu_j = vals[j][k][0]
                scale = max(np.linalg.norm(Gu_i, 2), np.linalg.norm(Gu_j, 2), np.finfo(float).tiny)
                X = Gu_j - Gu_i
                if mi.nd:
                    U, s, _ = np.linalg.svd(Gd_i)
                    r = int(np.sum(s > max(Gd_i.shape) * np.finfo(float).eps * max(s[0], np.finfo(float).tiny)))
                    X = U[:, r:].conj().T @ X
                    rd = max(rd, r)
                size = max(size, float(np.linalg.norm(X, 2)) / scale if X.size else 0.0)
            if size <= rtol:
                bad.append(f"model '{mj.name}' cannot be told from model '{mi.name}' by a filter that decouples u and "
                           f"d of '{mi.name}': rank condition rank [Gd Gu_{mj.name} − Gu_{mi.name}] > rank Gd fails "
                           f"({rd} vs {rd}; the u-difference left after removing the directions of d is "
                           f"{size:.2e} × ||Gu|| ≤ {rtol:.0e})")
    if bad:
        raise DesignError("model detection is not feasible: " + "; ".join(bad)
                          + ". Remove duplicate models or merge the ones no filter can separate")


def _u_map(model: FDIModel) -> LTI:
    """``[Gu; I]``: from u to [y; u]."""
    return model.augmented()[:, np.arange(model.nu)]


def _w_map(model: FDIModel) -> LTI:
    """``[Gw; 0]``: from w to [y; u]."""
    sl = model.group_slices()["w"]
    return model.augmented()[:, np.arange(sl.start, sl.stop)]


def _filters(bank) -> list[LTI]:
    if isinstance(bank, ResidualGenerator):
        return [bank.Q[g, :] for g in bank.groups]
    return list(bank)


def _gain(R: LTI, freqs=None, norm: str = "inf") -> float:
    """``||R||∞``, ``||R||₂`` or ``max_{ω ∈ freqs} σ_max(R(jω))`` (``mdperf``'s three gains)."""
    if R.m == 0 or R.p == 0:
        return 0.0
    if freqs is not None:
        vals = R.freqresp(np.atleast_1d(np.asarray(freqs, float)))
        return float(np.max(np.linalg.norm(vals, ord=2, axis=(1, 2))))
    # no minimal realisation: the norms of a stable, non-minimal realisation are exact, and a
    # rank decision there would leave cancelled modes behind as ~1e-10 "distances"
    if norm == "2":
        with np.errstate(invalid="ignore"):
            h2 = float(R.h2norm())
        return 0.0 if np.isnan(h2) else h2  # a trace below zero by rounding: the norm of an exact zero
    return float(R.hinfnorm()[0])


def distance_mapping(bank, models: Sequence[FDIModel], *, freqs=None, norm: str = "inf") -> np.ndarray:
    """Distance-mapping performance ``MDperf[i, j] = ||Q_i [Gu_j; I]||`` (FaultDetectionTools.jl ``mdperf``).

    Parameters
    ----------
    bank : ResidualBank or sequence of LTI
        Filter i is residual group i of the bank (inputs ``[y; u]``).
    models : sequence of FDIModel
        The model set (column j: model j true).
    freqs : array_like, optional
        With frequencies (rad/s): the largest ``σ_max(R_ij(jω))`` over them instead of a norm.
    norm : {'inf', '2'}
        H∞ (default) or H2 norm (∞ for a continuous ``R_ij`` with feedthrough).

    Returns
    -------
    ndarray, shape (filters, models)
        Zero (to rounding) where filter i is exact for model j; model detection picks the
        filter with the smallest residual.
    """
    if norm not in ("inf", "2"):
        raise DesignError(f"norm must be 'inf' or '2', got {norm!r}")
    freqs = strong_frequencies(freqs)
    Qs = _filters(bank)
    maps = [_u_map(mj) for mj in models]
    return np.array([[_gain(Qi @ Gj, freqs, norm) for Gj in maps] for Qi in Qs])


def noise_gaps(bank, models: Sequence[FDIModel], *, freqs=None,
               dec_tol: float = DEC_TOL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise gaps of a model detection bank (FaultDetectionTools.jl ``mdgap``).

    ``gap_i = β_i / γ_i`` with ``β_i = min_{j≠i} ||Q_i [Gu_j; I]||∞`` (the peak over ``freqs`` if
    given) and ``γ_i = ||Q_i [Gw_i; 0]||∞``, the noise response of filter i when its own model
    is true (∞ gap when the noise is decoupled: γ_i within ``dec_tol·β_i`` or its rounding, :func:`_noise_gain`).

    Returns
    -------
    gap, beta, gamma : ndarray
    """
    Qs = _filters(bank)
    if len(Qs) != len(models):
        raise DesignError(f"noise gaps need one filter per model: {len(Qs)} filters, {len(models)} models")
    perf = distance_mapping(Qs, models, freqs=freqs)
    beta = np.array([min(perf[i, j] for j in range(len(models)) if j != i) for i in range(len(Qs))])
    gamma = np.array([_noise_gain(Qi, mi, b * dec_tol) for Qi, mi, b in zip(Qs, models, beta)])
    gap = np.where(gamma > 0, beta / np.where(gamma > 0, gamma, 1.0), np.inf)
    return gap, beta, gamma


def _noise_gain(Q: LTI, model: FDIModel, decoupled: float = 0.0) -> float:
    """``γ = ||Q [Gw; 0]||∞``, or 0 where w counts as decoupled: γ at most ``decoupled`` (the caller's
    ``dec_tol·β``: the normalised form's decoupling, where the post-conditions read a leak as none) or the
    rounding of an exact decoupling, 1e-9 of ``||Q_y||∞ ||Gw||∞`` (the backward-error scale of the product, as in
    :mod:`..toolkit.postconditions`). ``Q_y``: the columns of Q on the outputs y — ``[Gw; 0]`` has zero u rows, so
    the product is ``Q_y Gw`` and the u columns round nothing of it. (With ``||Q||∞`` of every column, a filter
    ``[q, −q Gu]`` whose known input has a large gain read its own noise response as rounding: approximate audit
    seed 243, γ = 1.985e-7 against 1e-9·||Q||∞·||Gw||∞ = 3.8e-7 with ||Q||∞ = 2 from −q Gu, ||q||∞ ≤ 1.2e-6 —
    an infinite gap where numpy reads 5.04e6; tests/test_audit_seeds18.py.)"""
    if not model.nw:
        return 0.0
    Gw = _w_map(model)
    gamma = _gain(Q @ Gw)
    Qy = Q[:, np.arange(model.ny)]
    return 0.0 if gamma <= max(decoupled, 1e-9 * _gain(Qy) * _gain(Gw)) else gamma


def match_model(bank, model: FDIModel, *, freqs=None) -> tuple[np.ndarray, int]:
    """Distances of one model to every filter of the bank and the index of the smallest
    (FaultDetectionTools.jl ``mdmatch``): ``gains[i] = ||Q_i [Gu Gd Gw; I 0 0]||∞``.
    The filter with the smallest gain is the one whose model matches best."""
    freqs = strong_frequencies(freqs)
    sl = model.group_slices()
    G = model.augmented()[:, np.arange(sl["u"].start, sl["w"].stop)]
    gains = np.array([_gain(Qi @ G, freqs) for Qi in _filters(bank)])
    return gains, int(np.argmin(gains))


def _full_order(mi: FDIModel, design_kw: dict, gap_of) -> tuple[LTI, dict]:
    """``Q_i = Ro^{-1} Q1`` with all rows of the (u, d) null-space basis ``Q1``: the optimal gap.

    When ``Rw = Q1 [Gw; 0]`` has full normal row rank but no invertible co-outer factor (zeros
    at infinity, i.e. a feedthrough without full row rank, or on the stability boundary), the
    normaliser of the peer's ``nonstd`` choice is used (:func:`..toolkit.approximate.noise_normalizer`;
    without ``nonstd``, 1 and then 2, as ``amdsyn``'s default): a chosen ``nonstd`` always, the
    default only if it gives a larger measured gap than ``Q1`` itself."""
    from ...linalg import rank
    from ..toolkit.approximate import active_options, coouter_inverse_or_static, noise_normalizer

    g = nullspace_design(mi, rdim="all", noise="ignore", **design_kw)
    Q1 = g.Q
    Rw = (Q1 @ _w_map(mi)).minreal()
    info = dict(g.info)
    Ro_inv = (coouter_inverse_or_static(Rw) or (None,))[0]
    if Ro_inv is not None:
        info["noise"] = "co-outer normalised (optimal gap)"
        return (Ro_inv @ Q1).minreal(), info
    lam = _probe_points([mi])
    rw = max(rank(Rw.evalfr(l)) for l in lam)
    if rw < Rw.p:
        info["noise"] = (f"weighted by the filter poles: Q1 [Gw; 0] has normal rank {rw} < {Rw.p} rows, so some "
                         f"combination decouples w exactly — rdim=1 finds it (gap ∞)")
        return Q1, info
    opts = active_options()
    chosen = opts is not None and opts.nonstd is not None  # the user's choice of the peer's nonstd
    Ro_inv, how = noise_normalizer(Rw, smarg=design_kw.get("smarg"), poles=design_kw.get("poles"),
                                   sdeg=design_kw.get("sdeg"))
    if Ro_inv is not None:
        Qr = (Ro_inv @ Q1).minreal()
        if chosen or gap_of(Qr) > gap_of(Q1):
            info["noise"] = how
            return Qr, info
        how = f"{how} — not kept: its gap is not larger than the basis' own"
    info["noise"] = ("weighted by the filter poles: Q1 [Gw; 0] has zeros at infinity or on the stability boundary "
                     f"(no invertible co-outer factor; {how})")
    return Q1, info


@keeps_notes
@with_nonstandard_options
@single_blas_thread
def approximate_model_detection_bank(models: Sequence[FDIModel], *, rdim: int | str = 1, poles=None, sdeg=None,
                                     freqs=None, FDtol: float = 1e-4, FDGainTol: float = 0.01,
                                     tol: float | None = None, atol: float = 0.0, seed: int = 0,
                                     smarg: float | None = None, dec_tol: float = DEC_TOL, nonstd: int | None = None,
                                     epsreg: float = 0.1, sdegzer: float | None = None) -> ResidualBank:
    """Approximate model detection (AMDP): filter i exact for u and d of model i, noise gap maximised.

    Solves Varga's AMDP (Procedure AMD; FaultDetectionTools.jl ``amdsyn``) for a set of models
    with noise inputs w (see the module docstring for the equations). Models without noise
    get the exact filter (gap ∞), so this also solves the EMDP.

    Parameters
    ----------
    models : sequence of FDIModel
        The model set: the same outputs, known inputs and sample time, each stable. Unknown
        inputs d of model i are decoupled by filter i, its noise w is attenuated; faults of
        the models are ignored.
    rdim : int or 'all'
        Residual outputs per filter. 'all' (``amdsyn``'s ``minimal = false``): the whole
        co-outer normalised null-space basis, which attains the largest gap of any filter;
        an integer: that many gap-maximising combinations of its rows (a smaller filter).
    poles, sdeg : optional
        Poles of the null-space rows (as in :func:`~fmu_fdi.design.problems.nullspace.nullspace_design`).
    freqs : array_like, optional
        Frequencies (rad/s; ``amdsyn``'s ``MDfreq``) at which every other model must be strongly
        visible; the distances β and ``MDperf`` are then the peaks over these frequencies.
    FDtol, FDGainTol : float
        Weak and strong model detectability thresholds (``MDtol``, ``MDGainTol``).
    tol, atol, seed, smarg, dec_tol
        Rank tolerances, combination search seed, stability margin and the largest relative
        leakage of u and d allowed (:mod:`..toolkit.postconditions`).
    nonstd, epsreg, sdegzer
        ``amdsyn``'s choice for a noise response without an invertible co-outer factor
        (:func:`..toolkit.approximate.noise_normalizer`). Default (None): the regularised factor of
        ``[Rw  1e-3·||Rw||∞·I]`` when it improves the measured gap, else the filter poles weight the noise.

    Returns
    -------
    ResidualBank
        Member i (residual group i) is filter i, scaled so that ``β_i = 1``, attached to
        ``models[i]`` with the other models' differences ``Gu_j − Gu_i`` as its faults
        ``model_<name>`` (its internal form: ``Ru = Rd = 0``, ``Rw`` the noise response, ``Rf``
        the distances): ``member.info['postconditions']`` is judged on that object, so its
        ``leakage``/``structure_matrix`` are what :func:`~fmu_fdi.analysis.leakage` and
        :func:`~fmu_fdi.analysis.structure_matrix` report for the member.
        ``info``: ``MDperf`` (distance mapping of the returned filters, H∞ or at ``freqs``),
        ``MDperf_h2``, ``MDgap``, ``beta``, ``gamma``, ``models``, ``noise`` (how each filter
        treats w), ``postconditions`` (figures of every filter, ``per_filter``: decoupling of u and
        d of its model, visibility of every other model, pole margin; ``leakage`` the largest
        ``leakage(member)``, ``structure_matrix`` each member's).

    Raises
    ------
    DesignError
        A model that no filter exact for another model can see (the rank condition, with
        numbers), models that do not form a set, an unstable model, or a filter that fails
        its post-conditions.

    References
    ----------
    A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, sec. 6.3 and Example 6.2.
    """
    models = _check_set(models)
    if not (rdim == "all" or (isinstance(rdim, (int, np.integer)) and not isinstance(rdim, bool) and rdim >= 1)):
        raise DesignError(f"rdim must be a positive integer or 'all', got {rdim!r}")
    freqs = strong_frequencies(freqs)
    _check_distinguishable(models, rtol=np.sqrt(np.finfo(float).eps))
    stripped = [mj._replace(faults=[]) for mj in models]
    bare = [mj._replace(Bw=np.zeros((mj.n, 0)), Dw=np.zeros((mj.ny, 0)), w_names=[]) for mj in stripped]
    design_kw = dict(poles=poles, sdeg=sdeg, FDtol=FDtol, FDGainTol=FDGainTol, tol=tol, atol=atol, seed=seed,
                     smarg=smarg, dec_tol=dec_tol, nonstd=nonstd, epsreg=epsreg, sdegzer=sdegzer)
    umaps = [_u_map(mj) for mj in models]
    members, figures, rows, gammas = [], [], [], []
    for i, mi in enumerate(stripped):
        md = _with_model_faults(bare, i)
        pad = np.zeros((md.n - mi.n, mi.nw))
        md = md._replace(Bw=np.vstack([mi.Bw, pad]), Dw=mi.Dw, w_names=mi.w_names)
        try:
            if not mi.nw:
                g = nullspace_design(md, rdim=rdim, noise="ignore", freqs=freqs, **design_kw)
                Q, info = g.Q, dict(g.info, noise="no noise inputs")
            elif rdim == "all":
                def gap_of(Qc, i=i, mi=mi):
                    return min(_gain(Qc @ Gj, freqs) for j, Gj in enumerate(umaps) if j != i) / max(
                        _gain(Qc @ _w_map(mi)), np.finfo(float).tiny)

                Q, info = _full_order(md, design_kw, gap_of)
            else:
                g = nullspace_design(md, rdim=rdim, noise="optimize", **design_kw)
                Q, info = g.Q, dict(g.info)
            row = distance_mapping([Q], models, freqs=freqs)[0]
            beta = float(np.min(np.delete(row, i)))
            if not beta > 0:
                raise DesignError(f"every other model has zero distance to filter {i + 1} (β = {beta:.3g})")
            Q = Q * (1.0 / beta)
            exact_w = info.get("noise") in ("decoupled exactly", "no noise inputs")
            info.pop("postconditions", None)
            info["scale"] = 1.0 / beta
            # the member itself is judged, attached to the model it is read against (model i with the other
            # models as faults); its rows keep the β scaling (normalize=False), so the figures stored are
            # what leakage(member) and structure_matrix(member) report
            member = ResidualGenerator(Q, md, "approximate_model_detection", info=info)
            fig = check_generator(member, normalize=False,
                                  decouple=("u", "d", "w") if exact_w and mi.nw else ("u", "d"), block=True,
                                  freqs=freqs, FDtol=FDtol, FDGainTol=FDGainTol, smarg=smarg, dec_tol=dec_tol,
                                  hints={"visibility": "another model is (nearly) indistinguishable from this one "
                                                       "once u and d are decoupled: merge the two models, or lower "
                                                       "FDtol if the difference really is this small"})
        except DesignError as exc:
            msg = str(exc).replace("fault 'model_", "model '")  # the fault channels stand for the other models
            raise type(exc)(f"filter {i + 1} (model '{mi.name}'): {msg}") from None
        member.info["postconditions"] = fig
        rows.append(row / beta)
        gammas.append(_noise_gain(Q, mi, dec_tol))  # (β = 1: Q is scaled by 1/β above)
        members.append(member)
        figures.append(fig)
    bank = ResidualBank(members, "approximate_model_detection", info={"models": [mj.name for mj in models]})
    # the rows measured for the scaling, divided by their off-diagonal minimum β_i: that minimum
    # is now exactly 1 (β_i / β_i), so gap_i = 1 / γ_i
    perf, gamma = np.array(rows), np.array(gammas)
    beta = np.ones(len(perf))
    gap = np.where(gamma > 0, beta / np.where(gamma > 0, gamma, 1.0), np.inf)
    bank.info.update({
        "MDperf": perf.tolist(), "MDperf_h2": distance_mapping(bank, models, norm="2").tolist(),
        "MDgap": gap.tolist(), "beta": beta.tolist(), "gamma": gamma.tolist(),
        "noise": [m.info["noise"] for m in members], "orders": [int(m.Q.n) for m in members],
        "freqs": None if freqs is None else freqs.tolist(),
        "postconditions": {
            "decoupling": max(f["decoupling"] for f in figures),
            "leakage": max(f["leakage"] for f in figures),
            "structure_matrix": [f["structure_matrix"] for f in figures],
            "model_visibility": min(f["fault_visibility"] for f in figures),
            "pole_extreme": max((f.get("pole_extreme", -np.inf) for f in figures)),
            "dec_tol": dec_tol, "FDtol": FDtol, "per_filter": figures}})
    if freqs is not None:
        bank.info["MDperf_hinf"] = distance_mapping(bank, models).tolist()
    return bank
