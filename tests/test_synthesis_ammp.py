"""Approximate model matching (design/problems/approximate_matching.py) and the EMMP updating factor M.

Published sources: Varga (2017) Examples 5.6c, 5.11c, 5.12, 5.13c, 5.14-5.17 and the Niemann
model, as run by FaultDetectionTools.jl Examples/Ex5_1*.jl and test/test_ammsyn.jl,
test/test_emmsyn.jl, and the printed results of the FDITools user's guide (fditoolsdoc.pdf,
Examples 12-14 = book Examples 5.12, 5.13, 5.11). Where no γ value is printed, the optimum is
checked against an independent bound (a point evaluation or a brute-force optimisation).
"""
import re

import control as ct
import numpy as np
import published as pub
import pytest

from fmu_fdi import (
    DesignError,
    FDIModel,
    actuator_fault,
    approximate_model_matching,
    model_matching,
)
from fmu_fdi.lti import LTI, hstack

s = pub.s


def error_norm(gen, Mr, M, norm):
    """``||Q [Gf Gw; 0 0] − M [Mr 0]||`` measured from the model and the returned Q alone, factor by
    factor on a dense grid (independent of the design's own figures and of realisation-level norms,
    which lose digits on products with near-cancelling modes): H∞ as the peak over 1200
    log-spaced points refined around the maximum, H2 by the trapezoidal rule on the same points."""
    from fmu_fdi.design.problems.approximate_matching import fault_noise_map

    model = gen.model
    Mr = Mr if isinstance(Mr, LTI) else LTI.from_control(ct.ss(Mr))
    if not Mr.n and Mr.dt != model.dt:
        Mr = LTI.static(Mr.D, model.dt)
    F = hstack([Mr, LTI.zero(Mr.p, model.nw, model.dt)]) if model.nw else Mr
    MF = M @ F if M.n else M.D @ F
    fnm = fault_noise_map(model)
    top = np.pi / model.dt if model.dt else 1e5
    w = np.concatenate([[0.0], np.logspace(-5, np.log10(top), 1200)])

    def resp(S, w):  # C (λI − A)^{-1} B + D, batched over the points
        lam = np.exp(1j * w * model.dt) if model.dt else 1j * w
        if S.n == 0:
            return np.broadcast_to(S.D.astype(complex), (w.size,) + S.D.shape)
        X = np.linalg.solve(lam[:, None, None] * np.eye(S.n) - S.A, np.broadcast_to(S.B, (w.size,) + S.B.shape))
        return S.C @ X + S.D

    def values(w):
        return np.einsum("kij,kjl->kil", resp(gen.Q, w), resp(fnm, w)) - resp(MF, w)

    if norm == "inf":
        sig = np.linalg.norm(values(w), 2, axis=(1, 2))
        k = int(np.argmax(sig))
        ww = np.linspace(w[max(k - 1, 0)], w[min(k + 1, w.size - 1)], 400)
        return float(max(sig.max(), np.linalg.norm(values(ww), 2, axis=(1, 2)).max()))
    f = np.sum(np.abs(values(w)) ** 2, axis=(1, 2))
    tail = 0.0 if model.dt else f[-1] * w[-1]  # strictly proper: f ~ c/ω²
    return float(np.sqrt((np.trapezoid(f, w) + tail) / np.pi * (model.dt if model.dt else 1.0)))


def pointwise_bound(model, Mr, norm="inf"):
    """A lower bound of γopt0 that any design must respect: at each frequency the best constant
    Y(jω) leaves ||F(jω) (I − G1⁺G1)(jω)|| with G1 = N [Gf Gw; 0 0], N a left null space of
    [Gu Gd; I 0] at that point (SVD) — computed from the model alone. H∞: its peak over 400 log
    points; H2: (1/π ∫ ||·||_F² dω)^½ by the trapezoidal rule on 3000 log points (continuous)."""
    from fmu_fdi.design.problems.approximate_matching import fault_noise_map

    sl = model.group_slices()
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    Ge, fnm = model.augmented(), fault_noise_map(model)
    Mr = Mr if isinstance(Mr, LTI) else LTI.from_control(ct.ss(Mr))
    ws = np.concatenate([[0.0], np.logspace(-3, 3, 400)]) if norm == "inf" else np.logspace(-4, 5, 3000)
    vals = []
    for w in ws:
        lam = np.exp(1j * w * model.dt) if model.dt else 1j * w
        G = Ge.evalfr(lam)
        U, sv, _ = np.linalg.svd(G[:, ud]) if ud.size else (np.eye(G.shape[0]), np.zeros(0), None)
        N = U[:, int(np.sum(sv > 1e-10 * max(sv.max(initial=0.0), 1.0))):].conj().T  # left null space
        G1 = N @ fnm.evalfr(lam)
        Fv = np.hstack([Mr.evalfr(lam), np.zeros((Mr.p, model.nw))])
        P = np.eye(G1.shape[1]) - np.linalg.pinv(G1, rcond=1e-10) @ G1
        vals.append(np.linalg.norm(Fv @ P, 2 if norm == "inf" else "fro"))
    vals = np.asarray(vals)
    if norm == "inf":
        return float(vals.max())
    return float(np.sqrt(np.trapezoid(vals**2, ws) / np.pi))


def static(D):
    return ct.ss([], [], [], np.atleast_2d(np.asarray(D, float)))


def ex5_14():
    G = pub.tfm([[1 / (s + 1), 1 / (s + 2)]], ["f", "w"])
    return FDIModel.from_control(G, w=["w"], f=["f"], name="ex5_14")


