"""Exact and approximate model detection (design/problems/model_detection.py) against FaultDetectionTools.jl
test/test_emdsyn.jl and test/test_amdsyn.jl: the actuator example (four first-order actuator
models), Example 6.1c (lateral aircraft, nine loss-of-effectiveness models) and Example 6.2
(the same with noise; see the AMDP section below).

Published property: ``norm(diag(MDperf)) < 1e-7`` (filter i is exact for model i). The
published ranking property of the actuator example (``sortperm(distgap[i,:]) ==
sortperm(MDperf[i,:])``) holds at MDfreq = 1 (test_actuator_models_amdsyn_match_and_ranking)
but not for the H∞ distances of these filters Q_i = [s + a_i, -a_i]/(s + 20) (the unique
first-order filters up to scale, which emdsyn's observer-based design with poles = [-20] also
gives): row 1 ranks models 3 and 4 the other way, as the closed form shows.
"""
import numpy as np
import pytest
import scipy.signal as ss

from fmu_fdi import FDIModel
from fmu_fdi.design.problems.model_detection import (approximate_model_detection_bank, distance_mapping, match_model,
                                            model_detection_bank, noise_gaps, nu_gap_siso)
from fmu_fdi.errors import DesignError
from fmu_fdi.lti import LTI


def _actuator(k):
    return FDIModel.from_matrices([[-k]], [[k]], [[1.0]], name=f"act{k:g}".replace(".", "_"))


def test_actuator_models_distance_mapping():
    """Four first-order actuators a/(s+a), a = k, k/2, 10k, k/100 (k = 14), pole -20. With one
    output and one input the least-order filter of model 1 is unique up to scale,
    Q1 = [s+k, -k]/(s+20), so R_1j = (a_j - k) s / ((s+a_j)(s+20)): the distances of row 1 are
    known in closed form (grid peak, 1e-4 relative: the H∞ computation is exact to ~1e-10, the
    closed form is evaluated on a dense grid)."""
    k = 14.0
    a = [k, 0.5 * k, 10 * k, 0.01 * k]
    models = [_actuator(x) for x in a]
    bank = model_detection_bank(models, sdeg=-15.0, poles=[-20.0])
    perf = np.array(bank.info["MDperf_abs"])
    assert np.max(np.abs(np.diag(perf))) < 1e-7 * perf.max()
    assert np.all(perf[~np.eye(4, dtype=bool)] > 1e-3 * perf.max())
    w = np.logspace(-4, 5, 200001)
    closed = [np.max(abs(aj - k) * w / (np.abs(1j * w + aj) * np.abs(1j * w + 20))) for aj in a]
    assert np.allclose(perf[0, 1:] / perf[0, 1], np.array(closed[1:]) / closed[1], rtol=1e-4)
    assert all(np.allclose(m.Q.poles(), [-20.0]) for m in bank.members)


def test_nu_gap_of_first_order_models():
    """Chordal distance of k/(s+k) and a/(s+a): symmetric, zero on the diagonal, in [0, 1]."""
    G = [LTI([[-x]], [[x]], [[1.0]], [[0.0]]) for x in (14.0, 7.0, 140.0)]
    w = np.logspace(-4, 5, 4000)
    D = np.array([[nu_gap_siso(g, h, w) for h in G] for g in G])
    assert np.allclose(D, D.T) and np.allclose(np.diag(D), 0) and np.all((D >= 0) & (D <= 1))


def test_example_6_1c_lateral_aircraft_nine_loe_models():
    from plant_fmus.lateral_aircraft import lateral_physics as phys

    gammas = [(g1, g2) for g1 in (0, 0.5, 1) for g2 in (0, 0.5, 1)]
    models = [FDIModel.from_matrices(phys.A, phys.BU @ np.diag([1 - g1, 1 - g2]), phys.C,
                                     name=f"loe_{i}") for i, (g1, g2) in enumerate(gammas)]
    bank = model_detection_bank(models, sdeg=-1.0, poles=[-1.0])
    perf = np.array(bank.info["MDperf"])
    assert np.linalg.norm(np.diag(perf)) < 1e-7
    off = perf[~np.eye(9, dtype=bool)]
    assert off.min() > 1e-3  # every other model is seen by every filter


