"""Conformance of the native diagnostic FMU with the Python runtime (issue 8, docs/semantics.md).

Every design (synthetic ones that use every evaluator, threshold, isolation and decision
option; one per design method on the DTS200 plant, RLS included) is built as a native FMU,
as shipped, and driven in a subprocess by fmpy (tests/native_fmu_runner.py) through 3000
random calls with NaN/Inf bursts, out-of-range and overflowing samples, threshold_scale
changes, resets and FMU-state roll-backs, and with communication steps of Ts, multiples of
Ts, odd steps (exact re-discretisation of continuous designs) and steps that must be refused.
The reference is ``Diagnoser.from_design(...).runtime`` on the same operations, i.e. exactly
what ``Diagnoser.run`` does per row.
"""
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from fmu_fdi import build_fmu
from fmu_fdi.designfile import DesignFileError
from fmu_fdi.native.emit import EVALUATORS, THRESHOLDS, ISOLATIONS, RLS_POLICIES, NativeDesignError, emit_design_c
from fmu_fdi.runtime.engine import DiagnoserRuntime, output_type
from native_designs import METHOD_RUNS, feature_designs, method_designs
from native_runtime import CRuntime, c_outputs, compile_runtime
from native_scenario import compare, make_scenario, python_outputs

pytestmark = pytest.mark.slow

N_STEPS = 3000
RTOL = 1e-12  # docs/semantics.md §1: relative to each output's size, absolute below 1
FEATURE_NAMES = ["rms_peak_ewrms_adaptive_structure", "narendra_norm_majorant_direction", "chi2_cusum_glr_none",
                 "norm_direction_structure_latch"]
METHOD_NAMES = [name for name, _ in METHOD_RUNS] + ["rls_periodic", "rls_floor"]
FMI3 = ("rms_peak_ewrms_adaptive_structure", "rls_floor")  # also run as FMI 3.0 FMUs
RUNNER = Path(__file__).parent / "native_fmu_runner.py"


def _steps(Ts):
    """Ts, multiples (sub-steps), odd steps (re-discretised or refused), too small / too many."""
    return [Ts, 3 * Ts, 0.37 * Ts, 2.5 * Ts, Ts / 40, 20001 * Ts]


@pytest.fixture(scope="module")
def designs(tmp_path_factory):
    out = dict(feature_designs())
    out.update(method_designs(tmp_path_factory.mktemp("designs")))
    return out


