"""identify/noise.py: noise models of identified models (innovation form, measurement noise)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import FDIModel
from fmu_fdi.identify import model_from_fmu
from fmu_fdi.identify import IdentificationError, moesp
from fmu_fdi.identify.noise import innovation_noise, measurement_noise, predictor_innovations

# a 2-state, 1-input, 2-output plant (poles 0.85 ± 0.13j) with process and measurement noise
A = np.array([[0.9, 0.2], [-0.1, 0.8]])
B = np.array([[1.0], [0.5]])
C = np.eye(2)
QP = np.diag([0.02, 0.01])   # process noise covariance
RM = np.diag([0.01, 0.04])   # measurement noise covariance
N = 20000


def _true_innovation():
    """Re and K of the true model's steady-state Kalman predictor (DARE)."""
    P = sla.solve_discrete_are(A.T, C.T, QP, RM)
    Re = C @ P @ C.T + RM
    return Re, A @ P @ C.T @ np.linalg.inv(Re)


def _record(seed, n=N):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 1))
    w = rng.standard_normal((n, 2)) @ np.sqrt(QP)
    v = rng.standard_normal((n, 2)) @ np.sqrt(RM)
    x, y = np.zeros(2), np.empty((n, 2))
    for k in range(n):
        y[k] = C @ x + v[k]
        x = A @ x + B @ u[k] + w[k]
    return u, y


@pytest.fixture(scope="module")
def identified():
    u, y = _record(1)
    uv, yv = _record(2)
    sub = moesp(u, y, 1.0, order=2, feedthrough=False)
    return sub, u, y, uv, yv, innovation_noise(sub, u, y, uv, yv)


def _wishart_bound(S, n):
    """4 standard errors of each entry of a sample covariance of n samples: var S_ij = (S_ij² + S_ii S_jj)/n."""
    d = np.diag(S)
    return 4 * np.sqrt((S ** 2 + np.outer(d, d)) / n)


def test_innovation_covariance_matches_the_true_kalman_filter(identified):
    sub, u, y, uv, yv, nm = identified
    Re, K = _true_innovation()
    assert nm.kind == "innovation" and nm.run == "estimation"
    # Re is a sample covariance of ~N innovations (Wishart); the model error adds O(1/N) on top
    assert np.all(np.abs(nm.covariance - Re) <= _wishart_bound(Re, nm.samples)), (nm.covariance, Re)
    assert np.all(np.abs(nm.validation_covariance - Re) <= _wishart_bound(Re, N)), (nm.validation_covariance, Re)
    assert np.allclose(nm.Dw @ nm.Dw.T, nm.covariance, rtol=1e-12, atol=1e-15)
    assert np.allclose(nm.Bw, nm.K @ nm.Dw, rtol=1e-12, atol=1e-15)
    # the gain is basis dependent; its Markov parameters C A^i K are not. Their error is that of the
    # regression of N samples on a state of SNR ~ 1: relative ~ few/sqrt(N) ≈ 3 %; 10 % bounds it
    for i in range(4):
        true = C @ np.linalg.matrix_power(A, i) @ K
        got = sub.C @ np.linalg.matrix_power(sub.A, i) @ nm.K
        assert np.abs(got - true).max() <= 0.1 * np.abs(true).max(), (i, got, true)
    assert np.all(np.abs(np.linalg.eigvals(sub.A - nm.K @ sub.C)) < 1)  # the stabilising (Riccati) gain


