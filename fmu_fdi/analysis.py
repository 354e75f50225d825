"""Analysis of models and residual generators: structure, sensitivity, gaps, leakage.

Definitions (Varga 2017, ch. 3 and 5; acceptance.md):

- weak structure matrix: ``S[i, j] = 1`` when the block of ``Rf`` from fault j to
  residual group i is not identically zero;
- strong structure matrix at frequencies Ω: ``S[i, j] = 1`` when ``|Rf_ij(jω)| > tol``
  for every ω in Ω (block 2-norm);
- H∞− index: ``min_j ||Rf_j||∞`` over the fault column blocks;
- fault sensitivity condition: H∞− index over ``max_j ||Rf_j||∞`` (1 is ideal);
- fault-to-noise gap: H∞− index over ``||[Rd Rw]||∞``; per row of a structure matrix S,
  the faults with ``S[i, j] = 0`` count as noise of row i (Varga's ``fdif2ngap``);
- leakage: ``max(||Ru||∞, ||Rd||∞)`` — zero for an exact design.

Any function taking a generator also takes a :class:`~fmu_fdi.model.FDIModel` (then Gf,
the plant's own fault response, is analysed) or an :class:`~fmu_fdi.lti.LTI` /
python-control system (each column a fault, each row a residual).
"""
from __future__ import annotations

import numpy as np

from .design.toolkit._basis import normal_rank, sample_values, sampled_rank
from .errors import DesignError
from .generator import ResidualGenerator
from .linalg import single_blas_thread
from .lti import LTI, frequency_grid
from .model import FDIModel

DEFAULT_GAIN_TOL = 0.01  # Varga's FDGainTol: absolute gain for strong structure


def _fault_system(obj) -> tuple[LTI, list[list[int]], list[np.ndarray], list[str]]:
    """(Rf, residual groups, fault column blocks, fault names) of any analysable object."""
    if isinstance(obj, ResidualGenerator):
        Rf = obj.Rf
        m = obj.model
        return Rf, obj.groups, [np.arange(m.nf)[f.columns] for f in m.faults], m.fault_names
    if isinstance(obj, FDIModel):
        Gf = obj.lti("f")
        return Gf, [[i] for i in range(obj.ny)], [np.arange(obj.nf)[f.columns] for f in obj.faults], obj.fault_names
    if hasattr(obj, "runtime_spec"):
        raise TypeError(f"{type(obj).__name__} is not an LTI residual generator: it has no internal form to analyse")
    sys = obj if isinstance(obj, LTI) else LTI.from_control(obj)
    return sys, [[i] for i in range(sys.p)], [np.array([j]) for j in range(sys.m)], [f"f{j + 1}" for j in range(sys.m)]


def _block_norms(Rf: LTI, groups, blocks) -> np.ndarray:
    out = np.zeros((len(groups), len(blocks)))
    for i, g in enumerate(groups):
        for j, cols in enumerate(blocks):
            out[i, j] = Rf[g, cols].minreal().hinfnorm()[0]
    return out


def fault_gains(obj, freqs, block: bool = False) -> np.ndarray:
    """Gains ``||Rf_ij(jω)||_2`` of every (residual group, fault) block: shape (len(freqs), groups, faults).

    ``freqs`` in rad/s (``inf`` allowed in continuous time); ``block=True`` treats all
    residuals as one group (the norm over all outputs).
    """
    Rf, groups, blocks, _ = _fault_system(obj)
    if block:
        groups = [list(range(Rf.p))]
    H = Rf.freqresp(np.atleast_1d(np.asarray(freqs, float)))
    out = np.zeros((H.shape[0], len(groups), len(blocks)))
    for i, g in enumerate(groups):
        for j, cols in enumerate(blocks):
            out[:, i, j] = np.linalg.norm(H[:, g][:, :, cols].reshape(H.shape[0], -1), axis=1)
    return out