def ex5_16():
    A = np.array([[-.8, 0, 0], [0, -.5, .6], [0, -.6, -.5]])
    Bu = np.array([[1.0, 1], [1, 0], [0, 1]])
    Bw = 0.25 * np.array([[0.0, 0], [0, 1], [1, 0]])
    C = np.array([[0.0, 1, 1], [1, 1, 0]])
    return FDIModel.from_matrices(A, Bu, C, Bw=Bw, u_names=["u1", "u2"], y_names=["y1", "y2"], w_names=["w1", "w2"],
                                  faults=[actuator_fault("f1", "u1"), actuator_fault("f2", "u2")], name="ex5_16")


MR14 = ct.ss(1 / (s + 3))
MR17 = ct.ss(pub.tfm([[10 / (s + 10), 0], [0, 10 / (s + 10)]], ["f1", "f2"]))


def decoupling(gen):
    """``max_ω ||Q [Gu Gd; I 0]|| / max_ω ||Q|| ||[Gu Gd; I 0]||`` on 400 log points, by numpy solves
    on the returned Q and the model's matrices (independent of the package's judge, whose figure
    changed meaning with issue 17: absolute on the normalised form)."""
    model = gen.model
    top = np.pi / model.dt if model.dt else 1e4
    w = np.concatenate([[0.0], np.logspace(-4, np.log10(top), 400)])
    lam = np.exp(1j * w * model.dt) if model.dt else 1j * w
    B, D = np.hstack([model.Bu, model.Bd]), np.hstack([model.Du, model.Dd])
    if B.shape[1] == 0:
        return 0.0

    def resp(A, B, C, D):
        if A.shape[0] == 0:
            return np.broadcast_to(D.astype(complex), (w.size,) + D.shape)
        X = np.linalg.solve(lam[:, None, None] * np.eye(A.shape[0]) - A, np.broadcast_to(B, (w.size,) + B.shape))
        return C @ X + D

    G = np.concatenate([resp(model.A, B, model.C, D), np.broadcast_to(np.eye(model.nu, B.shape[1]), (w.size, model.nu,
                                                                                                      B.shape[1]))], axis=1)
    Q = resp(gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D)
    ok = np.all(np.isfinite(G), axis=(1, 2)) & np.all(np.isfinite(Q), axis=(1, 2))
    R = np.linalg.norm(Q[ok] @ G[ok], 2, axis=(1, 2))
    bound = np.linalg.norm(Q[ok], 2, axis=(1, 2)) * np.linalg.norm(G[ok], 2, axis=(1, 2))
    return float(R.max() / bound.max())


def check_contract(gen, Mr, norm, rel=None):
    """Decoupling to 1e-9 (relative, independent numpy measure) and the measured error equal to the
    reported gamma_sub."""
    info = gen.info
    assert decoupling(gen) < 1e-9
    err = error_norm(gen, Mr, info["M"], norm)
    # H∞: both are peaks of the same response on refined grids, 1e-5 relative; H2: trapezoid on
    # 1200 log points vs Gauss–Legendre panels, 1e-3 relative
    rel = rel if rel is not None else (1e-5 if norm == "inf" else 1e-3)
    assert err == pytest.approx(info["gamma_sub"], rel=rel, abs=1e-9 * max(1.0, info["gamma_sub"]))
    assert gen.Q.is_stable()
    return err


# ---------------------------------------------------------------- Example 5.13c (EMMP with M)
def test_example_5_13c_updating_factor():
    """Varga Ex. 5.13 / FDT Ex5_13c.jl: Gu = Gf, Mr = I, sdeg = -1; Rf has zeros at 0 and ∞, so
    no exact proper solution exists and M = diag(s/(s+1), 1/(s+1)) (zpk gain 1) is the least
    order diagonal factor (row 1: f1 is invisible at DC; row 2: relative degree 1)."""
    G = pub.tfm([[s / (s**2 + 3 * s + 2), 1 / (s + 2)], [s / (s + 1), 0], [0, 1 / (s + 2)]], ["u1", "u2"])
    model = FDIModel.from_control(G, u=["u1", "u2"], faults=[actuator_fault("f1", "u1"), actuator_fault("f2", "u2")])
    with pytest.raises(DesignError, match="updating factor"):
        model_matching(model, static(np.eye(2)), max_degree=2)
    gen = model_matching(model, static(np.eye(2)), updating=True, sdeg=-1)
    M = gen.info["M"]
    for w in (0.0, 0.3, 1.0, 7.0):
        jw = 1j * w
        want = np.diag([jw / (jw + 1), 1 / (jw + 1)])
        assert np.allclose(M.freqresp([w])[0], want, atol=1e-9)
    assert gen.info["row_degrees"] == [1, 1] and gen.Q.n == 2
    assert np.allclose(np.sort(gen.Q.poles().real), [-1, -1])
    assert gen.info["matching_error"] < 1e-9 and gen.info["postconditions"]["decoupling"] < 1e-9
    assert np.allclose(gen.info["M_zeros"][0], [0.0], atol=1e-9) and len(gen.info["M_zeros"][1]) == 0
    # Q Ge = [0 M Mr] checked independently: Q [Gu; I] = 0, Q [Gf; 0] = M
    for w in (0.2, 2.0):
        Rf = gen.Rf.freqresp([w])[0]
        assert np.allclose(Rf, M.freqresp([w])[0], atol=1e-9)
    # the printed Q (FDITools guide, Example 13) differs from ours by a left annihilator of
    # [Gu; I] (Q is not unique; M is): both have McMillan degree 2 and the same Q Ge
    Qbook = ct.ss(pub.tfm([[0, 1, 0, -s / (s + 1), 0], [0, 0, (s + 2) / (s + 1), 0, -1 / (s + 1)]],
                          ["y1", "y2", "y3", "u1", "u2"]))
    Rbook = LTI.from_control(Qbook) @ model.augmented()
    for w in (0.2, 2.0):
        assert np.allclose(Rbook.freqresp([w])[0], gen.Q.freqresp([w])[0] @ model.augmented().freqresp([w])[0],
                           atol=1e-9)


