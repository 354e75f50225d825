"""Observer-based residual generators: Luenberger, Kalman, UIO, Beard–Jones filter, factorised form.

Tolerances, derived once here and referred to below:

- DECOUPLED = 1e-9 (relative to the output signal size, or absolute on an H∞ norm of an
  O(1) model): a residual that is zero by construction is only rounding away from zero.
  The cascade plant + filter is simulated without cancellation for N ≤ 600 steps with
  matrices of norm ≲ 10 and eigenvector condition ≲ 1e2, so rounding stays below
  N · κ · eps ≈ 1e-11; 1e-9 leaves two digits of headroom.
- MOVED = 1e-6 (relative to the fault's own effect on y): a fault that moves the residual
  must do so three orders of magnitude above the DECOUPLED rounding floor.
- Poles: Bauer–Fike, a simple eigenvalue computed from a matrix of norm ‖A‖ with eigenvector
  condition κ is accurate to κ · eps · ‖A‖; we allow 1e4 of that (place_poles computes the
  gain through the eigenvectors, which costs a few digits).
- SAME = 1e-12: one quantity computed two ways (a formula against the design's own
  arithmetic) from O(1)–O(10) data; each way costs ≲ 1e2 flops per entry, so the two agree
  to ≲ 1e2 · eps · 10 ≈ 2e-13, and 1e-12 leaves a digit.
- RICCATI = 1e-10: Riccati solutions from different solvers or different but equivalent
  problem statements agree to the solvers' backward error times the condition number of
  the equation (≲ 1e3 here), ≈ 1e-13; 1e-10 leaves three digits.
- Monte Carlo (Kalman): a sample covariance of N Gaussian vectors has entry standard
  deviation sqrt((Σii Σjj + Σij²)/N); 5 of those keeps a false failure below 1e-6 per entry.
"""
import control as ct
import numpy as np
import pytest

import published as pub
from simulate import cascade_residual, plant_outputs
from fmu_fdi import (DesignError, FDIModel, LTI, actuator_fault, component_fault, leakage, sensor_fault,
                     structure_matrix)
from fmu_fdi.design.observers.beard_jones import fault_detection_filter
from fmu_fdi.design.observers._observer import filter_riccati
from fmu_fdi.design.problems.coprime import factorized, left_coprime_factors
from fmu_fdi.design.observers.kalman_filter import kalman
from fmu_fdi.design.observers.output_observer import luenberger
from fmu_fdi.design.observers.uio import unknown_input_observer

EPS = np.finfo(float).eps
DECOUPLED = 1e-9
MOVED = 1e-6
SAME = 1e-12
RICCATI = 1e-10
TS = 0.1      # sample time of the discrete models and of the continuous simulations
N = 300       # samples: 30 s, ten times the slowest plant time constant (≈ 1.2 s)


def plant(discrete: bool = False) -> FDIModel:
    """Four states, two inputs (one with feedthrough), three outputs, a disturbance entering
    x2, correlated noise, and an actuator, a component and a sensor fault."""
    A = np.array([[-1.0, 1, 0, 0], [0, -2, 1, 0], [0, 0, -3, 1], [1, 0, 0, -4]])
    Bu = np.array([[1.0, 0], [0, 0], [0, 1], [0, 0]])
    C = np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
    Du = np.array([[0.0, 0], [0, 0], [0, 0.5]])
    m = FDIModel.from_matrices(
        A, Bu, C, Du, Bd=[[0.0], [1], [0], [0]],
        Bw=[[0.1, 0], [0, 0.2], [0.1, 0], [0, 0]], Dw=[[0.0, 0.05], [0, 0], [0.05, 0]],
        u_names=["u1", "u2"], y_names=["y1", "y2", "y3"], d_names=["d"], w_names=["w1", "w2"],
        faults=[actuator_fault("act1", "u1"), component_fault("leak3", [[0], [0], [1], [0]]),
                sensor_fault("sens2", "y2")], name="plant4")
    return m.discretize(TS) if discrete else m


def euler_plant() -> FDIModel:
    """A discrete model written directly (forward Euler of :func:`plant`): unlike the ZOH
    sample of a plant, it keeps the structural zero C f = 0 of the leak, so the leak has
    detectability index 2 in discrete time too."""
    m = plant()
    return FDIModel.from_matrices(
        np.eye(4) + TS * m.A, TS * m.Bu, m.C, m.Du, Bd=TS * m.Bd, Bw=TS * m.Bw, Dw=m.Dw, dt=TS,
        u_names=m.u_names, y_names=m.y_names, d_names=m.d_names, w_names=m.w_names,
        faults=[actuator_fault("act1", "u1"), component_fault("leak3", [[0], [0], [TS], [0]]),
                sensor_fault("sens2", "y2")], name="plant4_euler")


def cpoles(model, continuous_poles):
    """The requested poles in the model's domain (z = e^{s Ts} for a discrete model)."""
    p = np.asarray(continuous_poles, complex)
    return np.exp(p * model.dt) if model.dt else p


def signals(model, seed=0, d=False):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((N, model.nu))
    dd = rng.standard_normal((N, model.nd)) if d else None
    return u, dd