def structure_matrix(obj, freqs=None, tol: float | None = None, block: bool = False) -> np.ndarray:
    """Weak (``freqs=None``) or strong (at every frequency in ``freqs``) structure matrix.

    Parameters
    ----------
    obj : ResidualGenerator, FDIModel, LTI or python-control system
    freqs : float or array_like, optional
        Frequencies Ω (rad/s) for the strong structure matrix.
    tol : float, optional
        Strong: absolute gain threshold, ``S_ij = 1`` when ``||Rf_ij(jω)|| ≥ tol`` at every ω
        (default 0.01, Varga's ``FDGainTol``, inclusive as ``fdisspec``). Weak: for a
        residual generator, the judge's absolute threshold on the peak ``max_λ ||Rf_ij(λ)||``
        over its grid (default :data:`~fmu_fdi.design.toolkit.postconditions.DEC_TOL`; the designs
        return rows normalised to unit weakest fault gain, so this is the decoupling tolerance
        of their post-conditions and ``structure_matrix(gen)`` is
        ``gen.info['postconditions']['structure_matrix']``); for a model or an LTI system, an
        absolute H∞-norm threshold (default ``1e-9`` times the largest block norm).
    block : bool
        Treat all residual outputs as one group.
    """
    if isinstance(obj, ResidualGenerator):
        from .design.toolkit.postconditions import DEC_TOL, report

        groups = [list(range(obj.Q.p))] if block else None
        if freqs is None:
            out = report(obj, dec_tol=DEC_TOL if tol is None else tol, groups=groups)
            return np.array(out["structure_matrix"], dtype=int).reshape(len(groups or obj.groups), -1)
        out = report(obj, freqs=np.atleast_1d(np.asarray(freqs, float)),
                     FDGainTol=DEFAULT_GAIN_TOL if tol is None else tol, groups=groups)
        return np.array(out["strong_structure_matrix"], dtype=int).reshape(len(groups or obj.groups), -1)
    Rf, groups, blocks, _ = _fault_system(obj)
    if block:
        groups = [list(range(Rf.p))]
    if freqs is None:
        norms = _block_norms(Rf, groups, blocks)
        thr = tol if tol is not None else 1e-9 * max(norms.max(initial=0.0), np.finfo(float).tiny)
        return (norms > thr).astype(int)
    gains = fault_gains(obj, freqs, block)
    thr = DEFAULT_GAIN_TOL if tol is None else tol
    return np.all(gains >= thr, axis=0).astype(int)


def _column_norms(obj, freqs=None, faults=None) -> np.ndarray:
    Rf, _, blocks, names = _fault_system(obj)
    if faults is not None:
        blocks = [b for b, nm in zip(blocks, names) if nm in set(faults)]
    if freqs is None:
        return np.array([Rf[:, cols].minreal().hinfnorm()[0] for cols in blocks])
    H = Rf.freqresp(np.atleast_1d(np.asarray(freqs, float)))
    return np.array([np.max(np.linalg.norm(H[:, :, cols].reshape(H.shape[0], -1), axis=1)) for cols in blocks])


def hinf_minus(obj, freqs=None, faults=None) -> float:
    """H∞− index: ``min_j ||Rf_j||∞`` (over the frequencies ``freqs`` when given)."""
    norms = _column_norms(obj, freqs, faults)
    return float(norms.min()) if norms.size else 0.0


def fault_sensitivity_condition(obj, freqs=None) -> float:
    """``min_j ||Rf_j|| / max_j ||Rf_j||`` (H∞ norms, or peak gains over ``freqs``)."""
    norms = _column_norms(obj, freqs)
    if not norms.size or norms.max() == 0:
        return 0.0
    return float(norms.min() / norms.max())