# ---------------------------------------------------------------------------------------------
# Approximate model detection (AMDP) against FaultDetectionTools.jl test/test_amdsyn.jl and
# Examples/Ex6_2c.jl (Varga 2017, Example 6.2: lateral aircraft, nine LOE models, noise w =
# six inputs through Bw = I(4,6), Dw = [0 I2], outputs 180/π·x1,2). The published checks are
# properties: diag(MDperf) < 1e-7, every off-diagonal ≥ 1 after the β_i = 1 scaling, MDgap equal
# to mdgap of the returned filters, stable filters; the actuator example's mdmatch picks model 2
# and, at MDfreq = 1, each row of MDperf ranks the models as their ν-gaps do.

_A62 = np.array([[-.4492, 0.046, .0053, -.9926], [0, 0, 1, 0.0067], [-50.8436, 0, -5.2184, .722],
                 [16.4148, 0, .0026, -.6627]])
_BU62 = np.array([[0.0004, 0.0011], [0, 0], [-1.4161, .2621], [-0.0633, -0.1205]])
_BW62 = np.eye(4, 6)
_C62 = 180 / np.pi * np.eye(2, 4)
_DW62 = np.hstack([np.zeros((2, 4)), np.eye(2)])
_GAMMAS = [(g1, g2) for g1 in (0, .5, 1) for g2 in (0, .5, 1)]


def _ex62_models(dt=0.0):
    ms = [FDIModel.from_matrices(_A62, _BU62 @ np.diag([1 - g1, 1 - g2]), _C62, Bw=_BW62, Dw=_DW62,
                                 name=f"loe_{i + 1}") for i, (g1, g2) in enumerate(_GAMMAS)]
    return [m.discretize(dt) for m in ms] if dt else ms


@pytest.fixture(scope="module")
def ex62():
    models = _ex62_models()
    return models, approximate_model_detection_bank(models, rdim="all", sdeg=-1.0, poles=[-1.0])


def _published_properties(bank, models):
    perf = np.array(bank.info["MDperf"])
    assert np.linalg.norm(np.diag(perf)) < 1e-7
    assert np.all(perf + np.finfo(float).eps * 2 + np.eye(len(models)) >= 1)  # β_i = 1 scaling
    gap, beta, gamma = noise_gaps(bank, models, freqs=bank.info["freqs"])
    assert np.allclose(gap, bank.info["MDgap"], rtol=1e-9) and np.allclose(beta, 1.0, rtol=1e-9)
    # off-diagonal: the same H∞ norms again (AB13DD, ~1e-10 relative); diagonal: rounding of an exact
    # decoupling, at most 1e-9 relative to β_i = 1 (the decoupling bound)
    assert np.max(np.diag(perf)) <= 1e-9
    assert np.allclose(perf, distance_mapping(bank, models, freqs=bank.info["freqs"]), rtol=1e-9, atol=1e-9)
    assert all(m.Q.is_stable() for m in bank.members)
    # decoupling of u (and d) of its own model: relative leakage of every filter
    assert bank.info["postconditions"]["decoupling"] <= 1e-9
    _figures_are_the_members(bank, models)


def _figures_are_the_members(bank, models):
    """The stored post-conditions are what analysis reports for the returned members (issue 17:
    one judge), and they describe the returned Q: independently, Q_i [Gu_i; I] evaluated with
    numpy at points off the judge's grid is rounding noise (≤ 1e-9 on β-scaled rows, the
    decoupling bound above) and every other model is seen (S row of ones)."""
    from fmu_fdi.analysis import leakage, structure_matrix

    for i, m in enumerate(bank.members):
        fig = m.info["postconditions"]
        assert fig["leakage"] == leakage(m)
        assert fig["structure_matrix"] == np.asarray(structure_matrix(m)).tolist()
        assert np.all(np.asarray(fig["structure_matrix"]) == 1)
        mi, Q = models[i], m.Q
        for z in ((1j * np.array([0.37, 2.9])) if not mi.dt else np.exp(1j * np.array([0.37, 2.9]))):
            Gu = mi.C @ np.linalg.solve(z * np.eye(mi.n) - mi.A, mi.Bu) + mi.Du
            Qz = Q.C @ np.linalg.solve(z * np.eye(Q.n) - Q.A, Q.B) + Q.D if Q.n else Q.D
            assert np.linalg.norm(Qz @ np.vstack([Gu, np.eye(mi.nu)]), 2) <= 1e-9
    assert bank.info["postconditions"]["leakage"] == max(leakage(m) for m in bank.members)
    assert bank.info["postconditions"]["structure_matrix"] == [m.info["postconditions"]["structure_matrix"]
                                                               for m in bank.members]