def assert_poles(gen, expected):
    """Filter eigenvalues equal ``expected`` (a multiset) to the Bauer–Fike tolerance above."""
    lam, X = np.linalg.eig(gen.Q.A)
    tol = 1e4 * EPS * np.linalg.cond(X) * max(1.0, np.linalg.norm(gen.Q.A, 2))
    expected = list(np.asarray(expected, complex))
    assert len(expected) == lam.size
    for v in lam:
        j = int(np.argmin([abs(v - e) for e in expected]))
        assert abs(v - expected.pop(j)) <= tol, (v, tol)


def assert_silent(gen, d=False, seed=0, steps=N):
    """No fault, no noise, zero initial state: r stays at rounding level relative to y."""
    m = gen.model
    u, dd = signals(m, seed, d)
    u, dd = u[:steps], None if dd is None else dd[:steps]
    r = cascade_residual(gen, steps, TS, u=u, d=dd)
    y = plant_outputs(m, steps, TS, u=u, d=dd)
    assert np.max(np.abs(r)) <= DECOUPLED * np.max(np.abs(y))


def assert_detection_claims(gen, seed=1, steps=N):
    """``info['detected_faults']`` = weak structure; each claimed fault moves r in a simulation,
    each other fault leaves r at rounding level. (For an unstable plant keep ``steps`` short:
    y grows without bound and the rounding floor grows with it.)"""
    m = gen.model
    seen = structure_matrix(gen)[0]
    assert gen.info["detected_faults"] == [nm for nm, s in zip(m.fault_names, seen) if s]
    rng = np.random.default_rng(seed)
    for spec in m.faults:
        f = np.zeros((steps, m.nf))
        f[:, spec.columns] = rng.standard_normal((steps, spec.columns.stop - spec.columns.start))
        r = cascade_residual(gen, steps, TS, f=f)
        yf = plant_outputs(m, steps, TS, f=f)
        size = np.max(np.abs(r)) / np.max(np.abs(yf))
        if spec.name in gen.info["detected_faults"]:
            assert size >= MOVED, spec.name
        else:
            assert size <= DECOUPLED, spec.name


def Ru_norm(gen):
    return gen.Ru.hinfnorm()[0] if gen.Ru.n or np.any(gen.Ru.D) else 0.0


# ============================================================================ Luenberger
@pytest.mark.parametrize("discrete", [False, True])
def test_luenberger_decouples_u_places_poles_and_detects(discrete):
    m = plant(discrete)
    poles = cpoles(m, [-2, -3, -4 + 1j, -4 - 1j])
    gen = luenberger(m, poles)
    assert gen.dt == m.dt and gen.groups == [[0, 1, 2]]
    assert_poles(gen, poles)
    assert Ru_norm(gen) < DECOUPLED
    assert_silent(gen)
    assert gen.info["detected_faults"] == ["act1", "leak3", "sens2"]
    assert_detection_claims(gen)


@pytest.mark.parametrize("discrete", [False, True])
def test_luenberger_error_decays_from_a_nonzero_plant_state(discrete):
    m = plant(discrete)
    gen = luenberger(m, cpoles(m, [-2, -3, -4, -5]))
    x0 = np.array([1.0, -2.0, 0.5, 3.0])
    r = cascade_residual(gen, N, TS, x0_plant=x0)
    # ||r_k|| ≤ ||C|| κ(X) ρ^k ||x0||: e = x − x̂ starts at x0 and decays with the slowest pole.
    lam, X = np.linalg.eig(gen.Q.A)
    t = np.arange(N) * TS
    rate = np.exp(-2.0 * t)  # slowest pole −2 (e^{−2 Ts} per sample in discrete time)
    bound = np.linalg.norm(m.C, 2) * np.linalg.cond(X) * rate * np.linalg.norm(x0)
    assert np.all(np.linalg.norm(r, axis=1) <= bound * (1 + DECOUPLED) + DECOUPLED)
    assert np.linalg.norm(r[0]) > 0.1  # it did start away from zero


def test_luenberger_weighting_and_deadbeat():
    m = plant(True)
    V = np.array([[1.0, -1.0, 0.0]])
    gen = luenberger(m, [0, 0, 0, 0], V=V)  # multiplicity 4 > rank C = 3: Schur placement
    assert gen.n_residuals == 1 and gen.info["placement"].startswith("Schur")
    # a 4-fold pole in one Jordan chain moves by O(eps^(1/4)) under rounding
    assert np.max(np.abs(gen.Q.poles())) < 1e3 * EPS ** 0.25
    assert Ru_norm(gen) < DECOUPLED
    assert_silent(gen)


def test_luenberger_unobservable_but_detectable():
    # x3 is seen by nobody and decays at -5: place the observable pair, keep -5.
    A = np.array([[0.0, 1, 0], [-2, 1, 0], [0, 0, -5]])
    m = FDIModel.from_matrices(A, [[0.0], [1], [1]], [[1.0, 0, 0]], faults=[actuator_fault("a", "u0")])
    gen = luenberger(m, [-3, -4])
    assert_poles(gen, [-3, -4, -5])
    assert np.allclose(gen.info["fixed_modes"], [-5])
    assert_silent(gen)
    with pytest.raises(DesignError, match=r"3 poles given but \(A, C\) has 2 observable .* fixed"):
        luenberger(m, [-3, -4, -6])


