"""Counts ok / refused / broken of the approximate designs on the seeded ill-scaled random models with
noise, judged independently (tests/test_approximate_random.py: numpy frequency responses of
R = Q·[Gu Gd Gw Gf; I 0 0 0], rows normalised to fault gain 1 (β = 1 for model detection),
‖R_u‖, ‖R_d‖ ≤ 1e-7, R stable by PBH, Q nonzero, the reported gap / matching error / MDgap equal to
numpy's refined peaks within the file's FIG_RTOL / ERR_RTOL; a matching error no worse than Q = 0 and
than the exact detection row it takes as reference).

Calls per model: nullspace_design (AFD), afdi_bank on up to 3 rows achievable_structure lists,
approximate_model_matching with Mr = an exact detection row's fault response and with Mr = I,
approximate_model_detection_bank on a three-model set (stable plants only). "broken": a returned
design failing the judge, another exception than DesignError, an achievable AFD/AFDI request refused
(or a detection-row reference whose matching is refused: Q_ref itself is admissible).

Run: python benchmarks/approximate_random_judged.py [N] [first_seed] [-v] [--timeout=SECONDS]
(a call that gives no answer within the timeout counts as "timeout", none by default)
(seeds first_seed … first_seed + N − 1; default 20 models from seed 0)

Measured 27 Nov (audit17, ``--timeout=120``, nice 10 beside the exact audit, load ~2):

    seeds    AFD     afdi_bank  amm(Mr=row)  amm(Mr=I)  model detection  total ok/refused/broken
    160-179  20/0/0  19/0/1     19/0/1       20/0/0     9/0/0            87/0/2
    180-199  20/0/0  20/0/0     19/0/1       20/0/0     8/0/0            87/0/1

no timeout; median 6.0 / 3.7 s per model, slowest 29.2 s (191), 20.2 s (199), 19.8 s (173). The three broken calls
are pinned and diagnosed in tests/test_audit_seeds17.py (176 afdi_bank: AB13DD returns a local peak of a row's fault
slice; 173, 199 amm(Mr = row): the shipped minimal realisation of Y·Φ·Q0 loses the u/d cancellation the product
keeps).

Measured 27-28 Nov (audit18, ``--timeout=120``, nice 10 beside the exact audit and four other helpers, load 2-9 —
times indicative):

    seeds    AFD     afdi_bank  amm(Mr=row)  amm(Mr=I)  model detection  total ok/refused/broken  median / slowest
    200-219  20/0/0  20/0/0     19/0/1       20/0/0     8/0/0            87/0/1                   6.2 / 26.9 s (219)
    220-239  20/0/0  20/0/0     20/0/0       20/0/0     7/0/0            87/0/0                   38.8 / 171 s (227)
    240-259  20/0/0  20/0/0     20/0/0       19/1/0     12/0/1           91/1/1                   33.2 / 109 s (243)
    260-279  20/0/0  20/0/0     18/0/2       19/1/0     9/0/0            86/1/2                   24.3 / 111 s (261)
    280-299  20/0/0  20/0/0     20/0/0       19/1/0     8/0/0            87/1/0                   9.6 / 71.8 s (282)

no timeout. Pinned in tests/test_audit_seeds18.py: seed 206 amm(Mr = row) (the judge's u/d reading refines only the
points near the unrefined readings' peak and over-read the product realisation's leak, 2.16e-7 for numpy's 1.6e-10,
so the leaking minimal realisation shipped: postconditions.py, strict xfail); seed 243 model detection (MDgap ∞ for
numpy's 5.04e6: fixed in model_detection._noise_gain); seed 240's amm(Mr = I) refusal is false (the optimum is Q = 0's
error 1, one admissible row for five faults; nonzero admissible filters attain it), as are seed 26's (re-run) and
seed 270's (three rows; refused for the near-optimal filter's u/d leak 1.9e-7) and 282's (two rows; R-stability:
residue 2.75e-11 against its bound 2.54e-11); seeds 268, 277 amm(Mr = row): the
error reported below the γ-iteration's certified infeasible level (4.63869 for numpy's 4.72841, 11.8347 for 11.8606)
— the design's grids straddle a lightly damped peak, and the true error exceeds the design's limit (strict xfails,
approximate_matching.py).

Measured 28 Nov (audit20, ``--timeout=120``, nice 10 beside four other helpers' work and a CI run, load 3-10 — times
indicative):

    seeds    AFD     afdi_bank  amm(Mr=row)  amm(Mr=I)  model detection  total ok/refused/broken  median / slowest
    300-319  20/0/0  20/0/0     20/0/0       20/0/0     7/0/0            87/0/0                   27.7 / 102 s (317)
    320-339  20/0/0  20/0/0     18/0/2       19/1/0     7/0/0            84/1/2                   19.7 / 135 s (331)
    340-359  20/0/0  20/0/0     20/0/0       20/0/0     9/0/0            89/0/0                   14.0 / 115 s (342)

no timeout. Pinned in tests/test_audit_seeds20.py (strict xfails, numpy-judged): seed 338 amm(Mr = row) refused for a
u/d leak 1.14e-6 the judge over-reads on the product realisation (numpy 1.6e-10; seed 206's cause, postconditions.py:
passes with judge19's refinement); seed 327 amm(Mr = row) refused (2.07e-7) where the product realisation meets the
final rule (4.4e-8) but is outside _decoupled_candidate's 0.1·dec_tol replacement margin (approximate_matching.py:
passes with the margin 0.5); seed 336's amm(Mr = I) refusal is false (one admissible row for four faults, Q = 0's
error optimal; seeds 26/240/270/282's case).

Measured 28 Nov (audit23, ``--timeout=120``, nice 10 beside three other helpers' work, load 2-9 — times indicative;
from seed 400 on, the ``amm(Mr=I)`` refusals naming the rank bound re-judged by numpy, :func:`rank_refusals_judged`,
and those of 360-399 the same way after the run: all 172 confirmed; 617 ok / 175 refused / 3 broken):

    seeds    AFD     afdi_bank  amm(Mr=row)  amm(Mr=I)  model detection  total ok/refused/broken  median / slowest
    360-379  20/0/0  20/0/0     20/0/0       1/19/0     10/0/0           71/19/0                  4.1 / 19.7 s (373)
    380-399  20/0/0  20/0/0     20/0/0       1/19/0     10/0/0           71/19/0                  8.9 / 42.8 s (397)
    400-419  20/0/0  20/0/0     20/0/0       0/20/0     6/0/0            66/20/0                  8.4 / 29.5 s (403)
    420-439  20/0/0  20/0/0     20/0/0       0/20/0     6/0/0            66/20/0                  6.1 / 33.9 s (421)
    440-459  20/0/0  20/0/0     19/0/1       0/20/0     8/0/0            67/20/1                  4.8 / 24.3 s (451)
    460-479  20/0/0  20/0/0     19/0/1       1/19/0     9/0/0            69/19/1                  9.3 / 50.9 s (469)
    480-499  20/0/0  20/0/0     20/0/0       2/18/0     10/0/0           72/18/0                  25.3 / 201 s (483)
    500-519  20/0/0  20/0/0     19/0/1       0/20/0     7/0/0            66/20/1                  8.5 / 93.0 s (513)
    520-539  20/0/0  20/0/0     20/0/0       0/20/0     9/0/0            69/20/0                  15.1 / 57.2 s (539)

no timeout. ``amm(Mr=I)`` is now mostly refused early by amm21's rank bound (the admissible fault response's normal
rank r below nf: 172 refusals, numpy's r = rank [Gd Gf] − rank Gd below nf on every one and equal to the message's)
and three times (388, 420, 522) by the γ-iteration's certificate that no admissible filter beats Q = 0 (not
re-judged: no numpy bound). Pinned in tests/test_audit_seeds23.py (strict xfails, approximate_matching.py and the
judge's reading): seed 458 amm(Mr = row) refused "error response differs from the designed one by 0.531 (relative
0.081 ...; 0.725 times its rounding estimate, at most 3.87 of the error's size)" — the reading without cancelled
modes adds c/λ, c ≈ 5.8e-9, at the integrator the filter cancels; seed 479 amm(Mr = row) refused for a u/d leak
1.29e-5 of a weakest fault gain 2.23e-5 (the reference row's noise gain 20787 against fault peaks 1-50.5: the
optimum is near Q = 0); seed 500 amm(Mr = row) refused for an error read below the certified level (15.6870387 <
15.6881036; numpy 15.6884809 at 0.3256 rad/s = γ_opt).

With ``--gap-time SEED [SEED …]`` it times instead, per seed, the afdi_bank of the audit (the rows
check_case picks) and then the bank's gaps read two ways in the same run: the baseline
``analysis.fault_noise_gap`` on the stacked bank (rows of the bank's internal form, which carry every
member's states) against ``banks.row_gaps`` (each row on its own member); prints both times, their
ratio and the largest relative difference of the gaps.
"""
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_synthesis_random  # noqa: E402
from test_approximate_random import check_case, noisy_case  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthesis_random_judged import KINDS, _kind as _kind_exact, tally  # noqa: E402