def fault_noise_gap(gen: ResidualGenerator, S=None, atol: float = np.sqrt(np.finfo(float).eps)):
    """Fault-to-noise gap ``H∞−(Rf) / ||[Rd Rw]||∞`` (∞ when the denominator is 0).

    With a structure matrix ``S`` (one row per residual group), returns the per-row gaps
    where the faults with ``S[i, j] = 0`` join the noise of row i. Denominators at or
    below ``atol`` count as zero.
    """
    R = gen.internal_form()
    m = gen.model
    blocks = [np.arange(m.nf)[f.columns] for f in m.faults]
    Rdw_cols = (R["d"], R["w"])
    if S is None:
        beta = hinf_minus(gen)
        noise = _hstack_norm([X for X in Rdw_cols if X.m])
        return float("inf") if noise <= atol else beta / noise
    S = np.asarray(S).astype(bool)
    if S.shape != (len(gen.groups), len(blocks)):
        raise DesignError(f"S must have shape {(len(gen.groups), len(blocks))}, got {S.shape}")
    gaps = []
    for i, g in enumerate(gen.groups):
        Rf_i = R["f"][g, :]
        beta = min((Rf_i[:, blocks[j]].minreal().hinfnorm()[0] for j in range(len(blocks)) if S[i, j]),
                   default=0.0)
        others = [Rf_i[:, blocks[j]] for j in range(len(blocks)) if not S[i, j]]
        others += [X[g, :] for X in Rdw_cols if X.m]
        noise = _hstack_norm(others)
        gaps.append(float("inf") if noise <= atol else beta / noise)
    return np.array(gaps)


def _hstack_norm(systems: list[LTI]) -> float:
    systems = [s for s in systems if s.m]
    if not systems:
        return 0.0
    from .lti import hstack

    return hstack(systems).minreal().hinfnorm()[0]


def leakage(gen: ResidualGenerator) -> float:
    """``max(||Ru||∞, ||Rd||∞)``: how much of the known and unknown inputs leaks into r.

    The judge's figure (:func:`fmu_fdi.design.toolkit.postconditions.report`): peaks of the block
    2-norms over its frequency grid, per residual group, of ``R = Q Ge`` evaluated point by
    point; on a design's normalised rows it is relative to the weakest fault gain, and equal
    to ``gen.info['postconditions']['leakage']``."""
    from .design.toolkit.postconditions import report

    return report(gen)["leakage"]


def detectability(model: FDIModel, freqs=None) -> dict[str, dict]:
    """Per fault: is it detectable once d is decoupled (``rank [Gd Gf_j] > rank Gd``)?

    With ``freqs``, also whether it is strongly detectable at each frequency (the same
    rank condition on the frequency responses).
    """
    G = model.lti("d", "f")
    values = sample_values(G)  # the ranks below are of columns of these values
    rd = sampled_rank(values, range(model.nd)) if model.nd else 0
    out = {}
    for spec in model.faults:
        cols = list(range(model.nd)) + list(model.nd + np.arange(model.nf)[spec.columns])
        rdf = sampled_rank(values, cols)
        entry = {"detectable": rdf > rd, "rank_Gd": rd, "rank_Gd_Gf": rdf}
        if freqs is not None:
            strong = {}
            for w in np.atleast_1d(freqs):
                H = G[:, cols].freqresp([w])[0]
                Hd = H[:, : model.nd]
                from .linalg import rank

                strong[float(w)] = rank(H) > (rank(Hd) if model.nd else 0)
            entry["strong"] = strong
        out[spec.name] = entry
    return out


def isolability(model: FDIModel) -> dict:
    """Pairwise isolability: ``matrix[i, j]`` is True when fault i stays detectable with
    fault j decoupled too (``rank [Gd Gf_j Gf_i] > rank [Gd Gf_j]``), so a residual can
    see i but not j. ``fully_isolable`` is True when the structure matrix I is
    achievable: ``rank [Gd Gf] = rank Gd + Σ_j rank Gf_j``."""
    G = model.lti("d", "f")
    values = sample_values(G)  # every rank below is of columns of these values
    nd = model.nd
    cols = [list(nd + np.arange(model.nf)[f.columns]) for f in model.faults]
    k = len(model.faults)
    M = np.zeros((k, k), dtype=bool)
    for i in range(k):
        for j in range(k):
            if i == j:
                continue
            base = list(range(nd)) + cols[j]
            M[i, j] = sampled_rank(values, base + cols[i]) > sampled_rank(values, base)
    rd = sampled_rank(values, range(nd)) if nd else 0
    full = sampled_rank(values) == rd + sum(sampled_rank(values, c) for c in cols) if k else True
    return {"faults": model.fault_names, "matrix": M, "fully_isolable": bool(full)}