@pytest.mark.parametrize("discrete", [False, True])
def test_observers_with_redundant_sensors(discrete):
    # Two sensors on one state (a row of C twice, as the wind-turbine benchmark's pitch and
    # speed sensors): rank C < p. The placement works on the row space of C; it used to hand
    # the rank-deficient C to scipy's place_poles, which raised a bare ValueError.
    base = plant()
    C = np.vstack([base.C, base.C[:1]])
    m = FDIModel.from_matrices(base.A, base.Bu, C, np.vstack([base.Du, base.Du[:1]]), Bd=base.Bd,
                               u_names=base.u_names, y_names=base.y_names + ["y1b"], d_names=base.d_names,
                               faults=[f for f in base.faults if f.kind != "sensor"]
                               + [sensor_fault("sens1b", "y1b")], name="redundant")
    m = m.discretize(TS) if discrete else m
    poles = cpoles(m, [-2, -3, -4 + 1j, -4 - 1j])
    gen = luenberger(m, poles)
    assert_poles(gen, poles)
    assert Ru_norm(gen) < DECOUPLED
    for other in (unknown_input_observer(m), fault_detection_filter(m, faults=["act1", "leak3"])):
        assert other.Q.is_stable() and Ru_norm(other) < DECOUPLED
    assert_silent(gen)


def test_luenberger_errors():
    m = plant()
    good = [-2, -3, -4, -5]
    cases = [
        (dict(poles=[-2, -3, -4]), "3 poles given but (A, C) has 4 observable"),
        (dict(poles=[-2, -3, -4, 0.5]), "are not stable"),
        (dict(poles=[-2, -3, -4, np.nan]), "must be finite"),
        (dict(poles=[-2, -3, -4 + 1j, -5]), "not closed under complex conjugation"),
        (dict(poles=good, V=np.eye(2)), "V must be kx3"),
        (dict(poles=good, V=np.zeros((1, 3))), "V is zero"),
        (dict(poles=good, V=[[1.0, np.nan, 0]]), "V contains NaN"),
    ]
    for kw, msg in cases:
        with pytest.raises(DesignError) as err:
            luenberger(m, **kw)
        assert msg in str(err.value), (kw, str(err.value))
    with pytest.raises(DesignError, match="inside the unit circle"):
        luenberger(plant(True), [0.1, 0.2, 0.3, 1.2])
    # an unstable mode no output sees: not detectable, the message names it
    bad = FDIModel.from_matrices([[1.0, 0], [0, -1]], [[1.0], [1]], [[0.0, 1]])
    with pytest.raises(DesignError, match=r"not detectable: the modes \[1\] are unobservable"):
        luenberger(bad, [-2])


# ============================================================================ Kalman
def _with_v_as_noise(m: FDIModel, Qw, Rv):
    """The same plant with the measurement noise v appended to w: w⁺ = [w; v], Dw⁺ = [Dw I]."""
    p = m.ny
    Bw = np.hstack([m.Bw, np.zeros((m.n, p))])
    Dw = np.hstack([m.Dw, np.eye(p)])
    Qe = np.block([[Qw, np.zeros((m.nw, p))], [np.zeros((p, m.nw)), Rv]])
    m2 = FDIModel.from_matrices(m.A, m.Bu, m.C, m.Du, Bw=Bw, Dw=Dw, dt=m.dt, u_names=m.u_names,
                                y_names=m.y_names, faults=m.faults, name="with_v")
    return m2, Qe


@pytest.mark.parametrize("discrete", [False, True])
def test_kalman_innovation_filter(discrete):
    m = plant(discrete)
    Qw, Rv = np.diag([1.0, 2.0]), np.diag([0.01, 0.02, 0.03])
    gen = kalman(m, Qw, Rv)
    A, C = m.A, m.C
    P, L = np.array(gen.info["P"]), np.array(gen.info["gain"])
    Qx, R, S = m.Bw @ Qw @ m.Bw.T, m.Dw @ Qw @ m.Dw.T + Rv, m.Bw @ Qw @ m.Dw.T
    Sig = np.array(gen.info["innovation_covariance"])
    # Riccati residuals relative to the size of their terms: RICCATI (see the top)
    if discrete:
        Kf = np.array(gen.info["filter_gain"])
        assert np.allclose(Sig, C @ P @ C.T + R, rtol=0, atol=SAME * np.abs(Sig).max())
        G = A @ P @ C.T + S
        res = A @ P @ A.T + Qx - G @ np.linalg.solve(Sig, G.T) - P
        assert np.allclose(Kf, P @ C.T @ np.linalg.inv(Sig), atol=SAME)
        assert np.allclose(L, A @ Kf + S @ np.linalg.inv(Sig), atol=SAME)  # predictor from the filter form
        assert gen.info["innovation_kind"] == "covariance"
    else:
        G = P @ C.T + S
        res = A @ P + P @ A.T - G @ np.linalg.solve(R, G.T) + Qx
        assert np.allclose(Sig, R)
        assert gen.info["innovation_kind"] == "intensity"
    assert np.abs(res).max() <= RICCATI * max(np.abs(Qx).max(), np.abs(P).max())
    Wh = np.array(gen.info["whitening"])
    assert np.allclose(Wh @ Sig @ Wh, np.eye(3), atol=SAME)
    assert_poles(gen, np.linalg.eigvals(A - L @ C))
    assert gen.Q.is_stable()
    assert Ru_norm(gen) < DECOUPLED
    assert_silent(gen)
    assert_detection_claims(gen)
    # the stated noise model: v is exactly a noise input entering through Dw = I
    m2, Qe = _with_v_as_noise(m, Qw, Rv)
    gen2 = kalman(m2, Qe, np.zeros((3, 3)))
    assert np.allclose(gen2.info["gain"], L, atol=RICCATI)
    assert np.allclose(gen2.info["innovation_covariance"], Sig, atol=RICCATI)


