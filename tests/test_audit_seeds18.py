"""Audit of seeds nobody had run (issue 17, thirteenth session), judged by numpy: exact
``benchmarks/synthesis_random_judged.py`` 739-798 (and 799-828), approximate ``benchmarks/approximate_random_judged.py``
200-239 (and 240-259), and the re-run of approximate seed 26 ``amm(Mr = I)``. The exact sets came back clean. Of the
findings below, seed 243's is fixed here (model_detection.py); seeds 206 and 26/240 are in files this audit does not
own, so they stay strict xfails with their cause and the change proposed (the figures: the commit messages). Seed
206's is fixed since (judge19, postconditions.py: the proposal below); its two tests pass.

- **Seed 206, approximate_model_matching with Mr = an exact detection row's Rf** (continuous n 30, p 3, m 4, no d,
  a fault-only mode at +1; an achievable request: the reference row is admissible) — refused "the returned filter leaks
  u/d above dec_tol ... 9.88e-05 (± 3.7e-07)". The optimal filter is right: its product realisation ``Y·Φ·Q0`` (order
  99) leaks 1.6e-10 of the weakest required fault by an independent refined evaluation (50-digit decimal arithmetic
  agrees: 3.13e-11 absolute at 1.0301 rad/s), and the shipped minimal realisation (same order, SLICOT's coordinates)
  leaks 9.6e-5 — the case ship17's ``_decoupled_candidate`` was made for. It did not swap because the judge read the
  product's leak at 2.16e-7 (± 4.8e-10): ``postconditions._decoupled_values`` refines only the points whose double
  reading could reach the block's peak, the peak taken from the *unrefined* readings; a point whose double reading
  over-states its value by more than its own first-order bound sets that peak (0.138 rad/s: read 1.18e-6, bound
  7.5e-7, value 1.2e-10), is refined and falls, and the points it had masked are left at their double readings
  (1.0301 rad/s: 2.09e-7 with a double bound 1.3e-7 — the value's own size — on the judge's grid of 222 points,
  103 refined; 6.3e-11 when read alone or among its six neighbours) while their error is reported at the extended
  precision's bound.
  Proposed (postconditions.py, judge18): refine until no unrefined point's reading plus bound reaches the refined peak
  (a loop over the existing test, refined points' bound then the extended one). Tried for the run by patching the
  module: the reading falls to the stored filter's, ``_decoupled_candidate`` ships the product and numpy's judge passes
  the design (``check_case(206, ('amm_ref',))`` ok, 32 s).
- **Seed 26, approximate_model_matching with Mr = I** (continuous n 27, p 3, m 6, nd 1, nf 5, a fault-only integrator
  at -5.7e-16) — refused "the returned filter's error response differs from the designed one by 0.0519 (relative
  0.0519, limit 0.001; 0.892 times its rounding estimate ...)". A refusal for the wrong reason: the optimum is
  ``||Mr||∞ = 1`` exactly (the admissible filters span p + m − rank [Gu Gd; I 0] = 2 < 5 rows, so ``Q·Gf − I`` is
  singular-valued ≥ 1 at every frequency, and Q = 0 attains 1) and a nonzero admissible stable filter within 1e-6 of
  it exists (below: ε times the exact detection row, judged by numpy). The γ-iteration's bracket is [1, 1.000048]; its
  near-optimal Y (peak gain 1.45e3, order 53) at that degenerate optimum is realised with the fault-only integrator's
  cancellation lost (the minimal realisation shipped regardless: residue 2.4e-9 > its rounding bound 1.41e-9, R not
  stable). Decided (amm21, a product decision): Q = 0 is then the optimum, no detection filter, so the design is
  refused early with the true condition — the admissible fault response's normal rank r and ``sup σ_{r+1}(Mr) =
  ||Mr||∞`` (``approximate_matching._unapproachable_reference``). Seed 240
  (audit 240-259: n 24, p 2, m 2, nd 1, nf 5, one admissible row) is refused the same way ("differs ... by 0.18").
- **Seed 243, approximate_model_detection_bank** (discrete n 28, p 1, m 2): MDgap reported ∞ for filter 2 where numpy
  reads 5.04e6 — its noise response γ = 1.985e-7 (the same as filters 0 and 1, which reported 5.04e6) was zeroed as
  "rounding" against 1e-9·||Q||∞·||Gw||∞, ||Q||∞ = 2 being the u columns' ``−q Gu``. Fixed in
  ``model_detection._noise_gain`` (the scale is ``||Q_y||∞ ||Gw||∞``; γ ≤ dec_tol·β counts as decoupled).
"""
from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_approximate_random import (_cols, _ge_values, _points, _refined_peak, check_case, judge_amm,  # noqa: E402
                                     noisy_case)
