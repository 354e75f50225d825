"""Audit of seeds nobody had run (issue 17, fifteenth session), judged by numpy: exact
``benchmarks/synthesis_random_judged.py`` from seed 1009, approximate ``benchmarks/approximate_random_judged.py`` from
seed 360, and the exact model-matching families (``--matching``) from seed 236 (the tallies: those scripts' docstrings
and the commit messages). Four findings; the first fixed here, the other three (approximate_matching.py and the
judge, files this audit does not own) pinned as strict xfails:

- **Exact matching seed 1149, unstable family with updating** (tests/test_synthesis_matching_order.py's
  ``_random_model(1149, unstable=True)``: discrete, n 6, p 3, m 2, nd 1, two faults; plant poles 0.667 … 0.976 and
  1.043) — ``model_matching(model, Rf, updating=True)`` with ``Rf`` the fault response of a degree-2 detection row
  (an exact solution of degree 2 exists: that row) was refused "u+d leak 1.03e-07 (± 1.6e-12) × the weakest fault
  gain > dec_tol = 1e-07". Numpy read the same: the least-order row from the pencil basis of the augmented system
  ``[Gu Gd Gf; 0 0 Mr; I 0 0]`` leaks 6.7e-8 on u, d and misses Mr by 1.7e-7 (Rf itself equals Q*·Gf to 6e-14).
  Cause: the staircase's rank decisions at the core's relative tolerance (mm_tol 1e-9; at 1e-11 it reads index 7
  instead of 2) truncate entries of that size, amplified in the row by the plant's gain (‖Ge‖ 187 near z = 1). Fixed
  in ``least_solve._refined_row``: the stable least-order solution's numerator is refitted (poles kept) to the
  matching equation itself on the plant's data (grid, plus points beside the plant poles outside the region, where a
  residue of R counts 1e4-fold), taken only when that lowers the equation's largest residual: leak 1.36e-11, match
  2.0e-11 (numpy, below).
- **Approximate seed 458, approximate_model_matching with Mr = an exact detection row's Rf** (continuous n 16, p 4,
  m 5, nd 2, nf 5; a fault-only integrator at −2.5e-16) — refused "the returned filter's error response differs from
  the designed one by 0.531 (relative 0.081, limit 0.001; 0.725 times its rounding estimate, at most 3.87 of the
  error's size; the candidates' gaps are 4.97, 0.0508 times their worst-case first-order rounding bound)": an
  achievable request (the reference row itself is admissible, error ‖Q_ref·Gw‖∞ = 10.6). Owner:
  approximate_matching.py (``_shipped_filter``); pinned as a strict xfail. With ``SHIPPED_ACCURACY`` lifted to 1
  (patched for the run) the candidate ships, decoupled and stable by numpy, error 4.34379 by numpy against the
  reported 4.37613 (0.74 % apart, above the judge's ERR_RTOL 1e-3): the comparison cannot resolve the candidates
  (its own rounding bound is 3.87 times the error's size), and the reported figure is not the shipped filter's.
  Cause, measured: the library's reading of the shipped response ``Q·[Gf Gw]`` (approximate_matching.
  ``_fault_noise_response``, which reads R without the plant modes a row cancels, postconditions.
  ``_without_cancelled_modes``) adds a spurious pole part c/λ, c ≈ 5.8e-9, at the fault-only integrator the filter
  cancels: its error reads 4.3820 at ω = 1e-8, 7.2199 at 1e-9, 57.853 at 1e-10, while numpy's plain product of the
  same stored filter (order 70) is flat at 4.343789 (= γ_opt, the designed error) from 1e-9 to 10 rad/s. So the
  shipped filter is the designed one; the comparison and the reported error read the removal's error. Owners:
  postconditions.py (judge23: the removal's residue) or approximate_matching.py (amm23: not reading it there).
  amm24 (measured on the filter shipped with SHIPPED_ACCURACY = 1, order 70): at ω = 1e-9, 1.09e-8 (the design's
  lowest point), 1e-7 rad/s the library's mode-free reading equals its own plain product (6.59980, 3.25282, 3.20969
  for the [f w] block's σ_max; numpy 3.20918 flat), so the removal changes nothing there; the difference is the
  plant's values: ``postconditions._values(model.augmented(), λ)`` (Schur form of the balanced A,
  freqresp.transfer_values) differs from numpy's dense balanced GEPP by 10.4, 0.176, 2.0e-3 (‖ΔGe‖_F; Q's values
  agree to 1.7e-7) — a displaced integrator r·δp/λ² that Q's cancellation turns into c/λ. Taking the β_w tier's gap
  only where the bound is below SHIPPED_ACCURACY of the size lets the comparison pass, but the judged error then
  reads 4.37613 > limit 4.34405 on the same values: not fixable in approximate_matching.py alone (reverted).
  Against the stored plant's exact value (Fractions, |Ge| 1.45e8 at 1e-9, 1.33e7 at 1.09e-8 rad/s) the library's
  reading errs 7.2 and 0.167, numpy's 17.6 and 0.0093: neither product is exact there (Q's cancellation of the
  integrator direction amplifies Ge's relative error 1e-8); a refined (double-double) plant reading is what helps.
- **Approximate seed 479, the same call** (discrete n 9, p 3, m 6, nd 2, nf 4; plant poles 0.93 … 0.985, lightly
  damped pairs at 0.985 ± 0.031j, 0.979 ± 0.011j) — refused "u/d leak 1.29e-05 (± 1.7e-09) plus the realisation's
  rounding sensitivity 1.8e-11 = 1.29e-05 of its weakest required fault's gain 2.23e-05 > dec_tol": the reference
  row's fault columns peak at 1, 1.58, 42.6, 50.5 but its noise gain is ‖Q_ref·Gw‖∞ = 20787, so the optimal filter
  is near Q = 0 (error ‖Mr‖∞ ≥ 50.5) and its weakest fault column shrinks to 2.2e-5 of the reference's, below which
  its u/d rounding is no longer dec_tol. Pinned as a strict xfail; it XPASSed on integ23 (f42920d). Bisected
  (amm24): refused on main 7bc7918, on amm23's commits and on dd23's tip; designed from judge23's 8b9da85 on (the
  plain reading's bound adds its measured residual |W r̂|) — the design now ships an order-36 filter at error
  66.08268 = γ_opt (zero filter 66.08356), normalised u/d leak 3.2e-10, judged ok by numpy: a passing test.
- **Approximate seed 500, the same call** (continuous n 11, p 3, m 3, nd 2, nf 5; a fault-only integrator at
  2.2e-16) — refused "the returned filter's error was read as 15.6870387, below the γ-iteration's certified
  infeasible level 15.6881036": the post-condition is right about the reading. With ``_below_certified_refused``
  disabled (patched for the run) the order-53 filter ships and numpy's refined error is 15.6884809 at ω = 0.32559
  rad/s (= γ_opt 15.6884809, the designed error; the reading missed that peak by 1.44e-3, 9.2e-5 relative —
  numpy's grid reads 15.6538 at 0.316); decoupled, stable, below the reference row's 22.6. Owner:
  approximate_matching.py (the shipped error's reading must refine to the peak the γ-iteration certifies; seeds
  268/277's kind, tests/test_audit_seeds18.py). Pinned as a strict xfail; fixed (amm24) in
  approximate_matching._refined_peak's ``climb`` (the judged error's 3 highest grid points were one cluster of
  resonance points at 0.3237 rad/s, 15.687039; the climb brackets past such a plateau): error 15.6884809, a passing
  test.
- **Exact seed 1331, structured_bank on a listed row** (discrete n 26, p 4, m 6, nd 1, faults fs1 fs2 fa1 fa2 fc;
  plant poles up to 0.986, 0.992, 0.996 and a marginal 1.0) — found in the session's last half hour: the row
  [0 1 1 1 0] (fs1 and fc decoupled), listed by ``achievable_structure`` and by numpy's normal-rank test, is refused
  "nullspace design fails its post-conditions (decoupling): residual 1: u+d leak 1.49e-06 (± 5.4e-10) × the
  weakest fault gain > dec_tol" (4.7 s alone). The refusal reads the filter right: numpy's product of the last
  checked generator (order 44, one row; 3,990 points on the unit circle ≥ 1e-3 off the plant's poles) leaks u, d
  9.96e-7 (at z = e^{1.266j}, away from the marginal pole), the excluded fc 8.4e-7 and fs1 2.5e-8, for required
  gains fs2 1.0, fa1 5.46, fa2 3.86 — the null-space row itself is inaccurate at 1e-6. Cause not found in the time
  left (nullspace.py / pencil.py, this audit's files: next session); pinned as a strict xfail.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_approximate_random import check_case  # noqa: E402
from test_synthesis_matching_order import _detection_reference  # noqa: E402
from test_synthesis_random import _extended, _freqresp  # noqa: E402

# dec_tol of the judge (absolute on the row normalised to its weakest fault gain 1). Numpy's reading of
# Q(λ)·Ge(λ) errs by ≲ γ_{3n}·‖Q‖·‖Ge‖ (GEPP on the balanced λI − A, Higham Thm 9.3): n ≤ 8, ‖Q‖ ≤ 2.3, ‖Ge‖ ≤ 187
# on the grid ≥ 1e-3 off the plant's poles — ≤ 1e-11 of the weakest fault gain (0.85): the tolerance is the
# contract itself, with four decades to spare over the reading's error.
TOL = 1e-7


def test_seed1149_unstable_reference_is_matched_without_leak():
    """~0.5 s. The matched filter decouples u, d to TOL of its weakest fault gain and matches M·Rf to TOL of its
    peak, at no higher order than the reference row (2), all read by numpy on 3000 points of the unit circle
    ≥ 1e-3 off the plant's poles. Old code: DesignError "u+d leak 1.03e-07 … > dec_tol" (numpy read the row of the
    pencil basis at 6.7e-8 leak, 1.7e-7 mismatch); new: 1.36e-11, 2.0e-11."""
    from fmu_fdi.design.problems.matching import model_matching

    model, ref = _detection_reference(1149, unstable=True)
    gen = model_matching(model, ref.Rf, updating=True)
    assert gen.info["row_orders"][0] <= ref.Q.n
    lam = np.exp(1j * np.linspace(0.0, np.pi, 3000))
    ev = np.linalg.eigvals(model.A)
    lam = lam[np.min(np.abs(lam[:, None] - ev[None, :]), axis=1) > 1e-3]
    R = _freqresp(gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D, lam) @ _freqresp(*_extended(model), lam)
    M = gen.info["M"]
    want = _freqresp(M.A, M.B, M.C, M.D, lam) @ _freqresp(ref.Rf.A, ref.Rf.B, ref.Rf.C, ref.Rf.D, lam)
    ud, f0 = model.nu + model.nd, model.nu + model.nd + model.nw
    weakest = min(float(np.abs(R[:, :, f0 + j]).max()) for j in range(model.nf))
    assert weakest > 0.1  # the normalised row's faults: 0.85 and 1.63
    assert float(np.abs(R[:, :, :ud]).max()) <= TOL * weakest
    assert float(np.abs(R[:, :, f0:] - want).max()) <= TOL * float(np.abs(want).max())
    eig = np.linalg.eigvals(gen.Q.A) if gen.Q.n else np.zeros(0)
    assert np.all(np.abs(eig) < 1.0)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 17: approximate_matching._shipped_filter refuses an achievable "
                                       "reference (error response 'differs from the designed one by 0.531')")
def test_seed458_detection_row_reference_is_designed():
    """~10-25 s under load (5.5 s of it the refused design). test_approximate_random's check_case on the call
    alone: designed, and its numpy judge (decoupling, R stable, the reported error equal to numpy's, no worse than
    the reference row's own 10.6) passes."""
    res = check_case(458, calls=("amm_ref",))
    assert [st for _, st, _ in res] == ["ok"], res


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 17: the reading without cancelled modes adds c/λ, c ≈ 5.8e-9, at the "
                                       "integrator the filter cancels (postconditions._without_cancelled_modes)")
