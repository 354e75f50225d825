"""approximate_model_matching(…, mindeg=True): FaultDetectionTools.jl ``ammsyn``'s least-order option.

Each row of the optimal filter is replaced by the least-order solution of ``Q_i Ge = [0 0 Rf_i Rw_i]``
(glasol's ``mindeg``). Judged independently of the design: the McMillan degree of each row by counting
the Hankel singular values of the row (Gramians from scipy's Lyapunov solvers on the returned
realisation), the matching error by the numpy frequency responses of test_synthesis_ammp.error_norm on
its own grid (1200 log points from 1e-5, refined at the peak — not the design's grid), decoupling by
test_synthesis_ammp.decoupling, stability by the eigenvalues of Q's A. Cases: Varga (2017) Examples
5.11, 5.14, 5.15, 5.16, 5.17 (FDT Ex5_1*.jl), Niemann's model, the seeded random models of
test_synthesis_ammp, and discrete-time versions of Ex. 5.16 and Niemann's model.
"""

import re

import numpy as np
import published as pub
import pytest
import scipy.linalg as sla
from test_synthesis_ammp import MR14, MR17, _random_case, decoupling, error_norm, ex5_14, ex5_16, static
from test_synthesis_published import niemann

from fmu_fdi import approximate_model_matching
from fmu_fdi.lti import LTI


def hankel_order(A, B, c, dt):
    """McMillan degree of the stable row ``(A, B, c)``: the Hankel singular values ``sqrt(eig(P Qo))``
    above 1e-7 of the largest. A mode the row really has contributes at the data's scale; one a minimal
    realisation should have removed (cancelled to rounding, ~1e-16 relative in P and Qo, so ~1e-8 in
    their square roots' product at worst) stays below 1e-7."""
    if A.shape[0] == 0 or not np.any(c):
        return 0
    if dt:
        P = sla.solve_discrete_lyapunov(A, B @ B.T)
        Qo = sla.solve_discrete_lyapunov(A.T, c.T @ c)
    else:
        P = sla.solve_continuous_lyapunov(A, -B @ B.T)
        Qo = sla.solve_continuous_lyapunov(A.T, -c.T @ c)
    hsv = np.sqrt(np.abs(np.linalg.eigvals(P @ Qo)))
    return int(np.sum(hsv > 1e-7 * hsv.max()))


def row_degrees(Q: LTI):
    return [hankel_order(Q.A, Q.B, Q.C[[i]], Q.dt) for i in range(Q.p)]


def stable(Q: LTI) -> bool:
    ev = np.linalg.eigvals(Q.A) if Q.n else np.zeros(0)
    return bool(np.all(np.abs(ev) < 1)) if Q.dt else bool(np.all(ev.real < 0))


CASES = {
    "5.14": (ex5_14, MR14, dict(sdeg=-1, normalize="gain", reltol=1e-5)),
    "5.15": (ex5_14, MR14, dict(norm="2", sdeg=-1, normalize="gain")),
    "5.11": (pub.a5a_model, static(np.eye(2)), dict(reltol=1e-6)),
    "5.16": (ex5_16, static(np.eye(2)), dict(sdeg=-10, reltol=5e-4)),
    "5.17": (ex5_16, MR17, dict(norm="2", sdeg=-10)),
    "seed14": (lambda: _random_case(14)[0], _random_case(14)[1], dict(reltol=1e-6)),
    # seed 9 (discrete, 33-state rows → 3: the covers of the balanced minimal rows reach it too, see below)
    "seed9": (lambda: _random_case(9)[0], _random_case(9)[1], dict(reltol=1e-6)),
    # discrete time (ZOH, the model's own discretize): Ex. 5.16 at 0.1 s and Niemann's model (d present) at 1 ms
    "5.16d": (lambda: ex5_16().discretize(0.1), static(np.eye(2)), dict(reltol=1e-5)),
    "niemann_d": (lambda: niemann().discretize(0.001), static([[1.0, 0.0]]), dict(reltol=1e-5)),
}
#: the optimal filter's rows carry modes the least-order rows do not: as states of their minimal realisations
#: (in 5.11, 5.14, 5.15, 5.16 and 5.16d only as near-cancellations, Hankel singular values 1e-11 … 1e-8 of the
#: row's largest, which the γ-iteration's central controller leaves), and as modes of Hankel size above 1e-7
#: (seed 14: 8 of them in a 23-state row, the least-order row has 2 — lowered by the Type 2 cover of the row by
#: the null-space basis of the whole Ge, without forming the reference Q_i [Gf Gw]; Niemann at 1 ms: 4 → 1;
#: Niemann's continuous model, below: 3 → 1)
STRICT_STATES = {"5.11", "5.14", "5.15", "5.16", "5.17", "seed14", "5.16d", "niemann_d", "seed9"}
STRICT_HANKEL = {"seed14", "niemann_d", "seed9"}