def test_updating_factor_is_constant_when_the_exact_solution_is_admissible():
    """FDT test_emmsyn.jl, Niemann (1998) bank references: emmsyn returns order-1 rows with
    R = M Rf; here the exact solution is stable and proper, so M = 1 (ν = 0) and Q Ge = [0 0 Rf]."""
    from test_synthesis_published import niemann

    from fmu_fdi import structured_bank

    model = niemann()
    for g in structured_bank(model, [[1, 1], [0, 1], [1, 0]]).members:
        mm = model_matching(model, g.Rf, updating=True)
        assert mm.info["row_degrees"] == [0] and mm.Q.n == 1 and mm.info["M"].n == 0
        assert np.allclose(mm.info["M"].D, 1.0) and mm.info["matching_error"] < 1e-9


def test_example_5_12_triplex_sensors_emmp():
    """FDITools guide Example 12 (book Ex. 5.12): triplex sensor redundancy, Mr = [0 1 −1; −1 0 1;
    1 −1 0]; published Q = [Mr 0 ⋯ 0] (static, unique: Gf = I forces the y-part, Mr·1 = 0 the u-part)."""
    rng = np.random.default_rng(3)  # Gu = 1·gu, Gd = 1·gd with random 3-state gu, gd (book: rss)
    A = -np.diag(rng.uniform(0.5, 3.0, 3))
    Bu, Bd = rng.normal(size=(3, 2)), rng.normal(size=(3, 1))
    C = np.ones((3, 1)) @ rng.normal(size=(1, 3))
    from fmu_fdi import sensor_fault

    model = FDIModel.from_matrices(A, Bu, C, Bd=Bd, u_names=["u1", "u2"], y_names=["y1", "y2", "y3"],
                                   d_names=["d"], faults=[sensor_fault(f"s{i}", f"y{i}") for i in (1, 2, 3)])
    Mr = np.array([[0.0, 1, -1], [-1, 0, 1], [1, -1, 0]])
    gen = model_matching(model, static(Mr))
    assert gen.Q.n == 0
    assert np.allclose(gen.Q.D, np.hstack([Mr, np.zeros((3, 2))]), atol=1e-9)


# --------------------------------------------------------------- Examples 5.14 / 5.15 (scalar)
def test_example_5_14_hinf():
    """FDT Ex5_14.jl (sdeg = -1, normalize = "gain"): Gf = 1/(s+1), Gw = 1/(s+2), Mr = 1/(s+3).
    Non-standard (Gf, Gw strictly proper): M = 1/(s+1). γopt0 = 0.174457 is the infimum of the
    original problem: a brute-force minimisation over Q = Ŷ(s+1), Ŷ with poles {-1,-2,-3,-4,-6,-10}
    on a 3000-point grid gives 0.1744575; FDT's test checks fdimmperf(R, M Mr) ≈ gammasub."""
    gen = approximate_model_matching(ex5_14(), MR14, sdeg=-1, normalize="gain", reltol=1e-5)
    info = gen.info
    assert not info["standard"] and info["interactor_steps"] == 1
    assert info["gamma_opt0"] == pytest.approx(0.1744575, rel=2e-5)  # brute-force value, its 7 digits
    # the pointwise bound 0.1744474 is attained here: the optimum must lie within reltol of it
    lb = pointwise_bound(ex5_14(), MR14)
    assert lb * (1 - 1e-9) <= info["gamma_opt0"] <= lb * (1 + 1e-4)
    err = check_contract(gen, MR14, "inf")
    assert info["gamma_opt"] <= err * (1 + 1e-5)  # the updated problem's optimum is a lower bound of gammasub
    assert np.allclose(info["M"].freqresp([0.0, 1.0])[:, 0, 0], [1.0, 1 / (1j + 1)], atol=1e-12)


def test_example_5_15_h2():
    """FDT Ex5_15.jl (H2, sdeg = -1, normalize = "gain"): M = 1/(s+1); the measured H2 error is
    gammasub (FDT: gl2norm(Me − Q Ge) ≈ gammasub) and the updated optimum bounds it from below.
    γopt0 = 0.2596: a least-squares fit of Ŷ on a 3000-point grid to 1e3 rad/s gives 0.2593."""
    model = ex5_14()
    g2 = approximate_model_matching(model, MR14, norm="2", sdeg=-1, normalize="gain")
    check_contract(g2, MR14, "2")
    assert g2.info["gamma_opt0"] == pytest.approx(0.2596, abs=3e-4)  # grid least squares: 0.2593 (tail cut at 1e3)
    # the pointwise H2 bound (0.2570; not attained: causality costs) is a lower bound, 1e-3 for the quadrature
    assert g2.info["gamma_opt0"] >= pointwise_bound(model, MR14, "2") * (1 - 1e-3)
    assert g2.info["gamma_opt"] <= g2.info["gamma_sub"] * (1 + 1e-9)