def test_example_6_2_full_order_gap_is_the_pointwise_optimum(ex62):
    """Every filter is Q_i = Ro^{-1} Q1 with Rw_ii = Ro Ri; here Rw_ii = Gw for all i, so the
    unscaled distances are ||Ro^{-1}(Gu_j − Gu_i)||∞ = sup_ω σ_max(L(jω)^{-1}(Gu_j − Gu_i)(jω)) for
    any factor L L^H = Gw Gw^H (the 2-norm is invariant to the unitary Ro^{-1} L): checked with a
    Cholesky factor on a grid, independent of the null-space basis and the Riccati solution."""
    models, bank = ex62
    _published_properties(bank, models)
    perf, gap = np.array(bank.info["MDperf"]), np.array(bank.info["MDgap"])
    w = np.logspace(-3, 3, 3001)
    s = 1j * w[:, None, None]
    res = lambda m, B, D: m.C @ np.linalg.solve(s * np.eye(4) - m.A, B) + D  # noqa: E731
    L = np.linalg.cholesky(np.einsum("kij,klj->kil", res(models[0], _BW62, _DW62),
                                     res(models[0], _BW62, _DW62).conj()))
    LGu = [np.linalg.solve(L, res(m, m.Bu, m.Du)) for m in models]
    D = np.array([[np.max(np.linalg.norm(Gj - Gi, 2, axis=(1, 2))) for Gj in LGu] for Gi in LGu])
    # unscaled distance = MDperf[i, j] · β_i(unscaled) and β_i(unscaled) = gap_i (γ_i = 1 unscaled);
    # a 3001-point grid under-reads a smooth peak by < 1e-4 relative
    assert np.allclose(perf * gap[:, None], D, rtol=1e-3, atol=1e-9)
    assert np.allclose(D, D.T, rtol=1e-9)  # the same Ro for every model: symmetric distances
    # the noise response of each scaled filter is co-inner up to the scale: all singular values = γ_i
    for m, g in zip(bank.members, gap):
        Rw = m.Rw.freqresp(np.logspace(-2, 2, 50))
        sv = np.linalg.svd(Rw, compute_uv=False)
        assert np.allclose(sv, 1.0 / g, rtol=1e-8)


def test_example_6_2_no_filter_beats_the_full_order_gap(ex62):
    """For any Q4, gap(Q4 Q_i) ≤ gap(Q_i): ||Q4 X||∞ ≤ ||Q4||∞ ||X||∞ = ||Q4 Ri||∞ ||X||∞."""
    models, bank = ex62
    gap = np.array(bank.info["MDgap"])
    rng = np.random.default_rng(7)
    for i in (0, 4, 8):
        Qi = bank.members[i].Q
        for _ in range(3):
            Q4 = LTI(-rng.uniform(0.5, 5.0) * np.eye(2), rng.standard_normal((2, 2)), rng.standard_normal((1, 2)),
                     rng.standard_normal((1, 2)))
            filters = [bank.members[k].Q if k != i else (Q4 @ Qi) for k in range(len(models))]
            other, _, _ = noise_gaps(filters, models)
            assert other[i] <= gap[i] * (1 + 1e-6)  # H∞ norms are computed to ~1e-8 relative


def test_example_6_2_kalman_innovation_filters_have_smaller_gaps(ex62):
    """Varga's Ex6_2KF.m: Kalman innovation filters (process noise 1e-4·I on the four state noises,
    measurement noise 0.04·I) also decouple u of their model exactly, so their gaps are bounded by
    the optimum (here 0.0153 against 0.0525)."""
    from fmu_fdi.design import kalman

    models, bank = ex62
    kf = [kalman(m, Qw=np.array([1e-4] * 4 + [0.04] * 2), Rv=0.0).Q for m in models]
    gap_kf, _, _ = noise_gaps(kf, models)
    assert np.max(np.diag(distance_mapping(kf, models))) < 1e-9 * np.max(distance_mapping(kf, models))
    assert np.all(gap_kf <= np.array(bank.info["MDgap"]) * (1 + 1e-6))