@pytest.mark.parametrize("name", sorted(CASES))
def test_least_order_rows_with_the_optimal_error(name):
    make, Mr, kw = CASES[name]
    model = make()
    norm = kw.get("norm", "inf")
    g0 = approximate_model_matching(model, Mr, **kw)
    g1 = approximate_model_matching(model, Mr, mindeg=True, **kw)
    info = g1.info["mindeg"]
    d0, d1 = row_degrees(g0.Q), row_degrees(g1.Q)
    # (1) no row of higher degree, strictly lower where the default is not least order; the reported
    # orders are the measured ones
    assert all(a <= b for a, b in zip(d1, d0)), (d0, d1)
    assert d1 == g1.info["row_orders"] == info["row_orders"]
    if name in STRICT_STATES:  # fewer states per row than the optimal filter's minimal rows
        assert info["lowered"] and sum(info["row_orders"]) < sum(info["row_orders_before"])
        assert all(a <= b for a, b in zip(info["row_orders"], info["row_orders_before"]))
    if name in STRICT_HANKEL:
        assert sum(d1) < sum(d0)
    # (2) the same error as the optimal filter: independent numpy responses on the test's own grid; the
    # two filters realise the same Q Ge (exact matching of each row), so the error differs only by the
    # realisations' rounding and the grid: H∞ 1e-5 (refined peaks of one response), H2 1e-3 (trapezoid on
    # 1200 points of two realisations of one response), plus 1e-9 absolute for the exactly matched case
    M = g1.info["M"]
    e0, e1 = error_norm(g0, Mr, g0.info["M"], norm), error_norm(g1, Mr, M, norm)
    rel = 1e-5 if norm == "inf" else 1e-3
    assert e1 == pytest.approx(e0, rel=rel, abs=1e-9)
    assert e1 <= g1.info["gamma_sub"] * (1 + rel) + 1e-9
    if g1.info["standard"] and norm == "inf":  # standard: the optimum to the bisection's reltol
        lo, hi = g1.info["gamma_bracket"]
        assert e1 <= hi * (1 + 1e-5) + 1e-9
    assert info["error"] <= info["error_before"] * (1 + kw.get("reltol", 1e-4)) + 1e-9
    # (3) decoupling (numpy, relative to |Q||G|) and stability of the returned filter
    assert decoupling(g1) < 1e-9
    assert stable(g1.Q)
    assert g1.info["postconditions"]["decoupling"] <= 1e-7