def test_kalman_discrete_matches_dlqe_predictor_gain():
    m = plant(True)
    m0 = FDIModel.from_matrices(m.A, m.Bu, m.C, m.Du, Bw=m.Bw, dt=m.dt)  # Dw = 0: no correlation
    Qw, Rv = np.diag([1.0, 2.0]), 0.05 * np.eye(3)
    gen = kalman(m0, Qw, Rv)
    Lp, P, _ = ct.dlqe(m.A, m.Bw, m.C, Qw, Rv)
    assert np.allclose(gen.info["gain"], Lp, atol=RICCATI)
    assert np.allclose(gen.info["P"], P, atol=RICCATI)
    # the filter gain is P Cᵀ Σ⁻¹, which dlqe does not return (python-control issue 1173)
    Sig = m.C @ P @ m.C.T + Rv
    assert np.allclose(gen.info["filter_gain"], P @ m.C.T @ np.linalg.inv(Sig), atol=RICCATI)


def test_kalman_innovations_are_white_with_covariance_sigma():
    m = plant(True)
    Qw, Rv = np.diag([1.0, 2.0]), np.diag([0.01, 0.02, 0.03])
    m2, Qe = _with_v_as_noise(m, Qw, Rv)
    gen = kalman(m2, Qe, np.zeros((3, 3)))
    Sig = np.array(gen.info["innovation_covariance"])
    n_mc, burn = 40000, 200  # burn-in: 200 samples ≫ the filter's slowest time constant (≈ 10 samples)
    rng = np.random.default_rng(7)
    w = rng.multivariate_normal(np.zeros(Qe.shape[0]), Qe, n_mc + burn)
    e = cascade_residual(gen, n_mc + burn, u=None, w=w)[burn:]
    est = e.T @ e / n_mc
    sd = np.sqrt((np.outer(np.diag(Sig), np.diag(Sig)) + Sig**2) / n_mc)
    assert np.all(np.abs(est - Sig) <= 5 * sd)
    # whitened innovations: unit covariance and no lag-1 correlation (std 1/sqrt(N) per entry)
    z = e @ np.array(gen.info["whitening"])
    lag1 = z[1:].T @ z[:-1] / n_mc
    assert np.all(np.abs(lag1) <= 5 / np.sqrt(n_mc))


def test_kalman_errors():
    m = plant()
    cases = [
        (dict(Qw=np.eye(3), Rv=0.1), "Qw must be 2x2"),
        (dict(Qw=[1.0, 2.0, 3.0], Rv=0.1), "Qw has 3 variances but there are 2"),
        (dict(Qw=[[1.0, 0.5], [0.0, 1.0]], Rv=0.1), "Qw is not symmetric"),
        (dict(Qw=[[1.0, 2.0], [2.0, 1.0]], Rv=0.1), "Qw is not positive semidefinite (smallest eigenvalue -1"),
        (dict(Qw=1.0, Rv=[[0.1, 0, 0], [0, np.nan, 0], [0, 0, 0.1]]), "Rv contains NaN"),
        (dict(Qw=1.0, Rv=np.eye(2)), "Rv must be 3x3"),
        (dict(Qw=1.0, Rv=-0.1), "Rv is not positive semidefinite"),
        (dict(Qw=1.0, Rv=0.0), "R = Dw Qw Dwᵀ + Rv is singular"),
        (dict(Qw=None, Rv=0.1), "Qw (noise covariance, 2x2) is required"),
        (dict(Qw=1.0, Rv=None), "Rv (measurement noise covariance, p×p) is required"),
        (dict(Qw="a lot", Rv=0.1), "Qw must be a number"),
    ]
    for kw, msg in cases:
        with pytest.raises(DesignError) as err:
            kalman(m, **kw)
        assert msg in str(err.value), (kw, str(err.value))
    bad = FDIModel.from_matrices([[1.0, 0], [0, -1]], [[1.0], [1]], [[0.0, 1]], Bw=np.eye(2))
    with pytest.raises(DesignError, match=r"not detectable: the modes \[1\] are unobservable"):
        kalman(bad, 1.0, 1.0)
    # detectable, but an undamped mode no noise reaches: no stabilising Riccati solution
    osc = FDIModel.from_matrices([[0.0, 1], [-1, 0]], [[0.0], [1]], [[1.0, 0]], Bw=np.zeros((2, 1)))
    with pytest.raises(DesignError, match="no stabilising solution"):
        kalman(osc, 1.0, 1.0)



# The wind-turbine drive train of the campaign (tests/campaign_plants.py, WIND, subsystem
# "drive"): ZOH at 0.01 s, state balanced and outputs in units of their noise std, rounded to
# 6 decimals. Its modes are 0.999928, 0.999451 (a pair) and 0.606531; the campaign's Kalman
# design has no noise on the states (Qx = 0, R = I, S = 0), and scipy's solve_discrete_are
# rejects that DARE ("symplectic pencil has eigenvalues too close to the unit circle") although
# P = 0 is its stabilising solution. The torque state x4 is autonomous (A[3, :3] = 0).
DRIVE_A = [[0.997561, 0.002566, -0.048445, -0.000002],
           [0.035099, 0.961899, 0.697166, -0.001988],
           [0.098684, -0.103816, 0.960617, 0.000114],
           [0.0, 0.0, 0.0, 0.606531]]