from test_synthesis_random import _extended  # noqa: E402


# ------------------------------------------------------------------------------------------- numpy
def refined_values(A, B, C, D, lam: np.ndarray, steps: int = 3) -> np.ndarray:
    """``C (λI − A)^{-1} B + D`` at the points ``lam`` (shape (points, p, m), clongdouble), each solve refined by
    ``steps`` steps of iterative refinement whose residual ``B − (λI − A) X`` is formed with the stored data in
    numpy's longdouble (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., ch. 12: GEPP's error
    contracts when ``u·cond(λI − A) ≪ 1`` — here ≤ 4e8·1.1e-16 = 4e-8 — and the refined solution is the stored
    system's to the residual's precision). No fmu_fdi code: the judge of the library's own accurate reading."""
    A, B, C, D = (np.asarray(X, float) for X in (A, B, C, D))
    n = A.shape[0]
    out = np.empty((lam.size,) + D.shape, np.clongdouble)
    Ax, Bx, Cx, Dx = (X.astype(np.longdouble) for X in (A, B, C, D))
    for k, lk in enumerate(np.asarray(lam, complex)):
        if not n:
            out[k] = Dx
            continue
        M = lk * np.eye(n) - A
        X = np.linalg.solve(M, B.astype(complex)).astype(np.clongdouble)
        for _ in range(steps):
            r = Bx - (np.clongdouble(lk) * X - Ax @ X)
            X = X + np.linalg.solve(M, r.astype(complex))
        out[k] = Cx @ X + Dx
    return out


def _product_realisation(monkeypatch, seed: int):
    """``(model, Mr, Q)``: the noisy audit model, the exact detection row's Rf as reference (as check_case's
    ``amm_ref``), and the realisation ``Y·Φ·Q0`` that approximate_model_matching hands its shipping stage (the
    design is stopped there: the stage's Qfull argument)."""
    import fmu_fdi.design.problems.approximate_matching as am
    from test_approximate_random import _detection_reference

    model = noisy_case(seed)
    Mr, _ = _detection_reference(model)
    got = {}

    class Stop(Exception):
        pass

    def stop(*args, **kw):
        got["Q"] = args[5]
        raise Stop

    monkeypatch.setattr(am, "_shipped_filter", stop)
    with pytest.raises(Stop):
        am.approximate_model_matching(model, Mr)
    Q = got["Q"]
    return model, Mr, (Q[1] if isinstance(Q, tuple) else Q)