def test_example_6_2_least_order_filters(ex62):
    """rdim = 1: a gap-maximising combination of the normalised rows; its gap cannot exceed the
    full-order optimum (the bound above)."""
    models, full = ex62
    bank = approximate_model_detection_bank(models, rdim=1, sdeg=-1.0, poles=[-1.0])
    _published_properties(bank, models)
    assert all(m.Q.p == 1 for m in bank.members)
    assert np.all(np.array(bank.info["MDgap"]) <= np.array(full.info["MDgap"]) * (1 + 1e-6))


def test_example_6_2_strong_model_detection_at_frequencies():
    """amdsyn(minimal = false, MDfreq = [0, 1]): MDgap and MDperf are the peaks over the frequencies."""
    models = _ex62_models()[:4]
    bank = approximate_model_detection_bank(models, rdim="all", sdeg=-1.0, poles=[-1.0], freqs=[0.0, 1.0])
    _published_properties(bank, models)
    hinf = np.array(bank.info["MDperf_hinf"])
    off = ~np.eye(len(models), dtype=bool)
    assert np.all(hinf[off] >= np.array(bank.info["MDperf"])[off] * (1 - 1e-9))  # a peak over points ≤ the H∞ norm


def test_example_6_2_discrete_time():
    models = _ex62_models(dt=0.05)[:4]
    bank = approximate_model_detection_bank(models, rdim="all")
    _published_properties(bank, models)
    assert all(np.max(np.abs(m.Q.poles())) < 1 for m in bank.members)


def test_example_6_2_noise_inputs_of_varying_dimensions():
    """test_amdsyn.jl's last case: model i has only the first mw_i noise inputs (here a fixed draw
    including 0, 1 and 6). With fewer noise inputs than w-free directions (mw_i = 1 < 2 outputs)
    a combination decouples w exactly (rdim = 1: gap ∞); with mw_i = 0 the filter is exact; the
    full-order filters of the models without feedthrough from w (zeros at infinity) cannot be
    co-outer normalised exactly and take the quasi-co-outer normaliser (nonstd = 1, the default) when it
    enlarges the gap, else Q1."""
    mw = [3, 3, 5, 6, 0, 1, 5, 6, 1]
    models = [FDIModel.from_matrices(_A62, _BU62 @ np.diag([1 - g1, 1 - g2]), _C62, Bw=_BW62[:, :k], Dw=_DW62[:, :k],
                                     name=f"loe_{i + 1}") for i, ((g1, g2), k) in enumerate(zip(_GAMMAS, mw))]
    full = approximate_model_detection_bank(models, rdim="all", sdeg=-1.0, poles=[-1.0])
    _published_properties(full, models)
    gap = np.array(full.info["MDgap"])
    assert np.isinf(gap[4]) and np.all(np.isfinite(np.delete(gap, 4)))
    assert full.info["noise"][3] == full.info["noise"][7] == "co-outer normalised (optimal gap)"
    # models 1-3 and 7 (no feedthrough from w: zeros at infinity) take amdsyn's default nonstd = 1, which
    # keeps a filter only if its measured gap beats the basis' own
    assert all(full.info["noise"][k].startswith("quasi-co-outer normalised (nonstd = 1)") for k in (0, 1, 2, 6))
    sub = [models[k] for k in (0, 3, 4, 5)]
    small = approximate_model_detection_bank(sub, rdim=1, sdeg=-1.0, poles=[-1.0])
    _published_properties(small, sub)
    assert np.isinf(small.info["MDgap"][2]) and np.isinf(small.info["MDgap"][3])  # mw = 0 and mw = 1
    assert small.members[3].info["noise"] == "decoupled exactly"


