"""Automatic experiment design and validation against the noise floor (issue 18).

``fmu-fdi model`` with default experiment options on the shipped plant FMUs, their noise on;
the model judged against the noise floor and its frequency response against the plant's own
linear model file within a tolerance derived from the noise level (Ljung's asymptotic
variance). The noise-floor and residual tests are checked on synthetic data first.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from fmu_fdi import FDIModel
from fmu_fdi.identify import model_from_fmu
from fmu_fdi.cli import main
from fmu_fdi.identify.validation import noise_floor, residual_tests

# ---- the noise floor and Ljung's residual tests on synthetic data ---------------------------------


def test_noise_floor_measures_the_fit_to_the_noise_free_response():
    rng = np.random.default_rng(1)
    N = 20000
    s = np.cumsum(rng.standard_normal((N, 2)), axis=0) * 0.02
    s -= s.mean(axis=0)
    sig = s.std(axis=0)
    v1, v2 = (rng.standard_normal((N, 2)) * sig for _ in range(2))      # signal/noise 1
    y, y_rep = s + v1, s + v2
    exact = noise_floor(y, s, y_rep)
    # a model equal to the noise-free response: its error is the noise alone. ||e||² − ||v||² has the
    # std of ||v1||² − (||v1 − v2||²)/2 = (||v1||² − ||v2||²)/2 + v1·v2, about sqrt(N) σ² · 1.2: relative to
    # ||s||² = N σ², 1.2/sqrt(N) = 0.0085; the fit's shortfall is its square root, ≤ 100·sqrt(5·0.0085) = 20 %
    assert np.all(exact.fit_noise_free > 80.0), exact.fit_noise_free
    # the plain fit is capped by the noise: 100 (1 − ||v|| / ||y − ȳ||) = 100 (1 − 1/√2) ≈ 29 %
    assert np.allclose(exact.floor, 100 * (1 - 1 / np.sqrt(2)), atol=2.0)
    # a model with 10 % gain error: fit to the noise-free response 90 %, ± the same 5 σ of the noise terms
    # ((0.1² + 5·0.0085)^½ = 0.23 at worst: ≥ 77 %) — and never above 100 %
    off = noise_floor(y, 0.9 * s, y_rep)
    assert np.all((off.fit_noise_free > 77.0) & (off.fit_noise_free <= 100.0)), off.fit_noise_free
    assert np.all(off.fit_noise_free < exact.fit_noise_free + 1e-9)
    # deterministic noise (the repeat is identical): the settle-phase std stands in
    same = noise_floor(y, s, y, sigma_settle=sig)
    assert same.source == "settle" and np.allclose(same.noise_rms, sig)


def test_residual_tests_tell_white_independent_errors_from_dynamics_left_in_them():
    rng = np.random.default_rng(2)
    N = 5000
    u = np.repeat(rng.choice([-1.0, 1.0], size=(N // 5 + 1, 2)), 5, axis=0)[:N]   # PRBS-like, coloured
    e = rng.standard_normal((N, 2))
    ok = residual_tests(e, e, u)
    assert ok.white and ok.independent, (ok.whiteness, ok.independence)
    # unmodelled dynamics: the error holds a filtered copy of the past input
    from scipy.signal import lfilter

    dyn = e + np.column_stack([lfilter([0, 0.3], [1, -0.8], u[:, 0]), np.zeros(N)])
    bad = residual_tests(None, dyn, u)
    assert not bad.independent and bad.independence[0] > 1 >= bad.independence[1]
    # coloured innovations (a noise model missing): AR(1) with coefficient 0.5, r(1) = 0.5 ≫ 2.6/√N
    ar = lfilter([1], [1, -0.5], e, axis=0)
    assert not residual_tests(ar, e, u).white


# ---- the shipped plant FMUs, default options, noise on ----------------------------------------------

@pytest.fixture(scope="module")
def plants(tmp_path_factory):
    import plant_fmus

    out = tmp_path_factory.mktemp("plants")
    return {name: plant_fmus.build(name, out) for name in plant_fmus.PLANTS}


# plant FMU, model file index, u, y, d, excite, FMU noise std per output (sensor noise; None: measured)
CASES = {
    "dts200": ("dts200", 0, ["Q1", "Q2"], ["h1", "h2", "h3"], [], None),
    "lateral_aircraft": ("lateral_aircraft", 0, ["u1", "u2"], ["beta", "phi", "p", "r"], [], None),
    "vtol": ("vtol", 0, ["collective", "cyclic"], ["vh", "vv", "q", "y4"], [], ["ref_collective", "ref_cyclic"]),
    "dr300": ("dr300", 0, ["voltage"], ["speed"], ["load_torque"], ["speed_ref", "load_torque"]),
    "wind_pitch": ("wind_turbine", 0, ["beta_ref_1", "beta_ref_2", "beta_ref_3"],
                   ["beta_1_m1", "beta_1_m2", "beta_2_m1", "beta_2_m2", "beta_3_m1", "beta_3_m2"], [], None),
    # a stiff plant: time scales 1/50 s (converter), a torsional mode at 28 rad/s and 138 s (the rotor)
    "wind_drive_train": ("wind_turbine", 1, ["tau_g_ref"],
                         ["omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2", "tau_g_m"], ["tau_r"], None),
}


def _noise_spectrum(plant, y, ts, w):
    """Two-sided noise spectrum per sample Φ_v,j(ω) of the unexcited plant at its operating point, from a
    plain co-simulation at the identification's ts (not the identification code): Welch's estimate
    (one-sided density per Hz × fs/2), at the frequencies w (rad/s; below its first bin, the first bin)."""
    from scipy.signal import welch

    from fmu_fdi.cosim import CoSimulation

    res = CoSimulation({"plant": plant}, None, None, step=ts, stop=4500 * ts, parameters={"plant.seed": 7}).run()
    out = []
    for n in y:
        f, pxx = welch(np.asarray(res[f"plant.{n}"], float)[500:], fs=1 / ts, nperseg=512)
        out.append(np.interp(w / (2 * np.pi), f[1:], pxx[1:]) / (2 * ts))
    return np.array(out)                      # p × len(w)


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_default_model_of_a_noisy_plant_fmu(plants, case, tmp_path, capsys):
    import plant_fmus

    fmu, index, u, y, d, excite = CASES[case]
    out, log = tmp_path / "m.toml", tmp_path / "log.csv"
    args = ["model", str(plants[fmu]), "--inputs", *u, "--outputs", *y, "--sensor-faults", "all", "-o", str(out),
            "--record", str(log)]
    if d:
        args += ["--disturbances", *d]
    if excite:
        args += ["--excite", *excite]
    clock = time.perf_counter()
    assert main(args) == 0
    wall = time.perf_counter() - clock
    text = capsys.readouterr().out
    assert "experiment (chosen:" in text and "noise std at the operating point" in text
    m = FDIModel.from_file(out)
    ref = FDIModel.from_file(plant_fmus.model_path(fmu, index))
    prov = m.provenance
    assert m.n == ref.n
    if not excite:
        # the pre-test's time scales cover the slowest mode (the plant's own, 1/min |Re λ|), to the factor 2 the
        # design allows its estimate (module docstring of fmu_fdi/identify/design.py); the drive train's 138 s
        # mode is 12 times its first pre-test's length
        tau_max = float(text.split("pre-test: time scales ")[1].split(" .. ")[1].split(" s")[0])
        tau_ref = 1.0 / np.min(np.abs(np.linalg.eigvals(ref.A).real))
        assert 0.5 <= tau_max / tau_ref <= 2.0, (case, tau_max, tau_ref)
    # judged against the noise floor: within 50 % of the noise-free response on every output, and the
    # noise model (innovation form) on by default
    assert min(prov["fit_corrected_percent"]) >= 50 and prov["noise_model"] == "innovation"
    # the frequency response over the excited band: from 10 cycles per record (the asymptotic variance
    # below needs several; and the spectra's resolution, 1024 samples) to the PRBS clock's −3 dB point
    # 0.44/(P ts) Hz. A stiff plant's model (refined by output error: its slow mode is what the refinement
    # is for) is judged down to the resolution of a quarter record (drive train: 0.1 rad/s, against 0.4),
    # and on every recorded input, u and d (the rotor torque is the input its diagnosis decouples)
    ts, N = prov["sample_time"], prov["samples"]
    P = int(prov["excitation"].split("clock ")[1].split(",")[0])
    refined = "output-error" in prov["method"]
    seg = N // 4 if refined else min(1024, N // 4)
    w = np.geomspace(2 * np.pi * max(10 / (N * ts), 2 / (seg * ts)), 2 * np.pi * 0.44 / (P * ts), 40)
    signals = ("u", "d") if refined else ("u",)
    inputs = u + d if refined else u
    Gi, Gr = m.lti(*signals).freqresp(w), ref.lti(*signals).freqresp(w)      # (len(w), p, m)
    # Ljung 1999, eq. 9.62: Var Ĝ(ω) ≈ (n/N) Φ_v(ω) Φ_u(ω)⁻¹ (per sample). Its matrix form bounds the
    # Frobenius error: E||ΔG||² ≈ (n/N) tr Φ_v · tr Φ_u⁻¹. Φ_u from the estimation run's own inputs
    # (--record; Welch, so a plant in its own loop is judged on the inputs it really had), Φ_v from the
    # unexcited plant (white sensor noise and the lateral aircraft's coloured process noise alike); the
    # error may reach 5 standard deviations. Relative to max |G| the result is also printed.
    import csv

    with open(log) as fh:
        rows = list(csv.DictReader(fh))
    from scipy.signal import csd

    uu = np.array([[float(r[n]) for n in inputs] for r in rows])
    uu -= uu.mean(axis=0)
    phi_u = np.empty((len(w), len(inputs), len(inputs)), complex)
    for i in range(len(inputs)):
        for k in range(len(inputs)):
            f, pxy = csd(uu[:, i], uu[:, k], fs=1 / ts, nperseg=seg)
            phi_u[:, i, k] = (np.interp(w / (2 * np.pi), f[1:], pxy[1:].real)
                              + 1j * np.interp(w / (2 * np.pi), f[1:], pxy[1:].imag)) / (2 * ts)
    tr_inv = np.array([np.trace(np.linalg.inv(phi)).real for phi in phi_u])
    phi_v = _noise_spectrum(plants[fmu], y, ts, w).sum(axis=0)              # tr Φ_v per frequency
    sd = np.sqrt(ref.n / N * phi_v * tr_inv)
    err = np.linalg.norm(Gi - Gr, axis=(1, 2))
    bias = 0.0
    if case == "dts200":
        # Torricelli: the linear coefficient ∝ 1/sqrt(Δh) changes by δh/(2Δh) for an excursion δh of the
        # smallest head, h1 − h3 = 4.4 cm; δh: its rms excursion in the record (the best linear model
        # averages the slope over the excursions), the sensor noise (0.1 cm on each level) removed
        yy = np.array([[float(r[n]) for n in y] for r in rows])
        dh = np.sqrt(max(float(np.var(yy[:, 0] - yy[:, 2])) - 2 * 0.1 ** 2, 0.0))
        bias = np.linalg.norm(Gr, axis=(1, 2)) * dh / 8.8
    z = (err - bias) / sd
    rel = np.abs(Gi - Gr).max() / np.abs(Gr).max()
    print(f"{case}: wall {wall:.1f} s, FR error {rel:.3g} of max |G| ({z.max():.3g} noise standard deviations), "
          f"fit {np.round(prov['fit_percent'], 1)}, noise-free {np.round(prov['fit_corrected_percent'], 1)}, floor "
          f"{np.round(prov['floor_percent'], 1)}, {prov['excitation']}, ts {ts}, N {N}")
    if excite:
        # a plant in its own loop, identified from its references (joint input-output method): the joint
        # model's error is of the noise-to-response ratio ||v||/||y − ȳ|| = 1 − floor/100 (relative to |G|),
        # and the inversion for the plant can amplify it: 3 times that, on every channel (u and d)
        tol = 3 * (1 - min(prov["floor_percent"]) / 100)
        assert rel <= tol, (case, rel, prov["floor_percent"])
        assert "joint input-output" in prov["method"]
        if d:
            Gd_i, Gd_r = m.lti("d").freqresp(w), ref.lti("d").freqresp(w)
            assert np.abs(Gd_i - Gd_r).max() / np.abs(Gd_r).max() <= tol
    else:
        # PO-MOESP is not minimum-variance: its variance exceeds the prediction-error method's asymptotic
        # one (eq. 9.62) by factors up to about 10 (Bauer & Ljung 2002, Automatica 38(5)): 5 × 10 std.
        # The output-error refinement is a prediction-error estimate, but eq. 9.62 is asymptotic in the
        # order (Ljung 1999, sec. 9.4): a low-order model's parameter shared by all frequencies (the drive
        # train's converter gain, set by the fast band) carries its error to where the local Φ_u is larger
        # (the slow PRBS's band, 0.1 rad/s: 11 std there, 0.2 std above 1 rad/s): the same factor 10
        assert z.max() <= 50.0, (case, z.max(), rel, z)


def test_joint_input_output_method_recovers_a_plant_under_noisy_feedback():
    """A plant under a PI controller with sensor noise fed back (numpy, not an FMU): identified from
    the reference, the plant's frequency response is right; the controller's output read one sample
    late, as from a co-simulation record (delay 1), and an integrating disturbance channel."""
    from scipy.signal import max_len_seq

    from fmu_fdi.identify.closed_loop import identify_closed_loop

    dt, N = 0.1, 4000
    A = np.array([[0.9, 0.2], [0.0, 0.7]])            # plant: u, d → y; poles 0.9, 0.7
    B = np.array([[0.0, 0.1], [0.5, 0.0]])
    C = np.array([[1.0, 0.0]])
    Kp, Ki = 0.8, 0.2

    def run(seed):
        rng = np.random.default_rng(seed)
        seq = np.roll(max_len_seq(12)[0] * 2.0 - 1, 97 * seed)
        r = np.column_stack([np.repeat(seq, 3)[:N], 0.3 * np.resize(seq[::-1], N)])  # reference, disturbance
        x, xi, u, y = np.zeros(2), 0.0, np.zeros((N, 2)), np.zeros((N, 1))
        for k in range(N):
            y[k] = C @ x + 0.05 * rng.standard_normal()
            e = (r[k - 1, 0] if k else 0.0) - y[k, 0]
            u[k] = [Kp * e + xi, r[k, 1]]
            xi += Ki * e
            x = A @ x + B @ u[k]
        return r, u, y

    (r, u, y), (rv, uv, yv) = run(1), run(2)
    plant, joint = identify_closed_loop(r, u, y, rv, uv, yv, dt, [None, 1])
    # closed loop: plant 2 + PI 1 + the reference's one-sample delay 1; the inversion's mode at 0 is removed
    # (the PI's state, unobservable from y only up to the noise, may stay as a near-cancelled pole/zero pair)
    assert joint.order == 4 and 2 <= plant.order <= 3 and plant.info["delays"] == [1, 0]
    z = np.exp(1j * np.linspace(0.01, 3.0, 50))
    G = np.array([C @ np.linalg.solve(zk * np.eye(2) - A, B) for zk in z])
    Gi = np.array([plant.C @ np.linalg.solve(zk * np.eye(plant.order) - plant.A, plant.B) for zk in z])
    # Ljung 1999 eq. 9.62: relative std ≈ sqrt(n/N) σ_v / σ_u ≈ sqrt(3/4000) · 0.05 / 0.5 ≈ 0.003 where
    # |G| is smallest; 10 standard deviations
    assert np.abs(Gi - G).max() / np.abs(G).max() < 0.03


def test_the_designed_experiment_does_not_depend_on_the_machines_speed(tmp_path, monkeypatch):
    """The plan (and so the model) is a function of the FMU and the options only: the same DTS200 FMU (noise
    on, its noise seed fixed) planned once on this machine's clock and once on a clock that runs 1000 times
    faster than real time (as if the machine were 1000 times slower: every co-simulation then takes 1000 times
    longer in the time the tool sees) gives the same sample time, record, settle, signal and amplitudes."""
    import plant_fmus
    from fmu_fdi.identify import Excitation
    from fmu_fdi.identify.design import plan_experiment

    fmu = plant_fmus.build("dts200", tmp_path)

    def plan():
        return plan_experiment(fmu, ["Q1", "Q2"], ["h1", "h2", "h3"], excite=None, at={}, parameters={"seed": 3},
                               ts=None, step=plant_fmus.PLANTS["dts200"].step, excitation=Excitation())

    fast = plan()
    real, start = time.perf_counter, time.perf_counter()
    monkeypatch.setattr(time, "perf_counter", lambda: start + 1000.0 * (real() - start))
    slow = plan()
    assert slow.steps_per_second < fast.steps_per_second / 100       # the slow clock did reach the experiment
    assert (slow.ts, slow.excitation, slow.tau, slow.noise_std) == (fast.ts, fast.excitation, fast.tau, fast.noise_std)


def test_designed_settle_lasts_until_the_start_transient_is_below_a_tenth_of_the_noise():
    """The settle rule on a synthetic pre-test: a start transient a·e^{−t/τ} (a = 10, τ = 50 s) seen for 200 s
    of 1 s samples with white noise of std 0.1: after the designed settle T the transient left, a·e^{−T/τ}
    (the exact decay, not the rule's estimate of it), is at most a tenth of the noise, and T ≤ 10 τ; with
    no transient (noise only) the settle stays at its 200-sample minimum; on a very slow plant the 10 τ
    and MAX_SETTLE-sample caps hold (a transient of 1e3 would need τ ln(1e3 / 7e-4) = 14 τ)."""
    from types import SimpleNamespace

    from fmu_fdi.identify.design import MAX_SETTLE, MIN_SETTLE, SETTLE_TAUS, _steady_settle

    rng = np.random.default_rng(5)
    t = np.arange(1, 201, dtype=float)
    a, tau, sigma = 10.0, 50.0, 0.1
    noise = sigma * rng.standard_normal((200, 1))
    dy = np.sin(np.arange(1000.0))[:, None]  # response std 0.7: its thousandth is below σ/10 here
    T = _steady_settle(SimpleNamespace(settle_y=a * np.exp(-t / tau)[:, None] + noise), [sigma], dy, tau, 1.0, 1.0)
    assert a * np.exp(-T / tau) <= sigma / 10 and T <= SETTLE_TAUS * tau, T
    # and not needlessly longer than the exact need: the rule bounds the transient by its peak-to-peak plus 6 σ,
    # noise included (at most 12 σ more: τ ln(1 + 12σ/a) = 5.7 s longer), over 1 − e^{−4} of its decay (τ · 0.02
    # = 1 s) and rounds up to a sample (1 s): 8 s
    assert T <= tau * np.log(a / (sigma / 10)) + 8.0, T
    quiet = _steady_settle(SimpleNamespace(settle_y=noise), [sigma], dy, tau, 1.0, 1.0)
    assert quiet == MIN_SETTLE * 1.0
    slow = _steady_settle(SimpleNamespace(settle_y=1e3 * np.exp(-t / 1e4)[:, None]), [0.0], dy, 1e4, 1.0, 10.0)
    assert slow == SETTLE_TAUS * 1e4                                   # (10⁴ samples of 10 s)
    at_1s = _steady_settle(SimpleNamespace(settle_y=1e3 * np.exp(-t / 1e4)[:, None]), [0.0], dy, 1e4, 1.0, 1.0)
    assert at_1s == MAX_SETTLE * 1.0                                   # and at most MAX_SETTLE samples


# ---- a stiff plant: the two-scale PRBS and the output-error refinement (synthetic) -------------------

def _zoh(A, B, ts):
    """Exact zero-order-hold sampling (expm of the augmented matrix), independent of the code under test."""
    import scipy.linalg as sla

    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A * ts, B * ts
    E = sla.expm(M)
    return E[:n, :n], E[:n, n:]


def _simulate(Ad, Bd, C, u):
    x, y = np.zeros(Ad.shape[0]), np.empty((len(u), C.shape[0]))
    for k in range(len(u)):
        y[k] = C @ x
        x = Ad @ x + Bd @ u[k]
    return y


def test_two_scale_prbs_keeps_its_peak_and_puts_power_below_the_slow_corner():
    from fmu_fdi.identify.experiment import Excitation, excitation_signals

    N, slow = 8000, 500
    one = excitation_signals(Excitation("prbs", None, N, None, 0.5, 1, 3), ["a", "b"], [2.0, 1.0])
    two = excitation_signals(Excitation("prbs", None, N, None, 0.5, 1, 3, slow_period=slow), ["a", "b"], [2.0, 1.0])
    # half of each sequence: values −a, 0, a, peak a
    assert np.allclose(np.abs(two).max(axis=0), [2.0, 1.0])
    assert set(np.unique(np.round(two[:, 1], 12))) <= {-1.0, 0.0, 1.0}
    # power below 1/(slow·step) (a slow corner): the single fast PRBS spreads a² over the whole band, so the
    # fraction below is ≈ 2/slow; the slow half puts (a/2)² there, ≥ a quarter of its total a²/2
    def low(x):
        X = np.abs(np.fft.rfft(x - x.mean(axis=0), axis=0)) ** 2
        return X[: N // slow].sum(axis=0) / X.sum(axis=0)
    assert np.all(low(one) < 10 / slow) and np.all(low(two) > 0.25)


def test_output_error_refinement_resolves_a_stiff_plant():
    """A 100 s mode beside a lightly damped 20 rad/s one (ratio 2000), sampled at 0.05 s: PO-MOESP's window of
    four samples misplaces the slow pole; the output-error refinement over the record recovers the plant to
    what the noise allows, judged on a fresh input against the exact sampling of the true plant."""
    from fmu_fdi.identify.experiment import Excitation, excitation_signals
    from fmu_fdi.identify.output_error import refine_output_error
    from fmu_fdi.identify.subspace import moesp

    A = np.array([[-0.01, 0.0, 0.0], [0.0, -0.2, 20.0], [0.0, -20.0, -0.2]])
    B = np.array([[1.0, 0.5], [0.0, 1.0], [1.0, -1.0]])
    C = np.array([[1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.0, 0.3, 1.0]])
    ts, N = 0.05, 8000
    Ad, Bd = _zoh(A, B, ts)
    u = excitation_signals(Excitation("prbs", None, N, None, 0.5, 1, 3, slow_period=500), ["a", "b"], [1.0, 1.0])
    y0 = _simulate(Ad, Bd, C, u)
    sigma = 0.1 * y0.std(axis=0)                                       # signal/noise 10 on every output
    y = y0 + np.random.default_rng(5).standard_normal(y0.shape) * sigma
    sub = moesp(u, y, ts, 3, feedthrough=False)
    ref, info = refine_output_error(sub, u, y, sigma)
    assert info["cost_after"] < info["cost_before"]
    uv = excitation_signals(Excitation("prbs", None, N, None, 0.5, 1, 4, slow_period=500), ["a", "b"], [1.0, 1.0])
    yv = _simulate(Ad, Bd, C, uv)

    def error(model):  # Σ_j mean((ŷ_j − y_j)² / σ_j²) on the fresh noise-free response
        return float(np.sum(np.mean((_simulate(model.A, model.B, model.C, uv) - yv) ** 2, axis=0) / sigma ** 2))
    # Ljung 1999, sec. 16.4: the weighted model error of a prediction-error estimate with d free parameters is
    # ≈ χ²_d / N (mean d/N); d = 5 (slow mode: log-rate, one free input coefficient, three output ones) + 10
    # (the pair) = 15; 5 × the mean is beyond the χ²_15 tail at 1e-15
    d = 15
    assert error(ref) <= 5 * d / N, (error(ref), d / N)
    assert error(sub) > 100 * error(ref)                               # the refinement is what resolves it


def test_plant_child_starts_with_one_blas_thread_unless_the_user_chose(monkeypatch):
    """The child's OpenBLAS reads its thread count when it loads: set around the start only, never over the
    user's own setting."""
    import os

    from fmu_fdi.identify.plant_child import _BLAS_THREADS, _one_blas_thread

    for k in _BLAS_THREADS:
        monkeypatch.delenv(k, raising=False)
    with _one_blas_thread():
        assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
    assert "OPENBLAS_NUM_THREADS" not in os.environ
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    with _one_blas_thread():
        assert "OPENBLAS_NUM_THREADS" not in os.environ and os.environ["OMP_NUM_THREADS"] == "2"
