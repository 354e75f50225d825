"""Benchmark plant FMUs (plant_fmus, issue 5 section 1).

The FMUs are built into a temporary folder and run by fmu_runner.py in a subprocess
(all five plants in one process, as a co-simulation host loads them), so this process's
imports cannot stand in for the modules the FMUs bundle. Every check is a property any
correct plant has: equilibria hold, small steps and fault inputs move the outputs as the
shipped model file predicts, noise is reproducible and has the configured spread, the
ODE solution matches scipy at tight tolerance.

Conventions of the prediction (docs/plant_fmus.md): inputs of step k are held over
[t_k, t_k+1]; the outputs at t_k+1 are computed at the end of that step, so a
direct-feedthrough term at t_k+1 uses the input of step k.
"""
from __future__ import annotations

import ast
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm, solve_continuous_are
from scipy.stats import chi2

import plant_fmus
from fmu_fdi import FDIModel
from plant_fmus.dts200 import dts200_physics as dts
from plant_fmus.vtol import vtol_physics as vtol
from plant_fmus.wind_turbine import windturbine_physics as wind

RUNNER = Path(__file__).with_name("fmu_runner.py")
TIGHT = {"noise_enable": False, "rtol": 1e-10, "atol": 1e-12}
ALPHA = 1e-4  # false-failure probability of each chi-square check (seeds are fixed anyway)


# ------------------------------------------------------------------ scenarios
def models(plant):
    return [FDIModel.from_file(p) for p in plant_fmus.PLANTS[plant].model_files]


def signals(plant):
    names = []
    for m in models(plant):
        names += [n for n in (*m.u_names, *m.d_names, *m.y_names) if n not in names]
    return names


def series(steps, k0, before, after):
    return [float(before)] * k0 + [float(after)] * (steps - k0)


SCENARIOS: dict[str, tuple[str, dict]] = {}


def scenario(key, plant, steps, params=None, inputs=None, extra_outputs=()):
    run = {"dt": plant_fmus.PLANTS[plant].step, "steps": steps, "params": dict(params or {}),
           "inputs": dict(inputs or {}), "outputs": signals(plant) + ["ode_steps", *extra_outputs]}
    SCENARIOS[key] = (plant, run)


DTS_H0, DTS_Q0 = dts.operating_point()
WIND_X0, WIND_TAU_R0 = wind.operating_point()

# Equilibria and small input steps (noise and faults off).
scenario("dts200/equilibrium", "dts200", 200, TIGHT)
scenario("dts200/step", "dts200", 400, TIGHT,
         {"Q1": series(400, 5, DTS_Q0[0], DTS_Q0[0] + 0.5), "Q2": series(400, 100, DTS_Q0[1], DTS_Q0[1] - 0.5)})
scenario("dr300/equilibrium", "dr300", 100, TIGHT)
scenario("dr300/step", "dr300", 300, TIGHT,
         {"speed_ref": series(300, 5, 0, 1), "load_torque": series(150, 100, 0, 0.01) + [0.0] * 150})
scenario("vtol/equilibrium", "vtol", 100, TIGHT)
scenario("vtol/step", "vtol", 300, TIGHT,
         {"ref_collective": series(300, 5, 0, 0.1), "ref_cyclic": series(300, 50, 0, -0.1)})
scenario("wind_turbine/equilibrium", "wind_turbine", 200, TIGHT)
scenario("wind_turbine/step", "wind_turbine", 200, TIGHT,
         {"beta_ref_1": series(200, 5, 0, 1), "beta_ref_3": series(200, 30, 0, 0.5),
          "tau_g_ref": series(200, 10, WIND_X0[3], WIND_X0[3] + 100),
          "tau_r": series(200, 20, WIND_TAU_R0, WIND_TAU_R0 + 1e4)})
scenario("vtol/uncertain", "vtol", 300, {**TIGHT, "delta_a32": 0.1, "delta_a34": -0.1, "delta_b21": 0.1},
         SCENARIOS["vtol/step"][1]["inputs"])
scenario("lateral_aircraft/equilibrium", "lateral_aircraft", 100, TIGHT)
scenario("lateral_aircraft/step", "lateral_aircraft", 300, TIGHT,
         {"u1": series(300, 5, 0, 0.05), "u2": series(300, 50, 0, -0.05)})