def test_kalman_on_the_identified_model_whitens_fresh_data(identified):
    from fmu_fdi.design import kalman

    sub, *_ , nm = identified
    model = FDIModel(sub.A, sub.B, sub.C, sub.D, Bw=nm.Bw, Dw=nm.Dw, dt=1.0)
    gen = kalman(model, Qw=1.0, Rv=0.0)  # w unit white is the whole noise model
    u, y = _record(3)
    r = gen.simulate(y, u)[200:] @ np.asarray(gen.info["whitening"]).T
    S = np.cov(r, rowvar=False)
    # whitened innovations: covariance I up to 4 standard errors (sqrt(2/N) diagonal, sqrt(1/N) off) plus
    # the model's misfit of Re, itself within the same 4 SE (test above): 8 SE in all
    assert np.all(np.abs(S - np.eye(2)) <= 2 * _wishart_bound(np.eye(2), len(r))), S
    # and white: the lag-1 autocorrelation of each channel within 4/sqrt(N)
    for j in range(2):
        rho = np.corrcoef(r[1:, j], r[:-1, j])[0, 1]
        assert abs(rho) <= 4 / np.sqrt(len(r)), (j, rho)


def test_measurement_noise_from_the_validation_error():
    # no process noise: the output error on the validation run is the sensor noise itself
    rng = np.random.default_rng(5)
    sub = moesp(*_noise_free(rng, 4000), 1.0, order=2, feedthrough=False)
    u, y = _noise_free(rng, 4000)
    y = y + rng.standard_normal(y.shape) @ np.sqrt(RM)
    nm = measurement_noise(sub, y, sub.simulate(u))
    assert nm.run == "validation (simulation)" and not nm.Bw.any()
    assert np.all(np.abs(nm.covariance - RM) <= _wishart_bound(RM, 4000)), nm.covariance
    assert np.allclose(nm.Dw @ nm.Dw.T, nm.covariance)


def _noise_free(rng, n):
    u = rng.standard_normal((n, 1))
    x, y = np.zeros(2), np.empty((n, 2))
    for k in range(n):
        y[k] = C @ x
        x = A @ x + B @ u[k]
    return u, y


def test_noise_free_output_is_refused():
    rng = np.random.default_rng(6)
    u, y = _noise_free(rng, 3000)
    sub = moesp(u, y, 1.0, order=2, feedthrough=False)
    with pytest.raises(IdentificationError, match="not positive definite.*noise-free"):
        measurement_noise(sub, y, sub.simulate(u))


def test_too_little_data_for_the_noise_model(identified):
    sub, u, y, *_ = identified
    with pytest.raises(IdentificationError, match="too little data for the noise model: 100 samples"):
        innovation_noise(sub, u[:100], y[:100])


def test_predictor_innovations_of_the_true_model_have_its_covariance():
    Re, K = _true_innovation()

    class True_:
        pass

    t = True_()
    t.A, t.B, t.C, t.D = A, B, C, np.zeros((2, 1))
    u, y = _record(4)
    e = predictor_innovations(t, K, u, y, drop=100)
    assert np.all(np.abs(np.cov(e, rowvar=False) - Re) <= _wishart_bound(Re, len(e)))


# ---- through the plant FMU and the model file ----------------------------------------------------

@pytest.fixture(scope="module")
def dts200(tmp_path_factory):
    import shutil

    if shutil.which("gcc") is None:
        pytest.skip("needs gcc to build the plant FMU")
    import plant_fmus

    return plant_fmus.build("dts200", tmp_path_factory.mktemp("plant"))


# PRBS of period 20 steps: the slow mode (τ ≈ 520 s) is excited above the 0.1 cm sensor noise
_EXPERIMENT = ["--inputs", "Q1", "Q2", "--outputs", "h1", "h2", "h3", "--signal", "prbs", "--period", "20",
               "--amplitude", "Q1=3", "Q2=5", "--samples", "3000", "--settle", "40", "--order", "3",
               "--sensor-faults", "all"]