def test_niemann_exact_match_at_least_order():
    """Niemann's model (d present; full minimal basis), Mr = [1 0]: matched exactly (FDT test_ammsyn.jl,
    fdimmperf < 1e-7) and, with mindeg, by a first-order filter (emmsyn's least-order rows are order 1)."""
    model, Mr = niemann(), static([[1.0, 0.0]])
    g0 = approximate_model_matching(model, Mr, sdeg=-5, reltol=1e-5)
    g1 = approximate_model_matching(model, Mr, sdeg=-5, reltol=1e-5, mindeg=True)
    assert row_degrees(g1.Q) == [1] and row_degrees(g0.Q) == [3]  # Hankel singular values above 1e-7
    assert error_norm(g1, Mr, g1.info["M"], "inf") < 1e-7
    assert decoupling(g1) < 1e-9 and stable(g1.Q)


def test_cannot_lower_returns_the_same_filter_and_says_why():
    """Ex. 5.6c (Mr = [1 1]): the optimal row has degree 2, which is least: the filter is returned
    unchanged and the reason says so."""
    model, Mr = pub.a5a_model(), static([[1.0, 1.0]])
    g0 = approximate_model_matching(model, Mr, sdeg=-3, reltol=1e-6)
    g1 = approximate_model_matching(model, Mr, sdeg=-3, reltol=1e-6, mindeg=True)
    assert not g1.info["mindeg"]["lowered"] and "already least order" in g1.info["mindeg"]["reason"]
    assert np.array_equal(g1.Q.A, g0.Q.A) and np.array_equal(g1.Q.D, g0.Q.D)


@pytest.mark.parametrize("seed, kw", [(6, {}), (3, dict(reltol=1e-6))])
def test_random_rows_lowered_with_the_optimal_error(seed, kw):
    """Seed 6 (non-standard, n = 24; the least-order re-solve of (2) against the reference Q_i [Gf Gw] fails its
    own checks, so the optimal 48-state row was kept) and seed 3 (two 54-state rows; the re-solve's rows leak):
    the Type 2 covers of the rows by the null-space basis lower them (fewer states, fewer Hankel singular values
    above 1e-7 than the optimal rows — seed 3's rows keep ~10 states below that level which its decoupling
    needs: truncated, they leak 8e-5 of the fault gain) with the same error (numpy responses, the test's grid;
    H∞ to the bisection's reltol), decoupled and stable."""
    model, Mr = _random_case(seed)
    g0 = approximate_model_matching(model, Mr, **kw)
    g1 = approximate_model_matching(model, Mr, mindeg=True, **kw)
    info = g1.info["mindeg"]
    assert info["lowered"] and sum(info["row_orders"]) < sum(info["row_orders_before"])
    assert sum(row_degrees(g1.Q)) < sum(row_degrees(g0.Q))
    assert all(a <= b for a, b in zip(row_degrees(g1.Q), row_degrees(g0.Q)))
    e0, e1 = error_norm(g0, Mr, g0.info["M"], "inf"), error_norm(g1, Mr, g1.info["M"], "inf")
    rel = kw.get("reltol", 1e-4)
    # the guard's contract: within reltol of the optimum plus 1e-9 ||M Mr||∞ (seed 3's optimum is ~1e-7, an
    # exactly matchable reference at rounding level, where two realisations differ by ~1e-9 of ||M Mr||)
    floor = 1e-9 * max(1.0, (g1.info["M"] @ Mr).hinfnorm()[0])
    assert e1 <= e0 * (1 + rel) + floor
    assert decoupling(g1) < 1e-9 and stable(g1.Q)


def test_mindeg_must_be_a_bool():
    from fmu_fdi import DesignError

    with pytest.raises(DesignError, match="mindeg must be True or False"):
        approximate_model_matching(ex5_14(), MR14, mindeg="yes")