# One run per model fault: a small step of f_<fault> (with an excitation where the fault
# is parametric and acts only through the inputs).
FAULT_RUNS = {
    "dts200": (200, 5, {"sensor_h1": 0.5, "sensor_h2": 0.5, "sensor_h3": 0.5, "pump_Q1": 0.5, "pump_Q2": 0.5,
                        "leak_T1": 2e-3, "leak_T2": 2e-3, "leak_T3": 2e-3,
                        "clog_13": 0.02, "clog_32": 0.02, "clog_20": 0.02}, {}),
    "dr300": (200, 20, {"actuator_voltage": 0.1, "sensor_speed": 0.05}, {}),
    "vtol": (200, 20, {f: 0.05 for f in vtol.SENSOR_FAULTS + vtol.ACTUATOR_FAULTS}, {}),
    "wind_turbine": (200, 20, {"sensor_beta_1_m1": 0.5, "sensor_beta_2_m2": 0.5, "sensor_beta_3_m1": 0.5,
                               "sensor_omega_r_m1": 0.05, "sensor_omega_r_m2": 0.05, "sensor_omega_g_m2": 0.5,
                               "converter_offset": 100.0, "drive_train_efficiency": -1e-3},
                     {}),
    "lateral_aircraft": (300, 0, {"loe_u1": 0.3, "loe_u2": 0.3},
                         {"u1": series(300, 10, 0, 0.05), "u2": series(300, 40, 0, -0.05)}),
}
for _plant, (_n, _k, _faults, _excite) in FAULT_RUNS.items():
    for _fault, _size in _faults.items():
        scenario(f"{_plant}/fault/{_fault}", _plant, _n, TIGHT, {f"f_{_fault}": series(_n, _k, 0, _size), **_excite})
for _blade, _kind in ((2, "pressure_drop"), (3, "air_in_oil")):
    scenario(f"wind_turbine/fault/pitch_{_blade}_{_kind}", "wind_turbine", 200, TIGHT,
             {f"f_pitch_{_blade}_{_kind}": 0.5, f"beta_ref_{_blade}": series(200, 20, 0, 1.0)})
scenario("lateral_aircraft/gamma", "lateral_aircraft", 300, {**TIGHT, "gamma_1": 0.3},
         {"u1": series(300, 10, 0, 0.05), "u2": series(300, 40, 0, -0.05)})
# A fault switched on mid-run, as an input and as the tunable parameter; and no fault.
_EXCITE = {"u1": series(300, 10, 0, 0.05), "u2": series(300, 40, 0, -0.05)}
SWITCH_STEP = 60
scenario("lateral_aircraft/switched/none", "lateral_aircraft", 300, TIGHT, _EXCITE)
scenario("lateral_aircraft/switched/f_loe_u1", "lateral_aircraft", 300, TIGHT,
         {"f_loe_u1": series(300, SWITCH_STEP, 0, 0.3), **_EXCITE})
scenario("lateral_aircraft/switched/gamma_1", "lateral_aircraft", 300, TIGHT,
         {"gamma_1": series(300, SWITCH_STEP, 0, 0.3), **_EXCITE})

# Noise: measurement noise at the defaults, process noise off; the same seed twice.
NOISE_STEPS = 400
for _plant, _p in plant_fmus.PLANTS.items():
    _quiet_process = {k: 0.0 for k in _p.noise if k.startswith("std_w_")}
    for _tag, _seed in (("a", 7), ("a_again", 7), ("b", 8)):
        scenario(f"{_plant}/noise/{_tag}", _plant, NOISE_STEPS, {"seed": _seed, **_quiet_process})
scenario("lateral_aircraft/process_noise", "lateral_aircraft", NOISE_STEPS,
         {"seed": 3, **{f"std_{y}": 0.0 for y in ("beta", "phi", "p", "r")}})

# DTS200 specifics: ODE accuracy, level limits, fault channels, error handling.
scenario("dts200/ode", "dts200", 300, {"noise_enable": False, "h1_start": 20.0, "h2_start": 10.0, "h3_start": 15.0},
         {"Q1": 35.0, "Q2": 30.0})
scenario("dts200/overflow", "dts200", 600, {"noise_enable": False}, {"Q1": 100.0, "Q2": 100.0},
         extra_outputs=("overflow", "empty"))
scenario("dts200/drain", "dts200", 1500, {"noise_enable": False}, {"Q1": 0.0, "Q2": 0.0},
         extra_outputs=("overflow", "empty"))
_channels = {"Q1": 0.0, "f_leak_T2": 1e-3}
scenario("dts200/channels_ref", "dts200", 100, {"noise_enable": False}, _channels)
scenario("dts200/channels", "dts200", 100, {"noise_enable": False},
         {**_channels, "Q1": 30.0, "stuck_Q1": 1.0, "stuck_value_Q1": 0.0, "gain_h1": 2.0,
          "stuck_h2": series(100, 10, 0, 1), "stuck_value_h2": 5.0})
scenario("dts200/nan_input", "dts200", 10, {}, {"Q1": [1.0, 2.0, 3.0] + [float("nan")] * 7})
scenario("dts200/bad_parameter", "dts200", 10, {"std_h1": -1.0})


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("plant_fmus")
    return {p.stem: p for p in plant_fmus.build_all(out)}