@pytest.fixture(scope="module")
def runs(designs, tmp_path_factory):
    """name -> (scenario, python reference, {fmi version: native outputs}, output names)."""
    folder = tmp_path_factory.mktemp("native_fmus")
    jobs, specs = [], []
    for name, d in designs.items():
        for fmi in ((2, 3) if name in FMI3 else (2,)):
            specs.append((name, fmi, folder / f"{name}_fmi{fmi}.fmu"))
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:  # the compiler runs in subprocesses
        list(pool.map(lambda s: build_fmu(designs[s[0]], s[2], target="native", fmi_version=s[1]), specs))
    scenarios = {}
    for i, (name, d) in enumerate(designs.items()):
        scenarios[name] = make_scenario(d, np.random.default_rng(1000 + i), N_STEPS,
                                        _steps(float(d["generator"]["dt"])))
    for name, fmi, path in specs:
        jobs.append({"fmu": str(path), "fmi": fmi, "ops": scenarios[name]})
    (folder / "jobs.json").write_text(json.dumps(jobs), encoding="utf-8")
    proc = subprocess.run([sys.executable, str(RUNNER), str(folder / "jobs.json"), str(folder / "result.json")],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    results = json.loads((folder / "result.json").read_text(encoding="utf-8"))
    out = {}
    for (name, fmi, _), res in zip(specs, results):
        if name not in out:
            rt = DiagnoserRuntime(designs[name])
            out[name] = (scenarios[name], python_outputs(designs[name], scenarios[name]), {}, rt.names)
            assert res["names"] == rt.names  # the same outputs in the same order
        out[name][2][fmi] = res["outputs"]
    return out


def _check(name, runs, designs):
    ops, ref, native, names = runs[name]
    types = [output_type(n) for n in names]
    is_rls = designs[name]["generator"]["discrete"]["kind"] == "rls"
    for fmi, got in native.items():
        # RLS: both runtimes sum sequentially in index order (docs/semantics.md §4.2), because the
        # recursion amplifies last-bit differences of a summation order: equal bit for bit
        worst, bad = compare(names, types, ref, got, rtol=0.0 if is_rls else RTOL)
        assert not bad, f"{name} FMI {fmi}:\n" + "\n".join(bad)
        print(f"{name} FMI {fmi}: max deviation {worst:.3g}")
    # the scenario exercised what it is meant to (else the comparison proves little)
    steps = [r for r in ref if r != "discard"]
    arr = np.array(steps)
    assert 0 < sum(r == "discard" for r in ref) < len(ref) // 4
    assert arr[:, -2].any() and arr[:, -1].any(), "no invalid input or no numeric reset exercised"
    alarms = arr[:, -4]
    assert 0.02 < alarms.mean() < 0.98 or designs[name]["decision"].get("latch"), "alarms never toggle"
    assert any(op[0] == "restore" for op in ops) and any(op[0] == "reset" for op in ops)


@pytest.mark.parametrize("name", FEATURE_NAMES)
def test_native_fmu_equals_python_runtime_every_kind(name, runs, designs):
    _check(name, runs, designs)


@pytest.mark.parametrize("name", METHOD_NAMES)
def test_native_fmu_equals_python_runtime_every_method(name, runs, designs):
    _check(name, runs, designs)


def test_the_suite_covers_every_kind(designs):
    """Every evaluator, threshold, isolation, reset policy and decision option is in some design,
    and some continuous design is run at an odd step."""
    evals = {e["evaluator"]["kind"] for d in designs.values() for e in d["evaluation"]}
    thrs = {e["threshold"]["kind"] for d in designs.values() for e in d["evaluation"]}
    isos = {d["decision"].get("isolation", "none") for d in designs.values()}
    policies = {d["generator"]["discrete"].get("reset", {}).get("policy", "none") for d in designs.values()
                if d["generator"]["discrete"]["kind"] == "rls"}
    assert evals == set(EVALUATORS) and thrs == set(THRESHOLDS) and isos == set(ISOLATIONS)
    assert policies >= {"floor", "periodic"} and set(RLS_POLICIES) >= policies
    assert any(d["decision"].get("latch") for d in designs.values())
    assert any(d["decision"].get("persistence", [1, 1])[1] > 1 for d in designs.values())
    assert any(d["signals"].get("valid_range") for d in designs.values())
    assert any(d["generator"].get("continuous") for d in designs.values())


@pytest.mark.parametrize("item, value", [("window", 100_001), ("persistence", [1, 200_000])])
def test_a_design_the_c_runtime_cannot_express_is_refused_at_build_time(designs, tmp_path, item, value):
    """Beyond the sizes the C runtime lays its block out for: a clear error naming the item, no
    FMU file (the design-file validator may refuse it first, S5: either names the item)."""
    d = json.loads(json.dumps(designs["rms_peak_ewrms_adaptive_structure"]))
    if item == "window":
        d["evaluation"][0]["evaluator"]["window"] = value
    else:
        d["decision"]["persistence"] = value
    with pytest.raises((NativeDesignError, DesignFileError), match=item):
        build_fmu(d, tmp_path / "x.fmu", target="native")
    assert not (tmp_path / "x.fmu").exists()


def test_emitted_constants_round_trip_exactly(designs):
    """Every double of the design appears as a hex literal that parses back to the same bits."""
    import re

    d = designs["chi2_cusum_glr_none"]
    src = emit_design_c(d)
    lits = {float.fromhex(x) for x in re.findall(r"-?0x[0-9a-f]\.[0-9a-f]*p[+-]\d+", src)}
    M = DiagnoserRuntime(d).generator.M
    assert set(M.ravel().tolist()) <= lits


def test_runtime_in_process_over_a_long_sequence(designs, tmp_path):
    """The runtime alone (ctypes, no FMI) over 20000 calls of the continuous design with valid
    ranges and odd steps: many ring wraps (exact re-summation), resets and roll-backs."""
    d = designs["rms_peak_ewrms_adaptive_structure"]
    ops = make_scenario(d, np.random.default_rng(7), 20_000, _steps(float(d["generator"]["dt"])))
    got = c_outputs(compile_runtime(d, tmp_path), ops)
    names = DiagnoserRuntime(d).names
    worst, bad = compare(names, [output_type(n) for n in names], python_outputs(d, ops), got, rtol=RTOL)
    assert not bad, "\n".join(bad)
    print(f"20000 calls in process: max deviation {worst:.3g}")


def test_runtime_refuses_a_bad_threshold_scale_and_keeps_the_old_one(designs, tmp_path):
    rt = CRuntime(compile_runtime(designs["chi2_cusum_glr_none"], tmp_path))
    assert rt.set_threshold_scale(2.5) == 0
    for bad in (float("nan"), float("inf"), -1.0):
        assert rt.set_threshold_scale(bad) == 2  # FDI_ERROR, with a reason
        assert "threshold_scale" in rt.why.value.decode()
    assert rt.threshold_scale() == 2.5