DRIVE_C = [[0.039789, 0, 0, 0], [0.039789, 0, 0, 0], [0, 2.0, 0, 0], [0, 2.0, 0, 0], [0, 0, 0, 0.111111]]


@pytest.mark.parametrize("q", [0.0, 1e-12, 1.0])
@pytest.mark.parametrize("reach", ["none", "x2", "all"])
def test_filter_dare_with_slow_modes_the_noise_does_not_reach(q, reach):
    A, C = np.array(DRIVE_A), np.array(DRIVE_C)
    G = {"none": np.zeros((4, 1)), "x2": np.eye(4)[:, [1]], "all": np.eye(4)}[reach]
    Qx, R, S = q * G @ G.T, np.eye(5), np.zeros((4, 5))
    kf = filter_riccati(A, C, Qx, R, S, 0.01)
    P, L = kf.P, kf.L
    Sig = C @ P @ C.T + R
    K = A @ P @ C.T + S
    res = A @ P @ A.T + Qx - K @ np.linalg.solve(Sig, K.T) - P
    # relative to the size of the equation's terms (‖A‖ ≈ 1.2, ‖Σ⁻¹‖ ≤ 1): RICCATI (see the top)
    size = max(np.abs(Qx).max(), np.abs(P).max(), np.finfo(float).tiny)
    assert np.abs(res).max() <= RICCATI * size
    assert np.array_equal(P, P.T)
    assert np.linalg.eigvalsh(P).min() >= -SAME * size  # a covariance
    assert np.max(np.abs(np.linalg.eigvals(A - L @ C))) < 1.0  # the stabilising solution
    if q == 0.0 or reach == "none":
        assert np.array_equal(P, np.zeros((4, 4)))  # A stable, no noise: the error dies out
    if reach == "x2":
        # x4 is autonomous, stable and noise-free: its error dies out, so P is zero on it
        assert np.abs(P[3]).max() <= SAME * size


def test_filter_riccati_uncontrollable_modes_off_and_on_the_boundary():
    # unstable but observable, no noise: the filter must still stabilise. Scalar closed forms:
    # DARE P = 4P − 4P²/(P + 1) → P = 3, L = 2·3/4, A − L C = 0.5; CARE 2P − P² = 0 → P = 2.
    one = np.ones((1, 1))
    kf = filter_riccati(2 * one, one, 0 * one, one, 0 * one, 0.1)
    assert np.allclose([kf.P[0, 0], kf.L[0, 0]], [3.0, 1.5], rtol=0, atol=SAME)
    kf = filter_riccati(one, one, 0 * one, one, 0 * one, 0.0)
    assert np.allclose([kf.P[0, 0], kf.L[0, 0]], [2.0, 2.0], rtol=0, atol=SAME)
    # a noise-free mode on the boundary (z = 1 next to a noisy stable one): no stabilising solution
    A, C = np.diag([1.0, 0.5]), np.array([[1.0, 1.0]])
    with pytest.raises(DesignError, match=r"no stabilising solution \(the modes \[1\] lie on the stability boundary"):
        filter_riccati(A, C, np.diag([0.0, 1.0]), one, np.zeros((2, 1)), 0.1)


# ============================================================================ UIO
def test_a6_unknown_input_observer_chen_patton():
    m = pub.a6_model()
    gen = unknown_input_observer(m, [-2, -10, -5])
    H, T, F = (np.array(gen.info[k]) for k in ("H", "T", "F"))
    # published: H = E (CE)⁺ = [1 0; 0 0; 0 0], T = I − H C = diag(0, 1, 1); exact in floating point
    assert np.array_equal(H, [[1.0, 0], [0, 0], [0, 0]])
    assert np.array_equal(T, np.diag([0.0, 1, 1]))
    assert np.array_equal(T @ m.Bd, np.zeros((3, 1)))
    K1, K = np.array(gen.info["K1"]), np.array(gen.info["K"])
    assert np.allclose(F, T @ m.A - K1 @ m.C, atol=SAME)
    assert np.allclose(K, K1 + F @ H, atol=SAME)
    assert_poles(gen, [-2, -10, -5])
    # eigenvalues of a 3x3 F with norm ≈ 10 and well-separated poles: Bauer–Fike as in assert_poles
    assert np.allclose(np.sort(np.linalg.eigvals(F).real), [-10, -5, -2], atol=1e4 * EPS * 10 * 10)
    R = gen.internal_form()
    for g in ("u", "d"):  # zero transfer from u and from d
        assert (R[g].hinfnorm()[0] if R[g].n or np.any(R[g].D) else 0.0) < DECOUPLED
    assert leakage(gen) < DECOUPLED
    assert_silent(gen, d=True)
    assert gen.info["detected_faults"] == ["s1", "s2"]
    assert_detection_claims(gen)