def run_jobs(fmus, keys, tmp_path, env=None):
    """Run the scenarios ``keys`` in one fresh process; returns {key: result}."""
    plants = list(dict.fromkeys(SCENARIOS[k][0] for k in keys))
    jobs = [{"fmu": str(fmus[p]), "runs": [SCENARIOS[k][1] for k in keys if SCENARIOS[k][0] == p]}
            for p in plants]
    jobs_file, result_file = tmp_path / "jobs.json", tmp_path / "results.json"
    jobs_file.write_text(json.dumps(jobs))
    proc = subprocess.run([sys.executable, str(RUNNER), str(jobs_file), str(result_file)],
                          capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    raw = json.loads(result_file.read_text())
    out = {}
    for plant, runs in zip(plants, raw):
        for key, res in zip([k for k in keys if SCENARIOS[k][0] == plant], runs):
            out[key] = res
    return out


@pytest.fixture(scope="module")
def results(fmus, tmp_path_factory):
    return run_jobs(fmus, list(SCENARIOS), tmp_path_factory.mktemp("runs"))


def test_plant_hosts_exit_cleanly_whatever_their_heap_layout(fmus, tmp_path):
    """pythonfmu 0.7 releases its interpreter handle twice at process exit; whether the host
    then aborts after its work is done depends only on its heap layout (fmu_fdi/fmu/exit_guard.py,
    bundled into every plant FMU too). The environment is copied onto the host's heap, so
    environments of different sizes give different layouts: every one must exit 0, and no
    plant may log that it could not guard its host."""
    import os

    keys = [next(k for k in SCENARIOS if SCENARIOS[k][0] == p) for p in ("dts200", "dr300")]
    for pad in range(0, 2400, 600):  # 4 layouts
        env = dict(os.environ, FMU_FDI_TEST_HEAP_PAD="x" * pad)
        for key, res in run_jobs(fmus, keys, tmp_path, env=env).items():
            assert not [m for _, _, m in res.get("log", []) if "corrupt the host's heap" in m], (key, res["log"])


def ok(results, key):
    res = results[key]
    assert res["status"] == "ok", f"{key}: {res.get('message')} {res.get('log')}"
    return {name: np.array(v, dtype=float) for name, v in res["outputs"].items()}


# ------------------------------------------------------------ model prediction
def discretize(A, B, h):
    n, m = B.shape
    M = expm(np.block([[A, B], [np.zeros((m, n + m))]]) * h)
    return M[:n, :n], M[:n, n:]


def held(run, name, out, steps):
    """The value of signal ``name`` held over each step k (scenario input, else recorded)."""
    value = run["inputs"].get(name)
    if value is None:
        return out[name][:steps]
    return np.array(value if isinstance(value, list) else [value] * steps, dtype=float)


def predict(model, run, out):
    """Outputs at t_0..t_N the model file predicts for the run's inputs and faults, and
    the predicted state deviations. Exact ZOH discretisation: every input is piecewise
    constant."""
    h, N = run["dt"], run["steps"]
    U = np.column_stack([held(run, u, out, N) for u in model.u_names]) - model.u0
    d0 = WIND_TAU_R0 if model.name == "wind_drive_train" else 0.0  # tau_r is not in the model's point
    D = (np.column_stack([held(run, d, out, N) for d in model.d_names]) - d0 if model.nd else np.zeros((N, 0)))
    F = np.zeros((N, len(model.faults)))
    for j, spec in enumerate(model.faults):
        value = run["inputs"].get(f"f_{spec.name}", 0.0)
        F[:, j] = value if not isinstance(value, list) else value
    additive = [j for j, s in enumerate(model.faults) if s.kind != "parametric"]
    param = [j for j, s in enumerate(model.faults) if s.kind == "parametric"]
    cols = [model.faults[j].columns for j in additive]
    Bf = np.hstack([model.Bf[:, c] for c in cols]) if cols else np.zeros((model.n, 0))
    Df = np.hstack([model.Df[:, c] for c in cols]) if cols else np.zeros((model.ny, 0))
    cache, x, Y, X = {}, np.zeros(model.n), [], []
    for k in range(N + 1):
        f_out = F[max(k - 1, 0), additive]  # outputs at t_k use the inputs of step k-1
        Y.append(model.C @ x + Df @ f_out + model.y0)
        X.append(x)
        if k == N:
            break
        theta = tuple(F[k, param])
        if theta not in cache:
            A, Bu = model.A.copy(), model.Bu.copy()
            for t, j in zip(theta, param):
                A += t * model.faults[j].dA
                Bu += t * model.faults[j].dB
            cache[theta] = discretize(A, np.hstack([Bu, model.Bd, Bf]), h)
        Phi, Gam = cache[theta]
        x = Phi @ x + Gam @ np.concatenate([U[k], D[k], F[k, additive]])
    return np.array(Y), np.array(X)


def integration_bound(model, run, out, n_fmu, x_abs_max):
    """Bound on |y_FMU - y_exact| from the integrator's local error control.

    Each accepted Dormand-Prince step keeps rms(err_i / (atol + rtol |x_i|)) <= 1, so
    |err_i| <= sqrt(n_fmu) (atol + rtol max|x_i|); a local error made at any time reaches
    the outputs through at most sup_k |C Phi^k| (elementwise); summed over the accepted
    steps (the FMU's ode_steps output)."""
    Phi, _ = discretize(model.A, model.Bu, run["dt"])
    local = np.sqrt(n_fmu) * (run["params"]["atol"] + run["params"]["rtol"] * np.asarray(x_abs_max))
    gain, P = np.abs(model.C), np.eye(model.n)
    for _ in range(run["steps"]):
        P = P @ Phi
        gain = np.maximum(gain, np.abs(model.C @ P))
    return out["ode_steps"][-1] * (gain @ local)


# --------------------------------------------------------------- build, files
def test_build_api_and_import_hygiene(tmp_path):
    before_path, before_mods = list(sys.path), set(sys.modules)
    path = plant_fmus.build("dts200", tmp_path)
    assert path == tmp_path / "dts200.fmu" and path.is_file()
    assert sys.path == before_path
    leaked = {m for m in set(sys.modules) - before_mods if m.split(".")[0] != "pythonfmu"}
    assert not any(m.startswith(("dts200_", "pythonfmu_")) for m in leaked), leaked
    with pytest.raises(KeyError, match="unknown plant"):
        plant_fmus.build("no_such_plant", tmp_path)
    assert plant_fmus.model_path("wind_turbine", 1).name == "wind_drive_train.toml"


def test_bundled_modules_are_unique_and_numpy_only(fmus):
    seen = {}
    # third-party: numpy and pythonfmu only; the rest is the standard library (the exit guard
    # of fmu_fdi/fmu/exit_guard.py needs importlib, atexit, ctypes, glob and os)
    allowed = {"numpy", "pythonfmu", "math", "__future__", "xml", "importlib", "atexit", "ctypes", "glob", "os"}
    for name, path in fmus.items():
        prefix = plant_fmus.PLANTS[name].prefix
        with zipfile.ZipFile(path) as zf:
            mods = [n for n in zf.namelist() if n.startswith("resources/") and n.count("/") == 1 and n.endswith(".py")]
            for mod in mods:
                stem = Path(mod).stem
                assert stem.startswith(prefix + "_"), f"{name}: bundled module {stem} lacks the prefix {prefix}_"
                assert stem not in seen, f"{stem} bundled by both {seen[stem]} and {name}"
                seen[stem] = name
                for node in ast.walk(ast.parse(zf.read(mod))):
                    if isinstance(node, ast.Import):
                        tops = [a.name.split(".")[0] for a in node.names]
                    elif isinstance(node, ast.ImportFrom):
                        tops = [node.module.split(".")[0]]
                    else:
                        continue
                    for top in tops:
                        assert top in allowed or top.startswith(prefix + "_"), f"{mod} imports {top}"
            for model_file in plant_fmus.PLANTS[name].model_files:
                assert f"resources/{model_file.name}" in zf.namelist()


@pytest.mark.parametrize("plant", list(plant_fmus.PLANTS))
def test_committed_model_files_equal_fresh_computation(plant):
    fresh = plant_fmus.linear_models(plant)
    for model, path in zip(fresh, plant_fmus.PLANTS[plant].model_files):
        committed = FDIModel.from_file(path).to_dict()
        computed = model.to_dict()

        def walk(a, b, where):
            if isinstance(a, dict):
                assert set(a) == set(b), where
                for k in a:
                    walk(a[k], b[k], f"{where}.{k}")
            elif isinstance(a, list):
                assert len(a) == len(b), where
                for i, (x, y) in enumerate(zip(a, b)):
                    walk(x, y, f"{where}[{i}]")
            elif isinstance(a, float):
                # Same formulas, same inputs: equal up to libm's last-bit differences between machines.
                assert a == pytest.approx(b, rel=1e-13, abs=1e-300), where
            else:
                assert a == b, where

        walk(committed, computed, path.name)


def test_model_signals_are_fmu_variables(fmus):
    from fmpy import read_model_description

    for name, path in fmus.items():
        plant = plant_fmus.PLANTS[name]
        md = {v.name: v for v in read_model_description(str(path)).modelVariables}
        for model in models(name):
            for u in model.u_names:
                assert md[u].causality in ("input", "output"), (name, u)
            for y in model.y_names:
                assert md[y].causality == "output", (name, y)
            for d in model.d_names:
                assert md[d].causality == "input", (name, d)
            for f in model.fault_names:
                assert md[f"f_{f}"].causality == "input", (name, f)
            for sig, unit in model.units.items():
                assert (md[sig].unit or "") == unit, (name, sig)
        for fault in plant.faults:
            assert md[fault.variable].causality == "input" and md[fault.variable].type == "Real", fault
        for std, default in plant.noise.items():
            assert md[std].causality == "parameter" and float(md[std].start) == pytest.approx(default), std
        assert md["seed"].type == "Integer" and md["noise_enable"].type == "Boolean"
        for v in md.values():
            assert v.causality and v.variability, f"{name}: {v.name} lacks causality or variability"


# ---------------------------------------------------------- plant parameters
def test_dts200_operating_point_is_exact_and_rounds_to_the_published_one():
    h, q = dts.operating_point()
    # f(x0) cancels flows of size ~75 cm3/s: a few ulps of that, divided by the tank area.
    assert np.max(np.abs(dts.derivative(h, q))) <= 16 * np.finfo(float).eps * 75 / dts.PARAMS["area"]
    assert round(h[2], 1) == 36.6 and (round(q[0], 2), round(q[1], 2)) == (21.37, 53.80)
    assert np.max(np.abs(dts.derivative(np.array([41, 32, 36.6]), q))) > 1e-5  # the rounded point is not one


def test_dts200_model_is_the_jacobian_of_the_nonlinear_plant():
    model = FDIModel.from_file(plant_fmus.model_path("dts200"))
    eps = 1e-4  # central differences: truncation ~ eps^2 |f'''| ~ 1e-8 |A|, rounding ~ 1e-16/eps
    J = np.column_stack([(dts.derivative(model.y0 + eps * e, model.u0) - dts.derivative(model.y0 - eps * e, model.u0))
                         / (2 * eps) for e in np.eye(3)])
    assert np.allclose(J, model.A, rtol=0, atol=1e-8)
    e = np.eye(3) * eps
    for name, kw in (("leak_T1", {"leak": e[0]}), ("leak_T3", {"leak": e[2]}), ("clog_13", {"clog": e[0]}),
                     ("clog_32", {"clog": e[1]}), ("clog_20", {"clog": e[2]})):
        fd = dts.derivative(model.y0, model.u0, **kw) / eps  # f is linear in theta; f(x0) is rounding only
        assert np.allclose(fd, model.Bf[:, model.fault(name).columns].ravel(), rtol=1e-12,
                           atol=16 * np.finfo(float).eps * 75 / dts.PARAMS["area"] / eps), name


def test_vtol_lqr_gain_matches_scipy_and_stabilises_the_sampled_loop():
    P = solve_continuous_are(vtol.A, vtol.B, vtol.LQR_Q, vtol.LQR_R)
    K = np.linalg.solve(vtol.LQR_R, vtol.B.T @ P)
    # The CARE solver is backward stable and this Riccati equation is well conditioned.
    assert np.allclose(vtol.K, K, rtol=1e-9, atol=1e-12)
    assert np.max(np.linalg.eigvals(vtol.A - vtol.B @ vtol.K).real) < 0
    Phi, Gam = discretize(vtol.A, vtol.B, plant_fmus.PLANTS["vtol"].step)
    assert np.max(np.abs(np.linalg.eigvals(Phi - Gam @ vtol.K))) < 1
    for d in ([0.1] * 3, [-0.1] * 3):  # the documented uncertainty bound keeps the loop stable
        A, B = vtol.plant_matrices(*d)
        assert np.max(np.linalg.eigvals(A - B @ vtol.K).real) < 0


def test_open_loop_plants_are_stable():
    for name in ("lateral_aircraft", "wind_turbine", "dts200"):
        for model in models(name):
            assert np.max(np.linalg.eigvals(model.A).real) < 0, model.name


# ------------------------------------------------------------- FMU behaviour
@pytest.mark.parametrize("plant", list(plant_fmus.PLANTS))
def test_equilibrium_is_held(results, plant):
    key = f"{plant}/equilibrium"
    out = ok(results, key)
    for model in models(plant):
        y = np.column_stack([out[n] for n in model.y_names])
        # Exact equilibrium: the derivative vanishes up to rounding, so every RK stage does;
        # what remains is rounding of the state (a few ulps of its size) per step.
        tol = out["ode_steps"][-1] * 8 * np.finfo(float).eps * np.maximum(np.abs(model.y0), 1.0)
        assert np.all(np.abs(y - model.y0) <= tol + 1e-300), (model.name, np.max(np.abs(y - model.y0), axis=0))


def _abs_state_max(model, plant, X):
    if plant == "dts200":
        return np.abs(X + model.y0).max(axis=0)
    if model.name == "wind_drive_train":
        return np.abs(X + WIND_X0).max(axis=0)
    return np.abs(X).max(axis=0)


N_FMU_STATES = {"dts200": 3, "dr300": 4, "vtol": 4, "wind_turbine": 10, "lateral_aircraft": 4}


def _check_against_model(results, plant, key, extra_bound=None):
    """Assert |y_FMU - y_model| <= bound for every model file of the plant; returns
    {model name: (largest predicted output deviation, largest bound)}."""
    out, run = ok(results, key), SCENARIOS[key][1]
    moved = {}
    for model in models(plant):
        Y, X = predict(model, run, out)
        y = np.column_stack([out[n] for n in model.y_names])
        tol = integration_bound(model, run, out, N_FMU_STATES[plant], _abs_state_max(model, plant, X))
        if extra_bound is not None:
            tol = tol + extra_bound(model, run, out, X)
        err = np.abs(y - Y).max(axis=0)
        assert np.all(err <= tol), f"{key} {model.name}: error {err} > bound {tol}"
        moved[model.name] = (float(np.max(np.abs(Y - model.y0))), float(np.max(tol)))
    return moved


def dts200_second_order(model, run, out, X, theta=None):
    """Bound on |y_nonlinear - y_linear| from the Taylor remainders of the Torricelli flows.

    The deviation e = x - x_lin obeys e' = A e + r(t) exactly, r the remainder of the
    nonlinear right-hand side at the actual state. For Q = c sqrt(D) at D0 + eps:
    |Q - Q0 - Q0 eps/(2 D0)| <= Q0 eps^2 / (8 D0^2) (1 - |eps|/D0)^(-3/2); a fault level
    theta multiplies the flow deviation, |Q - Q0| <= Q0 |eps|/(2 D0) (1 - |eps|/D0)^(-1/2).
    A is Metzler and Hurwitz, so e^{At} >= 0 and |e| <= (-A)^{-1}(I - e^{AT}) max|r|."""
    h = np.column_stack([out[n] for n in model.y_names])
    for i, y in enumerate(model.y_names):  # the true levels: take off the sensor faults (lagged one step)
        f = run["inputs"].get(f"f_sensor_{y}", 0.0)
        f = np.asarray(f if isinstance(f, list) else [f] * run["steps"], dtype=float)
        h[:, i] -= np.concatenate([f[:1], f])
    theta = theta or {}
    q13, q32, q20 = dts.flows(model.y0)
    d0 = {"13": model.y0[0] - model.y0[2], "32": model.y0[2] - model.y0[1], "20": model.y0[1]}
    dev = {"13": h[:, 0] - h[:, 2] - d0["13"], "32": h[:, 2] - h[:, 1] - d0["32"], "20": h[:, 1] - d0["20"]}
    rem, lin = {}, {}
    for key, q0 in (("13", q13), ("32", q32), ("20", q20)):
        eps = np.max(np.abs(dev[key]))
        rho = eps / d0[key]
        rem[key] = q0 * rho ** 2 / 8 * (1 - rho) ** -1.5
        lin[key] = q0 * rho / 2 * (1 - rho) ** -0.5
    r = np.array([rem["13"], rem["32"] + rem["20"], rem["13"] + rem["32"]])
    r += np.array([theta.get("clog_13", 0) * lin["13"], theta.get("clog_32", 0) * lin["32"]
                   + theta.get("clog_20", 0) * lin["20"], theta.get("clog_13", 0) * lin["13"]
                   + theta.get("clog_32", 0) * lin["32"]])
    for i in range(3):
        eps = np.max(np.abs(h[:, i] - model.y0[i]))
        r[i] += theta.get(f"leak_T{i + 1}", 0) * np.sqrt(2 * dts.PARAMS["g"]) * eps / (2 * np.sqrt(model.y0[i] - eps))
    r /= dts.PARAMS["area"]
    T = run["steps"] * run["dt"]
    L1 = np.linalg.solve(-model.A, np.eye(3) - expm(model.A * T))
    assert np.all(L1 >= -1e-12)
    return L1 @ r


@pytest.mark.parametrize("plant", list(plant_fmus.PLANTS))
def test_small_input_step_matches_the_model_file(results, plant):
    extra = dts200_second_order if plant == "dts200" else None
    moved = _check_against_model(results, plant, f"{plant}/step", extra)
    for name, (deviation, bound) in moved.items():
        assert deviation > 2 * bound, (name, deviation, bound)  # a wrong model could not pass


FAULT_KEYS = [k for k in SCENARIOS if "/fault/" in k]


@pytest.mark.parametrize("key", FAULT_KEYS)
def test_fault_input_moves_outputs_as_the_model_file_predicts(results, key):
    plant, fault = key.split("/")[0], key.split("/")[-1]
    run = SCENARIOS[key][1]
    value = run["inputs"][f"f_{fault}"]
    theta = max(np.abs(value)) if isinstance(value, list) else abs(value)
    extra = None
    if plant == "dts200":
        def extra(model, run, out, X):
            return dts200_second_order(model, run, out, X, {fault: theta})
    elif fault == "drive_train_efficiency":
        def extra(model, run, out, X):
            # Bilinear term theta * (dA/d eta) dx left out of the model: bounded through
            # sup_k |C Phi^k| times the sum over the steps of its ZOH effect.
            if model.name != "wind_drive_train":
                return 0.0
            dA = wind.drive_train_matrices(wind.PARAMS, 1.0)[0] - wind.drive_train_matrices()[0]
            r = theta * np.abs(dA) @ np.abs(X).max(axis=0)
            Phi, Gam = discretize(model.A, np.eye(model.n), run["dt"])
            total, P = np.zeros(model.ny), np.eye(model.n)
            for _ in range(run["steps"]):
                total += np.abs(model.C @ P @ Gam) @ r
                P = P @ Phi
            return total
    out = ok(results, key)
    bounds = _check_against_model(results, plant, key, extra)
    owners = [m for m in models(plant) if fault in m.fault_names]
    assert owners, f"{fault} is in no model file of {plant}"
    for model in owners:
        nominal = {**run, "inputs": {k: v for k, v in run["inputs"].items() if k != f"f_{fault}"}}
        effect = np.abs(predict(model, run, out)[0] - predict(model, nominal, out)[0]).max()
        # A missing or misdirected fault column leaves an error of at least the effect:
        # with the effect above twice the bound, such a model could not pass.
        assert effect > 2 * bounds[model.name][1], (model.name, effect, bounds[model.name])


def test_vtol_uncertain_parameters_act_on_a32_a34_b21(results):
    key = "vtol/uncertain"
    out, run = ok(results, key), SCENARIOS[key][1]
    nominal = models("vtol")[0]
    A, B = vtol.plant_matrices(0.1, -0.1, 0.1)
    perturbed = FDIModel.from_matrices(A, B, nominal.C, u_names=nominal.u_names, y_names=nominal.y_names)
    Y, X = predict(perturbed, run, out)
    y = np.column_stack([out[n] for n in nominal.y_names])
    bound = integration_bound(perturbed, run, out, 4, np.abs(X).max(axis=0))
    assert np.all(np.abs(y - Y).max(axis=0) <= bound)
    assert np.abs(y - predict(nominal, run, out)[0]).max() > 2 * bound.max()  # the nominal model misses


def test_registry_lists_the_benchmark_detection_targets():
    ts = plant_fmus.PLANTS["wind_turbine"].step
    targets = {f.model_fault: f.detection_target for f in plant_fmus.PLANTS["wind_turbine"].faults if f.model_fault}
    # plants.md (unverified, documented targets): sensors 10 Ts, fault 6 8 Ts, 7 600 Ts, 8 3-5 Ts.
    assert targets["sensor_beta_1_m1"] == pytest.approx(10 * ts) and targets["sensor_omega_g_m2"] == pytest.approx(10 * ts)
    assert targets["pitch_2_pressure_drop"] == pytest.approx(8 * ts)
    assert targets["pitch_3_air_in_oil"] == pytest.approx(600 * ts)
    assert 3 * ts <= targets["converter_offset"] <= 5 * ts and targets["drive_train_efficiency"] is None
    for plant in plant_fmus.PLANTS.values():
        model_faults = {f for m in plant.linear_models() for f in m.fault_names}
        listed = {f.model_fault for f in plant.faults if f.model_fault}
        assert listed == model_faults, plant.name  # every model fault has its FMU input


def test_gamma_parameter_equals_loe_fault_input(results):
    a, b = ok(results, "lateral_aircraft/gamma"), ok(results, "lateral_aircraft/fault/loe_u1")
    for y in ("beta", "phi", "p", "r"):
        assert np.array_equal(a[y], b[y])


def test_fault_switched_between_steps_acts_from_that_step_on(results):
    """Value k of an input (or tunable parameter) is set before step k: outputs up to t_k are
    those of the run without the fault, every later one differs (u1 = 0.05 excites it); the
    input and the parameter are summed, so they act alike."""
    none = ok(results, "lateral_aircraft/switched/none")
    for key in ("f_loe_u1", "gamma_1"):
        out = ok(results, f"lateral_aircraft/switched/{key}")
        y, y0 = (np.column_stack([o[n] for n in ("beta", "phi", "p", "r")]) for o in (out, none))
        assert np.array_equal(y[:SWITCH_STEP + 1], y0[:SWITCH_STEP + 1]), key
        assert np.all(np.any(y[SWITCH_STEP + 1:] != y0[SWITCH_STEP + 1:], axis=1)), key
    a, b = (ok(results, f"lateral_aircraft/switched/{k}") for k in ("f_loe_u1", "gamma_1"))
    assert all(np.array_equal(a[y], b[y]) for y in ("beta", "phi", "p", "r"))


@pytest.mark.parametrize("plant", list(plant_fmus.PLANTS))
def test_noise_is_reproducible_and_has_the_configured_std(results, plant):
    a, again, b = (ok(results, f"{plant}/noise/{t}") for t in ("a", "a_again", "b"))
    ys = [y for m in models(plant) for y in m.y_names]
    for y in ys:
        assert np.array_equal(a[y], again[y]), f"{plant}: seed 7 did not reproduce {y}"
        assert not np.array_equal(a[y], b[y]), f"{plant}: seeds 7 and 8 gave the same {y}"
    key = f"{plant}/noise/a"
    for model in models(plant):
        # The model is exact for the plant with the recorded inputs, so y - prediction is the
        # measurement noise (the closed loops feed it back, which the recorded u carries).
        Y, _ = predict(model, SCENARIOS[key][1], a)
        for i, y in enumerate(model.y_names):
            v = a[y] - Y[:, i]
            sigma = plant_fmus.PLANTS[plant].noise[f"std_{y}"]
            n = v.size
            # n * s^2 / sigma^2 ~ chi2(n) (zero mean known); two-sided, Bonferroni over sensors.
            lo, hi = chi2.ppf([ALPHA / (2 * len(ys)), 1 - ALPHA / (2 * len(ys))], n) / n
            assert lo <= np.mean(v ** 2) / sigma ** 2 <= hi, (plant, y, np.sqrt(np.mean(v ** 2)), sigma)


def test_lateral_process_noise_matches_the_model_Bw(results):
    out = ok(results, "lateral_aircraft/process_noise")
    model = models("lateral_aircraft")[0]
    x = np.column_stack([out[y] for y in model.y_names])  # C = I, measurement noise off
    Phi, Gam_w = discretize(model.A, model.Bw[:, :4], SCENARIOS["lateral_aircraft/process_noise"][1]["dt"])
    w = np.linalg.solve(Gam_w, (x[1:] - x[:-1] @ Phi.T).T).ravel()
    # The model's w is unit-variance white noise held over each step: chi-square on all samples.
    lo, hi = chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], w.size) / w.size
    assert lo <= np.mean(w ** 2) <= hi, np.sqrt(np.mean(w ** 2))


