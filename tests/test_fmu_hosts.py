"""The FMU-hosting layer with a stand-in diagnostic FMU: valid modelDescription, full FMU state,
catch-all callbacks, logging, and identical outputs in every host (docs/fmu-hosts.md).

Every FMU runs in a process of its own (``python -I`` or the C host), never in this one.
Real outputs are compared to the pure-Python reference with atol 1e-12: both sides do the same
O(10) double operations per step on values of order 1, so they may differ by a few ulp
(~1e-15) from exp() and summation order, not more.
"""
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmu_fdi.fmu import hosts
from fmu_fdi.fmu.model_description import patch_fmu, patch_model_description, read_fmu_model_description, validate_fmu
from fmu_fdi.fmu.packaging import build_slave_fmu
from fmu_fdi.fmu.slave_state import StateCodecError, decode_state, encode_state
from hosts import reference as ref

HERE = Path(__file__).parent / "hosts"
H = 0.01          # communication step
N = 200           # rows: t = 0 .. 1.99, the fault at t = 1 and the threshold change at 1.5 inside
STANDIN_OPTIONS = dict(
    units={"u1": "m3/s", "u2": "m3/s", "y1": "m", "residual_1": "m", "residual_2": "m", "evaluation_1": "m",
           "evaluation_2": "m", "threshold_1": "m", "threshold_2": "m", "tau": "s"},
    output_dependencies={"residual_1": ["u1", "y1"], "evaluation_1": ["u1", "y1"], "threshold_1": [],
                         "residual_2": ["u2", "y1"], "evaluation_2": ["u2", "y1"], "threshold_2": []},
    initial_dependencies={"threshold_1": ["threshold_scale"], "threshold_2": ["threshold_scale"]},
    capabilities={"canGetAndSetFMUstate": True, "canSerializeFMUstate": True,
                  "canHandleVariableCommunicationStepSize": True, "needsExecutionTool": True,
                  "canBeInstantiatedOnlyOncePerProcess": False},
    default_experiment={"startTime": 0.0, "stepSize": H},
    require_descriptions=True,
)


def build_standin(dest, variant=None, **kw):
    src = (HERE / "standin.py").read_text()
    if variant is not None:
        src = src.replace("VARIANT = 1.0", f"VARIANT = {variant!r}")
    return build_slave_fmu({"standin.py": src}, "standin:StandIn", dest, **dict(STANDIN_OPTIONS, **kw))


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmuhosts")
    data = ref.signals(N, H)
    return {
        "dir": d,
        "standin": build_standin(d / "StandIn.fmu"),
        "plant": build_slave_fmu({"plant.py": (HERE / "plant.py").read_text()}, "plant:Plant", d / "Plant.fmu",
                                 output_dependencies={"u1": [], "u2": [], "y1": []}, require_descriptions=True),
        "data": data,
        "csv": hosts.write_csv(d / "inputs.csv", data),
    }