def _kind(detail: str) -> str:
    """A short class of a breakage for the totals (the exact audit's classes and the figures' mismatches)."""
    return _kind_exact(detail, KINDS + (("gap: reported", "gap mismatch"), ("MDgap|MDperf", "MD figure mismatch"),
                                        ("matching error: reported", "error mismatch"),
                                        ("above", "error above a known filter's")))


def _desc(seed: int) -> str:
    m = noisy_case(seed)
    return f"n={m.n} p={m.ny} m={m.nu} nd={m.nd} nw={m.nw} nf={m.nf} {'disc' if m.dt else 'cont'}"


#: the rank a rank-bound refusal names (approximate_matching._unapproachable_reference's message)
_RANK_CLAIM = re.compile(r"normal rank (\d+) \(that of Q0")


def rank_refusals_judged(seed: int, results):
    """``results`` of check_case with every ``amm(Mr=I)`` refusal that names the rank bound judged again by numpy:
    every admissible filter is ``Y·Q0`` (Q0 a left null-space basis of ``[Gu Gd; I 0]``), so its fault response has
    normal rank at most ``r = rank [Gd Gf] − rank Gd`` (output rows; u is known), and with ``Mr = I`` on nf faults
    Weyl's bound ``sup σ_{r+1}(Mr) = 1 = ‖Mr‖∞`` makes Q = 0 optimal exactly when r < nf. Numpy's r:
    test_audit_achievable_rank's normal-rank test (unit-norm columns, four generic points, RANK_TOL = 1e-8, a decision
    inside UNDECIDED fails loudly). A refusal is broken when numpy's r is nf (some admissible filter does better than
    none) or differs from the r the message names."""
    if not any(what == "amm(Mr=I)" and st == "refused" for what, st, _ in results):
        return results
    import numpy as np

    from test_audit_achievable_rank import RANK_TOL, UNDECIDED, _normalised
    from test_synthesis_random import _extended, _freqresp

    model = noisy_case(seed)
    rng = np.random.default_rng(0)
    lam = rng.uniform(0.3, 3.0, 4) * np.exp(1j * rng.uniform(0.2, 1.3, 4))
    A, B, Ce, De = _extended(model)
    G = _freqresp(A, B, Ce[:model.ny], De[:model.ny], lam)
    d = list(range(model.nu, model.nu + model.nd))
    f = list(range(model.nu + model.nd + model.nw, B.shape[1]))

    def rank(M):
        s = np.linalg.svd(_normalised(M), compute_uv=False) if M.size else np.zeros(0)
        ratios = s / s[0] if s.size and s[0] > 0 else s
        return int(np.sum(ratios > RANK_TOL)), [x for x in ratios if UNDECIDED[0] < x < UNDECIDED[1]]

    r, undecided = 0, []
    for Gk in G:
        rd, ud = rank(Gk[:, d])
        rdf, udf = rank(Gk[:, d + f])
        r, undecided = max(r, rdf - rd), undecided + ud + udf
    out = []
    for what, st, detail in results:
        claim = _RANK_CLAIM.search(detail) if what == "amm(Mr=I)" and st == "refused" else None
        if claim:
            if undecided:
                st, detail = "broken", f"rank test cannot decide {undecided[:2]}; " + detail
            elif r >= model.nf or r != int(claim.group(1)):
                st, detail = "broken", (f"false refusal (numpy's normal rank of Q0·[Gf; 0] is {r} of nf = "
                                        f"{model.nf}): " + detail)
        out.append((what, st, detail))
    return out