def test_seed458_shipped_response_is_read_as_the_product():
    """~8-15 s under load (the design, with approximate_matching.SHIPPED_ACCURACY = 1 so that it ships). The library's
    reading of the shipped response ``Q·[Gf Gw; 0 0]`` (approximate_matching._fault_noise_response) equals numpy's
    plain product of the stored filter's and the plant's values at ω = 1e-9 … 1e-7 rad/s (beside the fault-only
    integrator at −2.5e-16, which Q cancels: numpy's error is flat at 4.343789 there, its residue below 5e-15) to
    1e-6 of the response's size. Tolerance: both are readings of the same stored data; numpy's balanced GEPP errs by
    ≲ γ_{3n}‖Q‖‖Ge‖ ≈ 1e-12 of it away from the poles (n = 70), the pole part c/ω a removal may leave at rounding
    level (c ≲ 1e-15 ·‖R‖) is ≤ 1e-6 at ω ≥ 1e-9 — the reading found adds c = 5.8e-9 (5.8 at 1e-9).

    Diagnosis (judge25, not fixed in time; 80-digit ``decimal`` GEPP on the stored doubles, real λ): the exact
    product R = Q·[Gf Gw] of the stored data reads 2.15851 at λ = 1e-7, 2.15725 at 1e-8, 2.14447 at 1e-9, 2.01671 at
    1e-10, 12.04 at 1e-12: its true residue at the integrator (−2.46e-16) is ~1e-11 — rounding level, so the
    "cancelled" decision (library residue 1.15e-7 ≤ δ_i 5.9e-7) is right and R is stable to rounding. The spurious
    c = 5.8e-9 is the library's evaluation of Q: ``postconditions._values(Q, λ)`` (balanced, freqresp.transfer_values'
    Hessenberg path, order 70 ≥ SCHUR_MIN_ORDER 64) errs by 1.19e-7 … 1.20e-7 absolute (|Q| 1.84; the error nearly
    the same at every λ) against 1.5e-9 … 3.8e-9 for numpy's balanced GEPP; that error times Ge's pole part gives
    (Q̂ − Q)·Ge exact = 0.578 at 1e-8, 57.8 at 1e-10, while Q exact·Ĝe errs only 7e-9, 1e-6 (Ge's error lies along
    c_p, which Q cancels). The removal (_without_cancelled_modes) then keeps R_i as evaluated: every reading's bound
    (raw ‖K‖ ≤ k_ρ = 7.1e-7; Y's e_Y = 0.23, ‖Y‖ 1.07e4) exceeds the 5.8e-9 it carries, so the smallest-e reading is
    the raw product — bounds honest, value wrong. Candidate fix: a fourth reading ``R̂_i − Q̂_i(p) C1 W``, the pole
    part subtracted with Q evaluated by the same evaluator at p (its λ-independent backward error cancels), or
    evaluating Q by GEPP per point. Note also this test's reference is itself off: numpy's product errs 1.7e-3 at
    1e-9 and 3.7e-2 at 1e-10 against the exact one (‖A_q‖ 4e5 balanced, poles 0.011 … 5186), so the assertion
    should compare with the exact mode-free R (≈ its value at 1e-7), not numpy's double product."""
    import fmu_fdi.design.problems.approximate_matching as am
    from fmu_fdi.design.toolkit.postconditions import _values
    from test_approximate_random import _detection_reference, noisy_case

    model = noisy_case(458)
    Mr, _ = _detection_reference(model)
    old = am.SHIPPED_ACCURACY
    am.SHIPPED_ACCURACY = 1.0
    try:
        Q = am.approximate_model_matching(model, Mr).Q
    finally:
        am.SHIPPED_ACCURACY = old
    lam = 1j * np.logspace(-9, -7, 5)
    cols = am._fault_noise_columns(model)
    product = (_freqresp(Q.A, Q.B, Q.C, Q.D, lam) @ _freqresp(*_extended(model), lam))[:, :, cols]
    read = am._fault_noise_response(model, Q, lam, _values(model.augmented(), lam))[0]
    size = float(np.max(np.linalg.norm(product, 2, axis=(1, 2))))
    assert float(np.max(np.linalg.norm(read - product, 2, axis=(1, 2)))) <= 1e-6 * size