def test_unknown_input_decoupled_and_full_order_gap_pointwise():
    """The nine LOE models with all four states measured, a gust d through Bd and sensor noise
    w (Dw = 0.1 I). Filter i is Q_i = [Qy, −Qy Gu_i] with Qy Gd_i = 0, so at each frequency its
    y-part spans the left null space N(jω) of Gd_i(jω) and the optimal full-order distances are
    sup_ω σ_max(L^{-1} N (Gu_j − Gu_i)) with L L^H = N Gw Gw^H N^H, for any such N (a change of basis
    T N changes L^{-1} N only by a unitary factor)."""
    Bd = np.array([[0.2], [0.0], [1.0], [0.5]])
    models = [FDIModel.from_matrices(_A62, _BU62 @ np.diag([1 - g1, 1 - g2]), np.eye(4), Bd=Bd, Bw=np.zeros((4, 4)),
                                     Dw=0.1 * np.eye(4), name=f"loe_{i + 1}") for i, (g1, g2) in enumerate(_GAMMAS)]
    bank = approximate_model_detection_bank(models, rdim="all", sdeg=-1.0, poles=[-1.0])
    _published_properties(bank, models)  # includes u and d decoupling ≤ 1e-9 relative
    assert all(m.Q.p == 3 for m in bank.members)  # 4 outputs − rank Gd
    perf, gap = np.array(bank.info["MDperf"]), np.array(bank.info["MDgap"])
    w = np.logspace(-3, 3, 2001)
    s = 1j * w[:, None, None]
    res = lambda m, B: m.C @ np.linalg.solve(s * np.eye(4) - m.A, B)  # noqa: E731
    Gd = res(models[0], Bd)
    U, _, _ = np.linalg.svd(Gd)
    N = np.conj(np.transpose(U[:, :, 1:], (0, 2, 1)))  # (K, 3, 4): N Gd = 0
    L = np.linalg.cholesky(0.01 * N @ np.conj(np.transpose(N, (0, 2, 1))))
    LGu = [np.linalg.solve(L, N @ res(m, m.Bu)) for m in models]
    D = np.array([[np.max(np.linalg.norm(Gj - Gi, 2, axis=(1, 2))) for Gj in LGu] for Gi in LGu])
    assert np.allclose(perf * gap[:, None], D, rtol=1e-3, atol=1e-9)  # grid under-reads a smooth peak < 1e-4


def test_example_6_2_smallest_residual_picks_the_true_model(ex62):
    """Simulation (the inputs of Varga's Fig. 6.3, seeded): with model j true, residual j is noise
    only and every other residual carries a model distance ≥ 1 (β-scaled); the smallest RMS
    residual names the model."""
    models, bank = ex62
    rng = np.random.default_rng(3)
    t = np.arange(0, 10.0001, 0.01)
    u = np.column_stack([(np.remainder(t, 2 * np.pi) >= np.pi) + 0.3, np.sin(2 * t) + 1.5])
    w = (rng.random((t.size, 6)) - 0.5) @ np.diag([0.01] * 4 + [0.03] * 2)
    Q = bank.Q
    for j, mj in enumerate(models):
        G = mj.lti("u", "w")
        _, y, _ = ss.lsim((G.A, G.B, G.C, G.D), np.hstack([u, w]), t)
        _, r, _ = ss.lsim((Q.A, Q.B, Q.C, Q.D), np.hstack([y, u]), t)
        rms = [np.sqrt(np.mean(np.sum(r[:, g] ** 2, axis=1))) for g in bank.groups]
        assert int(np.argmin(rms)) == j, (j, np.round(rms, 4))
        assert match_model(bank, mj)[1] == j