def torricelli(t, h, q):
    """plants.md section 1, written out independently of the package."""
    A, s, g = 154.0, 0.5, 981.0
    q13 = 0.46 * s * np.sign(h[0] - h[2]) * np.sqrt(2 * g * abs(h[0] - h[2]))
    q32 = 0.45 * s * np.sign(h[2] - h[1]) * np.sqrt(2 * g * abs(h[2] - h[1]))
    q20 = 0.60 * s * np.sqrt(2 * g * h[1])
    return np.array([q[0] - q13, q[1] + q32 - q20, q13 - q32]) / A


def test_dts200_ode_matches_solve_ivp(results):
    key = "dts200/ode"
    out = ok(results, key)
    run = SCENARIOS[key][1]
    t = np.arange(run["steps"] + 1) * run["dt"]
    ref = solve_ivp(torricelli, (0, t[-1]), [20.0, 10.0, 15.0], method="DOP853", t_eval=t, rtol=1e-12,
                    atol=1e-12, args=([35.0, 30.0],)).y.T
    h = np.column_stack([out[y] for y in ("h1", "h2", "h3")])
    assert h.max() < 62 and h.min() > 0  # the limits play no part here
    # Metzler Jacobian with column sums <= 0 at every state: the flow is non-expansive in the
    # 1-norm, so the global error is at most the sum of the local errors, each bounded by
    # sqrt(3) (atol + rtol max|h|) per component (default rtol 1e-8, atol 1e-10).
    bound = out["ode_steps"][-1] * 3 * np.sqrt(3) * (1e-10 + 1e-8 * h.max())
    err = np.abs(h - ref).max()
    assert err <= bound, (err, bound)
    assert np.abs(h - ref).max() < 1e-4  # and far better than one Euler step per second would be