@single_blas_thread  # as the designs: threaded BLAS on small matrices spin-waits (400x on a loaded machine)
def achievable_structure(model: FDIModel, faults=None, max_faults: int = 12, *, freqs=None,
                         FDGainTol: float = DEFAULT_GAIN_TOL, tol: float | None = None,
                         atol: float = 0.0) -> np.ndarray:
    """Every achievable specification: the rows ``s`` (0/1 over ``faults``, not all 0) for
    which a residual exists that sees exactly the faults with ``s_j = 1`` once u, d and the
    faults with ``s_j = 0`` are decoupled (Varga 2017, sec. 5.4, Procedure GENSPEC;
    FaultDetectionTools.jl ``fdigenspec``). Rows in lexicographic order.

    Weak (``freqs=None``): rank test per row, ``rank [Gd Gf_0 Gf_j] > rank [Gd Gf_0]`` for
    every ``j`` with ``s_j = 1`` (normal ranks at random points).

    Strong (``freqs`` given, rad/s, e.g. 0 for constant faults; Varga's ``FDfreq``): a weakly
    achievable row is kept when every fault with ``s_j = 1`` stays visible at every ω_k. With
    ``N(λ) = [V(λ) -W(λ)]`` a minimal polynomial basis of the left null space of
    ``[Gu Gd Gf_0; I 0 0]`` (irreducible: the values at λ_k of all decoupling filters without a
    pole there are the row space of ``N(λ_k)``, and their fault responses ``v Gf_j(λ_k)`` with
    v in the row space of ``V(λ_k)``), the gain kept at ω_k is
    ``g_j(ω_k) = max_{v, ||v|| = 1} ||v Gf_j(λ_k)||`` (a projection, no filter scaling), and
    the fault counts as visible when ``g_j(ω_k) > FDGainTol · min(||Gf_j(λ_k)||, max_ω g_j(ω))``:
    not a rounding-level part of the fault's own response there, nor of what the residuals
    see of it elsewhere. At a pole of ``Gf`` on the stability boundary (an integrator), where
    a stable residual must cancel the pole, the test uses the stable factor ``Ñ`` of a left
    coprime factorisation of ``N Ge_f`` (its ``||Ñ_j(λ_k)||`` against its own peak). A
    generic combination of the basis rows then sees all those faults at all those frequencies
    at once. ``tol``/``atol``: rank tolerances of the basis (as in
    :func:`~fmu_fdi.design.nullspace_design`). Published results (FaultDetectionTools.jl
    ``fdigenspec``) are reproduced in tests/test_achievable_structure.py.

    Raises
    ------
    DesignError
        Too many faults (``max_faults``), a frequency that is negative, not finite or a
        pole of the plant on the stability boundary (strong detectability is not defined there).
    """
    import itertools

    names = list(model.fault_names if faults is None else faults)
    for nm in names:
        model.fault(nm)
    if len(names) > max_faults:
        raise DesignError(f"{len(names)} faults give 2^{len(names)} candidate rows; pass max_faults to allow it")
    test = row_test(model, names, freqs=freqs, FDGainTol=FDGainTol, tol=tol, atol=atol)
    rows = [row for row in itertools.product((0, 1), repeat=len(names)) if any(row) and test(row) is None]
    return np.array(rows, dtype=int).reshape(-1, len(names))