def test_h2_and_hinf_optima_bound_each_other_standard_case():
    """Ex. 5.11c (A5a plant, Mr = I; standard: [Gf Gw] has a full-row-rank feedthrough): the H2
    filter is no worse in H2 than the H∞ filter, and vice versa in H∞ (to the γ-iteration's reltol)."""
    model = pub.a5a_model()
    Mr = static(np.eye(2))
    gi = approximate_model_matching(model, Mr, norm="inf", reltol=1e-6)
    Mr2 = ct.ss(pub.tfm([[3 / (s + 3), 0], [0, 3 / (s + 3)]], ["f1", "f2"]))  # strictly proper: finite H2
    gi2 = approximate_model_matching(model, Mr2, norm="inf", reltol=1e-6)
    g22 = approximate_model_matching(model, Mr2, norm="2")
    assert gi.info["standard"] and g22.info["standard"]
    I2 = LTI.static(np.eye(2))
    e_ii, e_i2 = error_norm(gi2, Mr2, I2, "inf"), error_norm(g22, Mr2, I2, "inf")
    h_ii, h_22 = error_norm(gi2, Mr2, I2, "2"), error_norm(g22, Mr2, I2, "2")
    assert e_ii <= e_i2 * (1 + 1e-6)
    assert h_22 <= h_ii * (1 + 1e-9)
    check_contract(gi, Mr, "inf")
    # standard case: the measured error is the optimum to the bisection's reltol
    lo, hi = gi.info["gamma_bracket"]
    # 1e-5: grid peaks of the same response (check_contract)
    assert lo * (1 - 1e-5) <= gi.info["error"] <= hi * (1 + 1e-5) and hi <= lo * (1 + 2e-6) + 1e-12
    # a lower bound at ω = 0 (row 1: [y(0)/2 − 1, y(0)/2] from Gf11(0) = Gw1(0) = 1/2): ≥ 1/√2
    assert gi.info["gamma_opt"] >= np.sqrt(0.5) * (1 - 1e-6)


def test_example_5_11_published_gamma_and_filter():
    """FDITools guide Example 14 (book Ex. 5.11 as an AMMP, Mr = I): published γopt = √2/2 = 0.7071
    with M = I2, attained by the printed Q = [0.7072 (s+2)/(s+√2)  0  −0.7072 (s+1)/(s+√2);
    0  0.7072  −0.7072 (s+2)/(s+3)]: our optimum equals it to the printed 4 digits and the printed
    filter's error (measured here) is that optimum too."""
    model = pub.a5a_model()
    gen = approximate_model_matching(model, static(np.eye(2)), reltol=1e-6)
    assert gen.info["standard"] and np.allclose(gen.info["M"].D, np.eye(2))
    assert round(gen.info["gamma_opt"], 4) == 0.7071
    r2 = np.sqrt(2.0)
    Qbook = ct.ss(pub.tfm([[0.7072 * (s + 2) / (s + r2), 0, -0.7072 * (s + 1) / (s + r2)],
                           [0, 0.7072, -0.7072 * (s + 2) / (s + 3)]], ["y1", "y2", "u"]))
    from fmu_fdi import ResidualGenerator

    book = ResidualGenerator(LTI.from_control(Qbook), model, "book")
    e_book = error_norm(book, static(np.eye(2)), LTI.static(np.eye(2)), "inf")
    assert round(e_book, 4) == 0.7071
    assert gen.info["error"] <= e_book * (1 + 1e-6)


def test_example_5_6c_optimum_beats_published_design():
    """FDT test_ammsyn.jl, Ex. 5.6c: with Mr = [1 1] the published (HDesign = [1 1]) filter has
    fdimmperf(R, Mr) = 0.7385533646476293. The optimum over all filters is 1/√2: at ω = 0 any
    filter has error ≥ min_t ||[t − 1, t]|| = 1/√2 (Gf11(0) = Gw1(0) = 1/2), and Q = [1 1 −Gu] attains it."""
    gen = approximate_model_matching(pub.a5a_model(), static([[1.0, 1.0]]), sdeg=-3, reltol=1e-6)
    assert gen.info["standard"]
    assert gen.info["gamma_opt"] == pytest.approx(np.sqrt(0.5), rel=1e-6)
    assert check_contract(gen, static([[1.0, 1.0]]), "inf") <= 0.7385533646476293


# --------------------------------------------------------------- Examples 5.16 / 5.17 (2×2)
def test_example_5_16_hinf():
    """FDT Ex5_16.jl (sdeg = -10, normalize = "dcgain", reltol = 5e-4): M = 10/(s+10) I and the
    published check err_sub − err_opt < 0.002 (sub-optimal vs optimal updated problem)."""
    gen = approximate_model_matching(ex5_16(), static(np.eye(2)), sdeg=-10, reltol=5e-4)
    info = gen.info
    assert info["interactor_steps"] == 1
    assert np.allclose(info["M"].freqresp([0.0, 10.0])[:, 0, 0], [1.0, 10 / (10 + 10j)], atol=1e-12)
    err = check_contract(gen, static(np.eye(2)), "inf")
    assert err - info["gamma_opt"] < 0.002 and err >= info["gamma_opt"] * (1 - 5e-4)
    # the pointwise bound 0.5167303 is attained here too: γopt0 within reltol of it
    lb = pointwise_bound(ex5_16(), static(np.eye(2)))
    assert lb * (1 - 1e-9) <= info["gamma_opt0"] <= lb * (1 + 5e-4)