def test_a_worse_least_order_filter_is_not_returned(monkeypatch):
    """The guard: a least-order row whose fault/noise response is not the optimal row's (here the
    correct least-order row times 1.5) must be refused with the reason, and the optimal filter kept."""
    import fmu_fdi.design.problems.approximate_matching as am

    real = am._refit_numerator
    monkeypatch.setattr(am, "_refit_numerator", lambda *a: real(*a) * 1.5)
    monkeypatch.setattr(am, "_truncation_orders", lambda S: [])  # (the optimal row's truncations: not spoiled)
    g0 = approximate_model_matching(ex5_14(), MR14, sdeg=-1, normalize="gain", reltol=1e-5)
    g1 = approximate_model_matching(ex5_14(), MR14, sdeg=-1, normalize="gain", reltol=1e-5, mindeg=True)
    info = g1.info["mindeg"]
    assert not info["lowered"] and "exceeds the optimal filter's" in info["reason"]
    assert np.array_equal(g1.Q.A, g0.Q.A)
    assert error_norm(g1, MR14, g1.info["M"], "inf") == pytest.approx(g0.info["error"], rel=1e-5)


def test_a_failed_null_space_basis_still_returns_a_judged_filter(monkeypatch):
    """When the null-space basis of the whole Ge cannot be computed (a DesignError of the core), mindeg lowers
    the rows by their near-cancelled modes only and says so; the filter still meets the guard (Ex. 5.14: no
    left null space anyway, so the least-order row [2] is reached; error as the optimal filter's)."""
    import fmu_fdi.design.problems.approximate_matching as am
    from fmu_fdi import DesignError

    def broken(*a, **k):
        raise DesignError("pencil null space: a rank decision failed (test)")

    monkeypatch.setattr(am, "_whole_null_basis", broken)
    g1 = approximate_model_matching(ex5_14(), MR14, sdeg=-1, normalize="gain", reltol=1e-5, mindeg=True)
    info = g1.info["mindeg"]
    assert info["lowered"] and info["row_orders"] == [2]
    assert "near-cancelled modes only" in info["reason"]
    assert info["error"] <= info["error_before"] * (1 + 1e-5) + 1e-9
    assert decoupling(g1) < 1e-9 and stable(g1.Q)


def test_covers_alone_lower_a_row_built_on_another_realisation(monkeypatch):
    """Random seed 9 (discrete, two 33-state optimal rows; least order 3): the optimal rows' realisations hold
    18 states with Hankel singular values ≤ 1e-13 of the largest, which the cover's minimal realisation of the
    compound [Q_i; N] keeps at every tolerance, so the cover of the row as realised lowers nothing. With the
    re-solve of (2) switched off, the covers of the balanced minimal rows (row 1's poles refitted: its order-3
    cover misses the optimal error 1e-11 by 4.7e-9 before) must still lower both rows to order ≤ 3 (Hankel
    singular values from scipy's Lyapunov solvers), with the optimal error (numpy responses, the test's grid,
    reltol 1e-6, plus the guard's floor 1e-9 ||M Mr||∞), decoupled and stable."""
    import fmu_fdi.design.problems.approximate_matching as am

    monkeypatch.setattr(am, "_resolved_row", lambda *a, **k: (None, ""))
    model, Mr = _random_case(9)
    g0 = approximate_model_matching(model, Mr, reltol=1e-6)
    g1 = approximate_model_matching(model, Mr, reltol=1e-6, mindeg=True)
    d0, d1 = row_degrees(g0.Q), row_degrees(g1.Q)
    assert g1.info["mindeg"]["lowered"] and max(d1) <= 3 < min(d0)
    e0, e1 = error_norm(g0, Mr, g0.info["M"], "inf"), error_norm(g1, Mr, g1.info["M"], "inf")
    assert e1 <= e0 * (1 + 1e-6) + 1e-9 * max(1.0, (g1.info["M"] @ Mr).hinfnorm()[0])
    assert decoupling(g1) < 1e-9 and stable(g1.Q)