def test_cli_model_noise_round_trip_and_default_unchanged(dts200, tmp_path, capsys):
    from fmu_fdi.cli import main

    files = {}
    for noise in (None, "innovation", "measurement"):
        files[noise] = tmp_path / f"{noise}.toml"
        assert main(["model", str(dts200), *_EXPERIMENT, "-o", str(files[noise])]
                    + ["--noise", noise or "none"]) == 0
    plain = FDIModel.from_file(files[None])
    assert plain.nw == 0 and not any(k.startswith("noise") for k in plain.provenance)
    n, p, ts = plain.n, plain.ny, plain.provenance["sample_time"]
    sigma2 = 0.1 ** 2  # the FMU's sensor noise variance (plant_fmus/dts200: NOISE_STD = 0.1 cm, white)
    cov = {}
    for noise in ("innovation", "measurement"):
        m = FDIModel.from_file(files[noise])
        assert m.w_names == ["w_h1", "w_h2", "w_h3"] and m.provenance["noise_model"] == noise
        assert m.provenance["noise_run"] == ("estimation" if noise == "innovation" else "validation (simulation)")
        cov[noise] = np.reshape(m.provenance["noise_covariance"], (p, p))
        assert np.allclose(m.Dw @ m.Dw.T, cov[noise], rtol=1e-9)
        # the option adds w and its provenance and changes nothing else, to the byte
        d = m.to_dict()
        d["signals"].pop("w")
        d["matrices"].pop("Bw", None), d["matrices"].pop("Dw")
        d["provenance"] = {k: v for k, v in d["provenance"].items() if not k.startswith("noise")}
        assert FDIModel.from_dict(d).to_file(tmp_path / "stripped.toml").read_bytes() == files[None].read_bytes()
        if noise == "innovation":
            # the continuous Bw is the inverse ZOH of K Lₑ: sampled at ts it is the innovation form again
            K = np.reshape(m.provenance["noise_gain"], (n, p))
            assert np.allclose(m.discretize(ts).Bw, K @ m.Dw, rtol=1e-8, atol=1e-12 * np.abs(K).max())
            val = np.reshape(m.provenance["noise_covariance_validation"], (p, p))
        else:
            assert not m.Bw.any()
    # the innovations hold at least the sensor noise (Re ≥ R for any predictor; 4 Wishart SE, N = 3000), and
    # the one-step predictor's error is at most the simulation error the measurement model takes as noise
    N = 3000
    assert np.all(np.diag(val) >= sigma2 * (1 - 4 * np.sqrt(2 / N))), np.diag(val)
    assert np.all(np.diag(val) <= np.diag(cov["measurement"])), (np.diag(val), np.diag(cov["measurement"]))
    assert not any(k in files[None].read_text() for k in ("Bw", "Dw", "noise"))


def test_bad_noise_option_is_refused(dts200, tmp_path, capsys):
    from fmu_fdi.cli import main

    with pytest.raises(IdentificationError, match="noise must be one of \\('innovation', 'measurement'\\)"):
        model_from_fmu(dts200, ["Q1"], ["h1"], noise="kalman")
    with pytest.raises(SystemExit):
        main(["model", str(dts200), "--inputs", "Q1", "--outputs", "h1", "--noise", "white", "-o",
              str(tmp_path / "m.toml")])
    err = capsys.readouterr().err
    assert "invalid choice: 'white'" in err and not (tmp_path / "m.toml").exists()


def test_cli_noise_choices_are_the_identifications():
    """cli.py writes the choices out (importing them would load the identification package on
    every CLI call); they must stay the list the identification accepts."""
    from fmu_fdi.cli import build_parser
    from fmu_fdi.identify.noise import NOISE_MODELS

    model_parser = build_parser()._subparsers._group_actions[0].choices["model"]
    noise = next(a for a in model_parser._actions if a.dest == "noise")
    assert tuple(noise.choices) == NOISE_MODELS + ("none",)


def test_noise_needs_identification(tmp_path):
    import shutil

    if shutil.which("gcc") is None:
        pytest.skip("needs gcc")
    from me_fmus import build_me_fmu

    fmu = build_me_fmu(tmp_path, "linear", 2, True)
    with pytest.raises(IdentificationError, match="noise='innovation' needs identification"):
        model_from_fmu(fmu, ["u1"], ["y1"], at={"u1": 1.0, "u2": -1.0}, noise="innovation")