# ------------------------------------------------------------------------------------------ seed 206
@pytest.mark.slow
def test_seed206_judge_reads_the_stored_filters_leak(monkeypatch):
    """~15 s under load (10 s of it the design up to its shipping stage). The library's normalised u/d reading of the
    product realisation Y·Φ·Q0 (order 99) is a reading of the stored filter with an error bound: it may not exceed
    numpy's refined reading of the same stored data by more than that bound. Numpy: ``Q(λ)`` and ``[Gu; I](λ)`` each by
    :func:`refined_values` on test_approximate_random's grid (every fourth of its 1500 log points over the poles' band),
    the peak refined there (:func:`_refined_peak`); normalised by the weakest required fault's peak on the same grid
    (Mr's row requires every fault). Tolerance: 1.05 × numpy's figure (the two normalising fault peaks are read on
    different grids: a grid peak is low by at most a few percent, test_approximate_random's FIG_RTOL derivation) plus
    the judge's own ``decoupling_error``. On audit18's code: judge 2.16e-7 (error 4.8e-10), numpy 1.6e-10 (a strict
    xfail); passes since judge19 refines until no double reading reaches the refined peak."""
    from fmu_fdi.design.problems.approximate_matching import normalised_leak, required_faults

    model, Mr, Q = _product_realisation(monkeypatch, 206)
    lam = _points(model, [Q])
    required = required_faults(model, Mr, lam)
    lam = lam[::4]  # (375 points: the leak is ~1e-10 everywhere, three decades below the reading compared)
    assert required.all()  # (numpy below normalises by the weakest of every fault)
    fig = normalised_leak(model, Q, required, None, 1e-7)
    A, B, Ce, De = _extended(model)
    cols = _cols(model)

    def R(pts):
        return (refined_values(Q.A, Q.B, Q.C, Q.D, pts) @ refined_values(A, B, Ce, De, pts)).astype(complex)

    fcols = np.concatenate([cols[f.name] for f in model.faults])
    Rv = R(lam)
    weakest = min(float(np.max(np.abs(Rv[:, :, c]))) for c in fcols)
    leak = _refined_peak(lambda L: R(L)[:, :, cols["u"]], lam, model.dt, np.linalg.eigvals(model.A)) / weakest
    assert leak < 1e-9  # the product realisation decouples (the optimal filter is right)
    read, bound = fig["decoupling"], fig["decoupling_error"]
    assert read <= 1.05 * leak + bound, (read, bound, leak)


@pytest.mark.slow
def test_seed206_matching_the_detection_row_is_designed():
    """~35 s under load. check_case's numpy judge (test_approximate_random.judge_amm) on
    ``approximate_model_matching(model, Mr = the exact detection row's Rf)``: refused on audit18's code (the
    shipped minimal realisation leaks 9.6e-5, the judge's over-read of the product's leak keeps it; module
    docstring; a strict xfail); with the judge's reading refined to its peak (judge19) the design passes."""
    assert check_case(206, calls=("amm_ref",)) == [("amm(Mr=detection row)", "ok", "")]


# ------------------------------------------------------------------------------------------- seed 26
def _lower_bound_rank(model, lam) -> int:
    """The most rows an admissible filter's fault response can have independent at ``lam``: the dimension of the
    left null space of ``[Gu Gd; I 0](λ)`` (numpy SVD, rank at 1e-10 of the largest singular value — the columns
    are I on the u rows, so the smallest nonzero singular value is ≥ ~1e-4 of the largest for these models' gains)."""
    nud = model.nu + model.nd
    dims = []
    for Gk in _ge_values(model, lam):
        s = np.linalg.svd(Gk[:, :nud], compute_uv=False)
        dims.append(Gk.shape[0] - int(np.sum(s > 1e-10 * s[0])))
    return max(dims)