@pytest.mark.parametrize("discrete", [False, True])
def test_uio_decouples_d_on_a_larger_plant(discrete):
    m = plant(discrete)
    gen = unknown_input_observer(m)  # default poles
    # continuous: x3 only reaches y through x2, where d enters: the invariant zero -3 of
    # (A, Bd, C) stays a (stable) mode of F, and leak3 (into x3) looks exactly like d.
    if discrete:
        assert gen.info["fixed_modes"] == []
    else:
        assert np.allclose(gen.info["fixed_modes"], [-3.0])
        assert "leak3" not in gen.info["detected_faults"]
    assert_poles(gen, np.concatenate([gen.info["poles"], gen.info["fixed_modes"]]))
    assert np.allclose(np.array(gen.info["T"]) @ m.Bd, 0, atol=SAME)
    assert leakage(gen) < DECOUPLED
    assert_silent(gen, d=True)
    assert {"act1", "sens2"} <= set(gen.info["detected_faults"])
    assert_detection_claims(gen)


def test_uio_errors():
    A6 = pub.a6_model()
    with pytest.raises(DesignError) as err:  # d acts on x2, which y does not see directly
        unknown_input_observer(FDIModel.from_matrices(A6.A, A6.Bu, A6.C, Bd=[[0.0], [1], [0]], d_names=["gust"]))
    msg = str(err.value)
    assert "rank(C E) = 0 < rank(E) = 1" in msg and "1·gust" in msg and "condition 1" in msg
    with pytest.raises(DesignError, match="Dd must be zero .* unknown inputs \\['d0'\\] act directly"):
        unknown_input_observer(FDIModel.from_matrices(A6.A, A6.Bu, A6.C, Bd=[[0.0], [0], [1]], Dd=[[0.0], [1]]))
    # (A, E, C) with an unstable invariant zero at 1 (x1 shows only through x2, where d enters):
    # condition 2 fails and the mode is named
    A = np.array([[1.0, 0, 0], [1, -1, 0], [0, 0, -2]])
    m = FDIModel.from_matrices(A, [[1.0], [0], [0]], [[0.0, 1, 0], [0, 0, 1]], Bd=[[0.0], [1], [0]])
    with pytest.raises(DesignError) as err:
        unknown_input_observer(m)
    msg = str(err.value)
    assert "(C, A1 = T A) is not detectable: the modes [1]" in msg and "invariant zeros" in msg
    full = FDIModel.from_matrices(A6.A, A6.Bu, A6.C, Bd=[[1.0, 0], [0, 0], [0, 1]])
    with pytest.raises(DesignError, match=r"no residual remains: rank\(E\) = 2 ≥ 2 outputs"):
        unknown_input_observer(full)
    with pytest.raises(DesignError, match="2 poles given but \\(C, A1 = T A\\) has 3 observable"):
        unknown_input_observer(A6, [-2, -3])
    with pytest.raises(DesignError, match="not stable"):
        unknown_input_observer(A6, [-2, -3, 4])
    with pytest.raises(DesignError, match="must be finite"):
        unknown_input_observer(A6, [-2, -3, np.nan])


# ============================================================================ Beard–Jones
@pytest.mark.parametrize("discrete", [False, True])
def test_fault_detection_filter_directions(discrete):
    m = euler_plant() if discrete else plant()
    requested = cpoles(m, [-2, -3, -4, -5])
    gen = fault_detection_filter(m, requested, faults=["act1", "leak3"])
    assert gen.info["detection_orders"] == {"act1": 1, "leak3": 2}
    assert_poles(gen, requested)
    assert Ru_norm(gen) < DECOUPLED
    assert_silent(gen)
    assert_detection_claims(gen)
    dirs = gen.info["fault_directions"]
    # the stored direction is the normalised C f_i*
    for nm, fs in gen.info["detector_directions"].items():
        g = m.C @ np.array(fs)
        assert np.allclose(np.abs(np.array(dirs[nm]) @ g), np.linalg.norm(g), rtol=SAME)
    assert abs(np.dot(dirs["act1"], dirs["leak3"])) < 0.5  # clearly distinct directions (here orthogonal)
    # the detection spaces span{f, ..., A^(k-1) f} are (A − D C)-invariant: the residual of the
    # least-squares fit is the rounding of one product, ≲ n eps ||Acl|| ||W||; 1e3 eps for headroom
    Acl = gen.Q.A
    for spec in m.faults[:2]:
        f = m.Bf[:, spec.columns][:, 0]
        k = gen.info["detection_orders"][spec.name]
        W = np.column_stack([np.linalg.matrix_power(m.A, j) @ f for j in range(k)])
        X = np.linalg.lstsq(W, Acl @ W, rcond=None)[0]
        assert np.linalg.norm(Acl @ W - W @ X) <= 1e3 * EPS * np.linalg.norm(Acl, 2) * np.linalg.norm(W)
    # a step on fault i moves r along C f_i* only. (A step, not noise: a residual that crosses
    # zero has no direction there, and rounding of size eps ||x|| would dominate the angle.)
    for spec in m.faults[:2]:
        f = np.zeros((N, m.nf))
        f[:, spec.columns] = 1.0
        r = cascade_residual(gen, N, TS, f=f)
        d = np.array(dirs[spec.name])
        size = np.linalg.norm(r, axis=1)
        # samples before the fault reaches r (r_0 = 0; r_1 = C f = 0 when k = 2) are rounding only
        live = size > DECOUPLED * size.max()
        assert live.sum() >= N - 2
        sin_angle = np.linalg.norm(r[live] - np.outer(r[live] @ d, d), axis=1) / size[live]
        assert sin_angle.max() < DECOUPLED, spec.name  # the off-direction part is rounding only