@pytest.mark.slow
def test_seed479_detection_row_reference_is_designed():
    """~2-5 s under load. As seed 458's test (a strict xfail until judge23's bound; XPASSed on integ23 f42920d).
    Cause, bisected on this check alone: refused (u/d leak 1.29e-5 of the weakest fault gain 2.23e-5) on main 7bc7918,
    on amm23's a78a7a4, 03f1cb3, ac0cfcd and on dd23's b3e8179; designed from judge23's 8b9da85 on (postconditions:
    the plain reading's bound adds its measured residual |W r̂|; its parent is 7bc7918). Now: order 36, error
    66.08268 (= γ_opt, below the zero filter's 66.08356), normalised u/d leak 3.2e-10, no plant-mode cancellation."""
    res = check_case(479, calls=("amm_ref",))
    assert [st for _, st, _ in res] == ["ok"], res


@pytest.mark.slow
def test_seed500_detection_row_reference_is_designed():
    """~3-10 s under load. As seed 458's test (a strict xfail on f42920d: refused 'error read as 15.6870387, below
    the certified infeasible level 15.6881036'). Fixed in approximate_matching._refined_peak (``climb``, used by
    _judged_error): the 3 highest grid points were all in one cluster of resonance points at 0.3237 rad/s reading
    15.687039, and their neighbours' intervals never reached the peak at 0.32558; the climb refines between the
    nearest lower points past the plateau. Now: order 53, error 15.6884809 (γ_opt 15.6884809, numpy's refined peak)."""
    res = check_case(500, calls=("amm_ref",))
    assert [st for _, st, _ in res] == ["ok"], res