def run(N: int = 20, first: int = 0, verbose: bool = False):
    return tally(range(first, first + N), lambda seed: rank_refusals_judged(seed, check_case(seed)), _desc,
                 kind=_kind, width=34, verbose=verbose)


def gap_time(seeds) -> None:
    import time

    import numpy as np

    from fmu_fdi.analysis import fault_noise_gap
    from fmu_fdi.design import afdi_bank
    from fmu_fdi.design.problems.achievable import achievable_structure
    from fmu_fdi.design.problems.banks import row_gaps
    from gap_speed import rel_diff

    print(f"{'seed':>4s} {'model':34s} {'afdi_bank s':>11s} {'stacked s':>9s} {'rows s':>7s} {'ratio':>7s} "
          f"{'max rel diff':>12s}")
    for seed in seeds:
        model = noisy_case(seed)
        listed = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
        rng = np.random.default_rng(seed)
        rows = listed if len(listed) <= 3 else listed[np.sort(rng.choice(len(listed), 3, False))]
        t = time.perf_counter()
        bank = afdi_bank(model, rows)
        t_design = time.perf_counter() - t
        t = time.perf_counter()
        own = np.array(row_gaps(bank, rows))
        t_rows = time.perf_counter() - t
        t = time.perf_counter()
        stacked = fault_noise_gap(bank, rows)
        t_stacked = time.perf_counter() - t
        diff, same_inf = rel_diff(own, stacked)
        print(f"{seed:4d} {_desc(seed):34s} {t_design:11.1f} {t_stacked:9.1f} {t_rows:7.2f} "
              f"{t_stacked / t_rows:7.1f} {diff:12.1e}{'' if same_inf else '  (an infinite gap differs)'}",
              flush=True)


if __name__ == "__main__":
    if "--gap-time" in sys.argv:
        gap_time([int(a) for a in sys.argv[sys.argv.index("--gap-time") + 1:]])
        sys.exit()
    args = [a for a in sys.argv[1:] if a != "-v" and not a.startswith("--timeout=")]
    for a in sys.argv[1:]:
        if a.startswith("--timeout="):
            test_synthesis_random.CALL_TIMEOUT = int(a.split("=", 1)[1])
    run(int(args[0]) if args else 20, int(args[1]) if len(args) > 1 else 0, "-v" in sys.argv)
