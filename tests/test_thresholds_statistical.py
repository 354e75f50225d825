"""Statistical thresholds meet their false-alarm targets on simulated fault-free data.

How the checks are made exact enough to be binomial:

- exceedances are counted on samples spaced by a gap G after which the evaluation is
  independent (disjoint windows of a white residual) or its correlation is below 1e-3
  (coloured residuals), so the count is binomial and the Clopper–Pearson interval
  applies; every interval is two-sided at 99 %, so each assertion fails by chance with
  probability 1 % for a correct implementation (the seeds are fixed, so the outcome is
  deterministic);
- long records are simulated with vectorised filters (scipy.signal.lfilter); that they
  equal the runtime evaluators is checked on a prefix, to rounding (1e-12);
- the data-driven thresholds are trained on one set of seeds and scored on fresh runs
  with other seeds.
"""
import numpy as np
import pytest
import scipy.linalg as sla
from scipy import integrate, signal, stats

from fmu_fdi import FDIModel, LTI, ResidualGenerator, kalman
from fmu_fdi.evaluation import analytic_threshold, data_driven_threshold, residual_autocovariance
from fmu_fdi.evaluation.datadriven import decorrelation_length
from fmu_fdi.evaluation.quadform import imhof_sf
from fmu_fdi.lti import hstack
from fmu_fdi.runtime.evaluation import Evaluator
from simulate import cascade_residual

LEVEL = 0.99  # two-sided Clopper–Pearson level of every simulation check


def clopper_pearson(count: int, n: int) -> tuple[float, float]:
    ci = stats.binomtest(count, n).proportion_ci(LEVEL, method="exact")
    return ci.low, ci.high


# --------------------------------------------------------------------- plants
POLE, MEAS = 0.9, 0.5  # AR(1) pole of the coloured residual; measurement-noise variance


def observer_generator(pole=POLE, dt=1.0) -> ResidualGenerator:
    """x+ = a x + u + w1, y = x + w2; r = y − (open-loop model output): r = AR(1) + white."""
    m = FDIModel.from_matrices([[pole]], [[1.0]], [[1.0]], Bw=[[1.0, 0.0]], Dw=[[0.0, 1.0]], dt=dt)
    Q = LTI([[pole]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]], dt)
    return ResidualGenerator(Q, m, "open-loop observer")


def coloured_residual(n: int, rng, pole=POLE) -> np.ndarray:
    """Stationary samples of that residual (the AR part starts from its stationary law)."""
    w = rng.standard_normal(n)
    w[0] /= np.sqrt(1 - pole**2)
    return signal.lfilter([1.0], [1.0, -pole], w) + np.sqrt(MEAS) * rng.standard_normal(n)


def rms_of(r, N):
    return np.sqrt(np.convolve(r * r, np.ones(N))[: r.size] / N)


def ewrms_of(r, lam):
    return np.sqrt(signal.lfilter([1.0 - lam], [1.0, -lam], r * r))


RV = 0.09  # measurement noise variance of the Kalman example (outside the model's w)


def kalman_generator():
    """The library's steady-state Kalman filter: innovations white with covariance Σ."""
    A = np.array([[0.8, 0.2], [-0.1, 0.7]])
    m = FDIModel.from_matrices(A, [[1.0], [0.5]], np.eye(2), Bw=0.5 * np.eye(2), dt=1.0)
    return kalman(m, Qw=1.0, Rv=RV)


def stacked_eigenvalues(gen, weights, noise_cov):
    """Eigenvalues of c^{1/2} Σ_z c^{1/2} built here from the public autocovariance."""
    N = len(weights)
    G = residual_autocovariance(gen, N - 1, noise_cov=noise_cov)[:, 0, 0]
    S = sla.toeplitz(G)
    s = np.sqrt(weights)
    return np.linalg.eigvalsh(s[:, None] * S * s[None, :])


