"""approximate_model_matching: one error limit for every stage (issue 17; ``approximate_matching.ErrorBudget``).

A user asking ``reltol`` must get a filter whose error, as numpy reads it, is within ``reltol`` of the optimum the
γ-iteration certified — in the standard H∞ problem the lower end of its bracket ``γ_lo ≤ γ_opt`` — not ``reltol``
per stage compounded. Before, each stage after the iteration (the shipped realisation's tier, the corrections, the
least-order acceptance) was allowed ``reltol`` of the filter before it and only the zero filter's error bounded the
total, which is no bound at all where ``γ_opt`` is well below ``||Mr||``."""
from __future__ import annotations

import control as ct
import numpy as np
import pytest

import fmu_fdi.design.problems.approximate_matching as am
from fmu_fdi import DesignError, FDIModel
from fmu_fdi.lti import LTI
from test_synthesis_ammp import error_norm, pub

RELTOL = 1e-4
#: the error limits' absolute floor (ZERO_ERROR_FLOOR of ||M [Mr 0]||∞ = 1 here) and the agreement of numpy's
#: refined 1200-point peak with the design's refined peak on its own points (both refine the same smooth maximum of a
#: first/second-order response: measured 1e-12 relative; 1e-9 leaves a margin)
FLOOR, READ_RTOL = 1e-9, 1e-9


def _sensor_and_noise(second: bool = False):
    """One output, y = f + w/(s + 1) (or (s+2)/(s+1) f + 2/(s+3) w): a standard H∞ problem (Gf has a feedthrough,
    K = 0) whose optimum with Mr = 1 is well below Q = 0's error 1 (γ_opt = 1/√2: min over Q of max_ω |[Q − 1,
    Q/(jω+1)]| is reached at ω = 0 by Q(0) = 1/2), so the zero-filter test cannot stand in for the budget."""
    s = ct.tf("s")
    G = pub.tfm([[(s + 2) / (s + 1), 2 / (s + 3)]] if second else [[1 + 0 * s, 1 / (s + 1)]], ["f", "w"])
    return FDIModel.from_control(G, w=["w"], f=["f"], name="sensor_and_noise")


MR = LTI.static(np.eye(1), 0.0)


@pytest.mark.parametrize("second", [False, True])
@pytest.mark.parametrize("reltol", [1e-4, 0.2])
def test_returned_error_within_reltol_of_the_certified_level(second, reltol):
    """Every returned standard H∞ design: numpy's error ≤ γ_lo (1 + reltol) + floor, γ_lo the bracket's lower end,
    and ``info['error_budget']`` is that limit (base = γ_lo, certified by the iteration's infeasible level)."""
    model = _sensor_and_noise(second)
    gen = am.approximate_model_matching(model, MR, reltol=reltol)
    lo = gen.info["gamma_bracket"][0]
    e = error_norm(gen, MR, gen.info["M"], "inf")
    assert e <= (lo * (1 + reltol) + FLOOR) * (1 + READ_RTOL), (e, lo)
    assert lo < 0.75  # (the premise: far below Q = 0's error 1)
    budget = gen.info["error_budget"]
    assert budget["base"] == lo and "infeasible level" in budget["certified_by"], budget


@pytest.mark.parametrize("delta", [2e-2, -2e-2])
def test_a_shipped_filter_beyond_the_certified_budget_is_refused(monkeypatch, delta):
    """The shipped filter replaced by (1 + δ)·Q, |δ| = 2e-2, at the stage's output (the stages after it then judge
    it as they judge any filter they are handed): its error, read by numpy, exceeds γ_lo (1 + reltol) (premise,
    asserted; the optimum is flat in Q(0) = 1/2 — |[Q − 1, Q]| at ω = 0 — so δ moves it by ~δ²: 2e-4 > reltol). Old
    code: returned — no stage compared the error with the certified level, each with the filter before it, and Q = 0's
    error (1) is far above. Now refused, the message naming the limit; were it returned, numpy's error would have to be
    within the budget."""
    model = _sensor_and_noise()
    gen0 = am.approximate_model_matching(model, MR, reltol=RELTOL)
    lo = gen0.info["gamma_bracket"][0]
    wrong = type(gen0)((1 + delta) * gen0.Q, model, "injected")
    assert error_norm(wrong, MR, gen0.info["M"], "inf") > (lo * (1 + RELTOL) + FLOOR) * (1 + READ_RTOL)
    real = am._shipped_filter

    def scaled(*args, **kw):
        Q, lam = real(*args, **kw)
        return (1 + delta) * Q, lam

    monkeypatch.setattr(am, "_shipped_filter", scaled)
    try:
        gen = am.approximate_model_matching(model, MR, reltol=RELTOL)
    except DesignError as exc:
        assert "exceeds the limit" in str(exc) and "infeasible level" in str(exc), str(exc)
        return
    e = error_norm(gen, MR, gen.info["M"], "inf")
    assert e <= (lo * (1 + RELTOL) + FLOOR) * (1 + READ_RTOL), (e, lo * (1 + RELTOL))


def test_budget_limit_is_the_stated_formula():
    """``ErrorBudget.limit = base (1 + reltol) + floor`` (to the rounding of one product and one sum, 2 u)."""
    b = am.ErrorBudget(0.7, 1e-4, 1e-9, "the γ-iteration's infeasible level")
    assert abs(b.limit - (0.7 * (1 + 1e-4) + 1e-9)) <= 2 * np.finfo(float).eps * b.limit
    assert b.as_info()["limit"] == b.limit