def test_example_5_17_h2():
    """FDT Ex5_17.jl: H2 with Mr = 10/(s+10) I; test: gl2norm(Me − Q Ge) ≈ gammasub. FDT's
    test_ammsyn.jl also runs Ex. 5.16c in H2 with Mr = I (sdeg = -10): its infinite-norm error is
    repaired by updating Mr with 10/(s+10), which is Ex. 5.17's problem, so M Mr and γsub coincide."""
    gen = approximate_model_matching(ex5_16(), MR17, norm="2", sdeg=-10)
    check_contract(gen, MR17, "2")
    gI = approximate_model_matching(ex5_16(), static(np.eye(2)), norm="2", sdeg=-10)
    assert gI.info["reference_lowpass"] and not gen.info["reference_lowpass"]
    assert gI.info["gamma_sub"] == pytest.approx(gen.info["gamma_sub"], rel=1e-9)
    assert check_contract(gI, static(np.eye(2)), "2") == pytest.approx(gen.info["gamma_sub"], rel=1e-3)
    # γopt0 = 1.1172 above the pointwise H2 bound 1.1138 (1e-3 for the quadrature)
    assert gen.info["gamma_opt0"] >= pointwise_bound(ex5_16(), MR17, "2") * (1 - 1e-3)
    assert gen.info["gamma_opt"] <= gen.info["gamma_sub"] * (1 + 1e-9)


# ------------------------------------------------------------------------------ Niemann
@pytest.mark.parametrize("row", [[1.0, 0.0], [0.0, 1.0]])
def test_niemann_exactly_matchable_references(row):
    """FDT test_ammsyn.jl, Niemann (1998) model: Mr = [1 0] and [0 1] are matched exactly
    (published: fdimmperf(Rf2, M sysr2) < 1e-7)."""
    from test_synthesis_published import niemann

    gen = approximate_model_matching(niemann(), static([row]), sdeg=-5, reltol=1e-5)
    err = check_contract(gen, static([row]), "inf", rel=1.0)
    assert err < 1e-7 and gen.info["gamma_sub"] < 1e-7


# ------------------------------------------------------------------------------ refusals
def test_refusals_name_the_condition():
    model = ex5_14()
    with pytest.raises(DesignError, match="must have 1 inputs"):
        approximate_model_matching(model, static([[1.0, 1.0]]))
    with pytest.raises(DesignError, match="Mr must be stable"):
        approximate_model_matching(model, ct.ss(1 / (s - 1)))
    with pytest.raises(DesignError, match="proper"):
        approximate_model_matching(model, ct.tf([1, 0, 1], [1, 1]))
    with pytest.raises(DesignError, match="finite matrix"):
        approximate_model_matching(model, [[np.nan]])
    assert approximate_model_matching(model, [[0.5]]).info["error"] > 0  # a constant reference is accepted
    with pytest.raises(DesignError, match="norm must be"):
        approximate_model_matching(model, MR14, norm="1")
    # H2 with a feedthrough no filter can cancel: G = [(s+2)/(s+1), 1], Mr = 1 → D_F = [1 0] ∉ rowspace [1 1]:
    # every error has infinite H2 norm, so (as ammsyn) Mr is updated by a/(s+a), which joins M
    G = pub.tfm([[(s + 2) / (s + 1), 1]], ["f", "w"])
    m2 = FDIModel.from_control(G, w=["w"], f=["f"])
    g = approximate_model_matching(m2, static([[1.0]]), norm="2", sdeg=-2)
    assert g.info["reference_lowpass"] and g.info["M"].n == 1
    assert np.allclose(g.info["M"].freqresp([0.0, 2.0])[:, 0, 0], [1.0, 2 / (2 + 2j)], atol=1e-12)
    check_contract(g, static([[1.0]]), "2")
    # [Gf Gw] vanishes at s = ±j (a zero on the imaginary axis): the optimum is not attained
    G = pub.tfm([[(s**2 + 1) / (s + 1) ** 2, (s**2 + 1) / (s + 2) ** 2]], ["f", "w"])
    with pytest.raises(DesignError, match="zeros on the imaginary axis"):
        approximate_model_matching(FDIModel.from_control(G, w=["w"], f=["f"]), static([[1.0]]))
    # no residual: d reaches every output
    G = pub.tfm([[1 / (s + 1), 1 / (s + 2)]], ["d", "f"])
    m3 = FDIModel.from_control(G, d=["d"], f=["f"])
    with pytest.raises(DesignError, match="no residual decouples u and d"):
        approximate_model_matching(m3, static([[1.0]]))