# ------------------------------------------------------ covariance (exact checks)
def markov_autocovariance(sys: LTI, V, lags, terms=3000):
    """Γ(k) = Σ_j h_{j+k} V h_jᵀ from the Markov parameters h_0 = D, h_j = C A^{j−1} B."""
    h = [sys.D]
    X = sys.B
    for _ in range(terms + lags):
        h.append(sys.C @ X)
        X = sys.A @ X
    return np.array([sum(h[j + k] @ V @ h[j].T for j in range(terms)) for k in range(lags + 1)])


def test_autocovariance_equals_the_markov_parameter_sum():
    gen = kalman_generator()
    Vw, Vv = np.diag([1.0, 2.0]), np.array([[0.5, 0.1], [0.1, 1.5]])
    Rw = (gen.Q @ gen.model.augmented())[:, 1:3]  # columns of w (after the one u column)
    Rv = gen.Q[:, :2]  # a measurement noise enters where y does
    # terms: the slowest mode is |eig(A)| < 0.8, 0.8^3000 is far below rounding
    ref = markov_autocovariance(hstack([Rw, Rv]), sla.block_diag(Vw, Vv), 6)
    got = residual_autocovariance(gen, 6, noise_cov=Vw, measurement_cov=Vv)
    assert np.allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


def test_continuous_generator_is_sampled_with_held_noise():
    """Continuous plant and filter, Ts = 0.5: the runtime filters the samples with Qd = ZOH(Q)."""
    Ts = 0.5
    m = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], Bw=[[1.0, 0.0]], Dw=[[0.0, 1.0]])
    gen = ResidualGenerator(LTI([[-1.0]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]]), m, "open-loop observer")
    plant = m.lti("u", "w").to_discrete(Ts)  # exact samples of y under held inputs
    filt = gen.Q.to_discrete(Ts)
    aug = LTI(plant.A, plant.B, np.vstack([plant.C, np.zeros((1, 1))]),
              np.vstack([plant.D, [[1.0, 0.0, 0.0]]]), Ts)  # [y; u] from [u; w]
    ref = markov_autocovariance((filt @ aug)[:, 1:], np.diag([0.4, 0.1]), 4)
    got = residual_autocovariance(gen, 4, noise_cov=[0.4, 0.1], Ts=Ts)
    assert np.allclose(got, ref, rtol=1e-10, atol=1e-14)


def test_noise_response_of_an_unstable_plant_with_measurement_noise_only():
    # The VTOL's open loop is unstable (z = 1.0028 at 0.01 s) and its noise is on the sensors
    # only, so r = Qy Dw w never sees the plant's modes. Composing the whole plant and leaving
    # minreal to cancel them failed for three of the four GOS residuals ("not stable").
    import plant_fmus
    from fmu_fdi import generalized_bank

    m = FDIModel.from_file(plant_fmus.model_path("vtol")).discretize(0.01)
    gen = generalized_bank(m, "sensor", noise="optimize")
    for i, rows in enumerate(gen.groups):
        Q = gen.Q[rows, : m.ny] @ m.Dw  # the whole noise response, without the plant
        P = sla.solve_discrete_lyapunov(Q.A, Q.B @ Q.B.T)
        direct = Q.C @ P @ Q.C.T + Q.D @ Q.D.T
        # two Lyapunov solutions of the same filter, one on a minimal realisation: ~1e-12 relative
        assert residual_autocovariance(gen, 0, noise_cov=np.eye(m.nw), group=i)[0] == pytest.approx(direct, rel=1e-9)


