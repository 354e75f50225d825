"""Fault analysis by recursive least squares (issue 2 §3 h): design, runtime, statistics.

Plants: the ARX model ``A(q) y = B(q) u + e`` with A = 1 - 1.5 q⁻¹ + 0.7 q⁻² (poles
0.75 ± 0.37j) and B = q⁻¹ + 0.5 q⁻², realised in observer canonical form so that a
parametric fault on one matrix entry changes one ARX coefficient; and the continuous
plant 2/((s+1)(s+2)). Seeds are fixed; every tolerance is derived in the comment next to it.
"""
import json

import numpy as np
import pytest
from scipy.stats import norm

from fmu_fdi import DesignError, FDIModel, parametric_fault
from fmu_fdi.design.problems.rls import RLSEstimator, rls_estimator
from fmu_fdi.lti import LTI
from fmu_fdi.runtime.generators import make_generator
from fmu_fdi.runtime.rls import RLSStep

EPS = np.finfo(float).eps
A_POLY = np.array([-1.5, 0.7])  # a1, a2
B_POLY = np.array([1.0, 0.5])  # b1_1, b1_2
THETA = np.concatenate([A_POLY, B_POLY])


def arx_model(faults=()):
    """Observer canonical form of A(q) y = B(q) u + e; the equation error e is the noise input w."""
    A = np.array([[-A_POLY[0], 1.0], [-A_POLY[1], 0.0]])
    return FDIModel.from_matrices(A, B_POLY.reshape(2, 1), [[1.0, 0.0]], Bw=-A_POLY.reshape(2, 1), Dw=[[1.0]],
                                  dt=1.0, u_names=["u"], y_names=["y"], w_names=["e"], faults=faults)


def simulate(model, u, w, fault=None, theta=0.0, k_fault=None):
    """Sampled y of the model; from k_fault on, the parametric fault acts with size theta."""
    A, Bu, C, Bw, Dw = model.A, model.Bu, model.C, model.Bw, model.Dw
    x = np.zeros(model.n)
    y = np.empty((len(u), model.ny))
    for k in range(len(u)):
        if fault is not None and k == k_fault:
            spec = model.fault(fault)
            A, Bu, C = A + theta * spec.dA, Bu + theta * spec.dB, C + theta * spec.dC
        y[k] = C @ x + Dw @ w[k]
        x = A @ x + Bu @ u[k] + Bw @ w[k]
    return y


def continuous_model():
    return FDIModel.from_matrices([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[2.0, 0.0]],
                                  u_names=["u"], y_names=["y"])


def zoh_outputs(model, Ts, u):
    G = model.lti("u").to_discrete(Ts)
    x = np.zeros(G.n)
    y = np.empty((len(u), G.p))
    for k in range(len(u)):
        y[k] = G.C @ x + G.D @ u[k]
        x = G.A @ x + G.B @ u[k]
    return y


# ------------------------------------------------------------------------ design
def test_arx_nominal_parameters_from_the_model():
    est = rls_estimator(arx_model())
    assert isinstance(est, RLSEstimator) and est.method == "rls"
    assert est.residual_names == ["a1", "a2", "b1_1", "b1_2"]
    assert est.input_names == ["y", "u"] and est.dt == 1.0 and est.n_residuals == 4
    assert est.groups == [[0, 1, 2, 3]]
    # θ0 solves a consistent least-squares problem of condition ~1e2: rounding ≲ 1e2·eps·|θ|,
    # 1e-12 leaves two digits of margin.
    assert np.allclose(list(est.info["theta0"].values()), THETA, rtol=0, atol=1e-12)
    assert est.info["regressor"]["y"] == {"target": "y[k]", "phi": ["-y[k-1]", "-y[k-2]", "u[k-1]", "u[k-2]"]}
    spec = est.runtime_spec()
    assert spec["kind"] == "rls"
    assert json.loads(json.dumps(spec)) == spec  # JSON-serialisable as is
    assert isinstance(make_generator(spec), RLSStep)