def _faults_only_plant(seed: int, dt: float):
    """A seeded random stable plant with 5 states, 3 outputs, 2 component faults and no u, d or w (the peer's
    test_ammsyn.jl case ``rss(·, 3, 2)`` with ``sysr = sysf[1:mf, :]``), and ``Mr = Gf``'s first two rows."""
    from fmu_fdi import FDIModel
    from fmu_fdi.faults import FaultSpec

    rng = np.random.default_rng(seed)
    n, p, mf = 5, 3, 2
    lam = rng.uniform(-0.8, 0.8, n) if dt else -rng.uniform(0.5, 4.0, n)
    T = rng.normal(size=(n, n))
    A = T @ np.diag(lam) @ np.linalg.inv(T)
    Bf, C, Df = rng.normal(size=(n, mf)), rng.normal(size=(p, n)), rng.normal(size=(p, mf))
    model = FDIModel(A, np.zeros((n, 0)), C, np.zeros((p, 0)), dt=dt,
                     faults=[FaultSpec(name="f", kind="component", Bf=Bf, Df=Df)])
    return model, LTI(A, Bf, C[:mf], Df[:mf], dt)


@pytest.mark.parametrize("seed, dt", [(0, 0.0), (2, 0.1)])
@pytest.mark.parametrize("covers_alone", [False, True])
def test_least_order_zero_where_a_static_filter_matches(monkeypatch, seed, dt, covers_alone):
    """Theory gives the least order here: with ``Mr`` the first two rows of ``Gf`` (no u, d, w), the static
    ``Q = [I 0]`` matches exactly, so the least McMillan degree of every row is 0 — FaultDetectionTools'
    test_ammsyn.jl ("solution Q = [I 0]", mindeg = true). The optimal filter's rows have the plant's states
    (5 continuous, 10 discrete); with mindeg every row must be static, also with the covers alone (the re-solve
    switched off). Judged without the design's figures: the Hankel singular values of each returned row
    (scipy Lyapunov solvers, :func:`row_degrees`), and Q's numpy frequency response constant to 1e-9 of its
    size on 50 points (a static row has one value; a dynamic one would move by its Hankel size, here ≥ 1e-7
    of the row's), and ``||Q Gf − Mr||∞ ≤ 1e-7`` (error_norm's numpy grid; the peer's fdimmperf < 1e-7)."""
    import fmu_fdi.design.problems.approximate_matching as am

    if covers_alone:
        monkeypatch.setattr(am, "_resolved_row", lambda *a, **k: (None, ""))
    model, Mr = _faults_only_plant(seed, dt)
    g0 = approximate_model_matching(model, Mr)
    g1 = approximate_model_matching(model, Mr, mindeg=True)
    assert min(row_degrees(g0.Q)) >= 5  # the optimal rows are not least order: there is something to lower
    assert row_degrees(g1.Q) == [0, 0]
    Q = g1.Q
    w = np.logspace(-3, np.log10(np.pi / dt) if dt else 3, 50)
    lam = np.exp(1j * w * dt) if dt else 1j * w
    vals = np.array([Q.C @ np.linalg.solve(z * np.eye(Q.n) - Q.A, Q.B) + Q.D if Q.n else Q.D.astype(complex)
                     for z in lam])
    assert np.max(np.abs(vals - vals[0])) <= 1e-9 * np.max(np.abs(vals))
    assert error_norm(g1, Mr, g1.info["M"], "inf") <= 1e-7
    assert decoupling(g1) < 1e-9