def test_noise_covariance_of_a_non_normal_filter():
    # The VTOL's DOS residuals: poles at the plant's, clustered at z ≈ 0.997, and a realisation
    # of eigenvector condition ~4e8. Against the impulse response summed to 40000 terms
    # (0.9977^40000 ≈ 1e-40), the Kronecker Lyapunov solve was off by ~1 %, the Schur route by
    # ≤ 1.2e-3 (measured): 3e-3 separates the two.
    import plant_fmus
    from fmu_fdi import dedicated_bank

    m = FDIModel.from_file(plant_fmus.model_path("vtol")).discretize(0.01)
    # issue 17's judge refuses this bank (its rows keep the plant's unstable pair |z| = 1.0028 in R
    # and leak u at 1e-4 of the weakest fault gain); the covariance of that very non-normal filter
    # is what is tested here, so its post-conditions are relaxed to let it through
    gen = dedicated_bank(m, "sensor", noise="optimize", smarg=1.003, dec_tol=1e-3)
    for i, rows in enumerate(gen.groups):
        R = gen.Q[rows, : m.ny] @ m.Dw  # measurement noise only: the plant adds no dynamics
        total, x = R.D @ R.D.T, R.B.copy()
        for _ in range(40000):
            total, x = total + (R.C @ x) @ (R.C @ x).T, R.A @ x
        assert residual_autocovariance(gen, 0, noise_cov=np.eye(m.nw), group=i)[0] == pytest.approx(total, rel=3e-3)


def test_kalman_innovations_are_white():
    gen = kalman_generator()
    cov = residual_autocovariance(gen, 10, noise_cov=1.0, measurement_cov=RV)
    assert np.allclose(cov[0], gen.info["innovation_covariance"], atol=1e-10)
    assert np.abs(cov[1:]).max() < 1e-10


@pytest.mark.parametrize("spec, weights", [
    ({"kind": "rms", "window": 7}, np.full(7, 1 / 7)),
    ({"kind": "ewrms", "lambda": 0.9}, 0.1 * 0.9 ** np.arange(200)),  # 0.9^200 ≈ 7e-10 of the weight left out
])
def test_satterthwaite_uses_the_exact_moments(spec, weights):
    """Closed-form mean and variance (ewrms: a Lyapunov sum) equal Σλ_j and 2Σλ_j² of the stacked window."""
    lam = stacked_eigenvalues(observer_generator(), weights, [1.0, MEAS])
    mean, var = lam.sum(), 2 * np.sum(lam**2)
    expected = np.sqrt(var / (2 * mean) * stats.chi2.isf(0.01, 2 * mean**2 / var))
    got = analytic_threshold(observer_generator(), spec, 0.01, noise_cov=[1.0, MEAS], method="satterthwaite")
    assert got == pytest.approx(expected, rel=1e-8)


@pytest.mark.parametrize("x", [540.0, 600.0, 650.0, 700.0, 800.0])
def test_imhof_with_hundreds_of_weights(x):
    # Q = χ²_400 + ½ χ²'_400 (mean 600, sd 35), the size of an rms window of 200 samples of a
    # 4-dim residual. Its characteristic-function amplitude 1/(u ρ(u)) overflowed (1/exp(...)),
    # and where φ(u) oscillates as fast as the Fourier weight of the tail integral (x near Σλ)
    # QAWF returned 0.5 whatever x was.
    lam = np.r_[np.ones(400), np.full(400, 0.5)]
    exact, _ = integrate.quad(lambda a: stats.chi2.pdf(a, 400) * stats.chi2.sf(2 * (x - a), 400), 0, x,
                              epsabs=1e-14, limit=200)
    exact += stats.chi2.sf(x, 400)
    # both routes integrate smooth functions to ~1e-13 absolute; P ≥ 5e-9 here
    assert imhof_sf(x, lam) == pytest.approx(exact, rel=1e-4)


def test_scalar_norm_threshold_is_sigma_z():
    sigma = np.sqrt(1.0 / (1 - POLE**2) + MEAS)
    for method in ("exact", "satterthwaite"):
        thr = analytic_threshold(observer_generator(), {"kind": "norm"}, 0.003, noise_cov=[1.0, MEAS], method=method)
        assert thr == pytest.approx(sigma * stats.norm.isf(0.0015), rel=1e-10)


def test_peak_threshold_is_the_union_bound():
    sigma = np.sqrt(1.0 / (1 - POLE**2) + MEAS)
    thr = analytic_threshold(observer_generator(), {"kind": "peak", "window": 10}, 0.01, noise_cov=[1.0, MEAS])
    assert thr == pytest.approx(sigma * stats.norm.isf(0.01 / 20), rel=1e-9)


