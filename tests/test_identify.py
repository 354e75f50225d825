"""identify/: linearisation of model-exchange FMUs, black-box identification of the plant FMUs, bad input."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from fmu_fdi import FDIModel
from fmu_fdi.identify import Excitation, IdentificationError, linearise, model_from_fmu

from me_fmus import analytic, build_me_fmu, equilibrium

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc to compile the test FMUs")

U_AT = {"nonlinear": [1.0, 0.5], "linear": [1.0, -1.0]}


@pytest.mark.parametrize("plant,fmi", [("nonlinear", 2), ("linear", 3), ("nonlinear", 3), ("linear", 2)])
@pytest.mark.parametrize("directional", [True, False])
def test_linearise_matches_analytic_jacobian(tmp_path, plant, fmi, directional):
    fmu = build_me_fmu(tmp_path, plant, fmi, directional)
    u = U_AT[plant]
    lin = linearise(fmu, at={"u1": u[0], "u2": u[1]})
    assert lin.method == ("directional derivatives" if directional else "central differences")
    xe = equilibrium(plant, u)
    # trim: Powell's method converges to machine precision on a smooth 2-3 state problem
    assert np.allclose(lin.x0, xe, rtol=1e-9, atol=1e-12)
    f, g, J = analytic(plant, xe, u)
    got = np.block([[lin.A, lin.B], [lin.C, lin.D]])
    # central differences: error ~ eps^(2/3) ≈ 4e-11 relative (module docstring), far inside 1e-6
    assert np.abs(got - J).max() <= 1e-6 * np.abs(J).max()
    assert np.allclose(lin.y0, g, rtol=1e-12, atol=1e-12)
    assert lin.state_names == [f"x{i + 1}" for i in range(len(xe))]


def test_from_fmu_linearised_model_file_round_trip(tmp_path):
    fmu = build_me_fmu(tmp_path, "nonlinear", 2, False)
    m = model_from_fmu(fmu, ["u1"], ["y1", "y2"], ["u2"], at={"u1": 1.0, "u2": 0.5}, sensor_faults="all",
                       actuator_faults=["u1"])
    assert m.u_names == ["u1"] and m.d_names == ["u2"] and m.fault_names == ["sensor_y1", "sensor_y2", "actuator_u1"]
    _, g, J = analytic("nonlinear", equilibrium("nonlinear", [1.0, 0.5]), [1.0, 0.5])
    assert np.allclose(m.Bd, J[:2, 3:], rtol=1e-6) and np.allclose(m.y0, g)
    assert m.provenance["method"] == "linearisation (central differences)" and m.provenance["trimmed"] is True
    path = m.to_file(tmp_path / "m.toml")
    back = FDIModel.from_file(path)
    assert back.provenance == m.provenance and np.array_equal(back.A, m.A)


def test_linearise_at_given_states_without_trim(tmp_path):
    fmu = build_me_fmu(tmp_path, "nonlinear", 2, False)
    x, u = [2.0, 0.7], [1.0, 0.5]
    lin = linearise(fmu, at={"x1": x[0], "x2": x[1], "u1": u[0], "u2": u[1]}, trim=False)
    f, g, J = analytic("nonlinear", x, u)
    assert not lin.trimmed and np.array_equal(lin.x0, x)
    assert lin.derivative_residual == pytest.approx(np.abs(f).max(), rel=1e-12)  # reported, not hidden
    assert np.abs(np.block([[lin.A, lin.B], [lin.C, lin.D]]) - J).max() <= 1e-6 * np.abs(J).max()
    # the point is no equilibrium: a warning names the largest derivative (from the analytic f)
    i = int(np.argmax(np.abs(f[:2])))
    assert f"der({lin.state_names[i]}) = {f[i]:.4g} is the largest derivative" in lin.warning
    # at an equilibrium, untrimmed: no warning
    xe = equilibrium("nonlinear", u)
    quiet = linearise(fmu, at={"x1": xe[0], "x2": xe[1], "u1": u[0], "u2": u[1]}, trim=False)
    assert quiet.warning == ""


def test_trim_without_steady_state_is_a_clear_error(tmp_path):
    fmu = build_me_fmu(tmp_path, "nonlinear", 3, True)
    # x1' = u1 - a sqrt(x1) < 0 for every x1 when u1 < 0: no steady state exists
    with pytest.raises(IdentificationError, match="no steady state found.*max\\|dx/dt\\|"):
        linearise(fmu, at={"u1": -0.5, "u2": 0.5})


def test_missing_variables_are_named(tmp_path):
    fmu = build_me_fmu(tmp_path, "linear", 2, True)
    with pytest.raises(IdentificationError, match="output 'h9' is not a Real output.*y1"):
        linearise(fmu, outputs=["h9"])
    with pytest.raises(IdentificationError, match="input 'u7'"):
        model_from_fmu(fmu, inputs=["u7"])


# ---- co-simulation FMUs: identification ---------------------------------------------------------

def test_too_little_data_for_the_order():
    from fmu_fdi.identify import moesp

    rng = np.random.default_rng(1)
    u = rng.standard_normal((100, 2))
    y = rng.standard_normal((100, 3))
    with pytest.raises(IdentificationError, match="too little data for order 8: 100 samples.*at least 197"):
        moesp(u, y, 1.0, order=8)


@pytest.fixture(scope="module")
def plant_dir(tmp_path_factory):
    import plant_fmus

    out = tmp_path_factory.mktemp("plants")
    return {name: plant_fmus.build(name, out) for name in plant_fmus.PLANTS}


def test_excitation_beyond_the_plants_limits(plant_dir):
    # +60 cm3/s on Q1 held 200 s raises h1 by ~0.0065·60·200 = 78 cm: tank 1 overflows (62 cm)
    with pytest.raises(IdentificationError, match="out of its limits: Boolean output 'overflow'.*lower the amplitude"):
        model_from_fmu(plant_dir["dts200"], ["Q1", "Q2"], ["h1", "h2", "h3"], at={"noise_enable": False},
                       excitation=Excitation("prbs", amplitude={"Q1": 60.0, "Q2": 1.0}, period=200, samples=400,
                                             settle=10))


def test_identification_names_missing_variables(plant_dir):
    with pytest.raises(IdentificationError, match="model input 'Q9' is neither.*'Q1'"):
        model_from_fmu(plant_dir["dts200"], ["Q9"], ["h1"])
    with pytest.raises(IdentificationError, match="output 'level' is not a Real output"):
        model_from_fmu(plant_dir["dts200"], ["Q1"], ["level"])


def test_closed_loop_plant_needs_excitation_named(plant_dir):
    with pytest.raises(IdentificationError, match="FMU outputs.*excite="):
        model_from_fmu(plant_dir["dr300"], ["voltage"], ["speed"], method="identify")


CASES = {  # plant, model file index, u, y, d, excite, amplitudes
    "dts200": ("dts200", 0, ["Q1", "Q2"], ["h1", "h2", "h3"], [], None, None),
    "dr300": ("dr300", 0, ["voltage"], ["speed"], ["load_torque"], ["speed_ref", "load_torque"],
              {"speed_ref": 1.0, "load_torque": 0.1}),
    "vtol": ("vtol", 0, ["collective", "cyclic"], ["vh", "vv", "q", "y4"], [], ["ref_collective", "ref_cyclic"],
             {"ref_collective": 1.0, "ref_cyclic": 1.0}),
    "lateral_aircraft": ("lateral_aircraft", 0, ["u1", "u2"], ["beta", "phi", "p", "r"], [], None,
                         {"u1": 0.01, "u2": 0.01}),
    "wind_pitch": ("wind_turbine", 0, ["beta_ref_1", "beta_ref_2", "beta_ref_3"],
                   ["beta_1_m1", "beta_1_m2", "beta_2_m1", "beta_2_m2", "beta_3_m1", "beta_3_m2"], [], None,
                   {f"beta_ref_{i}": 1.0 for i in (1, 2, 3)}),
    "wind_drive_train": ("wind_turbine", 1, ["tau_g_ref"],
                         ["omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2", "tau_g_m"], ["tau_r"], None, None),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_plant_fmu_identified_as_black_box(plant_dir, case, tmp_path):
    import plant_fmus

    fmu, index, u, y, d, excite, amp = CASES[case]
    ref = FDIModel.from_file(plant_fmus.model_path(fmu, index))
    png = tmp_path / "validation.png"
    m = model_from_fmu(plant_dir[fmu], u, y, d, at={"noise_enable": False}, excite=excite, max_order=8,
                       validation_png=png,
                       excitation=Excitation("multisine", amplitude=amp, samples=500,
                                             settle=40 * plant_fmus.PLANTS[fmu].step))
    assert m.n == ref.n
    ts = m.provenance["sample_time"]
    # the plant's bandwidth: from the lowest frequency the record resolves to half the Nyquist frequency
    w = np.geomspace(2 * np.pi / (500 * ts), 0.5 * np.pi / ts, 40)
    Gi, Gr = m.lti("u", "d").freqresp(w), ref.lti("u", "d").freqresp(w)
    err = np.abs(Gi - Gr).max(axis=(1, 2)) / np.abs(Gr).max(axis=(1, 2))
    if fmu == "dts200":
        # Torricelli: the linear coefficient ∝ 1/sqrt(Δh) changes by δh/(2Δh); level excursions of a 5 %
        # pump excitation stay below 0.4 cm and the smallest head h1 − h3 is 4.4 cm: ≤ 0.05
        tol = 0.05
    else:
        # linear plants, noise off: only the plant's integrator error (rtol 1e-8 per ODE step, up to ~10
        # steps per sample) remains, amplified by the conditioning 1/(1 − |z|) ≤ 1/(|λ_min| Ts) of the
        # slowest pole the record resolves; ×10 margin
        lam = np.abs(np.linalg.eigvals(ref.A))
        slow = max(lam[lam > 0].min(), 2 * np.pi / (500 * ts))
        tol = 10 * 10 * 1e-8 / (slow * ts)
    assert err.max() <= tol, (case, err.max(), tol)
    # dominant poles (the slowest, by magnitude) agree to the same relative accuracy
    pi = np.sort_complex(np.linalg.eigvals(m.A))
    pr = np.sort_complex(np.linalg.eigvals(ref.A))
    k = np.argsort(np.abs(pr))[: min(3, ref.n)]
    for p in pr[k]:
        assert np.min(np.abs(pi - p)) <= 10 * tol * max(abs(p), 1.0 / (500 * ts)), (case, p, pi)
    assert min(m.provenance["fit_percent"]) > 95.0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ---- data-driven design ---------------------------------------------------------------------------

def _dts200_linear_records(seeds, prbs: bool, faults=()):
    """Samples of the committed DTS200 linear model (ZOH, Ts = 1 s) with 0.1 cm sensor noise."""
    import plant_fmus
    from fmu_fdi.identify.experiment import excitation_signals

    model = FDIModel.from_file(plant_fmus.model_path("dts200"))
    d = model.lti("u").to_discrete(1.0)
    N = 3000 if prbs else 1500
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        u = (excitation_signals(Excitation("prbs", period=20, samples=N, seed=seed), ["Q1", "Q2"], [3.0, 5.0])
             if prbs else np.zeros((N, 2)))
        if not prbs:
            u[200:, 0], u[500:, 1] = 0.1 * model.u0[0], -0.1 * model.u0[1]
        x = np.zeros(3)
        y = np.empty((N, 3))
        for k in range(N):
            y[k] = d.C @ x + 0.1 * rng.standard_normal(3)
            x = d.A @ x + d.B @ u[k]
        for j, size in faults:
            y[900:, j] += size
        out.append((np.arange(N, dtype=float), u + model.u0, y + model.y0))
    return model, out


def test_data_driven_relations_detect_and_isolate_sensor_biases():
    from fmu_fdi import Diagnoser
    from fmu_fdi.design import data_driven

    model, [(t, u, y)] = _dts200_linear_records([1], prbs=True)
    gen = data_driven(model, t, u, y)  # the model gives names, faults, operating point: the filter is from data
    assert gen.method == "data" and [len(g) for g in gen.groups] == [1, 1, 1]
    ev = {"kind": "rms", "window": 20}
    calib = Diagnoser(gen, evaluation=ev, thresholds=1e150).run(t, u, y)
    # residuals have unit std on the log; 1.5 × the largest evaluation over its 3000 samples (past the
    # warm-up) bounds a fresh 1500-sample run of the same noise: the max of 1500 draws rarely exceeds that of 3000
    th = [1.5 * float(calib[f"evaluation_{i}"][200:].max()) for i in (1, 2, 3)]
    dg = Diagnoser(gen, evaluation=ev, thresholds=th, decision={"persistence": [3, 5]})
    sensors = [f.name for f in model.faults if f.kind == "sensor"]
    for j, size in [(None, 0.0), (0, 1.5), (1, 1.5), (2, -1.5)]:
        _, [(t2, u2, y2)] = _dts200_linear_records([7], prbs=False, faults=[(j, size)] if j is not None else [])
        out = dg.run(t2, u2, y2)
        if j is None:
            assert not out["fault_detected"].any()
            continue
        assert not out["fault_detected"][t2 < 900].any() and out["fault_detected"][t2 >= 900].any()
        iso = out["isolated_fault"][t2 >= 900]
        assert np.bincount(iso[iso > 0]).argmax() == dg.fault_names.index(sensors[j]) + 1


def test_data_driven_too_little_data():
    from fmu_fdi.design import data_driven
    from fmu_fdi.errors import DesignError

    model, [(t, u, y)] = _dts200_linear_records([1], prbs=True)
    with pytest.raises(DesignError, match="too little data: 60 samples"):
        data_driven(model, t[:60], u[:60], y[:60])


def test_cli_model_and_fmu_given_to_analyze(tmp_path, capsys):
    from fmu_fdi.cli import main

    fmu = build_me_fmu(tmp_path, "linear", 3, True)
    out = tmp_path / "lin.toml"
    assert main(["model", str(fmu), "--inputs", "u1", "--disturbances", "u2", "--at", "u1=2", "u2=0",
                 "--sensor-faults", "all", "-o", str(out)]) == 0
    m = FDIModel.from_file(out)
    x = equilibrium("linear", [2.0, 0.0])
    _, g, J = analytic("linear", x, [2.0, 0.0])
    assert np.allclose(m.A, J[:3, :3]) and np.allclose(m.Bd, J[:3, 4:]) and np.allclose(m.y0, g)
    assert m.provenance["method"] == "linearisation (directional derivatives)" and m.provenance["fmi_version"] == "3.0"
    assert "[provenance]" in out.read_text()
    for cmd in (["analyze", str(fmu)], ["design", str(fmu), "--method", "dos", "-o", str(tmp_path / "d.json")]):
        assert main(cmd) == 2
        assert "run 'fmu-fdi model" in capsys.readouterr().err


def test_poor_fit_is_refused(plant_dir):
    # 0.1 cm sensor noise against a ±0.2 % pump excitation: the levels move less than the noise
    with pytest.raises(IdentificationError, match="fits the validation run poorly.*excite more strongly"):
        model_from_fmu(plant_dir["dts200"], ["Q1", "Q2"], ["h1", "h2", "h3"],
                       excitation=Excitation(amplitude={"Q1": 0.05, "Q2": 0.1}, samples=400, settle=20))


@pytest.mark.parametrize("form", ["parity", "kernel"])
@pytest.mark.parametrize("kind", ["sensor", "detection"])
def test_data_driven_forms_on_a_fast_plant(form, kind):
    """A plant fast next to the window (poles 0.3-0.6): fault-free residuals stay at the record's level on a
    fresh run, a 5σ sensor bias lifts its relation(s) far above it."""
    from fmu_fdi import sensor_fault
    from fmu_fdi.design import data_driven

    A = np.array([[0.6, 0.2, 0.0], [-0.2, 0.5, 0.1], [0.0, 0.0, 0.3]])
    B = np.array([[1.0], [0.0], [0.5]])
    C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    model = FDIModel.from_matrices(A, B, C, dt=0.1, faults=[sensor_fault("s1", "y0"), sensor_fault("s2", "y1")])

    def record(seed, N, bias=None):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal((N, 1))
        x, y = np.zeros(3), np.empty((N, 2))
        for k in range(N):
            y[k] = C @ x + 0.01 * rng.standard_normal(2)
            x = A @ x + B @ u[k]
        if bias is not None:
            y[N // 2:, bias] += 0.1  # 10 σ of the sensor noise
        return np.arange(N) * 0.1, u, y

    gen = data_driven(model, *record(1, 2000), form=form, kind=kind)
    assert len(gen.groups) == (2 if kind == "sensor" else 1)
    t, u, y = record(2, 800)
    r0 = gen.simulate(y, u)[20:]
    # residuals are scaled to unit std (kernel) / unit covariance (parity) on the record
    assert np.all(np.std(r0, axis=0) < 1.5) and np.all(np.std(r0, axis=0) > 0.5)
    for j in (0, 1):
        t, u, y = record(3, 800, bias=j)
        r = gen.simulate(y, u)
        g = gen.groups[j] if kind == "sensor" else gen.groups[0]
        late = np.sqrt(np.mean(r[500:, g] ** 2, axis=0)).max()  # bias in place since sample 400
        # 10 σ of bias against unit fault-free residuals: the kernel residual (y − ŷ)/σ moves by ≈ 10; the
        # parity combination of a window of s ≤ 6 samples by ≳ 10/√s ≈ 4 (noise adds over the window,
        # the bias over at best the same samples); 3 keeps a margin below both
        assert late > 3.0, (form, kind, j, late)
        if kind == "sensor":  # the other relation does not read sensor j
            other = gen.groups[1 - j]
            assert np.sqrt(np.mean(r[500:, other] ** 2)) < 1.5


def _with_discrete_input(fmu, name, out):
    """A copy of ``fmu`` whose input ``name`` is declared discrete-variability (the binary is unchanged:
    what changes is what FMI lets a master do with it — set it only at events)."""
    import zipfile

    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                head = f'name="{name}"'
                i = text.index(head)
                j = text.index('variability="continuous"', i)
                text = text[:j] + 'variability="discrete"' + text[j + len('variability="continuous"'):]
                data = text.encode()
            dst.writestr(item, data)
    return out


def test_discrete_input_is_held_at_its_value_not_perturbed(tmp_path):
    fmu = _with_discrete_input(build_me_fmu(tmp_path, "nonlinear", 2, False), "u2", tmp_path / "discrete.fmu")
    # default inputs: the continuous ones only; u2 held at the value given, which moves the steady state
    lin = linearise(fmu, at={"u2": 0.8})
    assert lin.input_names == ["u1"]
    xe = equilibrium("nonlinear", [1.0, 0.8])        # u1 at its start value 1.0
    assert np.allclose(lin.x0, xe, rtol=1e-8)
    _, _, J = analytic("nonlinear", xe, [1.0, 0.8])
    assert np.abs(lin.A - J[:2, :2]).max() <= 1e-6 * np.abs(J).max()
    # naming it as an input is a clear refusal, not an FMU call failing
    with pytest.raises(IdentificationError, match="u2 .*discrete.*change only at events.*at="):
        linearise(fmu, inputs=["u1", "u2"])