def test_feedthrough_adds_b_0_and_mimo_gives_one_group_per_output():
    A = np.diag([0.5, 0.8])
    m = FDIModel.from_matrices(A, [[1.0, 0.0], [0.3, 1.0]], np.eye(2), [[0.2, 0.0], [0.0, 0.0]], dt=0.1,
                               u_names=["u1", "u2"], y_names=["ya", "yb"])
    est = rls_estimator(m)
    assert est.residual_names == ["ya.a1", "ya.b1_0", "ya.b1_1", "ya.b2_1",
                                  "yb.a1", "yb.b1_1", "yb.b2_1"]
    assert est.groups == [[0, 1, 2, 3], [4, 5, 6]]
    th = est.info["theta0"]
    # ya[k] - 0.5 ya[k-1] = 0.2 u1[k] + (1 - 0.5·0.2) u1[k-1]: the feedthrough enters b1_0 and b1_1.
    assert np.allclose([th["ya.a1"], th["ya.b1_0"], th["ya.b1_1"], th["ya.b2_1"]], [-0.5, 0.2, 0.9, 0.0],
                       atol=1e-12)
    assert np.allclose([th["yb.a1"], th["yb.b1_1"], th["yb.b2_1"]], [-0.8, 0.3, 1.0], atol=1e-12)
    one = rls_estimator(m, output="yb")
    assert one.residual_names == ["a1", "b1_1", "b2_1"] and one.input_names == ["ya", "yb", "u1", "u2"]


def test_identical_subsystems_each_estimated_at_their_own_order():
    # Three identical second-order systems sampled with a zero-order hold (the wind-turbine
    # pitch model): the row of output i must reduce to order 2. The minimal realisation did
    # not balance the triplet before SLICOT's staircase, whose rank decisions then kept 4
    # states: a singular regression ("not identifiable").
    block = LTI([[0.0, 1.0], [-123.4321, -13.332]], [[0.0], [123.4321]], [[1.0, 0.0]], [[0.0]]).to_discrete(0.01)
    A = np.kron(np.eye(3), block.A)
    m = FDIModel.from_matrices(A, np.kron(np.eye(3), block.B), np.kron(np.eye(3), block.C), dt=0.01)
    est = rls_estimator(m, output="y1")
    assert est.info["order"] == [2]
    assert est.residual_names == ["a1", "a2", "b1_1", "b1_2", "b2_1", "b2_2", "b3_1", "b3_2"]
    # z² + a1 z + a2 is the sampled block's characteristic polynomial (rounding of a 2x2 eig: 1e-12)
    assert np.allclose([est.info["theta0"]["a1"], est.info["theta0"]["a2"]], np.poly(np.linalg.eigvals(block.A))[1:],
                       atol=1e-12)


def test_rls_is_not_an_lti_generator():
    est = rls_estimator(arx_model())
    with pytest.raises(TypeError, match="RLS is not an LTI generator"):
        est.internal_form()
    with pytest.raises(TypeError, match="not an LTI generator"):
        est.Rf


# ------------------------------------------------------------------ convergence
def test_noise_free_arx_converges_to_theta0_and_residual_stays_small():
    rng = np.random.default_rng(0)
    N = 2000
    m = arx_model()
    u = rng.standard_normal((N, 1))
    y = simulate(m, u, np.zeros((N, 1)))
    est = rls_estimator(m)
    R, TH = est.simulate(y, u, return_estimates=True)
    # The equation holds to rounding, so θ̂ only collects rounding: ≲ 1e2·eps (condition of
    # the regression ~1e2, θ = O(1)) and forgetting keeps it from accumulating: 1e-12.
    assert np.max(np.abs(TH[100:] - THETA)) < 1e-12
    # σ is floored at √eps·ψ_rms (ψ_rms ≈ 4 here) and √P_ii ≈ √(1-μ)/φ_rms ≈ 0.1, so
    # |r| ≲ 1e2·eps / (0.1·√eps·4) ≈ 4e-6; 1e-3 adds margin and is far below any threshold.
    assert np.max(np.abs(R)) < 1e-3


def test_residual_is_zero_during_warmup():
    rng = np.random.default_rng(1)
    m = arx_model()
    u = rng.standard_normal((40, 1))
    y = simulate(m, u, np.zeros((40, 1))) * 1.5  # grossly wrong data from the first sample
    est = rls_estimator(m, warmup=12)
    R = est.simulate(y, u)
    assert not np.any(R[:11])  # samples 1..11 of 12: exactly 0
    assert np.all(np.abs(R[11]) > 0)
    assert est.runtime_spec()["estimators"][0]["warmup"] == 12
    assert rls_estimator(m).runtime_spec()["estimators"][0]["warmup"] == 2 + 2 * 4  # n + 2 n_θ


