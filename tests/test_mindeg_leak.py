"""approximate_model_matching(…, mindeg=True) meets the judge of the optimal design: every returned row's u/d leak at
most dec_tol = 1e-7 of its weakest required fault's peak gain (Varga's normalisation, the issue's judge; a fault is
required where the row of Mr is nonzero — here Mr's rows are dense, so every fault is).

Judged by numpy on the returned Q and the model's matrices alone (test_synthesis_ammp._numpy_leak_and_faults: 800 log
points, numpy solves), the error by test_synthesis_ammp.error_norm on its own grid, against the same design without
mindeg. The least-order rows are new realisations (covers, re-solve, numerator refits) that were judged unnormalised
only: on the random families (benchmarks/mindeg_time.py --judged 0-29, main cfcd677) six mindeg designs whose optimal
filter met dec_tol were returned leaking 1.4e-7 … 3.0e-5 (H∞ seeds 7, 13, 17; H2 seeds 7, 12, 17).
"""

import numpy as np
import pytest
from test_mindeg import row_degrees, stable
from test_synthesis_ammp import _numpy_leak_and_faults, _random_case, error_norm

from fmu_fdi import approximate_model_matching

#: the issue's decoupling tolerance on the normalised form (postconditions.DEC_TOL)
DEC_TOL = 1e-7


def _judged(seed, norm):
    """The mindeg design and the optimal one of random case ``seed``, and the numpy reading of the mindeg filter's
    worst row leak over that row's weakest fault peak."""
    model, Mr = _random_case(seed)
    g0 = approximate_model_matching(model, Mr, norm=norm, reltol=1e-6)
    g1 = approximate_model_matching(model, Mr, norm=norm, reltol=1e-6, mindeg=True)
    leak, faults = _numpy_leak_and_faults(model, g1.Q)
    # every fault required (Mr's rows are dense: rng.normal entries), so the weakest fault of each row normalises it
    assert np.all(np.abs(Mr.D + Mr.C @ np.linalg.solve(-Mr.A if not Mr.dt else np.eye(Mr.n) - Mr.A, Mr.B)) > 0)
    return Mr, g0, g1, float(np.max(leak / faults.min(axis=1)))


def _same_error(g0, g1, Mr, norm):
    # the guard's contract: within reltol = 1e-6 of the optimal filter's error plus 1e-9 ||M Mr||∞; the test's grid
    # reads the two peaks to 1e-5 (H∞, refined peaks of one response realised twice), the trapezoid to 1e-3 (H2)
    rel = 1e-5 if norm == "inf" else 1e-3
    floor = 1e-9 * max(1.0, (g1.info["M"] @ Mr).hinfnorm()[0])
    e0, e1 = error_norm(g0, Mr, g0.info["M"], norm), error_norm(g1, Mr, g1.info["M"], norm)
    assert e1 <= e0 * (1 + rel) + floor, (e0, e1)


def test_lowered_h2_row_of_seed_12_is_decoupled_on_the_normalised_form():
    """Random continuous H2 seed 12 (one 54-state optimal row, numpy leak 4.5e-11): on main the mindeg filter (an
    order-18 row) leaked u 9.2e-7 of its weakest fault (numpy; the library's normalised reading 9.5e-7), above
    dec_tol — its post-condition read the row unnormalised. Now each lowered candidate is judged on the normalised
    form (and re-decoupled where it leaks): an order-18 row that leaks 4.8e-8 is returned, the lowering kept."""
    Mr, g0, g1, worst = _judged(12, "2")
    info = g1.info["mindeg"]
    assert worst <= DEC_TOL, worst
    assert info["lowered"] and sum(row_degrees(g1.Q)) < sum(row_degrees(g0.Q))
    assert info["leak"] <= DEC_TOL
    _same_error(g0, g1, Mr, "2")
    assert stable(g1.Q)


@pytest.mark.slow
def test_seed_17_rows_are_lowered_and_re_decoupled():
    """Random discrete H∞ seed 17 (two 52-state optimal rows; slow: ~20 s idle, ~90 s beside three sessions): on
    cfcd677 the mindeg filter [5, 8] leaked u 3.3e-6 of its weakest fault (numpy). Row 2's order-8 cover leaks 4.7e-7
    and is re-decoupled below dec_tol. Row 1's order-5 re-solve: the one judge reads a lowered filter's leak as its
    stored value plus the realisation's sensitivity to rounding (``approximate_matching._leak_of``), and on its own
    realisation that sensitivity alone is 3.4e-7 (Schur coordinates 1.7e-7): every refit of it stayed above dec_tol
    and main kept row 1's optimal row ([52, 8]). Its balanced realisation (same order: nothing to truncate, so main
    never tried it) has sensitivity 3.0e-8 and its refit reads 5.1e-8: row 1 is lowered to 5. Returned: row orders
    [5, 8], below dec_tol by numpy, the optimal error (on a host whose longdouble is double, [5, 7], leaks 2.1e-13 and
    5.0e-11 by a refined numpy reading: each order at most [5, 8] is asserted)."""
    Mr, g0, g1, worst = _judged(17, "inf")
    info = g1.info["mindeg"]
    assert worst <= DEC_TOL, worst
    # each row's order at most [5, 8] (the least order may only improve: the simulated double host returns [5, 7])
    assert len(info["row_orders"]) == 2 and all(o <= c for o, c in zip(info["row_orders"], [5, 8])), info["row_orders"]
    assert row_degrees(g1.Q) == info["row_orders"], (row_degrees(g1.Q), info["row_orders"])
    assert info["ud_redecoupling"]["refined"]
    _same_error(g0, g1, Mr, "inf")
    assert stable(g1.Q)