@pytest.mark.parametrize("seed, rows", [(26, 2), (240, 1), (270, 3), (282, 2)])
def test_optimum_of_matching_identity_is_attained(seed, rows):
    """~2 s. Approximate seeds 26's, 240's, 270's and 282's ``amm(Mr = I)`` have the optimum ``||Mr||∞ = 1`` and an
    admissible nonzero filter attains it within 1e-6: the optimum is Q = 0's error (the condition the refusal names,
    :func:`test_matching_identity_is_refused_with_its_rank_bound`). (i) Lower bound: every admissible Q
    lies in the left null space of ``[Gu Gd; I 0]``, of dimension ``rows`` (2, 1, 3, 2; numpy SVD at 40 points) < nf =
    5, so ``Q(λ)Gf(λ)`` has rank ≤ ``rows`` and ``σ_max(Q Gf − I) ≥ 1`` (a unit vector of its null space
    v: ``(Q Gf − I) v = −v``). (ii) Attained: ε times the exact detection row (``nullspace_design(noise='ignore')``, as
    check_case's reference) in the first of five rows, ε = 1e-6 / ``||Q_ref [Gf Gw]||∞``: error ≤ 1 + 1e-6 by the
    triangle inequality; judged by test_approximate_random's judge_amm (u, d decoupled, R and Q stable, Q nonzero, error
    = 1 within its ERR_RTOL, not above Q = 0's) and numpy's refined error ≤ 1 + 2e-6 (the triangle's 1e-6 plus the
    refined peak's 1e-6)."""
    from fmu_fdi.design import nullspace_design
    from fmu_fdi.lti import LTI
    from test_synthesis_random import _freqresp

    model = noisy_case(seed)
    lam = _points(model)
    assert _lower_bound_rank(model, lam[:: max(1, lam.size // 40)]) == rows < model.nf
    ref = nullspace_design(model, noise="ignore").Q
    cols = _cols(model)
    fw = np.r_[np.concatenate([cols[f.name] for f in model.faults]), np.arange(model.nu + model.nd,
                                                                                model.nu + model.nd + model.nw)]
    gain = _refined_peak(lambda L: _freqresp(ref.A, ref.B, ref.C, ref.D, L) @ _ge_values(model, L)[:, :, fw], lam,
                         model.dt, np.linalg.eigvals(model.A))
    eps = 1e-6 / gain
    C = np.vstack([eps * ref.C, np.zeros((model.nf - 1, ref.n))])
    D = np.vstack([eps * ref.D, np.zeros((model.nf - 1, ref.D.shape[1]))])
    Q = LTI(ref.A, ref.B, C, D, model.dt)
    eye = LTI.static(np.eye(model.nf), model.dt)
    gen = SimpleNamespace(Q=Q, info={"M": eye, "error": 1.0})
    assert judge_amm(gen, model, eye, None) == []
    fcols = np.concatenate([cols[f.name] for f in model.faults])

    def error(L):
        Rv = _freqresp(Q.A, Q.B, Q.C, Q.D, L) @ _ge_values(model, L)
        E = np.concatenate([Rv[:, :, fcols], Rv[:, :, cols["w"]]], axis=2)
        E[:, :, :model.nf] -= np.eye(model.nf)
        return E

    assert _refined_peak(error, lam, model.dt, np.linalg.eigvals(model.A)) <= 1 + 2e-6


def _admissible_fault_rank(model, lam) -> int:
    """The largest rank over ``lam`` of the admissible filters' fault response ``N(λ) [Gf; 0](λ)``, N(λ) an orthonormal
    basis of the left null space of ``[Gu Gd; I 0](λ)`` (numpy SVD of the plant's values, test_approximate_random's
    ``_ge_values``): every admissible ``Q(λ)`` is ``Y(λ) N(λ)``, so ``Q Gf`` has at most this rank. Ranks at 1e-10 of
    the largest singular value (as :func:`_lower_bound_rank`)."""
    nud = model.nu + model.nd
    cols = _cols(model)
    fcols = np.concatenate([cols[f.name] for f in model.faults])
    out = 0
    for Gk in _ge_values(model, lam):
        if nud:
            U, s, _ = np.linalg.svd(Gk[:, :nud])
            N = U[:, int(np.sum(s > 1e-10 * s[0])):].conj().T
        else:
            N = np.eye(Gk.shape[0])
        sv = np.linalg.svd(N @ Gk[:, fcols], compute_uv=False)
        out = max(out, int(np.sum(sv > 1e-10 * sv[0])) if sv.size and sv[0] > 0 else 0)
    return out


def refused_with_rank_bound(model, points: int = 40) -> int:
    """``approximate_model_matching(model, Mr = I)`` raises a DesignError that names the normal rank of the admissible
    fault response — equal to numpy's (:func:`_admissible_fault_rank` at ``points`` points of test_approximate_random's
    grid) and below nf — and the bound ``σ_{r+1}(Mr) = 1`` reaching ``||Mr||∞ = 1`` (numpy's SVD of I: exact, so to
    1e-12). Returns the rank."""
    from fmu_fdi.design import approximate_model_matching
    from fmu_fdi.errors import DesignError
    from fmu_fdi.lti import LTI
    import re

    lam = _points(model)
    r_np = _admissible_fault_rank(model, lam[:: max(1, lam.size // points)])
    assert r_np < model.nf
    with pytest.raises(DesignError, match="cannot be approached") as exc:
        approximate_model_matching(model, LTI.static(np.eye(model.nf), model.dt))
    msg = str(exc.value)
    rank = int(re.search(r"normal rank (\d+)", msg).group(1))
    m = re.search(r"σ_(\d+)\(Mr\(λ\)\) = ([0-9.eE+-]+), which reaches \|\|Mr\|\|∞ = ([0-9.eE+-]+)", msg)
    assert m, msg
    sv = np.linalg.svd(np.eye(model.nf), compute_uv=False)
    assert rank == r_np and int(m.group(1)) == r_np + 1
    assert abs(float(m.group(2)) - sv[r_np]) <= 1e-12 and abs(float(m.group(3)) - sv[0]) <= 1e-12
    return rank


@pytest.mark.parametrize("seed, rows", [(26, 2), (240, 1), (270, 3), (282, 2)])
def test_matching_identity_is_refused_with_its_rank_bound(seed, rows):
    """~1-7 s each. Strict xfail until amm21 ("the design is returned and passes the numpy judge"); the product
    decision since: where no admissible filter does better than Q = 0 (the optimum is Q = 0's error, a filter of no
    use for detection — :func:`test_optimum_of_matching_identity_is_attained`), ``amm(Mr = I)`` is refused early with
    the true condition and its numbers (``approximate_matching._unapproachable_reference``), not with the numerical
    reasons the degenerate optimum's Y produced (seed 26: 'differs from the designed one by 0.0519'; 240: 'by 0.18';
    270: a u/d leak 1.9e-7; 282: an R residue 2.75e-11 against its bound 2.54e-11). Asserted
    (:func:`refused_with_rank_bound`): a DesignError naming the admissible fault response's normal rank, numpy's
    (2, 1, 3, 2 for 5 faults), and the bound ``σ_{r+1}(I) = 1 = ||I||∞``."""
    assert refused_with_rank_bound(noisy_case(seed)) == rows


# ------------------------------------------------------------------------------------------ seed 243
def _actuator_set(b: float, c: float):
    """Three first-order models ``y = (b (1 + 0.3 k) u + c w)/(s + 1)``, k = 0, 1, 2: the known input's gain ``b``
    and the noise's ``c`` in other units (approximate audit seed 243: ``||Gw||∞ = 190`` beside filters whose u
    columns have gain 2 after the β scaling, p = 1)."""
    from fmu_fdi import FDIModel

    return [FDIModel.from_matrices([[-1.0]], [[b * (1 + 0.3 * k)]], [[1.0]], Bw=[[c]], Dw=[[0.0]], name=f"m{k}")
            for k in range(3)]


@pytest.mark.parametrize("b, c", [(1e10, 1e4), (1e10, 1e2), (1e2, 1e-2)])
def test_model_detection_gap_is_numpys_whatever_the_input_units(b, c):
    """< 1 s. approximate_model_detection_bank's ``MDgap``, ``MDperf``, decoupling and stability, judged by
    test_approximate_random's judge_amd (numpy frequency responses, gap = β/γ with γ = ||Q_i [Gw; 0]||∞ read on a
    dense grid, ∞ where γ ≤ DEC_TOL·β: the normalised form's decoupling). Every filter here is
    ``Q_i = q (s + 1)/(s + a) [1, −b_i/(s + 1)]`` up to scaling, ``β_i = 0.3 b·||q/(s + a)||∞ = 1``, so its noise
    response ``γ = c/(0.3 b)`` is a transfer function of its own, whatever ``b``: 3.3e-6 for (1e10, 1e4) — a gap of
    3e5 — where ``_noise_gain`` compared γ with 1e-9·||Q||∞·||Gw||∞ = 1e-9·(1 + 0.3 i)/0.3·c ≥ 3.3e-5 (||Q||∞ is the
    u columns' ``(1 + 0.3 i)/0.3``) and reported γ = 0, an infinite gap on every filter (failed on c49e6c1, strict
    xfail there); now the rounding scale is ``||Q_y||∞ ||Gw||∞`` (3.3e-7 here) and γ ≤ dec_tol·β counts as decoupled,
    as the post-conditions read the normalised form. (1e10, 1e2): γ = 3.3e-8 below DEC_TOL — ∞ both ways, before and
    after; (1e2, 1e-2): the same filters in other units, a finite gap both ways."""
    from fmu_fdi.design import approximate_model_detection_bank
    from test_approximate_random import judge_amd

    models = _actuator_set(b, c)
    bank = approximate_model_detection_bank(models)
    assert judge_amd(bank, models) == []


# ------------------------------------------------------------------------------------- seeds 268, 277
@pytest.mark.slow
@pytest.mark.parametrize("seed", [268, 277])
def test_matching_error_is_the_peak_beside_a_resonance(seed):
    """~30-70 s under load (27 s, 60 s measured by amm20). Strict xfail on a5e420c; passes since amm20's
    ``_points`` reads every complex pole's resonance frequencies (below), and a reading below the bracket's certified
    lower end is now refused (``_below_certified_refused``; fast constructed case: tests/test_amm_resonance_grid.py).
    Approximate audit 260-279 (further seeds): ``amm(Mr = an exact detection row's Rf)``
    reported the error 4.63869 (seed 268: continuous n 29, p 1, m 1, plant pair −0.1096 ± 6.9247j, ζ = 0.016) and
    11.8347 (seed 277: discrete n 30, a pair 1.0e-3 inside the unit circle) where numpy's refined peak reads 4.72841
    at 6.960 rad/s and 11.8606 at 2.129 rad/s — both *below* the γ-iteration's certified infeasible level (bracket
    [4.71833, 4.71853], [11.85619, 11.85666]), which no filter's error can be. The designed ``Y Ĝ − F`` itself peaks
    at 4.72841 there (numpy, the captured factors): SB10FD's central controller at the feasible level 4.71853 exceeds
    its certificate ``< γ`` by 0.2 %, and both the check meant to catch that (``_hinf_at``: a 200-point grid) and the
    returned figure (``_judged_error``: 400 points, 60-point refinement around the three highest) read a log grid
    whose 4.7 % steps straddle a resonance of half-width ~1.6 % (values 2.6 and 3.6 at ±2 % of the peak), so the
    returned filter's true error 4.72841 is above the design's own limit 4.71880 (reltol 1e-4) unseen. Proposed
    (approximate_matching.py, amm18): ``_points`` adds every lightly damped pole's resonance frequencies of the systems
    it grids (``postconditions._resonances``: |Im s|, |Im s| ± |Re s|/2, as the judge's grid does); tried for the run by
    patching the module: both seeds then pass this judge (26 s, 46 s). A returned error below the bracket's lower end
    is a mis-read the function could refuse on."""
    assert check_case(seed, calls=("amm_ref",)) == [("amm(Mr=detection row)", "ok", "")]