def test_discrete_hinf_and_h2():
    """Discrete time (SLICOT SB10DD γ-iteration; H2 by the Kalman filter): the ZOH plant has a one-step
    delay (D = 0), M = 1/z is all-pass, so the measured error equals gamma_opt0, the infimum, to the
    bisection tolerance."""
    G = ct.c2d(ct.ss(pub.tfm([[1 / (s + 1), 1 / (s + 2)]], ["f", "w"])), 0.1)
    model = FDIModel.from_control(G, w=["w"], f=["f"])
    Mr = ct.c2d(ct.ss(1 / (s + 3)), 0.1)
    gen = approximate_model_matching(model, Mr, reltol=1e-6)
    info = gen.info
    err = check_contract(gen, LTI.from_control(Mr), "inf")
    lo, hi = info["gamma_bracket"]
    assert info["interactor_steps"] == 1
    # |M| = 1 on the unit circle; 1e-5: grid peaks of the same response (check_contract)
    assert lo * (1 - 1e-5) <= err <= hi * (1 + 1e-5) and hi <= lo * (1 + 2e-6) + 1e-12
    assert err == pytest.approx(info["gamma_opt0"], rel=1e-6)
    # discrete H2 (Kalman filter of F v from Ĝ v): M = 1/z is all-pass in H2 too, and each
    # optimum is no worse than the other design in its own norm (1e-5 / 1e-3: grid peak / trapezoid)
    g2 = approximate_model_matching(model, Mr, norm="2")
    e22 = check_contract(g2, LTI.from_control(Mr), "2")
    assert e22 == pytest.approx(g2.info["gamma_opt0"], rel=1e-3)
    Mr_ = LTI.from_control(Mr)
    assert error_norm(g2, Mr_, g2.info["M"], "2") <= error_norm(gen, Mr_, info["M"], "2") * (1 + 1e-3)
    assert error_norm(gen, Mr_, info["M"], "inf") <= error_norm(g2, Mr_, g2.info["M"], "inf") * (1 + 1e-5)


# ------------------------------------------------------------------ seeded random models
def _random_case(seed):
    """A model of tests/synthesis_models.py and a random stable first-order Mr (1-2 residuals)."""
    from synthesis_models import random_model

    model = random_model(seed)
    rng = np.random.default_rng(100 + seed)
    r = 1 + seed % 2
    pole = np.array([[0.5]]) if model.dt else np.array([[-2.0]])
    Mr = LTI(np.kron(np.eye(r), pole), rng.normal(size=(r, model.nf)), np.eye(r), np.zeros((r, model.nf)), model.dt)
    return model, Mr


@pytest.mark.parametrize("seed, norms", [(12, ("inf", "2")), (11, ("inf", "2")), (6, ("inf", "2")),
                                         (14, ("inf", "2")), (27, ("inf",))])
def test_random_models_keep_the_contract(seed, norms):
    """Standard (12: continuous with d, 11: discrete), non-standard (6: zeros at infinity) and
    rank-deficient reduced systems (14, 27: more basis rows than fault directions, regularised):
    decoupling ≤ 1e-9, the measured error is gamma_sub, no worse than Q = 0 (‖M Mr‖∞ with ‖M‖∞ = 1),
    and in the standard case each norm's optimum is no worse in its own norm than the other's."""
    model, Mr = _random_case(seed)
    gens = {nrm: approximate_model_matching(model, Mr, norm=nrm, reltol=1e-6) for nrm in norms}
    if "inf" in gens:
        assert gens["inf"].info["gamma_opt0"] >= pointwise_bound(model, Mr) * (1 - 1e-6)
    for nrm, gen in gens.items():
        check_contract(gen, Mr, nrm)
        if nrm == "inf":  # Ŷ = 0 is admissible: γsub = ||M (Ŷ Ĝ − F)|| ≤ γopt0 ≤ ||F||∞ = ||Mr||∞
            assert gen.info["gamma_sub"] <= Mr.hinfnorm()[0] * (1 + 1e-6)
    if seed in (14, 27):
        assert gens["inf"].info["regularised_rows"] > 0
    if seed == 6:
        assert gens["inf"].info["interactor_steps"] == 1 and not gens["inf"].info["standard"]
    if seed in (11, 12):
        gi, g2 = gens["inf"], gens["2"]
        assert gi.info["standard"] and g2.info["standard"]
        I = gi.info["M"]
        # 1e-5: grid peaks (check_contract); 1e-3: trapezoid vs Gauss–Legendre H2 values
        assert error_norm(gi, Mr, I, "inf") <= error_norm(g2, Mr, I, "inf") * (1 + 1e-5)
        assert error_norm(g2, Mr, I, "2") <= error_norm(gi, Mr, I, "2") * (1 + 1e-3)


def test_nearly_exact_ill_conditioned_problem_is_refused_not_returned():
    """Seed 7 (discrete, n = 29, d present): with the polynomial null-space basis the optimal Y has
    gain ~2e5 and the realisation of Q = Y Φ Q0 cannot reproduce the designed error; the design
    must then refuse and say why. (The basis of the issue-17 synthesis core may make it well
    conditioned: then the returned filter must meet its contract, judged independently.)"""
    model, Mr = _random_case(7)
    try:
        gen = approximate_model_matching(model, Mr)
    except DesignError as exc:
        assert re.search("lost accuracy.*gain of Y", str(exc))
    else:
        check_contract(gen, Mr, "inf")
        assert gen.info["gamma_sub"] <= Mr.hinfnorm()[0] * (1 + 1e-6)


def test_atol_accepted_and_validated():
    """A tiny absolute rank tolerance leaves Example 5.14's optimum unchanged (the same rank
    decisions); a negative one is a DesignError, not a ValueError."""
    a = approximate_model_matching(ex5_14(), MR14, sdeg=-1, normalize="gain", reltol=1e-5)
    b = approximate_model_matching(ex5_14(), MR14, sdeg=-1, normalize="gain", reltol=1e-5, atol=1e-12)
    assert b.info["gamma_opt0"] == pytest.approx(a.info["gamma_opt0"], rel=1e-9)
    with pytest.raises(DesignError, match="atol"):
        approximate_model_matching(ex5_14(), MR14, atol=-1.0)


