"""Designs for the native-runtime conformance suite.

``feature_designs()``: synthetic LTI designs that together use every evaluator kind, every
threshold kind, every isolation mode, persistence, latching, valid ranges and a continuous
realisation (for re-discretised steps). ``method_designs(folder)``: one design per design
method, made by ``fmu-fdi design`` (in-process) on the DTS200 three-tank model, with a few
evaluation and decision options varied across them.
"""
import copy
import json
from pathlib import Path

import numpy as np

from fmu_fdi.runtime.engine import DiagnoserRuntime
from fmu_fdi.runtime.expm import zoh

TS = 0.1
PLANT_MODEL = Path(__file__).parent.parent / "plant_fmus" / "dts200" / "dts200.toml"


def _stable_lti(rng, n, m, p):
    """A random stable continuous (Ac, Bc, Cc, Dc) and its ZOH discretisation at TS."""
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    Ac = Q @ np.diag(-rng.uniform(0.5, 4.0, n)) @ Q.T + 0.3 * rng.standard_normal((n, n))
    Ac -= (max(0.0, np.linalg.eigvals(Ac).real.max()) + 0.3) * np.eye(n)  # strictly stable
    Bc, Cc, Dc = rng.standard_normal((n, m)), rng.standard_normal((p, n)), 0.3 * rng.standard_normal((p, m))
    Ad, Bd = zoh(Ac, Bc, TS)
    return (Ac, Bc, Cc, Dc), (Ad, Bd, Cc, Dc)


def _design(name, rng, n, nu, ny, groups, evaluation, decision, faults, continuous=True, signals_extra=None):
    nr = sum(len(g) for g in groups)
    cont, disc = _stable_lti(rng, n, ny + nu, nr)
    sig = {"u": [f"u{i + 1}" for i in range(nu)], "y": [f"y{i + 1}" for i in range(ny)]}
    sig.update(signals_extra or {})
    d = {"format": "fmu-fdi-design/1", "name": name, "signals": sig,
         "operating_point": {"u": rng.uniform(-0.5, 0.5, nu).tolist(), "y": rng.uniform(-0.5, 0.5, ny).tolist()},
         "faults": [{"name": f} for f in faults],
         "generator": {"method": "synthetic", "dt": TS, "residual_names": [f"r{i + 1}" for i in range(nr)],
                       "groups": groups,
                       "discrete": {"kind": "lti", **{k: M.tolist() for k, M in zip("ABCD", disc)}},
                       "continuous": ({k: M.tolist() for k, M in zip("ABCD", cont)} if continuous else None)},
         "evaluation": evaluation, "decision": decision}
    return _calibrated(d, rng)


