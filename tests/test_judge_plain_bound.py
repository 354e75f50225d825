"""The judge's bound on a *plain* (double) reading of a decoupled block holds at every point, where the filter's A is
reduced to Hessenberg form (finding of judge21, measured by judge22 and pinned as a strict xfail; fixed by judge23).

Since judge23 the bound adds the a-posteriori term ``|W r̂|``, ``r̂ = B_q G − (λI − A_q) Z`` the plain solve's
residual against the stored A_q (``postconditions._plain_values``, ``_residual_term``): the solve's backward error is
measured, whatever its structure, and the componentwise terms pay only for roundings. Seed 4's worst point is now at
0.94 of its bound (was 13.1×); the bound grew 2.5× median, 13.9× at most on the u/d block (1.0–1.1× on the others).
The same on the audit readings: seed 338 21× → 0.96, 15.4× → 0.94; seed 206 1.65× → 0.67; the design's own
candidate 34.8× → 0.98. The test failed on the old code (7bc7918, strict xfail): "plain reading off by 13.1 times
its bound". What was measured before the fix:

``_plain_values`` reads ``R_X = C_q Z + D_q G``, ``Z = (λI − A_q)^{-1}(B_q G)``, with the LU of ``λI − H``,
``A_q = U H Uᵀ`` (:func:`fmu_fdi.freqresp.hessenberg_form`), and charges it ``3N·u·err``, ``err`` built from
``|W||λI − A_q||Z|`` (``_decoupled_reading``'s docstring: GEPP's componentwise backward error ``|ΔM| ≤ γ_3N|M|``).
That backward error is the one of an LU of ``λI − A_q`` itself. The Householder reduction to Hessenberg form has a
*normwise* backward error, ``U(H + ΔH)Uᵀ = A_q + ΔA`` with ``||ΔA||_F ≲ c·n²·u·||A_q||_F`` (Higham, *Accuracy and
Stability*, 2nd ed., §19.3; Golub & Van Loan §7.4), spread over every entry: on a balanced A whose entries span
1.3e-5 … 1.2e4 (||A||_F = 4.9e4, seed 4's row filter of order 22) that is far above ``u·|A_q|`` at the small
entries, so the componentwise bound is not a bound. Measured (x86, this file's independent reading as the truth):

- H∞ matching seed 4 (tests/test_synthesis_ammp.py ``_random_case``, default options), the judge's reading of the
  shipped filter (``check_generator(gen, raise_error=False, normalize=False)``), the u/d block: the plain reading
  exceeds its bound at 87 of 144 points, by up to 13.1× (a point reads 1.18e-9 where the value is 6.75e-12 and the
  bound is 9.1e-11); a reading of the design's own candidate (inside ``approximate_model_matching``) by up to 34.8×.
  The same solves by a dense GEPP of ``λI − A_q`` (scipy ``solve``, same balanced data) stay within the same bound
  (ratio ≤ 2.4e-3), although ``|L||U|/|λI − A|`` reaches 6.7e3 entrywise there: the cause is the reduction's
  normwise backward error, not GEPP's growth.
- Approximate audit cases (``approximate_model_matching(noisy_case(s), detection row's Rf)``, the judge's first two
  readings): seed 206 (order 99) up to 1.65× at 7 of 222 points, seed 338 (order 125) up to 21× at 76 of 244 (u/d)
  and 15.4× at 66 (the other block); seed 7 (order 29) ≤ 5.1e-3. Every reading beyond its bound *over-states* the
  value (no point anywhere read below ``value − bound``): the perturbation breaks the cancellation.
- Adding the reduction's term ``||W_i||₂·||A_q||_F·||Z_j||₂`` to err restores the bound at every point (ratio ≤
  0.084) and raises it by 329× (median) … 1.8e3× at seed 4; at seed 7 (order 29) by 1.5× … 1.9×.
- Verdicts: after ``_decoupled_values``' refine loop, no point left at its double reading had a true error that let it
  reach its block's refined peak (seed 4: max ratio 1.09 at unrefined points, whose ``reading + true error`` ≤
  1.2e-12 against the peak 6.8e-12; seed 7: ≤ 3.3e-3; 206: ≤ 0.012; 338: every point refined) — the over-stated
  readings set a peak, were refined and fell. A reading that *under-states* by more than its bound could however stay
  masked below a peak it reaches: nothing in the derivation excludes it. (At order 125, seed 338, this file's truth
  itself moves by 6× the *refined* bound between 2 and 5 refinement steps — 1/300 of the plain bound, so the plain
  figures stand, but the refined readings there could not be checked with it; judged since by mpmath at 40
  digits, they are within 1.3e-3 of their bound: tests/test_judge_refined_bound.py.)

The truth here: every solve of ``(λI − A) X = B`` by Gaussian elimination with partial pivoting in numpy's
clongdouble, refined twice with clongdouble residuals (numpy only; agrees with a dense double LU refined eight times
to 1e-4 of the block's peak — far below the 13× excess asserted against).
"""
import numpy as np
import pytest