@pytest.mark.slow
def test_h2_seed_13_row_1_is_lowered_by_truncating_the_optimal_row():
    """Random discrete H2 seed 13 (slow: ~50 s on the loaded 2-core machine): row 1 of the optimal filter has order
    84 but 19 Hankel singular values above 1e-7 of its largest; on integ13 it stayed at 84 (its covers unstable or
    leaking, the re-solve leaking 1.8e-3) → [84, 13]. Now the optimal row balanced-truncated (orders 19, 22, 24, 27:
    the Hankel counts at 1e-7 … 1e-13 of the largest) and refitted to zero u/d response and the row's fault/noise
    response is offered last: row 1 is lowered (measured [84, 84] → [26, 13], numpy leak 3.5e-9 of the weakest fault,
    error 6.36e-6 as the optimal's) and the filter meets the judge — numpy leak ≤ dec_tol of each row's weakest fault, the optimal
    error within the H2 test's 1e-3, stable."""
    Mr, g0, g1, worst = _judged(13, "2")
    info = g1.info["mindeg"]
    assert worst <= DEC_TOL, worst
    assert info["lowered"] and info["row_orders"][0] < info["row_orders_before"][0], info["row_orders"]
    assert sum(row_degrees(g1.Q)) < sum(row_degrees(g0.Q))
    _same_error(g0, g1, Mr, "2")
    assert stable(g1.Q)


@pytest.mark.parametrize("seed, norm", [(9, "inf"), (14, "2"), (23, "inf"), (27, "2")])
def test_every_mindeg_design_leaks_at_most_dec_tol(seed, norm):
    """The property on fast seeds (discrete and continuous, H∞ and H2, each lowered on main too): whatever rows are
    returned, each leaks at most dec_tol of its weakest fault by numpy, with the optimal error, stable; where a row
    is not lowered the reason is given."""
    Mr, g0, g1, worst = _judged(seed, norm)
    info = g1.info["mindeg"]
    assert worst <= DEC_TOL, worst
    _same_error(g0, g1, Mr, norm)
    assert stable(g1.Q)
    assert info["lowered"] or info["reason"]


@pytest.mark.parametrize("seed", [6, 0])
def test_lowered_continuous_h2_rows_leave_a_strictly_proper_error(seed):
    """Random continuous H2 seeds 6 and 0 (mindeg, reltol 1e-6): a continuous error ``E = Q [Gf Gw; 0 0] − M [Mr 0]``
    with a feedthrough has an infinite H2 norm. The optimal filters' feedthrough is exactly 0; main's lowered rows
    (numerators fitted on finite points) left 1.4e-12 and 1.1e-11 (``|D_Q||D_fw|`` 4.3e-11 and 0.33). Judged from
    the matrices alone: ``D_E = D_Q [Df Dw; 0 0] − D_M [D_Mr 0]`` is at most the rounding of that product, 64·eps
    times ``|D_Q||D_fw|`` entrywise (a sum of p + m products, each rounded, Higham's γ_k), and the u/d feedthrough
    ``D_Q [Du Dd; I 0]`` likewise; the filter still leaks at most dec_tol by numpy."""
    model, Mr = _random_case(seed)
    g = approximate_model_matching(model, Mr, norm="2", reltol=1e-6, mindeg=True)
    assert g.info["mindeg"]["lowered"]
    nu, nd, nw = model.nu, model.nd, model.nw
    Dfw = np.vstack([np.hstack([model.Df, model.Dw]), np.zeros((nu, model.nf + nw))])
    Dud = np.vstack([np.hstack([model.Du, model.Dd]), np.hstack([np.eye(nu), np.zeros((nu, nd))])])
    M = g.info["M"]
    DMF = M.D @ np.hstack([Mr.D, np.zeros((Mr.p, nw))])
    eps = np.finfo(float).eps
    DE = g.Q.D @ Dfw - DMF
    assert np.all(np.abs(DE) <= 64 * eps * (np.abs(g.Q.D) @ np.abs(Dfw)) + 1e-300), np.abs(DE).max()
    assert np.all(np.abs(g.Q.D @ Dud) <= 64 * eps * (np.abs(g.Q.D) @ np.abs(Dud)) + 1e-300)
    leak, faults = _numpy_leak_and_faults(model, g.Q)
    assert np.all(leak / faults.min(axis=1) <= DEC_TOL)