def _numpy_leak_and_faults(model, Q, num=800):
    """Per row of Q: ``max_ω |R_ud|`` and the peak gain of each fault, ``R = Q [Gu Gd Gf; I 0 0]`` from numpy
    solves on the model's and Q's matrices (independent of the package's judge and of its frequency responses)."""
    dt = model.dt
    w = np.concatenate([[0.0], np.logspace(-4, np.log10(np.pi / dt if dt else 1e4), num)])
    lam = np.exp(1j * w * dt) if dt else 1j * w

    def resp(S):
        X = np.linalg.solve(lam[:, None, None] * np.eye(S.n) - S.A, np.broadcast_to(S.B.astype(complex),
                                                                                       (lam.size,) + S.B.shape))
        return S.C @ X + S.D

    assert Q.n
    R = resp(Q) @ resp(model.augmented())
    sl = model.group_slices()
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    f = np.arange(sl["f"].start, sl["f"].stop)
    return np.abs(R[:, :, ud]).max(axis=(0, 2)), np.abs(R[:, :, f]).max(axis=0)


@pytest.mark.parametrize("seed", [3, 5, 9, 27, pytest.param(13, marks=pytest.mark.slow)])
def test_discrete_h2_optimum_is_no_worse_in_h2_than_the_hinf_filter(seed):
    """Random discrete seeds 3, 5, 9, 27: the H2 design is judged by numpy against an admissible competitor, the H∞
    design (same M = z^{-K}, so the same problem's search space): its numpy-measured H2 error is no larger, its u/d
    leak is below dec_tol = 1e-7 of every row's weakest fault peak gain (the strictest normalisation), and the
    measured error is the reported one. Before the filter DARE was solved by SLICOT SB02OD and checked
    (:func:`_filter_dare`), scipy's solution (indefinite, relative residual 0.75) gave seed 3 an H2 error 41.58
    where the H∞ filter's is 9.8e-10, and seeds 9, 27 (exactly matchable: optimum 0, reached with a gain of Y of
    32.5) filters of gain 7e7 and 3e7 whose u leak (1.6e-6, 2.5e-6 of the weakest fault) the judge refused; seed 13
    (slow: ~10 s) a gain of Y of 2.4e8 whose realisation could not reproduce the designed response (a gap 1.13 of the
    error): refused as "lost accuracy".
    Seed 5 (exactly matchable, error 4.9e-11): scipy found no stabilising solution; with SB02OD's, row_shifts divided a
    row by z^{-1} on a feedthrough 1.1e-9 of its [c d] (below its 1e-9·||B|| test, not zero) and the shipped response
    was 6.7e-6 off the designed one — now every row takes the K shifts when the per-row filter is not reproduced."""
    model, Mr = _random_case(seed)
    g2 = approximate_model_matching(model, Mr, norm="2")
    gi = approximate_model_matching(model, Mr, norm="inf")
    M = g2.info["M"]
    # the same updating factor (discrete, default sdeg = 0: z^{-K} with the same K): gi.Q is admissible for g2's
    # problem
    assert gi.info["interactor_steps"] == g2.info["interactor_steps"] and not g2.info["reference_lowpass"]
    e2 = check_contract(g2, Mr, "2")
    # 1e-3: the trapezoid's accuracy on both (check_contract); the floor 1e-9 ||Mr||∞ serves the exactly matchable ones
    assert e2 <= error_norm(gi, Mr, M, "2") * (1 + 1e-3) + 1e-9 * Mr.hinfnorm()[0]
    leak, faults = _numpy_leak_and_faults(model, g2.Q)
    assert np.all(leak <= 1e-7 * faults.min(axis=1))


def test_filter_dare_closed_form_and_refusal():
    """:func:`_filter_dare` against the scalar DARE solved by hand. Process noise b v1, measurement noise d v2
    (independent): ``c² P² + (d²(1 − a²) − b²c²) P − b²d² = 0``, P the positive root — for an unstable a = 1.2 and a
    measurement noise 1e-6 (R = 1e-12: the regularised rows' ε²); correlated noise with one input (B = b, D21 = d ≠ 0)
    is recoverable from y, so ``P = 0`` where that estimator is stable (``a − b c/d`` inside the unit circle). A
    marginal mode the output does not see (a = 1, c = 0) has no stabilising solution: DesignError, not a returned
    gain."""
    from fmu_fdi.design.problems.approximate_matching import _filter_dare

    for a, b, c, d in [(1.2, 0.7, 2.0, 1e-6), (0.5, 3.0, 0.1, 2.0), (-0.9, 1e3, 1e-3, 1.0)]:
        h = d * d * (1 - a * a) - b * b * c * c
        P_exact = (-h + np.sqrt(h * h + 4 * c * c * b * b * d * d)) / (2 * c * c)
        P = _filter_dare(np.array([[a]]), np.array([[b, 0.0]]), np.array([[c]]), np.array([[0.0, d]]))
        # the quadratic's own rounding: its terms are ~max(h², c²b²d²)/c² P, relative 1e-12 leaves 1e3 u of margin
        assert P[0, 0] == pytest.approx(P_exact, rel=1e-10)
    # v = (y − c x)/d: the state is known exactly, P = 0, stabilising as the channel's zero a − b c/d = −0.2 is stable
    # (the floor: rounding of the terms b² = 0.49, relative eps, times a few)
    P = _filter_dare(np.array([[1.2]]), np.array([[0.7]]), np.array([[2.0]]), np.array([[1.0]]))
    assert abs(P[0, 0]) <= 1e-14
    with pytest.raises(DesignError, match="no stabilising solution"):
        _filter_dare(np.array([[1.0]]), np.array([[1.0, 0.0]]), np.array([[0.0]]), np.array([[0.0, 1.0]]))