def test_actuator_models_amdsyn_match_and_ranking():
    """test_amdsyn.jl, actuator example (no noise: AMDP = EMDP): mdmatch of model 2 gives index 2
    and argmin; every column of MDperf has its minimum (0) on the diagonal; at MDfreq = 1 each row
    of MDperf orders the models as their ν-gaps at ω = 1 do (published sortperm check). The H∞
    sortperm check does not hold for these filters: row 1 ranks models 3 and 4 as 0.787 vs 0.688
    (closed form, see test_actuator_models_distance_mapping) against ν-gaps 0.579 vs 0.693."""
    k = 14.0
    a = [k, 0.5 * k, 10 * k, 0.01 * k]
    models = [_actuator(x) for x in a]
    bank = approximate_model_detection_bank(models, sdeg=-15.0, poles=[-20.0])
    perf = np.array(bank.info["MDperf"])
    assert np.all(np.isinf(bank.info["MDgap"]))
    assert np.all(np.argmin(perf, axis=0) == np.arange(4)) and np.max(np.diag(perf)) < 1e-9
    gains, mind = match_model(bank, models[1])
    assert mind == 1 and np.argmin(gains) == 1
    # H2 distances of row 1: ||(a_j − k) s / ((s + a_j)(s + 20))||₂ = |a_j − k| / sqrt(2 (a_j + 20)) (residues)
    h2 = np.array(bank.info["MDperf_h2"])[0]
    closed = np.array([abs(x - k) / np.sqrt(2 * (x + 20)) for x in a])
    assert np.allclose(h2[1:] / h2[1], closed[1:] / closed[1], rtol=1e-9) and h2[0] < 1e-9 * h2[1]
    bank1 = approximate_model_detection_bank(models, sdeg=-15.0, poles=[-20.0], freqs=1.0)
    G = [LTI([[-x]], [[x]], [[1.0]], [[0.0]]) for x in a]
    nu1 = np.array([[nu_gap_siso(g, h, np.array([1.0])) for h in G] for g in G])
    perf1 = np.array(bank1.info["MDperf"])
    for i in range(4):
        assert np.array_equal(np.argsort(nu1[i]), np.argsort(perf1[i]))


def test_actuator_models_with_measurement_noise_closed_form_gaps():
    """y = a_i/(s + a_i) u + v: Q1 = [s + a_i, −a_i]/(s + 20) has Rw = (s + a_i)/(s + 20), biproper and
    minimum phase, so Ro^{-1} Q1 = [1, −G_i], γ_i = 1 and β_i = min_j ||G_j − G_i||∞ with
    ||(a_j − a_i) s / ((s + a_i)(s + a_j))||∞ = |a_j − a_i| / (a_i + a_j) (peak at ω = sqrt(a_i a_j)).
    Strong detection at ω = 0 is impossible (equal DC gains) and is refused, naming the models."""
    a = [14.0, 7.0, 140.0, 0.14]
    models = [_actuator(x)._replace(Bw=np.zeros((1, 1)), Dw=np.eye(1), w_names=["v"]) for x in a]
    bank = approximate_model_detection_bank(models, sdeg=-15.0, poles=[-20.0])
    _published_properties(bank, models)
    closed = [min(abs(aj - ai) / (ai + aj) for aj in a if aj != ai) for ai in a]
    assert np.allclose(bank.info["MDgap"], closed, rtol=1e-8)
    with pytest.raises(DesignError, match=r"filter 1 \(model 'act14'\).*strong.*model 'act7' has gain .* at ω = 0"):
        approximate_model_detection_bank(models, sdeg=-15.0, poles=[-20.0], freqs=0.0)


def test_model_detection_refusals():
    models = _ex62_models()[:3]
    with pytest.raises(DesignError, match=r"'copy' cannot be told from model 'loe_1'.*rank condition.*\(0 vs 0"):
        approximate_model_detection_bank(models + [models[0]._replace(name="copy")])
    # a difference hidden in the directions of an unknown input d of model 1 is not detectable
    Bd = _BU62[:, :1]
    hidden = [FDIModel.from_matrices(_A62, _BU62, _C62, Bd=Bd, name="nominal"),
              FDIModel.from_matrices(_A62, _BU62 @ np.diag([0.5, 1.0]), _C62, Bd=Bd, name="half")]
    with pytest.raises(DesignError, match=r"'half' cannot be told from model 'nominal'.*\(1 vs 1"):
        approximate_model_detection_bank(hidden)
    unstable = FDIModel.from_matrices(np.diag([-1.0, 0.5]), np.ones((2, 1)), np.eye(2), name="unst")
    stable = FDIModel.from_matrices(np.diag([-1.0, -2.0]), np.ones((2, 1)), np.eye(2), name="st")
    with pytest.raises(DesignError, match=r"'unst' is not stable \(largest Re\(pole\) = 0.5\)"):
        approximate_model_detection_bank([stable, unstable])
    with pytest.raises(DesignError, match="at least two models"):
        approximate_model_detection_bank(models[:1])
    with pytest.raises(DesignError, match="rdim must be"):
        approximate_model_detection_bank(models, rdim=0)
    with pytest.raises(DesignError, match="has 1 outputs"):
        approximate_model_detection_bank([stable, FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], name="siso")])


