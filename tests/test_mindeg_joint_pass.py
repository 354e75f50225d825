"""approximate_model_matching(…, mindeg=True): the joint pass tries covers only, and no row is raised.

The mindeg stage (approximate_matching._least_order) first verifies every row at its j-th lowest candidate jointly,
then lowers the rows one by one. The optimal row's balanced truncations are a row's last resort; on main (253b4cb) they
sat at the end of each row's list, so a joint trial at an index beyond one row's covers paired that row's truncation
with another row's cover — random H∞ seed 17's joint pass accepted an intermediate [18, 24] whose verification was the
stage's slowest (59 of 190 s under cProfile) before the row pass lowered it to [5, 8]. And the row pass offered "the
lower ones" by list index, not by order: on random H∞ seed 1 (two 17-state optimal rows) the joint pass accepted a
pair of truncations [14, 15], then the row pass replaced row 1's order-14 truncation by an order-15 cover (listed
before it) — returned [15, 15].

Spied on the stage's own verifier (which filters it verified, which it accepted), judged by numpy on the returned
filter: its rows' McMillan degrees by Hankel singular values (test_mindeg.row_degrees, scipy Lyapunov solves), its u/d
leak by test_synthesis_ammp._numpy_leak_and_faults against dec_tol = 1e-7 of each row's weakest fault, its error
against the optimal filter's (the one the stage lowered) by test_synthesis_ammp.error_norm.
"""

import numpy as np
import pytest
from test_mindeg import row_degrees, stable
from test_synthesis_ammp import _numpy_leak_and_faults, _random_case, error_norm

import fmu_fdi.design.problems.approximate_matching as am
from fmu_fdi import approximate_model_matching

#: the issue's decoupling tolerance on the normalised form (postconditions.DEC_TOL)
DEC_TOL = 1e-7


def _spied_design(monkeypatch, seed, norm):
    """The mindeg design of random case ``seed``, the optimal filter it lowered, and the stage's verifications in
    order: ``(row orders, row kinds, row ids, accepted)`` — a row's kind 'truncation' where it is the stage's refit of
    the optimal row's balanced truncation (``_refit_or_why(…, ref=row)``), 'cover' where a cover or re-solve
    candidate (``_refit_numerator``), '-' otherwise (the optimal row)."""
    kinds, log, captured = {}, [], {}

    def marked(fn, kind, need_ref=False):
        def wrapper(*args, **kw):
            out = fn(*args, **kw)
            if (not need_ref or kw.get("ref") is not None) and isinstance(out, am.LTI):
                kinds[id(out)] = (kind, out)  # (the object kept: its id is not reused)
            return out
        return wrapper

    real_verified, real_least = am._verified, am._least_order

    def verified(model, gen, rows, *args, **kw):
        out = real_verified(model, gen, rows, *args, **kw)
        log.append(([r.n for r in rows], [kinds.get(id(r), ("-",))[0] for r in rows], [id(r) for r in rows],
                    out[0] is not None))
        return out

    def least(*args, **kw):
        captured["optimal"] = args[1]
        return real_least(*args, **kw)

    monkeypatch.setattr(am, "_refit_numerator", marked(am._refit_numerator, "cover"))
    monkeypatch.setattr(am, "_refit_or_why", marked(am._refit_or_why, "truncation", need_ref=True))
    monkeypatch.setattr(am, "_verified", verified)
    monkeypatch.setattr(am, "_least_order", least)
    model, Mr = _random_case(seed)
    gen = approximate_model_matching(model, Mr, norm=norm, reltol=1e-6, mindeg=True)
    return model, Mr, gen, captured["optimal"], log


def _numpy_judged(model, Mr, gen, opt, norm):
    """numpy's judge of the returned mindeg filter ``gen`` against the optimal one ``opt`` it lowered: numpy's McMillan
    degrees (Hankel values above 1e-7 of the largest) at most the reported states (seed 1 H∞: [13, 13] for [14, 15]:
    the rows keep modes at 1e-8 … 1e-7 of their scale); every row's u/d leak at most dec_tol of its weakest fault; the
    error within the guard's contract — reltol = 1e-6 of the optimal filter's plus 1e-9 ||M Mr||∞ — read on the test's
    grid to 1e-5 (H∞: two peaks of one response realised twice) or 1e-3 (H2: the trapezoid; test_mindeg_leak's
    _same_error); Q stable."""
    info = gen.info["mindeg"]
    degrees = row_degrees(gen.Q)
    assert all(d <= r for d, r in zip(degrees, info["row_orders"])), (degrees, info["row_orders"])
    leak, faults = _numpy_leak_and_faults(model, gen.Q)
    assert np.all(leak <= DEC_TOL * faults.min(axis=1)), leak / faults.min(axis=1)
    opt.info.update({k: gen.info[k] for k in ("M", "norm", "reference_lowpass")})
    e0, e1 = error_norm(opt, Mr, gen.info["M"], norm), error_norm(gen, Mr, gen.info["M"], norm)
    rel = 1e-5 if norm == "inf" else 1e-3
    assert e1 <= e0 * (1 + rel) + 1e-9 * max(1.0, (gen.info["M"] @ Mr).hinfnorm()[0]), (e0, e1)
    assert stable(gen.Q)