@pytest.mark.slow
def test_covers_alone_reach_the_resolve_on_random_seed_5(monkeypatch):
    """Random seed 5 (discrete, two 66-state optimal rows): the exact re-solve of (2) reaches order 7 per row; the
    covers alone stopped at 21 while their step (i) kept the 20 states an output injection through the basis
    makes uncontrollable (PBH values ≤ 2e-9 of the compound's norm, which the deflation at working precision does
    not remove; see covers.left_cover2's ``vrtol``). With
    the re-solve switched off, the covers must now reach the design's orders with it (Hankel singular values
    from scipy's Lyapunov solvers), with the optimal error (numpy responses, the test's grid, reltol 1e-6 plus
    the guard's floor 1e-9 ||M Mr||∞), decoupled and stable."""
    import fmu_fdi.design.problems.approximate_matching as am

    model, Mr = _random_case(5)
    g0 = approximate_model_matching(model, Mr, reltol=1e-6)
    both = approximate_model_matching(model, Mr, reltol=1e-6, mindeg=True)
    monkeypatch.setattr(am, "_resolved_row", lambda *a, **k: (None, ""))
    g1 = approximate_model_matching(model, Mr, reltol=1e-6, mindeg=True)
    d1, db = row_degrees(g1.Q), row_degrees(both.Q)
    assert max(db) <= 7 and all(a <= b for a, b in zip(d1, db)), (d1, db)
    e0, e1 = error_norm(g0, Mr, g0.info["M"], "inf"), error_norm(g1, Mr, g1.info["M"], "inf")
    assert e1 <= e0 * (1 + 1e-6) + 1e-9 * max(1.0, (g1.info["M"] @ Mr).hinfnorm()[0])
    assert decoupling(g1) < 1e-9 and stable(g1.Q)


@pytest.mark.slow
def test_covers_alone_on_random_seed_17_keep_only_decoupled_rows(monkeypatch):
    """Random seed 17 (discrete, two 52-state optimal rows): the exact re-solve of (2) lowers the rows to [5, 8]
    (benchmarks/mindeg_time.py --seeds 17). With the re-solve switched off, the covers alone reached [5, 8] on main:
    row 1's order-5 cover with its free poles chosen stable (covers.stable_left_cover, step (i) mode by mode) met the
    unnormalised guard, but it leaks u 2.1e-4 of the row's weakest fault (the library's normalised reading; the
    re-decoupling refits leave 4.4e-5, weighted 6e-6) — the returned filter leaked 3.3e-6 of the weakest fault by
    numpy. Judged on the normalised form, that cover is refused with its figures; what the covers return must meet
    the judge: every row's u/d leak at most dec_tol = 1e-7 of its weakest fault by numpy (_numpy_leak_and_faults),
    row 2 still at the re-solve's 8, row 1 below the optimal 52; the optimal error (numpy responses, the test's grid,
    reltol 1e-6 plus the guard's floor 1e-9 ||M Mr||∞); McMillan degrees by Hankel singular values (:func:`row_degrees`);
    stable."""
    import fmu_fdi.design.problems.approximate_matching as am
    from test_synthesis_ammp import _numpy_leak_and_faults

    model, Mr = _random_case(17)
    g0 = approximate_model_matching(model, Mr, reltol=1e-6)
    monkeypatch.setattr(am, "_resolved_row", lambda *a, **k: (None, ""))
    g1 = approximate_model_matching(model, Mr, reltol=1e-6, mindeg=True)
    d0, d1 = row_degrees(g0.Q), row_degrees(g1.Q)
    assert d1[0] < d0[0] and d1[1] <= 8 and min(d0) > 8, (d0, d1)
    leak, faults = _numpy_leak_and_faults(model, g1.Q)
    assert np.all(leak <= 1e-7 * faults.min(axis=1)), leak / faults.min(axis=1)
    # the leaking order-5 cover is not returned: refused with its figures, or row 1 lowered by another candidate (since
    # amm12 the optimal row's balanced truncations are offered last; the reason then lists no refusal of a lowered row)
    assert re.search(r"order-5 candidate \(stable cover[^;]*u/d leak on the normalised form",
                     g1.info["mindeg"]["reason"]) or (d1[0] != 5 and g1.info["mindeg"]["lowered"])
    e0, e1 = error_norm(g0, Mr, g0.info["M"], "inf"), error_norm(g1, Mr, g1.info["M"], "inf")
    assert e1 <= e0 * (1 + 1e-6) + 1e-9 * max(1.0, (g1.info["M"] @ Mr).hinfnorm()[0])
    assert stable(g1.Q)