def _fr(A, B, C, D, lam):
    """``C (λI − A)^{-1} B + D`` by numpy solves (independent of the package's LTI code)."""
    n = np.shape(A)[0]
    return np.array([D + (C @ np.linalg.solve(l * np.eye(n) - A, B) if n else 0.0) for l in lam])


def test_emdsyn_bank_is_normalised_to_unit_nearest_distance():
    """emdsyn's default (normalize = false): filter i is scaled so that its smallest distance to
    another model is 1 — the normalised internal form, the other models being the faults filter i
    must see. MDperf is the distance mapping of the returned filters: zero diagonal, off-diagonal
    row minimum 1. (Before, the filters were returned unscaled and MDperf rows scaled to maximum 1,
    so a filter's gains and its MDperf row disagreed.) Judged by numpy frequency responses of
    Q_i [Gu_j; I] on a dense grid: the grid peak is at most the H∞ norm, and within 1e-3 of it (the
    peaks of these first/second-order responses are flat to that on 2000 log points per 9 decades)."""
    k = 14.0
    models = [_actuator(x) for x in (k, 0.5 * k, 10 * k, 0.01 * k)]
    bank = model_detection_bank(models, sdeg=-15.0, poles=[-20.0], atol=1e-10)
    perf = np.array(bank.info["MDperf"])
    off = ~np.eye(4, dtype=bool)
    assert np.allclose([perf[i, off[i]].min() for i in range(4)], 1.0, rtol=1e-12)
    assert np.max(np.abs(np.diag(perf))) < 1e-7
    assert np.allclose(np.array(bank.info["MDperf_abs"]) / np.array(bank.info["beta"])[:, None], perf)
    lam = 1j * np.logspace(-4, 5, 2000)
    for i, g in enumerate(bank.members):
        Qv = _fr(g.Q.A, g.Q.B, g.Q.C, g.Q.D, lam)
        for j, mj in enumerate(models):
            Gj = np.concatenate([_fr(mj.A, mj.Bu, mj.C, mj.Du, lam), np.ones((lam.size, 1, 1))], axis=1)
            peak = np.max(np.abs(Qv @ Gj))
            if i == j:
                assert peak < 1e-7
            else:
                assert perf[i, j] * (1 - 1e-3) <= peak <= perf[i, j] * (1 + 1e-9)


def test_emdsyn_refuses_unstable_models_and_bad_atol():
    k = 14.0
    stable, unstable = _actuator(k), FDIModel.from_matrices([[1.0]], [[1.0]], [[1.0]], name="unstable")
    with pytest.raises(DesignError, match="not stable"):
        model_detection_bank([stable, unstable])
    with pytest.raises(DesignError, match="atol"):
        model_detection_bank([stable, _actuator(2.0)], atol=-1.0)
    # a copy of a model: no filter exact for one sees the other (was a ModelError about a zero fault)
    with pytest.raises(DesignError, match="cannot be told from"):
        model_detection_bank([stable, stable._replace(name="copy")])


def test_emdsyn_static_models():
    """Static models y = [1; 2] u and y = [1; 3] u (n = 0): filter i is the row annihilating
    [Du_i; I], scaled to distance 1 from the other model; MDperf = [[0, 1], [1, 0]]. Skipped where
    FDIModel has no n = 0 support yet (issue 17, core)."""
    from fmu_fdi.errors import ModelError

    try:
        models = [FDIModel.from_matrices(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((2, 0)), Du=np.array(Du),
                                         name=nm) for nm, Du in (("a", [[1.0], [2.0]]), ("b", [[1.0], [3.0]]))]
    except ModelError as exc:
        pytest.skip(f"static plants need FDIModel n = 0 support: {exc}")
    bank = model_detection_bank(models)
    assert np.allclose(bank.info["MDperf"], [[0.0, 1.0], [1.0, 0.0]], atol=1e-12)
    for i, g in enumerate(bank.members):  # independent: Q_i [Du_j; 1] by matrix products
        dist = [abs((g.Q.D @ np.vstack([m.Du, np.eye(1)]))[0, 0]) for m in models]
        assert dist[i] < 1e-12 and abs(dist[1 - i] - 1.0) < 1e-12