import fmu_fdi.design.toolkit.postconditions as pc
from fmu_fdi.design.problems.approximate_matching import approximate_model_matching
from fmu_fdi.design.toolkit.postconditions import EPS, check_generator
from test_synthesis_ammp import _random_case

pytestmark = pytest.mark.skipif(np.finfo(np.longdouble).eps >= np.finfo(float).eps,
                                reason="numpy's longdouble is double here: no independent truth to compare with")


def _ld_solve(M, B):
    """``M^{-1} B`` by Gaussian elimination with partial pivoting in clongdouble (numpy only)."""
    M, X = M.astype(np.clongdouble), B.astype(np.clongdouble)
    n = M.shape[0]
    for j in range(n):
        p = j + int(np.argmax(np.abs(M[j:, j])))
        M[[j, p]], X[[j, p]] = M[[p, j]], X[[p, j]]
        f = M[j + 1:, j] / M[j, j]
        M[j + 1:, j:] -= f[:, None] * M[j, j:][None, :]
        X[j + 1:] -= f[:, None] * X[j][None, :]
    for j in range(n - 1, -1, -1):
        X[j] = (X[j] - M[j, j + 1:] @ X[j + 1:]) / M[j, j]
    return X


def _ld_response(S, lam):
    """``S(λ)`` at the points lam, each solve by :func:`_ld_solve` refined twice with clongdouble residuals."""
    LD = np.clongdouble
    A, B, C, D = (X.astype(np.longdouble) for X in (S.A, S.B, S.C, S.D))
    out = np.empty((lam.size, S.p, S.m), LD)
    for k, lk in enumerate(lam):
        L = LD(lk) * np.eye(S.n) - A
        X = _ld_solve(L, B)
        for _ in range(2):
            X = X + _ld_solve(L, B - (LD(lk) * X - A @ X))
        out[k] = C @ X + D
    return out


@pytest.fixture(scope="module")
def readings():
    """The (row, plant columns, points, blocks) of each decoupled reading of seed 4's shipped filter by the judge."""
    model, Mr = _random_case(4)
    gen = approximate_model_matching(model, Mr)
    calls, orig = [], pc._decoupled_values

    def spy(Qi, Geb, lam, blocks, with_refined=False):
        calls.append((Qi, Geb, lam, blocks))
        return orig(Qi, Geb, lam, blocks, with_refined)

    mp = pytest.MonkeyPatch()
    mp.setattr(pc, "_decoupled_values", spy)
    try:
        check_generator(gen, raise_error=False, normalize=False)
    finally:
        mp.undo()
    assert calls
    return calls


class _Stop(Exception):
    pass


@pytest.fixture(scope="module")
def candidate_reading():
    """The second decoupled reading inside seed 4's design (its order-70 candidate, where the old bound was exceeded
    34.8×; 5.31× in the first); the design is stopped there."""
    model, Mr = _random_case(4)
    calls, orig = [], pc._decoupled_values

    def spy(Qi, Geb, lam, blocks, with_refined=False):
        calls.append((Qi, Geb, lam, blocks))
        if len(calls) == 2:
            raise _Stop
        return orig(Qi, Geb, lam, blocks, with_refined)

    mp = pytest.MonkeyPatch()
    mp.setattr(pc, "_decoupled_values", spy)
    try:
        approximate_model_matching(model, Mr)
    except _Stop:
        pass
    finally:
        mp.undo()
    assert calls and orig is pc._decoupled_values
    return calls[1:2]


def _worst_ratio(readings) -> float:
    worst = 0.0
    for Qi, Geb, lam, blocks in readings:
        Qb = Qi.balanced()[0]
        N = max(Qb.n, Geb.n, 1)
        val, err, _ = pc._plain_values(Qb, Geb, lam)
        true = (_ld_response(Qb, lam) @ _ld_response(Geb, lam)).astype(complex)
        for b in blocks:
            d = np.linalg.norm((val - true)[:, :, b], axis=(1, 2))
            e = 3 * N * EPS / 2 * np.linalg.norm(err[:, :, b], axis=(1, 2))
            worst = max(worst, float(np.max(d / e)))
    return worst


def test_plain_reading_lies_within_its_bound_at_every_point(readings):
    """At every point and block, ``|plain reading − value|_F ≤ 3N·u·||err||_F`` (``_plain_values``, the bound
    ``_refine_mask`` masks points by), the value from :func:`_ld_response` (whose own error, ~1e-19 relative times
    the same conditioning, is ~1e-4 of the bound at most). Measured 0.94 (13.1 on 7bc7918)."""
    worst = _worst_ratio(readings)
    assert worst <= 1.0, f"plain reading off by {worst:.3g} times its bound"


@pytest.mark.slow
def test_plain_reading_of_the_designs_candidate_lies_within_its_bound(candidate_reading):
    """The same on the design's own order-70 candidate (~12 s: the design up to its second reading, the clongdouble
    truth at 169 points). Measured 0.98
    (34.8 on 7bc7918)."""
    worst = _worst_ratio(candidate_reading)
    assert worst <= 1.0, f"plain reading off by {worst:.3g} times its bound"