def test_fault_detection_filter_on_a_sampled_plant_is_ill_conditioned():
    """ZOH sampling spreads the leak over every state (C Γ e3 ≠ 0), so its index drops to 1
    and the second direction of its continuous detection space is nearly invisible to the
    projected output: the design is exact but needs a large gain, which info reports."""
    m = plant(True)
    gen = fault_detection_filter(m, cpoles(m, [-2, -3, -4, -5]), faults=["act1", "leak3"])
    assert gen.info["detection_orders"] == {"act1": 1, "leak3": 1}
    assert gen.info["eigenvector_condition"] > 1e5  # vs ≈ 3 for the continuous design (measured)
    assert_silent(gen)
    assert_detection_claims(gen)


def test_fault_detection_filter_default_poles_and_fixed_mode():
    # Three states, two outputs, one fault of index 1 into x2: x3 feeds only x2, whose output
    # is the fault direction, so the projected output (y1) cannot see it: -3 is fixed (an
    # input-decoupling zero of the fault channel); it is stable, the design succeeds.
    A = np.array([[-1.0, 0, 0], [0, -2, 1], [0, 0, -3]])
    C = np.array([[1.0, 0, 0], [0, 1, 0]])
    m = FDIModel.from_matrices(A, np.zeros((3, 0)), C, faults=[component_fault("f", [[0.0], [1], [0]])])
    gen = fault_detection_filter(m)
    assert gen.info["detection_orders"] == {"f": 1}
    assert_poles(gen, np.concatenate([gen.info["poles"], gen.info["fixed_modes"]]))
    assert np.allclose(gen.info["fixed_modes"], [-3.0])
    assert np.allclose(np.abs(gen.info["fault_directions"]["f"]), [0, 1])


@pytest.mark.parametrize("discrete", [False, True])
def test_fault_detection_filter_default_poles_with_complex_plant_modes(discrete):
    # The defaults follow the plant's modes (complex here); a detection space of order 1 took
    # one of a conjugate pair and the design failed ("not closed under complex conjugation").
    m = plant(discrete)
    assert np.any(np.abs(np.linalg.eigvals(m.A).imag) > 0)
    gen = fault_detection_filter(m, faults=["act1", "leak3"])
    lam = gen.Q.poles()
    assert gen.Q.is_stable() and np.all(np.abs(np.asarray(gen.info["poles"]).imag) == 0)
    assert Ru_norm(gen) < DECOUPLED and lam.size == m.n


def test_fault_detection_filter_errors():
    m = plant()
    with pytest.raises(DesignError) as err:  # default faults include the sensor fault
        fault_detection_filter(m)
    msg = str(err.value)
    assert "fault 'sens2' acts on the measurements directly" in msg and "faults=['act1', 'leak3']" in msg
    with pytest.raises(DesignError, match="unknown fault 'nope'"):
        fault_detection_filter(m, faults=["act1", "nope"])
    # actuator on u2, which has feedthrough: its Df column is nonzero, so it is a measurement fault too
    m2 = FDIModel.from_matrices(m.A, m.Bu, m.C, m.Du, u_names=["u1", "u2"], faults=[actuator_fault("act2", "u2")])
    with pytest.raises(DesignError, match="fault 'act2' acts on the measurements directly"):
        fault_detection_filter(m2)
    multi = FDIModel.from_matrices(m.A, m.Bu, m.C, faults=[component_fault("two", np.eye(4)[:, :2])])
    with pytest.raises(DesignError, match="fault 'two' has 2 columns"):
        fault_detection_filter(multi)
    # same output direction: e1 and e1 + e3 (C e3 = 0) both appear along y1
    dep = FDIModel.from_matrices(m.A, m.Bu, m.C, faults=[
        component_fault("fa", [[1.0], [0], [0], [0]]), component_fault("fb", [[1.0], [0], [1], [0]]),
        component_fault("fc", [[0.0], [0], [0], [1]])])
    with pytest.raises(DesignError) as err:
        fault_detection_filter(dep)
    msg = str(err.value)
    assert "faults ['fa', 'fb'] are not mutually detectable" in msg and "rank C F* = 2 < 3" in msg
    unobs = FDIModel.from_matrices([[-1.0, 0], [0, -2]], [[1.0], [0]], [[1.0, 0]],
                                   faults=[component_fault("hidden", [[0.0], [1]])])
    with pytest.raises(DesignError, match="fault 'hidden' is undetectable: C A\\^k f = 0 for every k"):
        fault_detection_filter(unobs)
    # an unstable mode outside the detection space that the projected output cannot see
    A = np.array([[-1.0, 0, 0], [0, -2, 1], [0, 0, 2]])
    bad = FDIModel.from_matrices(A, np.zeros((3, 0)), [[1.0, 0, 0], [0, 1, 0]],
                                 faults=[component_fault("f", [[0.0], [1], [0]])])
    with pytest.raises(DesignError) as err:
        fault_detection_filter(bad)
    msg = str(err.value)
    assert "the modes [2] are unobservable" in msg and "invariant zeros of the fault channels" in msg
    with pytest.raises(DesignError, match="3 poles given but the Beard–Jones filter assigns 4: 3 for the detection"):
        fault_detection_filter(m, [-2, -3, -4], faults=["act1", "leak3"])
    with pytest.raises(DesignError, match="detection spaces alone need 3"):
        fault_detection_filter(m, [-2, -3], faults=["act1", "leak3"])
    with pytest.raises(DesignError, match="must be finite"):
        fault_detection_filter(m, [-2, -3, np.nan, -5], faults=["act1", "leak3"])
    with pytest.raises(DesignError, match="are not stable"):
        fault_detection_filter(m, [-2, -3, -4, 5], faults=["act1", "leak3"])
    with pytest.raises(DesignError, match="poles of the detection space of fault 'act1'"):
        fault_detection_filter(m, [-2 + 1j, -2 - 1j, -4, -5], faults=["act1", "leak3"])