def test_dts200_level_limits(results):
    over = ok(results, "dts200/overflow")
    h = np.column_stack([over[y] for y in ("h1", "h2", "h3")])
    assert h.max() == dts.PARAMS["h_max"] and over["overflow"][-1] == 1
    assert np.all(np.diff(h[:, 0]) >= 0)  # T1 fills, then holds at the rim
    drain = ok(results, "dts200/drain")
    h = np.column_stack([drain[y] for y in ("h1", "h2", "h3")])
    assert h.min() >= 0 and np.all(np.diff(h.sum(axis=1)) <= 1e-12)  # water only leaves (up to rounding)
    assert drain["empty"][-1] == 1 and drain["overflow"].max() == 0


def test_dts200_fault_channels(results):
    ref, out = ok(results, "dts200/channels_ref"), ok(results, "dts200/channels")
    assert np.array_equal(out["h1"], 2.0 * ref["h1"])  # gain fault; pump 1 stuck at 0 = commanded 0
    assert np.array_equal(out["h3"], ref["h3"])
    assert np.all(out["h2"][11:] == 5.0) and np.array_equal(out["h2"][:11], ref["h2"][:11])


def test_errors_reach_the_host_as_fmi_error_not_fatal(results):
    for key, what in (("dts200/nan_input", "input Q1"), ("dts200/bad_parameter", "std_h1")):
        res = results[key]
        assert res["status"] == "error" and res["code"] in (2, 3), res  # discard/error, never fatal (4)
        assert any(what in message and status == 3 for _, status, message in res["log"]), res["log"]


def test_plants_run_the_same_alone_as_together(fmus, results, tmp_path):
    keys = ["dts200/noise/a", "lateral_aircraft/noise/a"]
    alone = {}
    for key in keys:
        sub = tmp_path / key.split("/")[0]
        sub.mkdir()
        alone.update(run_jobs(fmus, [key], sub))
    for key in keys:
        assert alone[key]["outputs"] == results[key]["outputs"], key
