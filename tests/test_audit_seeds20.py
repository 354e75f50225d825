"""Audit of seeds nobody had run (issue 17, fourteenth session), judged by numpy: exact
``benchmarks/synthesis_random_judged.py`` from seed 889 and approximate ``benchmarks/approximate_random_judged.py`` from
seed 300 (the tallies: those scripts' docstrings and the commit messages). The exact sets came back clean. The
approximate findings are in files this audit does not own (approximate_matching.py, postconditions.py), so they are
pinned here with their cause (seed 338's two tests pass since judge19's refinement landed with judge20):

- **Seed 338, approximate_model_matching with Mr = an exact detection row's Rf** (continuous n 30, p 4, m 5, nd 1,
  nf 5; an achievable request: the reference row is admissible) — refused "residual 1: u/d leak 1.14e-06 (± 1.3e-10)
  plus the realisation's rounding sensitivity 5e-10 = 1.14e-06 of its weakest required fault's gain 3.31 > dec_tol".
  The optimal filter is right: its product realisation ``Y·Φ·Q0`` (order 125) leaks 1.6e-10 of the weakest required
  fault by numpy's refined evaluation, but the library's judge reads that same stored filter at 1.14e-6 ± 1.3e-10 —
  the cause of seed 206 (tests/test_audit_seeds18.py): ``postconditions._decoupled_values`` refines only the points
  near the *unrefined* readings' peak, and a point it masked keeps its double reading with the extended precision's
  bound. With judge19's repeated refinement (branch judge19, 19b66e6, postconditions.py only) the judge reads the
  product at 3.15e-11 ± 1.3e-10, ``_decoupled_candidate`` ships it and check_case's numpy judge passes the design (65 s
  under load). Owner: postconditions.py (judge20, landing judge19's refinement).
- **Seed 327, the same call** (discrete n 25, p 3, m 4, nd 2, nf 5) — refused "residual 1: u/d leak 9.13e-08
  (± 2.6e-08) plus the realisation's rounding sensitivity 1.2e-07 = 2.07e-07 of its weakest required fault's gain
  0.673 > dec_tol". Not the judge (with judge19's refinement it is refused the same way): the product realisation
  ``Y·Φ·Q0`` (order 115) reads 8.98e-9 ± 7.9e-9 with sensitivity 3.45e-8 — 4.4e-8, within the final rule
  (``_ud_leak_refused``: reading + sensitivity ≤ dec_tol) — and numpy's refined evaluation reads 1.09e-8; but
  ``approximate_matching._decoupled_candidate`` replaces the taken minimal realisation (2.07e-7) only by a candidate
  within ``SHIPPED_LEAK_MARGIN·dec_tol = 1e-8``, so nothing replaced it, the re-decoupling found no refit, and the
  minimal one was refused. With ``SHIPPED_LEAK_MARGIN = 0.5`` (patched for the run) the product ships and check_case's
  numpy judge passes the design (48 s). Proposed (approximate_matching.py, amm21): where no candidate is within the
  margin and the re-decoupling fails, ship the candidate of least leak that meets the final rule (and its error tests)
  rather than refuse the taken one.
- **Seed 336, approximate_model_matching with Mr = I** (continuous n 29, p 2, m 1, nd 1, nf 4; one admissible row for
  four faults) — refused "the returned filter's error response differs from the designed one by 0.615 (relative
  0.615, limit 0.001; 28.2 times its rounding estimate ...)": the degenerate optimum of seeds 26, 240, 270, 282
  (tests/test_audit_seeds18.py; Q = 0's error 1 is optimal and a nonzero admissible filter attains it, below).
  Owner: approximate_matching.py (amm21, the Q = 0-optimal matching).

Since (amm22, on integ20 135bd96): seed 327 is designed (the least-leaking realisation within dec_tol ships where the
taken one cannot be re-decoupled) and seed 336 is refused early naming its rank bound, the product decision for
seeds 26, 240, 270, 282 (amm21's ``_unapproachable_reference``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_approximate_random import _points, _refined_peak, check_case  # noqa: E402
from test_audit_seeds18 import _product_realisation, refined_values  # noqa: E402
from test_synthesis_random import _extended  # noqa: E402


def _numpy_leak(model, Q, lam) -> float:
    """The u/d leak of ``Q·[Gu Gd; I 0]`` normalised by the weakest fault's peak (every fault required: Mr is an exact
    detection row of every fault), by numpy alone: ``Q(λ)`` and ``Ge(λ)`` each by test_audit_seeds18's
    :func:`refined_values` (iterative refinement in longdouble), the leak's peak refined around the grid's highest
    points (test_approximate_random's :func:`_refined_peak`)."""
    plant = _extended(model)
    f0 = model.nu + model.nd + model.nw  # the fault columns follow u, d, w (test_approximate_random._cols)

    def R(pts):
        Qv = refined_values(Q.A, Q.B, Q.C, Q.D, pts)
        return (Qv @ refined_values(*plant, pts)).astype(complex)

    Rf = np.abs(R(lam)[:, :, f0:])
    weakest = min(float(np.max(Rf[:, :, np.arange(model.nf)[f.columns]])) for f in model.faults)
    ud = slice(0, model.nu + model.nd)
    return _refined_peak(lambda L: R(L)[:, :, ud], lam, model.dt, np.linalg.eigvals(model.A)) / weakest


# ------------------------------------------------------------------------------------------ seed 338
@pytest.mark.slow
def test_seed338_judge_reads_the_stored_filters_leak(monkeypatch):
    """~1-2 min under load (15-60 s of it the design up to its shipping stage, the rest numpy's refined evaluation of
    the order-125 filter; 255 s on every fourth point). The library's normalised u/d reading of the product
    realisation Y·Φ·Q0 is a reading of the stored filter with an error bound: it may not exceed numpy's refined
    reading of the same stored data by more than that bound. Numpy: :func:`_numpy_leak` on every 16th point of
    test_approximate_random's grid (1500 log points over the poles' band; the leak is ~1e-10 everywhere, four
    decades below the reading compared). Tolerance: 1.05 × numpy's figure (the two normalising fault peaks are read
    on different grids: a grid peak is low by at most a few percent, test_approximate_random's FIG_RTOL derivation)
    plus the judge's own ``decoupling_error``. On this session's base (tB): judge 1.14e-6 (error 1.3e-10), numpy
    1.64e-10 — failed; with judge19's refinement (landed with judge20) the judge reads 3.15e-11 and this passes."""
    from fmu_fdi.design.problems.approximate_matching import normalised_leak, required_faults

    model, Mr, Q = _product_realisation(monkeypatch, 338)
    lam = _points(model, [Q])
    required = required_faults(model, Mr, lam)
    assert required.all()  # (numpy normalises by the weakest of every fault)
    fig = normalised_leak(model, Q, required, None, 1e-7)
    leak = _numpy_leak(model, Q, lam[::16])
    assert leak < 1e-9  # the product realisation decouples (the optimal filter is right)
    read, bound = fig["decoupling"], fig["decoupling_error"]
    assert read <= 1.05 * leak + bound, (read, bound, leak)


@pytest.mark.slow
def test_seed338_matching_the_detection_row_is_designed():
    """~40-70 s under load. check_case's numpy judge (test_approximate_random.judge_amm) on
    ``approximate_model_matching(model, Mr = the exact detection row's Rf)``: refused on this session's code (module
    docstring); with judge19's repeated refinement the design passes (65 s)."""
    assert check_case(338, calls=("amm_ref",)) == [("amm(Mr=detection row)", "ok", "")]


# ------------------------------------------------------------------------------------------ seed 327
@pytest.mark.slow
def test_seed327_matching_the_detection_row_is_designed():
    """~30-70 s under load (31 s measured). check_case's numpy judge on ``approximate_model_matching(model, Mr = the
    exact detection row's Rf)``. Strict xfail on integ20 135bd96 (refused: the minimal realisation's u/d leak 2.07e-7
    > dec_tol, module docstring); since amm22, ``_decoupled_candidate`` lists the candidates within dec_tol but not
    its 0.1·dec_tol margin, and approximate_model_matching ships the least-leaking one that meets the final rule where
    the taken one's re-decoupling fails: the product realisation (order 115, 4.4e-8), numpy's judge passes it."""
    assert check_case(327, calls=("amm_ref",)) == [("amm(Mr=detection row)", "ok", "")]


# ------------------------------------------------------------------------------------------ seed 336
def test_seed336_optimum_of_matching_identity_is_attained():
    """~2 s. Why the refusal of seed 336's ``amm(Mr = I)`` is right: test_audit_seeds18's proof for seeds 26, 240,
    270, 282 — the admissible filters span 1 row for 4 faults, so the optimum is Q = 0's error 1 (no admissible filter
    does better than the zero filter, of no use for detection), and ε times the exact detection row attains it within
    1e-6, judged by numpy."""
    from test_audit_seeds18 import test_optimum_of_matching_identity_is_attained

    test_optimum_of_matching_identity_is_attained(336, 1)


def test_seed336_matching_identity_is_refused_with_its_rank_bound():
    """~4 s. Strict xfail on integ20 before amm21's refusal ("the design is returned and passes the numpy judge"; it
    was refused with 'error response differs from the designed one by 0.615'); the product decision since (seeds 26,
    240, 270, 282: test_audit_seeds18.test_matching_identity_is_refused_with_its_rank_bound): refused early by
    ``approximate_matching._unapproachable_reference`` with a DesignError naming the admissible fault response's normal
    rank — numpy's, 1 for 4 faults — and the bound ``σ_2(I) = 1 = ||I||∞`` (test_audit_seeds18's
    :func:`refused_with_rank_bound`)."""
    from test_audit_seeds18 import noisy_case, refused_with_rank_bound

    assert refused_with_rank_bound(noisy_case(336)) == 1