def test_rounding_bound_lets_a_well_realised_candidate_through():
    """Random continuous H∞ seed 28 (K = 1, two regularised rows, error ~5e-8): the fixed 1e-6 gap test took the
    minimal realisation of Y Φ Q0, whose u+d leak (4.9e-7 of the weakest fault gain) the judge refused; with the
    derived rounding bound that candidate is not taken and the returned filter meets the contract, judged by numpy:
    u/d leak ≤ 1e-7 of the weakest fault's peak gain on every row (Varga's normalisation with every fault
    required: the strictest), the measured error is gamma_sub, no worse than Q = 0 and no better than the
    pointwise lower bound."""
    model, Mr = _random_case(28)
    gen = approximate_model_matching(model, Mr)
    check_contract(gen, Mr, "inf")
    leak, faults = _numpy_leak_and_faults(model, gen.Q)
    assert np.all(leak / faults.min(axis=1) <= 1e-7)
    assert gen.info["gamma_opt0"] >= pointwise_bound(model, Mr) * (1 - 1e-6)
    assert gen.info["gamma_sub"] <= Mr.hinfnorm()[0]


@pytest.mark.parametrize("seed", [2, 10])
def test_leaking_matching_rows_are_re_decoupled_on_the_normalised_form(seed):
    """Random continuous H∞ seeds 2 and 10 (benchmarks/ammp_random_set.py): the shipped filter Y·Φ·Q0 leaked u
    1.83e-7 and 3.63e-7 of its row's weakest required fault gain (every fault is required: Mr's row is dense), above
    dec_tol = 1e-7 on Varga's normalised form, and was returned (the matching post-condition reads rows unnormalised).
    The re-decoupling stage refits its numerator; judged by numpy on the returned Q and the model alone: the leak is at
    most dec_tol of the weakest fault's peak gain (the issue's judge), and the measured error is within reltol = 1e-4
    of that of the same design without the stage (``dec_tol = 1``: its leak is below it, so the stage does not run),
    plus 1e-9 ||Mr||∞ (the stage's own allowance for exactly matchable references: seed 10's error is 1.4e-8)."""
    model, Mr = _random_case(seed)
    gen = approximate_model_matching(model, Mr)
    note = gen.info["ud_redecoupling"]
    assert note["refined"], note["reason"]
    assert note["leak_before"] > 1e-7 >= note["leak_after"]
    leak, faults = _numpy_leak_and_faults(model, gen.Q)
    assert np.all(leak / faults.min(axis=1) <= 1e-7)
    plain = approximate_model_matching(model, Mr, dec_tol=1.0)
    assert not plain.info["ud_redecoupling"]["refined"]
    leak0, faults0 = _numpy_leak_and_faults(model, plain.Q)
    assert np.any(leak0 / faults0.min(axis=1) > 1e-7)  # the case exercises the stage: the plain design leaks
    e, e0 = error_norm(gen, Mr, gen.info["M"], "inf"), error_norm(plain, Mr, plain.info["M"], "inf")
    assert e <= e0 * (1 + 1e-4) + 1e-9 * Mr.hinfnorm()[0]
    check_contract(gen, Mr, "inf")


def test_re_decoupling_on_the_minimal_balanced_realisation():
    """Random continuous H∞ seed 4 (this test pinned, before, that the filter was returned with numpy's leak 1.8e-7 of
    its weakest required fault, "at the rounding floor"). The judge now reads the stored filter's u/d leak with
    refined solves (postconditions._decoupled_reading): the shipped filter (order 70, Hankel singular values down to 1e-25
    of the largest) leaks 2.0e-8 as stored, but its realisation's sensitivity is 3.4e-7 — numpy's plain evaluation
    read it at 1.8e-7, and so would any double-precision evaluation of that realisation. The stage now refits the
    minimal balanced realisation (order 22, sensitivity 4.6e-11): judged by numpy on the returned Q and the model, the
    leak is at most dec_tol = 1e-7 of the weakest required fault's peak gain (every fault is required: Mr's row is
    dense), and the measured error is within reltol = 1e-4 of the shipped filter's plus 1e-9 ||Mr||∞ (the stage's
    allowance; the error is 7.9e-8)."""
    model, Mr = _random_case(4)
    gen = approximate_model_matching(model, Mr)
    note = gen.info["ud_redecoupling"]
    assert note["refined"] and note["realisation"] == "minimal balanced", note["reason"]
    leak, faults = _numpy_leak_and_faults(model, gen.Q)
    assert np.all(leak / faults.min(axis=1) <= 1e-7)
    plain = approximate_model_matching(model, Mr, dec_tol=1.0)
    leak0, faults0 = _numpy_leak_and_faults(model, plain.Q)
    assert np.any(leak0 / faults0.min(axis=1) > 1e-7)  # the case exercises the stage: numpy reads the shipped one above
    e, e0 = error_norm(gen, Mr, gen.info["M"], "inf"), error_norm(plain, Mr, plain.info["M"], "inf")
    assert e <= e0 * (1 + 1e-4) + 1e-9 * Mr.hinfnorm()[0]
    check_contract(gen, Mr, "inf")