@pytest.mark.slow
def test_seed_1_truncations_stay_out_of_the_joint_pass_and_no_row_is_raised(monkeypatch):
    """Random continuous H∞ seed 1 (two 17-state optimal rows; slow: 23 s at load 3, 77 s at load ~8). On 253b4cb: 4
    verified filters paired a truncation with another row's untried candidate, and the accepted filters went [14, 15] →
    [15, 15] → [15, 15] (row 1 raised). Now: a verified filter holding a truncation not yet accepted differs from the
    accepted ones in that row only; each accepted filter lowers the previous one (no row higher, one row lower)."""
    model, Mr, gen, opt, log = _spied_design(monkeypatch, 1, "inf")
    accepted, current = set(), None
    for orders, kinds, ids, ok in log:
        new = [k for k, i in zip(kinds, ids) if k != "-" and i not in accepted]
        assert not ("truncation" in new and len(new) > 1), (orders, kinds)
        if ok:
            if current is not None:
                assert all(a <= b for a, b in zip(orders, current)) and sum(orders) < sum(current), (current, orders)
            accepted.update(ids)
            current = orders
    info = gen.info["mindeg"]
    assert info["lowered"] and info["row_orders"] == current
    assert sum(info["row_orders"]) < sum(info["row_orders_before"])
    _numpy_judged(model, Mr, gen, opt, "inf")


@pytest.mark.slow
def test_h2_seed_17_row_1_keeps_its_truncation_beside_the_optimal_row_2(monkeypatch):
    """Random discrete H2 seed 17 (two 52-state optimal rows; slow: ~70 s at load 3, ~100 s at load 8). Row 1's covers
    and re-solve (order 5) leak 6e-7 … 2e-4 of its weakest fault after every refit; its order-19 truncation is the
    lowest that passes. Main (253b4cb) reached [19, 5] through a joint trial of two truncations ([19, 19], then row 2
    → 5). With the truncations out of the joint pass (2cd232a) the row pass verified row 1's order-19 truncation beside
    the optimal order-52 row 2, and every whole-filter refit of that order-71 filter stalled at a normalised leak of
    1.09e-7 > dec_tol (weights 10, 100, 1000, 10000: 1.84e-7, 1.09e-7, 1.09e-7, 1.09e-7) where the row refitted on its
    own realisation reads 1.7e-9 + 7.1e-9 at weight 100: 2cd232a returned [21, 5]. Now the weighted stage ends with
    each leaking row refitted on its own realisation: row 1 at most 19, judged by numpy as above.

    Why not 5 (H∞ seed 17's row 1): the order-5 re-solve, beside the optimal row 2, is within the error budget
    (1.060936e-7, limit 1.096533e-7) but no realisation of it tried is decoupled: numpy reads its leak at 1.9e-5 of the
    row's weakest fault (7.7e-5), its refits (shipped, balanced, balanced Schur, Schur; weights 10, 100) at 4.8e-7 …
    4.7e-6, the judge 1.4e-7 … 4.4e-7 plus sensitivities 2.2e-7 … 8.6e-6; of the best (balanced Schur) sensitivity,
    u·|D||G| 3.8e-8 (free of the coordinates) and u·|C||Z| 3.3e-8 (3.3e-8 … 5.8e-8 in every coordinates tried) alone
    are 0.7 dec_tol."""
    model, Mr, gen, opt, log = _spied_design(monkeypatch, 17, "2")
    info = gen.info["mindeg"]
    assert info["lowered"] and info["row_orders"][0] <= 19 and info["row_orders"][1] <= 5, info["row_orders"]
    _numpy_judged(model, Mr, gen, opt, "2")