def row_test(model: FDIModel, names, *, freqs=None, FDGainTol: float = DEFAULT_GAIN_TOL, tol: float | None = None,
             atol: float = 0.0):
    """The one test of a structure row, shared by :func:`achievable_structure` (which lists the
    rows it passes) and :func:`~fmu_fdi.design.problems.banks.structured_bank` (which refuses the rows
    it fails, before designing): a predicate ``row -> None`` (achievable) or the reason it is
    not (a string naming the fault and the test). Weak: ``rank [Gd Gf_0 Gf_j] > rank [Gd Gf_0]``
    for every required fault j (normal ranks, cached over the rows); strong (``freqs``): the
    projection test of :func:`achievable_structure`. ``names`` are the faults of the row's
    columns; ``tol``/``atol`` the basis rank tolerances of the designs."""
    names = list(names)
    for nm in names:
        model.fault(nm)
    G = model.lti("d", "f")
    nd = model.nd
    cols = {f.name: list(nd + np.arange(model.nf)[f.columns]) for f in model.faults}
    cache: dict[tuple, int] = {}

    def rk(idx: tuple) -> int:
        if idx not in cache:
            cache[idx] = normal_rank(G[:, list(idx)]) if idx else 0
        return cache[idx]

    strong = None if freqs is None else _strong_test(model, freqs, FDGainTol, tol, atol)

    def test(row) -> str | None:
        row = tuple(int(x) for x in row)
        if len(row) != len(names):
            raise DesignError(f"structure row {list(row)} has {len(row)} entries for the faults {names}")
        if not any(row):
            return "a residual that sees no fault detects nothing"
        base = tuple(range(nd)) + tuple(c for nm, s in zip(names, row) if not s for c in cols[nm])
        r0 = rk(base)
        if r0 >= model.ny:
            return (f"no residual generator exists: the unknown inputs d and the faults marked 0 span every output "
                    f"direction (normal rank of Gd = {r0} = number of outputs {model.ny}, the faults marked 0 "
                    f"counted as d)")
        for nm, s in zip(names, row):
            if s and not rk(base + tuple(cols[nm])) > r0:
                return (f"fault '{nm}' is invisible once d and the faults marked 0 are decoupled (normal rank "
                        f"{rk(base + tuple(cols[nm]))} of [Gd Gf_0 Gf_{nm}] = rank {r0} of [Gd Gf_0])")
        if strong is not None and not strong(names, row):
            return (f"a required fault is not strongly detectable at ω = {np.ravel(freqs).tolist()} rad/s "
                    f"(FDGainTol = {FDGainTol:g}) once d and the faults marked 0 are decoupled")
        return None

    return test