# ------------------------------------------------- analytic thresholds on data
def test_chi2_on_kalman_innovations_gives_alpha():
    gen, N, alpha = kalman_generator(), 5, 0.01
    spec = {"kind": "chi2", "window": N, "W": gen.info["whitening"]}
    thr = analytic_threshold(gen, spec, alpha)
    assert thr == pytest.approx(stats.chi2.isf(alpha, 2 * N))
    # with the noise covariances the exact route finds the same χ² law (innovations are white)
    thr_cov = analytic_threshold(gen, spec, alpha, noise_cov=1.0, measurement_cov=RV)
    assert thr_cov == pytest.approx(thr, rel=1e-6)
    n, burn = 60_000, 200  # burn-in: the filter starts from x̂ = 0
    rng = np.random.default_rng(11)
    w, v = rng.standard_normal((n, 2)), np.sqrt(RV) * rng.standard_normal((n, 2))
    r = cascade_residual(gen, n, w=w) + gen.simulate(v, np.zeros((n, 1)))  # the filter is linear in y
    J = Evaluator(spec, 2).run(r)
    # disjoint windows of a white Gaussian sequence are independent: exact binomial count
    x = J[burn + N - 1::N]
    lo, hi = clopper_pearson(int(np.sum(x >= thr)), x.size)
    assert lo <= alpha <= hi


def _thinned(make_J, gap, n_rec=4, length=1_000_000, seed=21):
    rng = np.random.default_rng(seed)
    return np.concatenate([make_J(coloured_residual(length, rng))[gap::gap] for _ in range(n_rec)])


def test_evaluator_formulas_used_below_match_the_runtime():
    r = coloured_residual(3000, np.random.default_rng(3))
    assert np.allclose(Evaluator({"kind": "rms", "window": 20}, 1).run(r[:, None]), rms_of(r, 20), atol=1e-12)
    assert np.allclose(Evaluator({"kind": "ewrms", "lambda": 0.95}, 1).run(r[:, None]), ewrms_of(r, 0.95),
                       atol=1e-12)


def test_rms_of_coloured_residual_exact_and_satterthwaite():
    N, alpha = 20, 0.01
    spec = {"kind": "rms", "window": N}
    gen = observer_generator()
    exact = analytic_threshold(gen, spec, alpha, noise_cov=[1.0, MEAS], method="exact")
    satt = analytic_threshold(gen, spec, alpha, noise_cov=[1.0, MEAS], method="satterthwaite")
    assert analytic_threshold(gen, spec, alpha, noise_cov=[1.0, MEAS]) == exact  # auto: window small enough
    # gap: window + 66 samples, where the AR correlation 0.9^66 < 1e-3
    x = _thinned(lambda r: rms_of(r, N), N + 66)
    lo, hi = clopper_pearson(int(np.sum(x >= exact)), x.size)
    assert lo <= alpha <= hi
    # Satterthwaite's tail is too light: its threshold's true rate is the exact tail at it
    p_satt = imhof_sf(satt**2, stacked_eigenvalues(gen, np.full(N, 1.0 / N), [1.0, MEAS]))
    assert 1.2 * alpha < p_satt < 1.6 * alpha  # the documented 1.41 α
    lo, hi = clopper_pearson(int(np.sum(x >= satt)), x.size)
    assert lo <= p_satt <= hi and lo > alpha  # the simulation sees the bias


def test_ewrms_of_coloured_residual_exact():
    lam, alpha = 0.95, 0.01
    thr = analytic_threshold(observer_generator(), {"kind": "ewrms", "lambda": lam}, alpha, noise_cov=[1.0, MEAS])
    # gap: 0.95^200 < 4e-5 (memory of the evaluator) + 66 (AR correlation < 1e-3)
    x = _thinned(lambda r: ewrms_of(r, lam), 266)
    lo, hi = clopper_pearson(int(np.sum(x >= thr)), x.size)
    assert lo <= alpha <= hi


