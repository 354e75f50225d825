"""Which realisation of ``Q = Y Φ Q0`` approximate model matching ships (issue 17, approximate audit seed 119).

``_shipped_filter`` compares the shipped error response ``Q [Gf Gw; 0 0] − M [Mr 0]`` with the designed
``M (Y Ĝ − F)`` point by point against a first-order bound of the comparison's *evaluation* rounding (the estimate β,
then the worst-case β_w). The factors' realisations also carry their *construction's* errors (coprime factorisation,
minimal realisation, series products: normwise ~n·u·‖A‖ of each), which no term of β bounds; seed 119's product
realisation differed by 1.14 β_w and was refused although numpy's judge passes it. The question the user's residual
asks is not "is this the designed realisation" but "is this filter's error the optimum's within reltol" (the
decoupling is judged after, on the shipped realisation): where no candidate is within β_w, the one nearest the
designed response whose own error is the designed one's within reltol is shipped. A realisation whose error is not
is refused. Judged by numpy on the returned filter and the model's matrices (test_synthesis_ammp.error_norm).
"""
import pytest

import fmu_fdi.design.problems.approximate_matching as am
from fmu_fdi import DesignError
from test_synthesis_ammp import MR14, check_contract, error_norm, ex5_14

RELTOL = 1e-4


def _inject(monkeypatch, factor: float):
    """Every candidate realisation of Q scaled by ``factor``: another filter, beyond any rounding bound."""
    real = am._shipped_filter

    def wrong(*args, **kw):
        args = list(args)
        Qf = args[5]
        args[5] = tuple(factor * X for X in Qf) if isinstance(Qf, tuple) else factor * Qf
        return real(*args, **kw)

    monkeypatch.setattr(am, "_shipped_filter", wrong)


@pytest.mark.parametrize("delta", [5e-4, -5e-4])
def test_a_realisation_whose_error_is_not_the_optimum_is_refused(monkeypatch, delta):
    """Example 5.14 (Gf = 1/(s+1), Gw = 1/(s+2), Mr = 1/(s+3), default sdeg and normalize; error 0.159): Q shipped as
    (1 + δ)·Q, |δ| = 5e-4 — a pointwise gap ~|δ|·||Q [Gf Gw]|| ≈ 1.7e-4, below SHIPPED_ACCURACY·size (3.3e-4), far
    beyond the rounding bound (~1e-15). Returned ⇒ numpy's error is within reltol of the designed filter's;
    refused ⇒ numpy's error of (1 + δ)·Q exceeds it by more than reltol (−5e-4 does: the next test)."""
    gen0 = am.approximate_model_matching(ex5_14(), MR14)
    e0 = error_norm(gen0, MR14, gen0.info["M"], "inf")
    wrong = type(gen0)((1 + delta) * gen0.Q, gen0.model, "injected")
    e_wrong = error_norm(wrong, MR14, gen0.info["M"], "inf")
    # the limit _shipped_filter applies, e0·(1 + reltol), read by numpy; ± 1e-5 for the two grids' peaks
    # (check_contract's refined-grid agreement)
    _inject(monkeypatch, 1 + delta)
    try:
        gen = am.approximate_model_matching(ex5_14(), MR14)
    except DesignError as exc:
        assert "differs from the designed one" in str(exc) and "exceed the designed" in str(exc), str(exc)
        assert e_wrong > e0 * (1 + RELTOL) * (1 - 1e-5), (e_wrong, e0)
        return
    err = check_contract(gen, MR14, "inf")
    assert err <= e0 * (1 + RELTOL) * (1 + 1e-5), (err, e0)


def test_a_scaled_realisation_raises_the_error_beyond_reltol():
    """The premise of the refusal test (so that its refusing branch runs), read by numpy alone: (1 − 5e-4)·Q's
    error exceeds Q's by more than reltol (measured: 0.158981 → 0.159022, 2.6e-4 relative; (1 + 5e-4)·Q's is
    0.158939, below — M's updated problem is not the one this error measures, so Q is not its minimiser)."""
    gen0 = am.approximate_model_matching(ex5_14(), MR14)
    e0 = error_norm(gen0, MR14, gen0.info["M"], "inf")
    wrong = type(gen0)((1 - 5e-4) * gen0.Q, gen0.model, "injected")
    assert error_norm(wrong, MR14, gen0.info["M"], "inf") > e0 * (1 + RELTOL) * (1 + 1e-5)


def test_a_realisation_beyond_the_rounding_bound_with_the_optimal_error_is_shipped(monkeypatch):
    """Q shipped as (1 + 1e-8)·Q: a gap ~3e-9, a million times the worst-case evaluation bound (β_w ~1e-15: the
    construction error seed 119 showed, 1.14 β_w, exaggerated), and an error moved by ~1e-8 relative, within
    reltol. Shipped, with a note naming the gap and both errors; numpy reads its error within reltol of the designed
    one and decoupling to 1e-9 (check_contract). Old code: DesignError "differs from the designed one"."""
    gen0 = am.approximate_model_matching(ex5_14(), MR14)
    e0 = error_norm(gen0, MR14, gen0.info["M"], "inf")
    _inject(monkeypatch, 1 + 1e-8)
    gen = am.approximate_model_matching(ex5_14(), MR14)
    err = check_contract(gen, MR14, "inf")
    assert err <= e0 * (1 + RELTOL)
    assert any("worst-case first-order evaluation bound" in n and "within reltol" in n
               for n in gen.info.get("notes", [])), gen.info.get("notes")