def _calibrated(d, rng, n=400):
    """Fixed thresholds (given as None) at the median evaluation of a pilot run on the
    conformance inputs' distribution, so that alarms rise and fall often."""
    pilot = copy.deepcopy(d)
    for e in pilot["evaluation"]:
        if e["threshold"]["kind"] == "fixed" and e["threshold"]["value"] is None:
            e["threshold"]["value"] = 1e150
    rt = DiagnoserRuntime(pilot)
    nu, ny = rt.nu, rt.ny
    rows = [rt.advance(rng.standard_normal(nu), rng.standard_normal(ny)) for _ in range(n)]
    evals = np.array(rows)[:, rt.n_residuals:rt.n_residuals + rt.n_groups]
    for g, e in enumerate(d["evaluation"]):
        if e["threshold"]["kind"] == "fixed" and e["threshold"]["value"] is None:
            e["threshold"]["value"] = float(np.median(evals[n // 4:, g]))
    return d


def _fixed():
    return {"kind": "fixed", "value": None}


def feature_designs():
    """name -> design dict; every evaluator, threshold and decision kind appears."""
    rng = np.random.default_rng(20261123)
    out = {}
    out["rms_peak_ewrms_adaptive_structure"] = _design(
        "rms_peak_ewrms_adaptive_structure", rng, n=4, nu=2, ny=2, groups=[[0], [1, 2], [3]],
        evaluation=[
            {"evaluator": {"kind": "rms", "window": 7}, "threshold": _fixed()},
            {"evaluator": {"kind": "peak", "window": 5},
             "threshold": {"kind": "adaptive", "a": 0.8, "J0": 0.9}},
            {"evaluator": {"kind": "ewrms", "lambda": 0.9},
             "threshold": {"kind": "adaptive", "a": 0.5, "J0": 0.6, "evaluation": {"kind": "rms", "window": 4}}}],
        decision={"persistence": [2, 3], "latch": False, "isolation": "structure",
                  "structure": [[1, 0], [0, 1], [1, 1]]},
        faults=["f1", "f2"],
        signals_extra={"valid_range": {"y1": [-2.5, 2.5], "u2": [None, 2.0]}})
    out["narendra_norm_majorant_direction"] = _design(
        "narendra_norm_majorant_direction", rng, n=3, nu=1, ny=3, groups=[[0], [1], [2]],
        evaluation=[
            {"evaluator": {"kind": "narendra", "alpha": 0.5, "beta": 2.0, "gamma": 0.8},
             "threshold": {"kind": "majorant", "taps": [0.6, 0.3, 0.1], "tail": 0.05, "J0": 2.0}},
            {"evaluator": {"kind": "norm"}, "threshold": {"kind": "majorant", "taps": [0.4], "J0": 0.8}},
            {"evaluator": {"kind": "rms", "window": 3}, "threshold": _fixed()}],
        decision={"persistence": [1, 1], "latch": True, "isolation": "direction", "min_margin": 0.05,
                  "directions": [[1.0, 0.0, 0.2], [0.5, 0.0, 1.0], [0.0, 0.0, -0.3]]},
        faults=["a", "b", "c"], continuous=False)
    out["chi2_cusum_glr_none"] = _design(
        "chi2_cusum_glr_none", rng, n=5, nu=1, ny=2, groups=[[0, 1], [2, 3], [4]],
        evaluation=[
            {"evaluator": {"kind": "glr", "window": 6, "W": [[1.2, 0.1], [0.0, 0.8]]}, "threshold": _fixed()},
            {"evaluator": {"kind": "cusum", "delta": 0.8, "sigma": [1.1, 0.9]}, "threshold": _fixed()},
            {"evaluator": {"kind": "chi2", "window": 6, "sigma": 1.3}, "threshold": _fixed()}],
        decision={"persistence": [2, 4], "latch": False, "isolation": "none"},
        faults=[], continuous=True)
    out["norm_direction_structure_latch"] = _design(
        "norm_direction_structure_latch", rng, n=2, nu=2, ny=1, groups=[[0], [1]],
        evaluation=[
            {"evaluator": {"kind": "norm"}, "threshold": {"kind": "adaptive", "a": 0.3, "J0": 0.4,
                                                          "evaluation": {"kind": "ewrms", "lambda": 0.7}}},
            {"evaluator": {"kind": "narendra", "alpha": 1.0, "beta": 0.5, "gamma": 0.5},
             "threshold": {"kind": "adaptive", "a": 0.2, "J0": 0.7,
                           "evaluation": {"kind": "narendra", "alpha": 0.0, "beta": 1.0, "gamma": 0.6}}}],
        decision={"persistence": [3, 5], "latch": True, "isolation": "structure", "structure": [[1, 1], [0, 1]]},
        faults=["g1", "g2"])
    return out


#: (name, command-line options of ``fmu-fdi design``) on the DTS200 model
METHOD_RUNS = [
    ("nullspace", ["--method", "nullspace", "--evaluation", "peak:6", "--persistence", "2/3"]),
    ("parity", ["--method", "parity", "--evaluation", "ewrms:0.8"]),
    ("luenberger", ["--method", "luenberger", "--evaluation", "narendra:0.5,1,0.9", "--latch"]),
    ("kalman", ["--method", "kalman", "--Rv", "0.01", "0.01", "0.01", "--evaluation", "chi2:8",
                "--threshold", "sigma:0.01"]),
    ("uio", ["--method", "uio"]),
    ("factorized", ["--method", "factorized", "--evaluation", "norm"]),
    ("dos", ["--method", "dos"]),
    ("gos", ["--method", "gos", "--persistence", "2/2"]),
    ("structured", ["--method", "structured", "--structure", "0,1,1;1,0,1;1,1,0", "--faults", "sensor_h1",
                    "sensor_h2", "sensor_h3"]),
    ("fdf", ["--method", "fdf", "--faults", "pump_Q1", "pump_Q2"]),
]


def method_designs(folder):
    """name -> design dict, one per design method (``fmu-fdi design`` on DTS200, Ts = 1 s)."""
    from fmu_fdi.cli import main

    folder = Path(folder)
    out = {}
    for name, opts in METHOD_RUNS:
        path = folder / f"{name}.json"
        if not path.exists():
            assert main(["design", str(PLANT_MODEL), "--ts", "1", "-o", str(path), *opts]) == 0, name
        out[name] = json.loads(path.read_text(encoding="utf-8"))
    out.update(rls_designs())
    return out


def rls_designs():
    """Two RLS designs (state-variable-filter prefilters on DTS200, one estimator each) with the
    periodic and the floor covariance reset."""
    from fmu_fdi import Diagnoser, FDIModel, rls_estimator

    model = FDIModel.from_file(PLANT_MODEL)
    periodic = rls_estimator(model, output="h1", Ts=1.0, reset="periodic", reset_period=150)
    floor = rls_estimator(model, output="h3", Ts=1.0, reset="floor", reset_trace=50.0, forgetting=1.0)
    return {"rls_periodic": Diagnoser(periodic, evaluation={"kind": "norm"}, thresholds=2.0).design,
            "rls_floor": Diagnoser(floor, evaluation={"kind": "rms", "window": 5}, thresholds=1.5,
                                   decision={"persistence": [2, 3]}).design}