@pytest.mark.parametrize("spec", [{"kind": "narendra"}, {"kind": "cusum"}, {"kind": "glr", "window": 5}])
def test_no_analytic_threshold_for_non_quadratic_evaluators(spec):
    with pytest.raises(ValueError, match="data_driven_threshold"):
        analytic_threshold(observer_generator(), spec, 0.01, noise_cov=1.0)


@pytest.mark.parametrize("kwargs, message", [
    ({"evaluation": {"kind": "rms", "window": 5}}, "noise_cov, disturbance_cov and/or measurement_cov"),
    ({"noise_cov": [[1.0, 0.0]]}, "must be a scalar"),
    ({"noise_cov": -1.0}, "positive semidefinite"),
    ({"disturbance_cov": 1.0}, "no disturbance inputs"),
    ({"alpha": 1.0, "noise_cov": 1.0}, r"alpha must be a probability"),
    ({"noise_cov": 1.0, "Ts": 0.5}, "differs from the discrete generator"),
    ({"noise_cov": 1.0, "method": "mc"}, "unknown method"),
    ({"evaluation": {"kind": "rms", "window": 3000}, "noise_cov": 1.0, "method": "exact"}, "limit 2000"),
])
def test_analytic_threshold_errors(kwargs, message):
    args = {"evaluation": {"kind": "norm"}, "alpha": 0.01, **kwargs}
    with pytest.raises(ValueError, match=message):
        analytic_threshold(observer_generator(), args.pop("evaluation"), args.pop("alpha"), **args)


def test_analytic_threshold_structural_errors():
    cont = ResidualGenerator(LTI([[-1.0]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]]),
                             FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], Bw=[[1.0]]), "obs")
    with pytest.raises(ValueError, match="give the sample time Ts"):
        analytic_threshold(cont, {"kind": "norm"}, 0.01, noise_cov=1.0)
    with pytest.raises(ValueError, match="choose one with group="):
        analytic_threshold(ResidualGenerator(kalman_generator().Q, kalman_generator().model, "k"), {"kind": "norm"},
                           0.01, noise_cov=1.0)  # one group per residual
    unstable = observer_generator(pole=1.2)
    with pytest.raises(ValueError, match="not stable"):
        analytic_threshold(unstable, {"kind": "norm"}, 0.01, noise_cov=1.0)
    with pytest.warns(RuntimeWarning, match="Satterthwaite"):
        analytic_threshold(observer_generator(), {"kind": "rms", "window": 2500}, 0.01, noise_cov=1.0)


# ---------------------------------------------------------- data-driven thresholds
RMS_N = 10


def rms_records(seeds, length, burn=200):
    """Fault-free rms evaluations of the coloured residual, one record per seed."""
    return [rms_of(coloured_residual(length + burn, np.random.default_rng(s)), RMS_N)[burn:] for s in seeds]


@pytest.fixture(scope="module")
def training():
    return rms_records(range(1, 5), 20_000)


@pytest.fixture(scope="module")
def fresh():
    # 10 fresh runs of 1e6 samples: ≈ 7.7e5 thinned samples, ≈ 77 exceedances at 1e-4
    return rms_records(range(100, 110), 1_000_000)


def _fresh_rate(records, thr, gap):
    x = np.concatenate([r[::gap] for r in records])
    return clopper_pearson(int(np.sum(x >= thr)), x.size)


def test_empirical_threshold_meets_its_rate_on_fresh_runs(training, fresh):
    rate = 0.01
    est = data_driven_threshold(training, rate)
    assert est.method == "empirical" and est.confidence >= 0.95
    assert est.n_effective == pytest.approx(est.n_samples / est.decorrelation_length, rel=1e-3)
    lo, hi = _fresh_rate(fresh, est.value, est.decorrelation_length)
    assert lo <= rate  # not significantly above the target
    # not needlessly conservative: with n_eff ≈ 6000 the relative s.e. of the rate of an
    # order statistic is sqrt((1-p)/(n p)) ≈ 0.13; the 95 % bound sits 1.645 s.e. low, and
    # 99 % of the time the rate is above 1 - (1.645 + 2.576)·0.13 ≈ 0.45 of the target
    assert hi >= 0.45 * rate