def test_seed1331_row_is_achievable_by_numpy():
    """~1 s. Numpy's normal-rank test (tests/test_audit_achievable_rank.py: four generic points, unit-norm columns,
    RANK_TOL 1e-8, undecided ratios fail) lists the row [0 1 1 1 0] of exact seed 1331, as achievable_structure does:
    its refusal (the next test) is a false one."""
    from test_audit_achievable_rank import numpy_rows
    from test_synthesis_random import random_case

    rows, undecided = numpy_rows(random_case(1331))
    assert not undecided and (0, 1, 1, 1, 0) in rows


@pytest.mark.xfail(strict=True, reason="issue 17: structured_bank refuses a listed row of exact seed 1331: the series "
                                       "realisation fac @ Q1 of the noise normaliser (nullspace._noise_combination) "
                                       "leaks u+d 1e-6 where the pointwise product leaks 1e-8")
def test_seed1331_listed_row_is_designed():
    """~5-10 s. structured_bank on the row alone: designed, and test_synthesis_random's numpy judge (u, d and the
    excluded faults fs1, fc below 1e-7 of the weakest required fault, R stable by PBH, Q nonzero, faults visible)
    passes.

    Diagnosis (audit24; numpy's product Q(z)·Ge(z) on 4,000 points of the unit circle ≥ 1e-3 off the plant's
    poles, leak = max |R_u, R_d| over the weakest required fault peak; the row's model: fs1, fc as disturbances,
    nw > 0, so nullspace_design takes _approximate_pencil → _noise_combination):
    - the pencil basis Q0 (pencil_basis: one row, order 26, staircase all 1s): leak 7.3e-8 (0.342 absolute for
      fault peaks 4.7e6, 9.2e8, 4.6e9 — rounding of the strongest fault's scale). Identical at rtol 1e-13, 1e-11,
      1e-9 (the default 8.4e-11·‖[A B; C D]‖): the rank decisions are not the cause;
    - after stable_internal_form (order 26, z = 0.999 moved): 2.9e-8;
    - the co-outer noise normaliser fac (order 22, |fac| 2.2e-9 … 0.13 on the circle): numpy's POINTWISE product
      fac(z)·Q1(z)·Ge(z) leaks 1.0e-8 — the design is right; but the series realisation ``fac @ Q1`` (order 48)
      reads 9.1e-6 and its minreal (the stored Q) 1.0e-6; scaling Q1 by a constant or balancing the series
      before minreal does not change it (7.3e-6, 1.0e-6);
    - _refined leaves it (1.0e-6) without trying the refit: on its own grid (76 usable of 202 points) the leak
      reads 2.0e-4 of the weakest fault, above REFINE_MAX_LEAK 1e-4 (points nearer the plant's poles than
      numpy's 1e-3 amplify it); _boundary_modes_cancelled's four candidates read 1.49e-6 … 1.73e-6 (order
      48, 44) by _verdict: refused.
    Cause: realising the product of two ill-scaled systems (Q1's gain ~1e9 against fac's ~1e-9) in one state
    space: the coupling block B_fac·C_Q1 makes the product's resolvent ill-conditioned, and its values lose
    ~2 decades against the product of the values. Fix to try (nullspace.py, audit24's file; next session):
    realise ``fac·Q1`` without the large coupling (a constant rescaling cannot: it commutes) — e.g. an additive
    (modal) decomposition of the series (Sylvester-separated blocks; fac's and Q1's poles are disjoint), or a
    numerator refit on the pointwise product (as refine.refine_decoupling, poles kept), the judge (_verdict)
    choosing the better realisation."""
    from fmu_fdi.design import structured_bank
    from test_synthesis_random import judge, random_case

    model = random_case(1331)
    S = np.array([[0, 1, 1, 1, 0]])
    bank = structured_bank(model, S)
    wdec = bool(model.nw) and all(g.info.get("noise") == "decoupled exactly" for g in bank.members)
    assert judge(bank, model, S, model.fault_names, w_decoupled=wdec) == []