# ---- 1. modelDescription ---------------------------------------------------------------------
def test_built_fmus_pass_fmpy_validate(work):
    assert validate_fmu(work["standin"]) == []
    assert validate_fmu(work["plant"]) == []
    # the CLI says the same (exit status = number of problems)
    proc = subprocess.run([sys.executable, "-I", "-m", "fmpy", "validate", str(work["standin"])],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout


def test_raw_pythonfmu_description_fails_and_patch_fixes_it(tmp_path):
    from fmu_fdi.fmu.packaging import installed_pythonfmu

    script = tmp_path / "rawslave.py"
    script.write_text(
        "from pythonfmu import Fmi2Slave, Fmi2Causality as C, Real, Integer, Boolean\n"
        "class RawSlave(Fmi2Slave):\n"
        "    def __init__(self, **kw):\n"
        "        super().__init__(**kw)\n"
        "        self.u = 0.0; self.r = 0.0; self.a = False; self.i = 0\n"
        "        self.register_variable(Real('u', causality=C.input))\n"
        "        self.register_variable(Real('r', causality=C.output))\n"
        "        self.register_variable(Boolean('a', causality=C.output))\n"
        "        self.register_variable(Integer('i', causality=C.output))\n"
        "    def do_step(self, t, h):\n"
        "        return True\n")
    try:
        with installed_pythonfmu():  # not the binary-less copy of an FMU that ran in this process
            from pythonfmu import FmuBuilder

            fmu = FmuBuilder.build_FMU(script, dest=tmp_path / "RawSlave.fmu")
    finally:
        sys.modules.pop("rawslave", None)
        sys.path[:] = [p for p in sys.path if p != str(tmp_path)]
    problems = validate_fmu(fmu)
    assert any('"a"' in p and "continuous" in p for p in problems)
    assert any("InitialUnknowns" in p for p in problems)
    patch_fmu(fmu)
    assert validate_fmu(fmu) == []


def test_model_description_content(work):
    import xml.etree.ElementTree as ET

    root = ET.fromstring(read_fmu_model_description(work["standin"]))
    sv = {e.get("name"): e for e in root.find("ModelVariables")}
    index = {name: str(i + 1) for i, name in enumerate(sv)}
    assert "initial" not in sv["u1"].attrib and sv["u1"].get("variability") == "continuous"
    assert (sv["threshold_scale"].get("variability"), sv["threshold_scale"].get("initial")) == ("tunable", "exact")
    assert (sv["tau"].get("variability"), sv["tau"].get("initial")) == ("fixed", "exact")
    for name in ("alarm_1", "fault_detected", "isolated_fault", "input_invalid"):
        assert (sv[name].get("variability"), sv[name].get("initial")) == ("discrete", "calculated")
    assert all(e.get("description") for e in sv.values())
    assert sv["residual_1"].find("Real").get("unit") == "m"
    assert "start" not in sv["residual_1"].find("Real").attrib
    assert sorted(u.get("name") for u in root.find("UnitDefinitions")) == ["m", "m3/s", "s"]
    outputs = {u.get("index"): u.get("dependencies") for u in root.find("ModelStructure/Outputs")}
    assert outputs[index["residual_1"]] == f"{index['u1']} {index['y1']}"
    assert outputs[index["threshold_1"]] == ""
    assert outputs[index["fault_detected"]] == " ".join(index[n] for n in ("u1", "u2", "y1"))
    initial = {u.get("index"): u.get("dependencies") for u in root.find("ModelStructure/InitialUnknowns")}
    assert set(initial) == {index[n] for n, e in sv.items() if e.get("causality") == "output"}
    assert initial[index["threshold_2"]] == index["threshold_scale"]
    cs = root.find("CoSimulation").attrib
    assert cs["canGetAndSetFMUstate"] == cs["canSerializeFMUstate"] == "true"
    assert [c.tag for c in root][:3] == ["CoSimulation", "UnitDefinitions", "LogCategories"]
    cats = {c.get("name") for c in root.find("LogCategories")}
    assert {"logFdiEvents", "logFdiInput", "logStatusError"} <= cats


@pytest.mark.parametrize("options, message", [
    ({"units": {"nope": "m"}}, "no variable named 'nope'"),
    ({"units": {"alarm_1": "m"}}, "Real variables only"),
    ({"output_dependencies": {"residual_1": ["tau"]}}, "not inputs"),
    ({"output_dependencies": {"u1": []}}, "not an output"),
    ({"initial_dependencies": {"residual_1": ["residual_2"]}}, "neither inputs nor exact parameters"),
    ({"capabilities": {"canFly": True}}, "unknown CoSimulation capabilities"),
])
def test_patch_rejects_wrong_statements(work, options, message):
    with pytest.raises(ValueError, match=message):
        patch_model_description(read_fmu_model_description(work["standin"]), **options)


# ---- 2. state codec (in this process: it is plain numpy + stdlib) ------------------------------
def test_state_codec_is_exact():
    state = {"x": np.array([[1.0, -0.0], [np.nan, np.inf]]), "k": np.int64(-7), "i32": np.arange(5, dtype=np.int32),
             "b": np.array([True, False]), "c": np.array([1 + 2j], dtype=np.complex128), "f": 0.1, "nan": float("nan"),
             "negz": -0.0, "big": 2 ** 80, "t": (1, "a", None), "s": {1, 2}, "bytes": b"\x00\xff",
             "nested": [{"deep": np.zeros((0, 3))}], 3: "int key", "be": np.array([1.5], dtype=">f8")}
    back = decode_state(encode_state(state))
    assert set(back) == set(state)
    for key in ("x", "i32", "b", "c", "be"):
        assert back[key].dtype.newbyteorder("=") == state[key].dtype.newbyteorder("=")
        assert back[key].tobytes() == state[key].astype(back[key].dtype).tobytes()
    assert type(back["k"]) is np.int64 and back["k"] == -7
    assert np.isnan(back["nan"]) and str(back["negz"]) == "-0.0" and back["big"] == 2 ** 80
    assert back["t"] == (1, "a", None) and back["s"] == {1, 2} and back["bytes"] == b"\x00\xff"
    assert back["nested"][0]["deep"].shape == (0, 3) and back[3] == "int key"
    back["x"][0, 0] = 5.0  # decoded arrays are writable copies


def test_state_codec_refuses_what_it_cannot_restore():
    with pytest.raises(StateCodecError, match="cannot encode"):
        encode_state({"f": lambda: 1})
    with pytest.raises(StateCodecError, match="bad magic"):
        decode_state(b"pickle? no")
    blob = encode_state({"x": np.ones(4)})
    with pytest.raises(StateCodecError, match="truncated"):
        decode_state(blob[:-3])


# ---- 2. FMU state, reset, failures, logging (in fmpy FMU2Slave processes) ---------------------
def _run_scenario(name, spec, tmp_path):
    spec = dict(spec, workdir=str(tmp_path))
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    proc = subprocess.run([sys.executable, "-I", str(HERE / "scenarios.py"), name, str(tmp_path / "spec.json")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    answer = json.loads((tmp_path / "answer.json").read_text())
    return answer, {n: np.load(tmp_path / f"{n}.npy") for n in answer["arrays"]}


def test_state_save_restore_serialize_reset(work, tmp_path):
    np.save(tmp_path / "in.npy", work["data"])
    spec = {"fmu": str(work["standin"]), "inputs": str(tmp_path / "in.npy"), "step": H}
    first_dir = tmp_path / "run1"
    first_dir.mkdir()
    answer, a = _run_scenario("state", spec, first_dir)
    # save -> 100 steps -> restore -> 100 steps (twice): bit-identical outputs of every type
    assert np.array_equal(a["first"], a["repeat1"]) and np.array_equal(a["first"], a["repeat2"])
    # serialized bytes restored into a second instance in the same process
    assert np.array_equal(a["first"], a["second"])
    # fmi2Reset returns to the just-instantiated state: same outputs and same FMU state as a fresh instance
    assert np.array_equal(a["after_reset"], a["fresh"])
    s_reset = decode_state((first_dir / "reset_state.bin").read_bytes())["attributes"]
    s_fresh = decode_state((first_dir / "fresh_state.bin").read_bytes())["attributes"]
    assert s_reset.keys() == s_fresh.keys()
    for key in s_fresh:
        assert np.array_equal(s_reset[key], s_fresh[key]), key
    # the serialized state is the whole instance, numpy arrays with their dtype included
    saved = decode_state((first_dir / "state.bin").read_bytes())["attributes"]
    assert saved["x"].dtype == np.float64 and saved["x"].shape == (2,)
    assert saved["alarm_count"].dtype == np.int64 and saved["n_steps"] == 50
    # a corrupt state is not fatal: set returns OK, the next step is discarded, reset heals
    assert answer["statuses"] == {"after_corrupt": 2, "terminated": True}
    assert np.array_equal(a["healed"], a["fresh"])
    errors = [entry for entry in answer["log"] if entry[2] == "logStatusError"]
    assert any("bad magic" in e[3] for e in errors), errors
    # bytes written by that process restored in a new process
    second_dir = tmp_path / "run2"
    second_dir.mkdir()
    _, b = _run_scenario("state", dict(spec, foreign_state=str(first_dir / "state.bin")), second_dir)
    assert np.array_equal(b["foreign"], a["first"])


def test_exception_in_step_becomes_discard_not_fatal(work):
    ans = hosts.run_fmu2slave(work["standin"], work["data"][:20], step=H, parameters={"fail_at_step": 5},
                              log_categories=[])
    assert ans["statuses"] == [0, 0, 0, 0, 0, 2]  # fmi2Discard at the 6th doStep
    assert ans["terminated"] is True
    errors = [m for s, c, m in ans["log"] if c == "logStatusError"]
    assert len(errors) == 1 and "injected failure at step 5" in errors[0] and "Traceback" in errors[0]
    ref.assert_matches(ans["result"], ref.aligned(work["data"][:6], H))


def test_log_categories_and_invalid_input(work):
    data = work["data"][:120].copy()
    data["y1"][30:33] = np.nan
    everything = hosts.run_fmu2slave(work["standin"], data, step=H, log_categories=[])
    only_input = hosts.run_fmu2slave(work["standin"], data, step=H, log_categories=["logFdiInput"])
    off = hosts.run_fmu2slave(work["standin"], data, step=H, log_categories=None)
    cats = [c for _, c, _ in everything["log"]]
    assert {"logAll", "logFdiEvents", "logFdiInput"} <= set(cats)
    assert [(s, c) for s, c, _ in only_input["log"]] == [(1, "logFdiInput")] * 3  # status 1 = fmi2Warning
    assert off["log"] == []
    assert "numpy" in everything["log"][0][2]  # the environment line logged at instantiation
    r = everything["result"]
    assert list(np.flatnonzero(r["input_invalid"])) == [30, 31, 32]
    ref.assert_matches(r, ref.aligned(data, H))


# ---- 3. hosts ---------------------------------------------------------------------------------
def test_fmpy_cli_with_recorded_csv(work):
    out, stdout = hosts.run_fmpy_cli(work["standin"], input_csv=work["csv"], output_csv=work["dir"] / "cli.csv",
                                     output_interval=H, stop_time=(N - 1) * H, debug_logging=True)
    assert len(out) == N and np.allclose(out["time"], work["data"]["time"], rtol=0, atol=1e-12)
    # fmpy reads outputs right after doStep, before it applies the inputs of the new time
    ref.assert_matches(out, ref.after_step(work["data"], np.r_[np.diff(out["time"]), H]))
    assert "alarm raised" in stdout


def test_fmpy_cli_default_interval_changes_the_step(work):
    # without --output-interval fmpy steps with DefaultExperiment stepSize doubled until at
    # most 1000 steps remain: 20 s at 0.01 s (2000 steps) becomes 1000 steps of 0.02 s
    args = [sys.executable, "-I", "-m", "fmpy", "simulate", str(work["standin"]), "--stop-time", "20",
            "--output-file", str(work["dir"] / "default.csv")]
    subprocess.run(args, check=True, capture_output=True, timeout=120)
    out = hosts.read_csv(work["dir"] / "default.csv")
    assert np.allclose(np.diff(out["time"]), 0.02)


def test_fmu2slave_loop(work):
    ans = hosts.run_fmu2slave(work["standin"], work["data"], step=H)
    assert ans["statuses"] == [0] * N
    ref.assert_matches(ans["result"], ref.aligned(work["data"], H))
    assert set(ans["result"]["isolated_fault"]) == {-1, 0, 1, 2}  # none, each alone, both


@pytest.mark.skipif(importlib.util.find_spec("libcosimpy") is None,
                    reason="libcosimpy is not installed (test extra: libcosimpy>=0.0.6)")
def test_libcosim_plant_and_diagnoser(work):
    names = ("u1", "u2", "y1")
    ans = hosts.run_libcosim({"plant": work["plant"], "diag": work["standin"]},
                             [("plant", n, "diag", n) for n in names], step=H, stop_time=N * H,
                             observe={"plant": list(names), "diag": list(ref.OUTPUTS)})
    plant, diag = ans["plant"], ans["diag"]
    times = np.arange(N + 1) * H
    assert len(diag) == N and np.allclose(diag["time"], times[1:], rtol=0, atol=1e-12)
    v = ref.plant(times, H)
    assert np.max(np.abs(np.column_stack([plant[n] for n in names]) - v[1:])) <= 1e-12
    # libcosim samples after doStep; the diagnoser still holds the inputs of the step: v_k
    x = ref.states(v[:-1], H)
    ref.assert_matches(diag, ref.outputs(x[1:], v[:-1], 1.0))


def test_container_fmu_plant_and_diagnoser(work):
    names = ("u1", "u2", "y1")
    exposed = [("plant", n) for n in names] + [("diag", n) for n in ref.OUTPUTS]
    container = hosts.build_container_fmu({"plant": work["plant"], "diag": work["standin"]},
                                          [("plant", n, "diag", n) for n in names], exposed,
                                          work["dir"] / "Container.fmu", step=H)
    assert validate_fmu(container) == []
    out, _ = hosts.run_fmpy_cli(container, input_csv=None, output_csv=work["dir"] / "container.csv",
                                output_interval=H, stop_time=N * H)
    times = np.arange(N + 1) * H
    v = ref.plant(times, H)
    assert np.max(np.abs(np.column_stack([out[f"plant.{n}"] for n in names]) - v)) <= 1e-12
    # the container transfers plant outputs to the diagnoser right after each step: aligned rows
    diag = out[[f"diag.{n}" for n in ref.OUTPUTS]]
    diag.dtype.names = ref.OUTPUTS
    ref.assert_matches(diag, ref.outputs(ref.states(v, H)[:-1], v, 1.0))


def _c_host_or_skip(tmp_path):
    if not (shutil.which("gcc") or shutil.which("cc")):
        pytest.skip("no C compiler")
    try:
        hosts.libpython_path()
    except hosts.HostError as exc:
        pytest.skip(str(exc))
    return hosts.compile_c_host(HERE / "c_host.c", tmp_path / "c_host")


def test_c_host_without_python_in_the_process(work, tmp_path):
    exe = _c_host_or_skip(tmp_path)
    out, stdout = hosts.run_c_host(exe, work["standin"], work["csv"], tmp_path / "c_out.csv", step=H)
    ref.assert_matches(out, ref.aligned(work["data"], H))
    assert "[OK][c_host][logFdiEvents] t=0: alarm raised" in stdout  # the FMI logger, printf-formatted
    site = hosts.c_host_env()["PYTHONPATH"].split(":")[0]
    assert f"numpy {np.__version__} at {site}/numpy" in stdout  # numpy of this environment


def test_c_host_environment_is_needed(work, tmp_path):
    exe = _c_host_or_skip(tmp_path)
    unzip = tmp_path / "unzipped"
    with zipfile.ZipFile(work["standin"]) as zf:
        zf.extractall(unzip)

    def run_without(name):
        env = hosts.c_host_env()
        del env[name]
        # An embedded interpreter without PYTHONHOME/PYTHONPATH hints resolves its prefix from
        # the first "python" on PATH: inside an activated virtual environment (as in CI) it
        # finds that environment by itself. Drop this environment's bin folder from PATH to
        # show what a host outside it gets.
        venv_bin = str(Path(sys.executable).parent)
        env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if p != venv_bin)
        return subprocess.run([str(exe), str(unzip), str(work["csv"]), str(tmp_path / "o.csv"), repr(H)], env=env,
                              capture_output=True, text=True, timeout=60)

    proc = run_without("LD_PRELOAD")
    assert proc.returncode == 2 and "undefined symbol: _Py" in proc.stderr
    # without PYTHONPATH the embedded interpreter does not see this environment's site-packages:
    # it either fails to import numpy or takes another numpy (the base interpreter's)
    proc = run_without("PYTHONPATH")
    site = hosts.c_host_env()["PYTHONPATH"].split(":")[0]
    assert f"at {site}/numpy" not in proc.stdout


def test_module_names_must_be_unique_per_fmu(work, tmp_path):
    """pythonfmu issue 228: two FMUs whose slave module names are equal share the first one's code."""
    np.save(tmp_path / "in.npy", work["data"])

    def pair(tag, **kw):
        d = tmp_path / tag
        return [str(build_standin(d / "a" / "StandIn.fmu", variant=1.0, **kw)),
                str(build_standin(d / "b" / "StandIn.fmu", variant=2.0, **kw))]

    spec = {"inputs": str(tmp_path / "in.npy"), "step": H}
    (tmp_path / "same").mkdir()
    (tmp_path / "unique").mkdir()
    same = pair("same", bundle_name="fdi_slave")
    unique = pair("unique")
    assert Path(unique[0]).read_bytes() != Path(unique[1]).read_bytes()
    _, clash = _run_scenario("clash", dict(spec, fmus=same), tmp_path / "same")
    _, fine = _run_scenario("clash", dict(spec, fmus=unique), tmp_path / "unique")
    expect = ref.aligned(work["data"][:50], H)
    r1 = list(ref.OUTPUTS).index("residual_1")
    # same module name: the second FMU silently runs the first one's code
    assert np.array_equal(clash["fmu1"], clash["fmu0"])
    # unique names (the default): each FMU runs its own code, in the same process
    assert np.max(np.abs(fine["fmu0"][:, r1] - expect["residual_1"])) <= 1e-12
    assert np.max(np.abs(fine["fmu1"][:, r1] - 2 * expect["residual_1"])) <= 1e-12