def test_extreme_value_threshold_meets_its_rate_on_fresh_runs(training, fresh):
    rate = 1e-4  # below 1/n_eff ≈ 1.6e-4: no order statistic can bound it
    est = data_driven_threshold(training, rate)
    assert est.method == "gpd" and est.details["excesses"] >= 30
    assert est.value >= est.point
    lo, hi = _fresh_rate(fresh, est.value, est.decorrelation_length)
    assert lo <= rate
    # extrapolating 500x beyond the fitted tail, the bootstrap bound is conservative by up
    # to an order of magnitude in rate (about +10 % in threshold); more is a regression
    assert hi >= rate / 20


def test_thresholds_against_a_known_law():
    """chi2 of a white residual: J(k) ~ χ²_8 exactly, so the true rate is chi2.sf(threshold)."""
    N = 8
    recs = []
    for s in range(31, 35):
        z2 = np.random.default_rng(s).standard_normal(20_000 + N) ** 2
        recs.append(np.convolve(z2, np.ones(N))[N - 1: 20_000 + N - 1][N:])
    for rate, method in ((0.01, "empirical"), (1e-4, "gpd")):
        est = data_driven_threshold(recs, rate)
        assert est.method == method
        # holds with probability 0.95 over the training data (seeds fixed); the factor 20
        # as in the fresh-run test above
        assert rate / 20 <= stats.chi2.sf(est.value, N) <= rate


def test_empirical_bound_has_its_coverage():
    """Over 200 independent training sets the bound holds in ≥ the achieved confidence."""
    rate, n, reps = 0.01, 1000, 200
    rng = np.random.default_rng(7)
    ok, achieved = 0, None
    for _ in range(reps):
        est = data_driven_threshold(rng.standard_normal(n), rate, confidence=0.9, thin=1)
        ok += stats.norm.sf(est.value) <= rate
        achieved = est.confidence
    assert ok >= stats.binom.ppf(0.005, reps, achieved)  # one-sided 99.5 % lower limit


def test_decorrelation_length_of_a_moving_sum():
    """A window-20 moving sum of white noise has ACF (20 - k)/20: first below 0.05 at k = 20.

    The ACF estimate from 2e5 samples has s.e. ≈ 0.01, so the crossing lands in 19..21.
    """
    z2 = np.random.default_rng(5).standard_normal(200_020) ** 2
    J = np.convolve(z2, np.ones(20))[19:200_019]
    assert 19 <= decorrelation_length([J]) <= 21
    assert decorrelation_length([np.random.default_rng(6).standard_normal(10_000)]) == 1


@pytest.mark.parametrize("args, kwargs, message", [
    ((np.zeros((3, 100)), 0.01), {}, "must be 1-D"),
    ((np.array([1.0, np.nan, 2.0]), 0.01), {}, "NaN"),
    ((np.ones(1000), 0.01), {}, "constant"),
    ((np.random.default_rng(0).standard_normal(500), 1e-3), {"method": "empirical"}, "at least 2995"),
    ((np.random.default_rng(0).standard_normal(500), 0.0), {}, "rate must be in"),
    ((np.random.default_rng(0).standard_normal(50), 1e-3), {"method": "gpd", "thin": 1}, "too few"),
    ((np.random.default_rng(0).standard_normal(500), 0.01), {"skip": 600}, "no samples left"),
])
def test_data_driven_errors(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        data_driven_threshold(*args, **kwargs)


def test_docstring_examples():
    import doctest

    import fmu_fdi.evaluation.analytic
    import fmu_fdi.evaluation.datadriven

    for mod in (fmu_fdi.evaluation.analytic, fmu_fdi.evaluation.datadriven):
        assert doctest.testmod(mod).failed == 0