def test_continuous_model_via_svf_converges_to_continuous_coefficients():
    m = continuous_model()
    theta_c = np.array([3.0, 2.0, 0.0, 2.0])  # s² + 3 s + 2, numerator 0·s + 2
    Ts = 0.05
    est = rls_estimator(m, Ts=Ts)
    lam = est.info["svf_bandwidth"]
    assert lam == pytest.approx(2.0)  # default: the largest pole magnitude
    assert np.allclose(list(est.info["theta_continuous"].values()), theta_c, atol=1e-12)
    theta_s = np.array(list(est.info["theta0"].values()))
    bias = theta_s - theta_c
    # Discretisation bias of the ZOH-held y (it lags by about Ts/2): first order in Ts, so it
    # halves with Ts up to second-order terms of relative size O(λ Ts) = 0.1.
    bias_half = np.array(list(rls_estimator(m, Ts=Ts / 2).info["svf_bias"].values()))
    assert np.linalg.norm(bias_half) / np.linalg.norm(bias) == pytest.approx(0.5, abs=0.05)
    # A coefficient of characteristic frequency ω is off by about ω Ts/2 relative; with
    # ω ≤ max(λ, |poles|) = 2, ω_max·Ts bounds it with a factor-2 margin.
    nz = theta_c != 0
    assert np.all(np.abs(bias[nz] / theta_c[nz]) <= 2.0 * Ts)

    rng = np.random.default_rng(2)
    N = 4000
    u = np.repeat(rng.standard_normal((N // 20, 1)), 20, axis=0)  # held 1 s: excites up to ~λ
    y = zoh_outputs(m, Ts, u)
    R, TH = est.simulate(y, u, return_estimates=True)
    # Exact sampled relation: θ̂ reaches θ_s to rounding (cond ~1e2 of the regression, values
    # O(1): 1e-10 covers it), hence θ_c within the discretisation bias plus that.
    assert np.max(np.abs(TH[-1000:] - theta_s)) < 1e-10
    assert np.all(np.abs(TH[-1] - theta_c) <= np.abs(bias) + 1e-10)
    assert np.max(np.abs(R)) < 1e-3  # as in the ARX test: rounding over the √eps floor


def test_mimo_continuous_model_with_feedthrough_and_complex_poles():
    """One SVF estimator per output; p has a feedthrough from u1, so b1_0 is estimated for p only."""
    A = np.array([[0.0, 1.0], [-4.0, -0.8]])  # poles -0.4 ± 1.96j
    m = FDIModel.from_matrices(A, [[0.0, 1.0], [1.0, 0.5]], [[1.0, 0.0], [0.5, 1.0]], [[0.3, 0.0], [0.0, 0.0]],
                               u_names=["u1", "u2"], y_names=["p", "q"])
    Ts = 0.02
    est = rls_estimator(m, Ts=Ts)
    assert est.groups == [list(range(7)), list(range(7, 13))]
    th_c = est.info["theta_continuous"]
    # p = (0.3 s² + 0.24 s + 2.2) u1 / (s² + 0.8 s + 4) + (s + 1.3) u2 / (s² + 0.8 s + 4)
    assert np.allclose([th_c[k] for k in ("p.a1", "p.a2", "p.b1_0", "p.b1_1", "p.b1_2", "p.b2_1", "p.b2_2")],
                       [0.8, 4.0, 0.3, 0.24, 2.2, 1.0, 1.3], atol=1e-12)
    assert json.loads(json.dumps(est.info)) == est.info
    rng = np.random.default_rng(10)
    u = np.repeat(rng.standard_normal((160, 2)), 25, axis=0)  # 4000 samples, held 0.5 s
    R, TH = est.simulate(zoh_outputs(m, Ts, u), u, return_estimates=True)
    # As in the SISO SVF test: exact sampled relation, rounding only.
    assert np.max(np.abs(TH[-1] - list(est.info["theta0"].values()))) < 1e-10
    assert np.max(np.abs(R)) < 1e-3


def test_static_output_estimates_its_gain():
    m = FDIModel.from_matrices([[0.5]], [[1.0]], [[0.0]], [[2.0]], dt=1.0)  # y = 2 u, no dynamics
    est = rls_estimator(m)
    assert est.residual_names == ["b1_0"] and est.info["order"] == [0]
    u = np.random.default_rng(11).standard_normal((200, 1))
    gain = np.where(np.arange(200) < 100, 2.0, 2.2)[:, None]  # 10 % high from sample 100
    R = est.simulate(gain * u, u)
    assert np.max(np.abs(R[:100])) < 1e-3  # rounding over the √eps floor, as above
    # Noise-free: σ sits on the √eps floor and the 3σ clip keeps the fault's errors out of
    # it, so the change is an enormous residual from the first faulty sample on.
    assert np.all(R[100:] > 1e3)


def test_rls_solves_the_regularised_exponentially_weighted_least_squares_problem():
    """θ̂_k = argmin μ^k/P0 |θ - θ0|² + Σ μ^{k-i} (ψ_i - φ_iᵀθ)² (no trace bound, no reset)."""
    rng = np.random.default_rng(3)
    N, mu, P0 = 300, 0.97, 10.0
    m = arx_model()
    u = rng.standard_normal((N, 1))
    y = simulate(m, u, 0.1 * rng.standard_normal((N, 1)))
    est = rls_estimator(m, forgetting=mu, P0=P0, trace_max=1e300)
    _, TH = est.simulate(y, u, return_estimates=True)
    spec = est.runtime_spec()["estimators"][0]
    Pi = LTI(spec["A"], spec["B"], spec["C"], spec["D"], 1.0)
    Z = np.array([Pi.C @ x + Pi.D @ v for x, v in _states(Pi, np.hstack([y, u]))])
    psi, phi = Z[:, 0], Z[:, 1:]
    skip = spec["skip"]
    for k in (10, 100, N - 1):
        w = mu ** (k - np.arange(skip, k + 1))
        M = mu ** (k - skip + 1) / P0 * np.eye(4) + (phi[skip:k + 1].T * w) @ phi[skip:k + 1]
        b = mu ** (k - skip + 1) / P0 * THETA + (phi[skip:k + 1].T * w) @ psi[skip:k + 1]
        ref = np.linalg.solve(M, b)
        # Both are backward stable solutions of a system of condition ≤ 1e4 (checked):
        # relative agreement to 1e4·(a few hundred updates)·eps ≈ 1e-9.
        assert np.linalg.cond(M) < 1e4
        assert np.allclose(TH[k], ref, rtol=0, atol=1e-9 * np.linalg.norm(ref))


def _states(Pi, V):
    x = np.zeros(Pi.n)
    for v in V:
        yield x, v
        x = Pi.A @ x + Pi.B @ v


# --------------------------------------------------------------- fault response
@pytest.mark.parametrize("fault, direction, theta, affected", [
    ("gain", {"dB": B_POLY.reshape(2, 1)}, 0.2, [2, 3]),  # B → 1.2 B: b1_1, b1_2 move by 0.2, 0.1
    ("pole", {"dA": [[1.0, 0.0], [0.0, 0.0]]}, -0.1, [0]),  # A[0,0] = -a1 + θ: a1 → -1.4 only
])
def test_parametric_fault_moves_only_its_parameters_beyond_a_gaussian_bound(fault, direction, theta, affected):
    m = arx_model(faults=[parametric_fault(fault, **direction)])
    rng = np.random.default_rng(4)
    N, kf, sigma_e = 3000, 1500, 0.02
    u = rng.standard_normal((N, 1))
    y = simulate(m, u, sigma_e * rng.standard_normal((N, 1)), fault=fault, theta=theta, k_fault=kf)
    mu = 0.98
    est = rls_estimator(m, forgetting=mu)
    R = est.simulate(y, u)
    # Without fault r_i ~ N(0, s²) with s ≈ 1/√(1+μ) ≤ 1. Bonferroni over all N·n_θ samples
    # (correlated samples only make it conservative) at a family-wise false-alarm rate of
    # 1e-3 gives the two-sided Gaussian bound c ≈ 5.3 for unit variance.
    c = norm.isf(1e-3 / (2 * N * 4))
    warm = est.runtime_spec()["estimators"][0]["warmup"]
    assert np.max(np.abs(R[warm:kf])) < c
    unaffected = [i for i in range(4) if i not in affected]
    # Detection delay: a step Δθ is tracked as about Δθ (1 - μ^k), and |Δθ|/σ_θ ≳ 20 here
    # (σ_θ ≈ σ_e √(1-μ)/φ_rms ≤ 3e-3, Δ ≥ 0.1), so c is crossed once 1 - μ^k ≳ 0.25, k ≈ 15;
    # σ̂_e may still grow by (1 + γ_σ (3² - 1))^k ≈ 1.2 over that time (3σ clip, γ_σ = 0.002):
    # 25 samples.
    first = [kf + int(np.argmax(np.abs(R[kf:, i]) > c)) for i in affected]
    assert all(np.abs(R[f, i]) > c and f - kf <= 25 for f, i in zip(first, affected))
    # During the transient the window mixes data of two plants and the estimates of the other
    # parameters move too (the LS solution of mixed data is a matrix-weighted mean); after
    # 5 memory lengths 5/(1-μ) the old data weigh μ^250 < 1 %, and the others are back below c
    # while the affected ones stay above.
    settled = kf + int(5 / (1 - mu))
    assert np.max(np.abs(R[settled:, unaffected])) < c
    assert np.min(np.abs(R[settled:, affected])) > c
    assert np.max(np.abs(R[kf:, unaffected])) < np.max(np.abs(R[kf:, affected]))


# ---------------------------------------------------------------- numerics
def test_forgetting_without_excitation_keeps_P_bounded_and_definite():
    rng = np.random.default_rng(5)
    m = arx_model()
    est = rls_estimator(m, forgetting=0.95)
    run = RLSStep(est.runtime_spec())
    u = rng.standard_normal((200, 1))
    y = simulate(m, u, 0.01 * rng.standard_normal((200, 1)))
    run.run(np.hstack([y, u]))
    trace_max = run.estimators[0].trace_max
    assert trace_max == 4 * est.info["P0"]  # default: the initial trace n_θ·P0
    traces = []
    for _ in range(20000):  # 0.95^-20000 would be 1e445 without the bound
        r = run.step([0.0, 0.0])
        traces.append(run.P_traces[0])
        assert np.all(np.isfinite(r))
    P = np.array(run.get_state()["estimators"][0]["P"])
    # Scaling to the bound is one multiplication: it may overshoot by one rounding.
    assert max(traces) <= trace_max * (1 + 4 * EPS)
    assert np.array_equal(P, P.T) and np.linalg.eigvalsh(P).min() > 0


def test_covariance_reset_policies():
    rng = np.random.default_rng(6)
    m = arx_model()
    u = rng.standard_normal((3000, 1))
    y = simulate(m, u, 0.01 * rng.standard_normal((3000, 1)))
    V = np.hstack([y, u])
    # μ = 1: trace P ≈ tr(R⁻¹)/k falls below a floor of 1e-2 after ~ 4/(0.01·E[φ²]) ≈ 100-400
    # samples; each reset restarts it.
    floor = RLSStep(rls_estimator(m, forgetting=1.0, reset="floor", reset_trace=1e-2).runtime_spec())
    floor.run(V)
    assert floor.get_state()["estimators"][0]["resets"] >= 3
    assert floor.P_traces[0] >= 1e-2 * (1 - 1e-12)
    periodic = RLSStep(rls_estimator(m, reset="periodic", reset_period=500).runtime_spec())
    periodic.run(V)
    updates = periodic.get_state()["estimators"][0]["updates"]
    assert periodic.get_state()["estimators"][0]["resets"] == updates // 500


# ------------------------------------------------------------- runtime contract
def _record(seed=7, N=400):
    rng = np.random.default_rng(seed)
    m = arx_model()
    u = rng.standard_normal((N, 1))
    y = simulate(m, u, 0.05 * rng.standard_normal((N, 1)), fault=None)
    return m, np.hstack([y, u])


def test_step_over_a_record_equals_the_batch_helpers_bit_for_bit():
    m, V = _record()
    est = rls_estimator(m)
    one = RLSStep(est.runtime_spec())
    stepped = np.array([one.step(v) for v in V])
    assert np.array_equal(stepped, RLSStep(est.runtime_spec()).run(V))
    assert np.array_equal(stepped, est.simulate(V[:, :1], V[:, 1:]))
    assert np.array_equal(stepped, make_generator(est.runtime_spec()).run(V))


def test_state_round_trip_reproduces_bit_identically():
    m, V = _record(seed=8)
    run = RLSStep(rls_estimator(m, reset="periodic", reset_period=70).runtime_spec())
    run.run(V[:150])
    saved = json.loads(json.dumps(run.get_state()))  # through JSON, as a host would store it
    first = run.run(V[150:])
    run.set_state(saved)
    assert np.array_equal(run.run(V[150:]), first)
    other = RLSStep(rls_estimator(m, reset="periodic", reset_period=70).runtime_spec())
    other.set_state(saved)
    assert np.array_equal(other.run(V[150:]), first)
    run.reset()
    fresh = RLSStep(rls_estimator(m, reset="periodic", reset_period=70).runtime_spec())
    assert json.dumps(run.get_state()) == json.dumps(fresh.get_state())


def test_bad_samples_raise_and_leave_the_state_alone():
    m, V = _record(seed=9, N=50)
    run = RLSStep(rls_estimator(m).runtime_spec())
    run.run(V)
    before = json.dumps(run.get_state())
    with pytest.raises(ValueError, match="NaN or Inf at \\[0\\]"):
        run.step([np.nan, 0.0])
    with pytest.raises(ValueError, match="expected 2 values"):
        run.step([0.0, 0.0, 0.0])
    assert json.dumps(run.get_state()) == before
    with pytest.raises(ValueError, match="expected x"):
        run.set_state({"k": 0, "estimators": [{"x": [0.0], "theta": [0.0] * 4, "P": np.eye(4).tolist(),
                                               "sigma2": 0.0, "psi2": 0.0, "updates": 0, "resets": 0}]})
    assert json.dumps(run.get_state()) == before


# ------------------------------------------------------------------ bad designs
@pytest.mark.parametrize("kwargs, message", [
    ({"order": 3}, "order 3 of output 'y' exceeds its minimal order 2"),
    ({"order": 1}, "order 1 of output 'y' is below its minimal order 2"),
    ({"forgetting": 0.0}, r"forgetting must be in \(0, 1\]"),
    ({"forgetting": 1.01}, r"forgetting must be in \(0, 1\]"),
    ({"forgetting": float("nan")}, "forgetting must be finite"),
    ({"P0": -1.0}, "P0 must be positive"),
    ({"noise_std": float("nan")}, "noise_std must be finite"),
    ({"noise_forgetting": 0.0}, r"noise_forgetting must be in \(0, 1\]"),
    ({"trace_max": 0.0}, "trace_max must be positive"),
    ({"Ts": 0.5}, "differs from the discrete model's dt"),
    ({"svf_bandwidth": 3.0}, "svf_bandwidth applies to continuous models only"),
    ({"output": "z"}, "output 'z' is not an output of the model"),
    ({"reset": "periodic"}, "needs reset_period"),
    ({"reset": "sometimes"}, "reset must be one of"),
    ({"reset": "floor", "reset_trace": 1e9}, "must be below trace_max"),
    ({"warmup": 1}, "warmup must be an integer >= 2"),
])
def test_invalid_designs_are_named(kwargs, message):
    with pytest.raises(DesignError, match=message):
        rls_estimator(arx_model(), **kwargs)


def test_models_the_estimator_cannot_use_are_named():
    no_input = FDIModel.from_matrices([[0.5]], np.zeros((1, 0)), [[1.0]], dt=1.0)
    with pytest.raises(DesignError, match="has no known inputs"):
        rls_estimator(no_input)
    with pytest.raises(DesignError, match="Ts .* is required for a continuous model"):
        rls_estimator(continuous_model())
    decoupled = FDIModel.from_matrices(np.diag([0.5, 0.6]), [[1.0], [0.0]], [[1.0, 0.0], [0.0, 1.0]], dt=1.0)
    with pytest.raises(DesignError, match="output 'y1' does not depend on the known inputs"):
        rls_estimator(decoupled)
    with pytest.raises(DesignError, match="needs an FDIModel"):
        rls_estimator(LTI.static([[1.0]]))


def test_invalid_runtime_specs_are_named():
    spec = rls_estimator(arx_model()).runtime_spec()
    for key, value, message in [("forgetting", 0.0, r"forgetting must be in \(0, 1\]"),
                                ("P0", float("nan"), "P0 must be a finite positive number"),
                                ("reset", {"policy": "often"}, "reset policy must be one of")]:
        with pytest.raises(ValueError, match=message):
            RLSStep({**spec, key: value})
    bad = json.loads(json.dumps(spec))
    bad["estimators"][0]["C"] = bad["estimators"][0]["C"][:-1]
    with pytest.raises(ValueError, match=r"estimator 0 C must have shape \(5, 4\)"):
        RLSStep(bad)


def test_noise_std_sets_the_equation_error_floor():
    est = rls_estimator(arx_model(), noise_std=0.1)
    # White noise v on y enters the equation error as A(q) v: std 0.1·||[1, a1, a2]||_2.
    floor = est.runtime_spec()["estimators"][0]["sigma_floor"]
    assert floor == pytest.approx(0.1 * np.linalg.norm([1.0, *A_POLY]), rel=1e-12)