# ============================================================================ factorised form
def _grid_identity_error(M: LTI, Nf: LTI) -> float:
    w = np.logspace(-3, 3, 121) if not M.dt else np.linspace(0, np.pi / M.dt, 121)
    Mv, Nv = M.freqresp(w), Nf.freqresp(w)
    S = np.einsum("kij,klj->kil", Mv, Mv.conj()) + np.einsum("kij,klj->kil", Nv, Nv.conj())
    return float(np.abs(S - np.eye(M.p)).max())


@pytest.mark.parametrize("discrete", [False, True])
def test_normalized_coprime_factorization(discrete):
    # Ex 5.4 is unstable (poles 2, 3): 30 samples (3 s) keep y below e^9 and rounding meaningful
    for m, steps in ((plant(discrete), N), (pub.ex5_4().discretize(TS) if discrete else pub.ex5_4(), 30)):
        M, Nf = left_coprime_factors(m, normalized=True)
        assert M.is_stable() and Nf.is_stable()
        # M M~ + N N~ = I on the stability boundary: an identity of O(1) rational functions
        # evaluated by O(n^3) solves, so rounding is ~1e-13; the Riccati solution's own
        # error enters too, hence RICCATI
        assert _grid_identity_error(M, Nf) < RICCATI
        # Gu = M⁻¹ N, i.e. M Gu − N = 0 (the internal form's Ru)
        gen = factorized(m, normalized=True)
        assert Ru_norm(gen) < DECOUPLED
        assert_silent(gen, steps=steps)
        assert_detection_claims(gen, steps=steps)


@pytest.mark.parametrize("discrete", [False, True])
def test_factorized_with_post_filters(discrete):
    m = plant(discrete)
    poles = cpoles(m, [-2, -3, -4, -5])
    Rc = ct.ss(ct.tf([[[3.0], [0.0], [0.0]]], [[[1.0, 3.0], [1.0], [1.0]]]))  # 3/(s+3) on y1
    R = ct.c2d(Rc, TS) if discrete else Rc
    for post, extra in ((None, []), (R, cpoles(m, [-3])), (np.array([[1.0, -1.0, 0.5]]), [])):
        gen = factorized(m, poles, post_filter=post)
        assert_poles(gen, np.concatenate([poles, extra]))
        assert Ru_norm(gen) < DECOUPLED
        assert_silent(gen)
        assert_detection_claims(gen)
    # the observer form is Luenberger's residual: the same filter for a static post-filter
    V = np.array([[1.0, -1.0, 0.5]])
    a = factorized(m, poles, post_filter=V).Q
    b = luenberger(m, poles, V=V).Q
    w = [0.0, 0.3, 2.0]
    assert np.allclose(a.freqresp(w), b.freqresp(w), atol=SAME)  # same gain, same arithmetic
    # a python-control filter with an unspecified time base takes the model's
    if discrete:
        gen = factorized(m, poles, post_filter=ct.ss(0.5, [[1.0, 0, 0]], 1.0, 0.0, True))
        assert gen.dt == m.dt and gen.Q.n == 5


def test_factorized_errors():
    m = plant()
    cases = [
        (dict(poles=[-1, -2, -3, -4], normalized=True), "poles cannot be given with normalized=True"),
        (dict(post_filter=np.eye(2)), "post_filter must be kx3"),
        (dict(post_filter=LTI([[1.0]], [[1.0, 0, 0]], [[1.0]], [[0.0, 0, 0]])), "post_filter must be stable"),
        (dict(post_filter=LTI.static(np.eye(2))), "post_filter must have 3 inputs"),
        (dict(post_filter=np.zeros((1, 3))), "post_filter is zero"),
        (dict(post_filter=ct.ss(-1.0, [[1.0, 0, 0]], 1.0, 0.0, 0.1)), "post_filter is discrete with dt=0.1 but the model is continuous"),
        (dict(normalized="yes"), "normalized must be True or False"),
        (dict(poles=[-1, -2, -3, np.inf]), "must be finite"),
    ]
    for kw, msg in cases:
        with pytest.raises(DesignError) as err:
            factorized(m, **kw)
        assert msg in str(err.value), (kw, str(err.value))
    bad = FDIModel.from_matrices([[1.0, 0], [0, -1]], [[1.0], [1]], [[0.0, 1]])
    for normalized in (False, True):
        with pytest.raises(DesignError, match="not detectable|no stabilising solution"):
            factorized(bad, normalized=normalized)