def _strong_test(model: FDIModel, freqs, FDGainTol: float, tol, atol):
    """The predicate ``(names, row) -> bool`` of strong achievability at ``freqs``
    (see :func:`achievable_structure`)."""
    from .design.toolkit._basis import minimal_basis

    omega = np.atleast_1d(np.asarray(freqs, float))
    if omega.ndim != 1 or not omega.size or np.any(omega < 0) or not np.all(np.isfinite(omega)):
        raise DesignError(f"freqs must be finite non-negative frequencies in rad/s, got {np.ravel(freqs).tolist()}")
    if not np.isfinite(FDGainTol) or not 0 < FDGainTol < 1:
        raise DesignError(f"FDGainTol must be in (0, 1), got {FDGainTol!r}")

    def points(w):
        return np.exp(1j * w * model.dt) if model.dt else 1j * w

    # the fault channels only (a pole of Gu or Gd is annihilated by every decoupling filter),
    # minimal to 1e-10 relative: a mode coupled more weakly makes the decision ill-posed anyway
    from .model import minimal_realisation

    Gf = model.lti("f")
    Af, Bf, Cf, _ = minimal_realisation(Gf.A, Gf.B, Gf.C, 1e-10)
    Gf = LTI(Af, Bf, Cf, Gf.D, Gf.dt)

    def near_pole(w, rel):
        if not Gf.n:
            return np.zeros(w.size, bool)
        poles = Gf.poles()
        dist = np.min(np.abs(points(w)[:, None] - poles[None, :]), axis=1)
        return dist <= rel * max(1.0, float(np.max(np.abs(poles))))

    at_pole = near_pole(omega, 1e-9)
    # the kept gains are also compared with their peak over a grid (off Gf's boundary poles)
    grid = frequency_grid([model.lti()], num=120, extra=omega[~at_pole])
    w_all = np.concatenate([omega[~at_pole], grid[~near_pole(grid, 1e-6)]])
    Gf_vals = [Gf.evalfr(x) for x in points(w_all)]
    finite = np.array([bool(np.all(np.isfinite(v))) for v in Gf_vals])
    nk = int(np.sum(~at_pole))
    # ||Gf_j(λ)|| at the kept frequencies (0 where Gf is not finite): per fault, the same for every row
    local_all = {nm: np.array([np.linalg.norm(Gf_vals[k][:, model.fault(nm).columns], 2) if finite[k] else 0.0
                               for k in range(nk)]) for nm in model.fault_names}

    def test(names, row) -> bool:
        ignore = [nm for nm, s in zip(names, row) if not s]
        keep = [nm for nm, s in zip(names, row) if s]
        mi = model.with_disturbances(ignore)
        mi = mi._replace(faults=[f for f in mi.faults if f.name in keep])
        basis = minimal_basis(mi, tol, atol)
        gains, local = np.zeros((len(keep), w_all.size)), np.zeros((len(keep), nk))
        for j, nm in enumerate(keep):
            local[j] = local_all[nm]
        for k, x in enumerate(points(w_all)):
            if not finite[k]:
                continue
            # y-part of N at λ (its u-part only cancels Gu): the values v = a^T U^T, ||v|| = ||a||
            # (rank relative to the whole row values: a y-part at rounding level is no direction)
            Nk = np.stack([r.at([x / basis.rho])[0] for r in basis.rows])
            U, sv, _ = np.linalg.svd(Nk[:, :model.ny].T, full_matrices=False)
            Pi = U[:, sv > 1e-12 * np.linalg.norm(Nk, 2)]
            for j, nm in enumerate(keep):
                Gj = Gf_vals[k][:, model.fault(nm).columns]
                gains[j, k] = np.linalg.norm(Pi.T @ Gj, 2)
        ref = np.minimum(local, gains.max(axis=1, initial=0.0)[:, None])
        if np.any(gains[:, :nk] <= FDGainTol * ref) or np.any(ref == 0):
            return False
        # what a *stable* residual keeps at every ω (the peer's fdisspec(...; stabilize = true)): at a
        # boundary pole of Gf the only finite value; off it, a near-boundary pole (Boeing 747: +3.1e-5)
        # makes the projection above see a large Gf(0) whose stable factor has a zero there
        T = _stable_fault_response(mi, basis)
        # the reference peak on 80 log points (a sharp resonance between them lowers the reference only)
        grid_T = frequency_grid([T], num=80) if T.n else np.array([0.0])
        H, Hk = T.freqresp(grid_T), np.stack([T.evalfr(x) for x in points(omega)])
        for f in mi.faults:
            peak = np.max(np.linalg.norm(H[:, :, f.columns], axis=(1, 2)))
            if peak == 0 or not np.all(np.linalg.norm(Hk[:, :, f.columns], axis=(1, 2)) > FDGainTol * peak):
                return False
        return True

    return test


def _stable_fault_response(mi: FDIModel, basis) -> LTI:
    """At a pole of a fault channel on the stability boundary (an integrator, say), where
    no stable residual may keep it: the fault responses ``Ñ`` of all decoupling filters of
    ``mi``, stable: ``T = N Ge_f`` with the basis rows over the design's default denominators,
    and ``Ñ`` the fault part of the stable factor ``M·[Q T]`` of the joint left coprime
    factorisation :func:`~fmu_fdi.design.toolkit.stable_factor.stable_joint_factor` (glcf: an ordered Schur
    form moves only the poles on or outside the boundary; the designs end with the same
    factorisation, and the peer's ``fdigenspec`` judges ``fdisspec(...; stabilize = true)`` on the
    ``glnull`` rows stabilised so). Any stable residual's fault response is ``Y Ñ`` with Y stable,
    and Ñ is unique up to a unit (no zeros on the boundary), so the zeros of ``Ñ_j`` at ω are those
    every decoupling residual has.
    """
    from .design.toolkit._basis import pole_chooser, realize_rows
    from .design.toolkit.stable_factor import stable_joint_factor
    from .design.toolkit.postconditions import NumericalDesignError

    choose = pole_chooser(mi, None, None)
    Q = realize_rows([r.coef for r in basis.rows], [choose(r.degree) / basis.rho for r in basis.rows],
                     basis.rho, mi.dt)
    try:
        J, q, _ = stable_joint_factor(mi, Q)
    except NumericalDesignError as exc:
        raise DesignError(f"strong detectability at a pole of the fault channels on the stability boundary "
                          f"cannot be decided: {exc}; pass other freqs") from None
    return J[:, q + mi.nw:]
