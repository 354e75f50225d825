"""The diagnostic FMU as shipped, in every host, against Diagnoser.run.

Each host runs in its own process (fmu_fdi.fmu.hosts), so the test process's imports cannot
stand in for what the FMU bundles. Timing convention of the FMU: fmi2DoStep(t_k) consumes
the inputs set for t_k and makes the outputs the diagnosis of that sample, so an output read
after the step for t_k (row k+1 of a host that reads before stepping) equals row k of
Diagnoser.run. Outputs must agree to 1e-12 (the same runtime code on the same floats; the
bound only absorbs the host's float formatting of CSV files, which is exact with repr).
"""
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import published as pub
from fdi_plant import build_plant
from fmu_fdi import Diagnoser, FDIModel, build_fmu, nullspace_design, parity_space, rls_estimator
from fmu_fdi.designfile import DesignFileError
from fmu_fdi.fmu import hosts
from simulate import plant_outputs

TS = 0.01
N = 200
NARENDRA = {"kind": "narendra", "alpha": 0.0, "beta": 10.0, "gamma": 0.9}
TOL = 1e-12
HOSTS_DIR = Path(__file__).parent / "hosts"


def a7_record():
    t = np.arange(N) * TS
    u = np.sin(2 * np.pi * t)[:, None]
    d = np.random.default_rng(0).standard_normal((N, 1))
    f = np.zeros((N, 2))
    f[5:] = 0.5
    y = plant_outputs(pub.ex5_3(), N, TS, u=u, d=d, f=f)
    return t, u, y


def as_inputs(t, u, y, names=("u", "y1", "y2")):
    arr = np.zeros(t.size, dtype=[("time", "f8")] + [(n, "f8") for n in names])
    arr["time"] = t
    cols = np.hstack([u, y])
    for j, n in enumerate(names):
        arr[n] = cols[:, j]
    return arr


def assert_matches(host, ref, names, shift=1):
    """host row k+shift == ref row k for every output (bool/int exactly, reals to TOL)."""
    n = min(len(host[names[0]]) - shift, len(ref))
    assert n > 10
    for nm in names:
        h = np.asarray(host[nm][shift:shift + n], float)
        r = np.asarray(ref[nm][:n], float)
        assert np.allclose(h, r, rtol=0, atol=TOL * max(1.0, np.abs(r).max())), nm


@pytest.fixture(scope="module")
def ex53(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ex53")
    gen = nullspace_design(pub.ex5_3(), poles=[-3])
    dg = Diagnoser(gen, Ts=TS, evaluation=NARENDRA, thresholds=1.0)
    fmu = build_fmu(dg, tmp / "ex53_fdi.fmu")
    t, u, y = a7_record()
    return {"dg": dg, "fmu": fmu, "t": t, "u": u, "y": y, "ref": dg.run(t, u, y), "tmp": tmp,
            "outputs": dg.output_names}


def test_fmpy_validate_finds_no_problem(ex53):
    res = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(ex53["fmu"])], capture_output=True, text=True)
    assert res.returncode == 0 and "No problems found" in res.stdout, res.stdout + res.stderr


def test_fmu2slave_loop_matches_diagnoser_run(ex53):
    ans = hosts.run_fmu2slave(ex53["fmu"], as_inputs(ex53["t"], ex53["u"], ex53["y"]), step=TS,
                              outputs=ex53["outputs"])
    assert_matches(ans["result"], ex53["ref"], ex53["outputs"])
    assert ex53["ref"]["fault_detected"].any()  # the record does exercise the alarm path


def test_host_exits_cleanly_whatever_its_heap_layout(ex53, monkeypatch):
    """pythonfmu 0.7 releases its interpreter handle twice at exit (fmu_fdi.fmu.exit_guard):
    whether the host then aborts ("corrupted double-linked list", exit -6) after its work is
    done depends only on its heap layout. The host's environment is copied onto its heap, so
    environments of different sizes give different layouts; every one must exit 0."""
    inputs = as_inputs(ex53["t"], ex53["u"], ex53["y"])[:20]
    for pad in range(0, 2400, 300):  # 8 layouts; before the guard, 6 of them aborted here
        monkeypatch.setenv("FMU_FDI_TEST_HEAP_PAD", "x" * pad)
        ans = hosts.run_fmu2slave(ex53["fmu"], inputs, step=TS, outputs=["fault_detected"])  # HostError if not 0
        assert ans["statuses"] == [0] * len(inputs)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_host_shutdown_is_clean_under_valgrind(ex53, tmp_path):
    """No invalid memory access in the FMU's library in the whole life of an fmpy host, exit
    included (before the guard: "Invalid read of size 4 at finalizePythonInterpreter", a
    block freed by the exit handlers, in every layout)."""
    np.save(tmp_path / "inputs.npy", as_inputs(ex53["t"], ex53["u"], ex53["y"])[:5], allow_pickle=False)
    spec = {"fmu": str(ex53["fmu"]), "inputs": str(tmp_path / "inputs.npy"), "step": TS,
            "outputs": ["fault_detected"], "parameters": {}, "log_categories": None, "workdir": str(tmp_path)}
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    log = tmp_path / "valgrind.log"
    proc = subprocess.run(["valgrind", "--undef-value-errors=no", f"--log-file={log}", sys.executable, "-I",
                           str(hosts.WORKER), "fmu2slave", str(tmp_path / "spec.json")],
                          env=hosts.python_env(), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    # one valgrind error report per block of lines between "==pid== " separators
    blocks = re.split(r"\n==\d+== \n", log.read_text())
    assert (tmp_path / "answer.json").exists()
    ours = [b for b in blocks if re.search(r"^==\d+== (Invalid|Mismatched|Conditional|Syscall)", b, re.M)
            and ("finalizePythonInterpreter" in b or "pythonfmu" in b or "/binaries/" in b)]
    assert not ours, "\n".join(ours)[:3000]


def test_exit_guard_never_loads_a_library_itself(ex53, tmp_path):
    """The guard only ever takes the library the host loaded (RTLD_NOLOAD): for an FMU not
    loaded in this process it guards nothing and loads nothing (a second copy would run
    pythonfmu's static constructors and add one more global to release at exit)."""
    import zipfile

    from fmu_fdi.fmu.exit_guard import guard_interpreter_exit

    with zipfile.ZipFile(ex53["fmu"]) as zf:
        zf.extractall(tmp_path)
    libs = list(tmp_path.glob("binaries/*/*"))
    assert libs
    assert guard_interpreter_exit(str(tmp_path / "resources"), libs[0].stem) is None
    maps = Path("/proc/self/maps")
    if maps.exists():
        assert str(tmp_path) not in maps.read_text()


def test_fmpy_simulate_offline_csv_matches(ex53, tmp_path):
    csv_in = hosts.write_csv(tmp_path / "log.csv", as_inputs(ex53["t"], ex53["u"], ex53["y"]))
    res, _ = hosts.run_fmpy_cli(ex53["fmu"], input_csv=csv_in, output_csv=tmp_path / "out.csv",
                                output_interval=TS, stop_time=ex53["t"][-1])
    assert_matches(res, ex53["ref"], ex53["outputs"])


def test_c_host_without_python_in_the_process(ex53, tmp_path):
    exe = hosts.compile_c_host(HOSTS_DIR / "c_host.c", tmp_path / "c_host")
    csv_in = hosts.write_csv(tmp_path / "log.csv", as_inputs(ex53["t"], ex53["u"], ex53["y"]))
    res, _ = hosts.run_c_host(exe, ex53["fmu"], csv_in, tmp_path / "out.csv", step=TS)
    assert_matches(res, ex53["ref"], ex53["outputs"])


@pytest.fixture(scope="module")
def plant_fmu(ex53):
    return build_plant(ex53["tmp"] / "ex53_plant.fmu", TS)


def test_libcosim_with_a_plant_fmu(ex53, plant_fmu):
    pytest.importorskip("libcosimpy", reason="libcosimpy (DNV OSP libcosim) is a test extra")
    conn = [("plant", n, "fdi", n) for n in ("u", "y1", "y2")]
    ans = hosts.run_libcosim({"plant": plant_fmu, "fdi": ex53["fmu"]}, conn, step=TS, stop_time=0.8,
                             observe={"plant": ["u", "y1", "y2"], "fdi": ex53["outputs"]})
    plant, fdi = ans["plant"], ans["fdi"]
    ref = ex53["dg"].run(plant["time"], np.c_[plant["u"]], np.c_[plant["y1"], plant["y2"]])
    # libcosim reads after each step; whichever one-sample alignment it has, it is one for all rows
    shifts = [s for s in (0, 1, 2) if np.allclose(fdi["evaluation_1"][s:s + 50], ref["evaluation_1"][:50],
                                                   rtol=0, atol=TOL)]
    assert shifts, "no consistent alignment between libcosim rows and Diagnoser.run"
    assert_matches(fdi, ref, ex53["outputs"], shift=shifts[0])
    assert fdi["fault_detected"].any()


def test_container_fmu_holding_plant_and_diagnoser(ex53, plant_fmu, tmp_path):
    conn = [("plant", n, "fdi", n) for n in ("u", "y1", "y2")]
    exposed = [("plant", n) for n in ("u", "y1", "y2")] + [("fdi", n) for n in ex53["outputs"]]
    container = hosts.build_container_fmu({"plant": plant_fmu, "fdi": ex53["fmu"]}, conn, exposed,
                                          tmp_path / "container.fmu", step=TS)
    res, _ = hosts.run_fmpy_cli(container, input_csv=None, output_csv=tmp_path / "out.csv", output_interval=TS,
                                stop_time=0.8)
    ref = ex53["dg"].run(res["time"], np.c_[res["plant.u"]], np.c_[res["plant.y1"], res["plant.y2"]])
    renamed = {n: res[f"fdi.{n}"] for n in ex53["outputs"]}
    shifts = [s for s in (0, 1, 2) if np.allclose(renamed["evaluation_1"][s:s + 50], ref["evaluation_1"][:50],
                                                   rtol=0, atol=TOL)]
    assert shifts, "no consistent alignment between container rows and Diagnoser.run"
    assert_matches(renamed, ref, ex53["outputs"], shift=shifts[0])


def test_state_save_restore_reset_and_two_fmus_in_one_process(ex53, tmp_path):
    """save → 100 steps → restore → the same 100 steps bit-identical (twice; also from bytes
    into a second instance); fmi2Reset returns to a fresh instance's behaviour."""
    data = as_inputs(ex53["t"], ex53["u"], ex53["y"])
    spec_in = tmp_path / "inputs.npy"
    np.save(spec_in, data, allow_pickle=False)
    script = HOSTS_DIR / "scenarios.py"

    def scenario(name, spec):
        import json

        spec = dict(spec, workdir=str(tmp_path / name))
        Path(spec["workdir"]).mkdir()
        (tmp_path / f"{name}.json").write_text(json.dumps(spec))
        proc = subprocess.run([sys.executable, "-I", str(script), name, str(tmp_path / f"{name}.json")],
                              capture_output=True, text=True, env=hosts.python_env(), timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        return {p.stem: np.load(p) for p in Path(spec["workdir"]).glob("*.npy")}

    out = scenario("state", {"fmu": str(ex53["fmu"]), "inputs": str(spec_in), "step": TS})
    for other in ("repeat1", "repeat2", "second"):
        assert np.array_equal(out["first"], out[other]), other
    assert np.array_equal(out["after_reset"], out["fresh"])

    # two *different* diagnostic FMUs with the same interface in one process: each must run
    # its own design (with a module clash the second would silently run the first's)
    other = Diagnoser(nullspace_design(pub.ex5_3(), poles=[-5]), Ts=TS, evaluation={"kind": "rms", "window": 4},
                      thresholds=0.05)
    other_fmu = build_fmu(other, tmp_path / "other.fmu")
    both = scenario("clash", {"fmus": [str(ex53["fmu"]), str(other_fmu)], "inputs": str(spec_in), "step": TS})
    for arr, dg in ((both["fmu0"], ex53["dg"]), (both["fmu1"], other)):
        ref = dg.run(ex53["t"], ex53["u"], ex53["y"])
        host = {nm: arr[:, j] for j, nm in enumerate(dg.output_names)}
        assert_matches(host, ref, dg.output_names)
    assert not np.allclose(both["fmu0"], both["fmu1"])


def test_nan_burst_sets_input_invalid_and_recovers(ex53):
    y = ex53["y"].copy()
    y[30:36, 0] = np.nan
    y[40, 1] = np.inf
    ref = ex53["dg"].run(ex53["t"], ex53["u"], y)
    ans = hosts.run_fmu2slave(ex53["fmu"], as_inputs(ex53["t"], ex53["u"], y), step=TS, outputs=ex53["outputs"])
    res = ans["result"]
    assert_matches(res, ref, ex53["outputs"])
    assert res["input_invalid"][31:37].all() and res["input_invalid"][41] and not res["input_invalid"][50:].any()
    assert np.all(np.isfinite(res["residual_1"]))


def test_alarm_events_name_the_isolation_the_fmu_outputs(ex53, tmp_path):
    # The event message read the alarm of the last group as fault_detected and fault_detected as
    # isolated_fault: an alarm without isolation (one group) was logged "isolated as" the first
    # fault, and a design without faults (RLS) failed its step with an IndexError.
    t, u, y = ex53["t"], ex53["u"], ex53["y"]
    ans = hosts.run_fmu2slave(ex53["fmu"], as_inputs(t, u, y), step=TS, log_categories=["logFdiEvents"])
    events = [m for _, _, m in ans["log"]]
    assert ex53["ref"]["fault_detected"].any() and events
    assert all("isolated as" not in m for m in events)
    assert any("fault detected, not isolated" in m for m in events)
    m = FDIModel.from_matrices([[0.9]], [[0.5]], [[1.0]], dt=TS, u_names=["u"], y_names=["y1"])
    rls = Diagnoser(rls_estimator(m, warmup=2), thresholds=1e-9)  # alarms as soon as it runs
    fmu = build_fmu(rls, tmp_path / "rls.fmu")
    ans = hosts.run_fmu2slave(fmu, as_inputs(t, u, y[:, :1], names=("u", "y1")), step=TS,
                              log_categories=["logFdiEvents"])
    assert set(ans["statuses"]) <= {0} and any("fault detected" in m for _, _, m in ans["log"])


def test_odd_step_sizes(ex53, tmp_path):
    """A non-multiple step re-discretises the continuous design exactly (as Diagnoser.run does
    for that spacing); a multiple runs sub-steps; a discrete-only design refuses with Discard."""
    h = 0.013
    t = np.arange(60) * h
    u = np.sin(2 * np.pi * t)[:, None]
    y = np.c_[np.cos(t), 0.5 * np.sin(3 * t)]
    for step in (h, 3 * TS):
        tt = np.arange(60) * step
        ref = ex53["dg"].run(tt, u, y)
        ans = hosts.run_fmu2slave(ex53["fmu"], as_inputs(tt, u, y), step=step, outputs=ex53["outputs"],
                                  log_categories=["logStatusWarning"])
        assert_matches(ans["result"], ref, ex53["outputs"])
        # a change of the effective sample time restarts the evaluation: said once, in the log
        restarts = [m for _, _, m in ans["log"] if "evaluation windows and thresholds restarted" in m]
        assert len(restarts) == (1 if step == h else 0), ans["log"]
    parity = Diagnoser(parity_space(pub.ex5_3().discretize(TS), 1), thresholds=1.0)
    fmu = build_fmu(parity, tmp_path / "parity.fmu")
    ans = hosts.run_fmu2slave(fmu, as_inputs(t, u, y), step=h, log_categories=[])
    assert ans["statuses"] == [2]  # the first step is answered with fmi2Discard
    text = " ".join(str(m) for entry in ans["log"] for m in entry)
    assert "not an integer multiple" in text and "exists only in discrete time" in text


def test_malformed_design_file_gives_clear_error_and_no_fmu(ex53, tmp_path):
    import json

    d = json.loads(json.dumps(ex53["dg"].design))
    d["generator"]["discrete"]["C"] = [[1.0, 2.0, 3.0]]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(DesignFileError, match="generator.discrete.C must be"):
        build_fmu(bad, tmp_path / "bad.fmu")
    assert not (tmp_path / "bad.fmu").exists()
    d = json.loads(json.dumps(ex53["dg"].design))
    d["signals"]["y"][0] = "residual_1"
    with pytest.raises(DesignFileError, match="collide"):
        build_fmu(d, tmp_path / "clash.fmu")


def test_same_fmu_runs_again_after_its_extraction_is_deleted(ex53, tmp_path):
    """The co-simulation master deletes an FMU's extraction after each run, while pythonfmu
    keeps the slave module imported: a second run in the same process must still find its
    design (in its new resources folder)."""
    code = ("from fmu_fdi.cosim import CoSimulation\n"
            "for _ in range(2):\n"
            f"    r = CoSimulation({{'fdi': {str(ex53['fmu'])!r}}}, None, None, step={TS}, stop={5 * TS},\n"
            "                     allow_unconnected=True).run()\n"
            "print(len(r))\n")
    # -c from the checkout: fmu_fdi importable whether installed or not
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          cwd=Path(__file__).parent.parent)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "6"


# ---- issue 12: reliability of the FMU as shipped (items 1, 2, 5; docs/semantics.md) ----------
def contract(tmp_path, fmus, actions):
    """Run ``actions`` through the ``contract`` scenario of tests/hosts/scenarios.py in a fresh
    process; per action
    ``{"status", "values", "log"}`` and the output names."""
    import json

    work = tmp_path / f"contract{len(list(tmp_path.glob('contract*')))}"
    work.mkdir()
    spec = work / "spec.json"
    spec.write_text(json.dumps({"fmus": {k: str(v) for k, v in fmus.items()}, "workdir": str(work),
                                "actions": actions}))
    proc = subprocess.run([sys.executable, "-I", str(HOSTS_DIR / "scenarios.py"), "contract", str(spec)],
                          capture_output=True, text=True, env=hosts.python_env(), timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    answer = json.loads((work / "answer.json").read_text())
    return answer["actions"], answer["outputs"]


def _row(u, y, k):
    return {"u": float(u[k, 0]), "y1": float(y[k, 0]), "y2": float(y[k, 1])}


def _errors(action):
    return " | ".join(m for s, _, m in action["log"] if s >= 3)  # fmi2Error and above


INIT = [["setup", "a"], ["enter", "a"], ["exit", "a"]]


def test_fmu_detects_a_bias_after_a_1e300_glitch(ex53):
    """Item 1 in the FMU as shipped: the glitch is flagged on numeric_reset at its sample, the
    outputs stay finite and equal to Diagnoser.run, and a later 5 cm bias is detected."""
    n, k0, glitch = 400, 250, 50
    t = np.arange(n) * TS
    u = np.sin(2 * np.pi * t)[:, None]
    d = np.random.default_rng(0).standard_normal((n, 1))
    f = np.zeros((n, 2))
    f[k0:, 1] = 0.05
    y = plant_outputs(pub.ex5_3(), n, TS, u=u, d=d, f=f)
    clean = ex53["dg"].run(t, u, y)
    y[glitch, 1] = 1e300
    ref = ex53["dg"].run(t, u, y)
    ans = hosts.run_fmu2slave(ex53["fmu"], as_inputs(t, u, y), step=TS, outputs=ex53["outputs"],
                              log_categories=["logFdiNumeric"])
    res = ans["result"]
    assert set(ans["statuses"]) == {0}
    assert_matches(res, ref, ex53["outputs"])
    assert list(np.flatnonzero(res["numeric_reset"])) == [glitch + 1]  # host row k+1 = sample k
    assert [c for _, c, _ in ans["log"]] == ["logFdiNumeric"]
    assert np.all(np.isfinite(res["evaluation_1"]))
    first = k0 + np.flatnonzero(clean["fault_detected"][k0:])[0]
    assert not clean["fault_detected"][:k0].any() and res["fault_detected"][first + 1] and res["fault_detected"][-1]
    assert not res["fault_detected"][k0 - 50:first + 1].any()  # the restart transient has decayed


HOSTILE_STEPS = [1e300, 1e7 * TS, 1e-6, 1e-9, 1e-300, float("nan"), -TS, 10001 * TS]


def test_fmu_refuses_hostile_step_sizes_and_goes_on(ex53, tmp_path):
    """Item 2: each hostile doStep is answered at once with fmi2Discard and its reason, leaves
    the instance as it was, and the steps after it give Diagnoser.run's outputs."""
    n = 40
    t, u, y = ex53["t"][:n], ex53["u"][:n], ex53["y"][:n]
    ref = ex53["dg"].run(t, u, y)
    actions = [["instantiate", "a", "fdi"], *INIT]
    for k in range(n):
        if k == 10:
            actions += [["step", "a", h, _row(u, y, k)] for h in HOSTILE_STEPS]
        actions.append(["step", "a", TS, _row(u, y, k)])
    done, names = contract(tmp_path, {"fdi": ex53["fmu"]}, actions)
    hostile = done[4 + 10:4 + 10 + len(HOSTILE_STEPS)]
    assert [a["status"] for a in hostile] == [2] * len(HOSTILE_STEPS)
    for a in hostile:
        reasons = [m for s, c, m in a["log"] if c == "logStatusDiscard"]
        assert len(reasons) == 1 and "refused" in reasons[0], a["log"]
        assert a["values"] == hostile[0]["values"]  # nothing moved
    regular = [a for a in done[4:] if a not in hostile]
    assert [a["status"] for a in regular] == [0] * n
    host = {nm: [a["values"][j] for a in regular] for j, nm in enumerate(names)}
    assert_matches(host, ref, names, shift=0)


def test_fmpy_simulate_at_an_interval_off_the_design_grid_matches_run(ex53, tmp_path):
    """Item 2: fmpy at an output interval that is not a multiple of Ts passes step sizes that
    differ in their last bits; they are one step size, so the FMU equals Diagnoser.run on the
    same log (it differed by 65 % when each restarted the evaluation)."""
    h = 0.013
    t = np.arange(120) * h
    u = np.sin(2 * np.pi * t)[:, None]
    y = np.c_[np.cos(t), 0.5 * np.sin(3 * t)] + 0.01 * np.random.default_rng(2).standard_normal((120, 2))
    steps = np.diff([k * h for k in range(121)])
    assert len(set(steps.tolist())) > 1  # the premise: fmpy's step sizes differ in their last bits
    ref = ex53["dg"].run(t, u, y)
    csv_in = hosts.write_csv(tmp_path / "log.csv", as_inputs(t, u, y))
    res, _ = hosts.run_fmpy_cli(ex53["fmu"], input_csv=csv_in, output_csv=tmp_path / "out.csv",
                                output_interval=h, stop_time=t[-1])
    assert_matches(res, ref, ex53["outputs"])


def test_fmi_state_machine_is_enforced(ex53, tmp_path):
    """Item 5: doStep before initialisation or after terminate, and initialisation calls out of
    order, are refused with an error-status message (fmi2Discard: pythonfmu cannot return
    fmi2Error) and change nothing; after a reset the instance runs like a fresh one."""
    n = 30
    t, u, y = ex53["t"][:n], ex53["u"][:n], ex53["y"][:n]
    ref = ex53["dg"].run(t, u, y)
    steps = [["step", "a", TS, _row(u, y, k)] for k in range(n)]
    actions = ([["instantiate", "a", "fdi"], ["step", "a", TS, _row(u, y, 0)], ["exit", "a"], ["setup", "a"],
                ["enter", "a"], ["enter", "a"], ["step", "a", TS, _row(u, y, 0)], ["exit", "a"], ["setup", "a"]]
               + steps + [["terminate", "a"], ["step", "a", TS, _row(u, y, 0)], ["terminate", "a"], ["reset", "a"],
                          *INIT] + steps)
    done, names = contract(tmp_path, {"fdi": ex53["fmu"]}, actions)
    before_init, early_exit, _, _, second_enter, init_step, _, late_setup = done[1:9]
    assert before_init["status"] == 2 and "fmi2DoStep refused" in _errors(before_init)
    assert "phase 'instantiated'" in _errors(before_init)
    assert init_step["status"] == 2 and "phase 'initialization'" in _errors(init_step)
    for a, call in ((early_exit, "fmi2ExitInitializationMode"), (second_enter, "fmi2EnterInitializationMode"),
                    (late_setup, "fmi2SetupExperiment")):
        assert call in _errors(a)
    first = done[9:9 + n]
    after_terminate = done[9 + n + 1]
    assert after_terminate["status"] == 2 and "phase 'terminated'" in _errors(after_terminate)
    assert "fmi2Terminate" in _errors(done[9 + n + 2])  # terminate twice
    again = done[-n:]
    for run in (first, again):
        assert [a["status"] for a in run] == [0] * n
        host = {nm: [a["values"][j] for a in run] for j, nm in enumerate(names)}
        assert_matches(host, ref, names, shift=0)


@pytest.fixture(scope="module")
def other_fmu(ex53):
    other = Diagnoser(nullspace_design(pub.ex5_3(), poles=[-5]), Ts=TS, evaluation={"kind": "rms", "window": 4},
                      thresholds=0.05)
    return build_fmu(other, ex53["tmp"] / "other_design.fmu")


def test_unusable_fmu_states_are_refused_when_set(ex53, other_fmu, tmp_path):
    """Item 5: another FMU's state, truncated bytes and zeros are refused at fmi2SetFMUstate with
    an error-status message; the instance is unchanged, the next doStep is discarded with the
    reason (pythonfmu cannot answer the set with fmi2Error), and a valid state heals it."""
    n = 40
    t, u, y = ex53["t"][:n], ex53["u"][:n], ex53["y"][:n]
    ref = ex53["dg"].run(t, u, y)
    actions = ([["instantiate", "a", "fdi"], *INIT, ["instantiate", "b", "other"], ["setup", "b"], ["enter", "b"],
                ["exit", "b"]]
               + [["step", "a", TS, _row(u, y, k)] for k in range(20)]
               + [["step", "b", TS, _row(u, y, k)] for k in range(5)]
               + [["get_state", "a", "good"], ["get_state", "b", "other"], ["serialize", "b", "other_bytes", "other"],
                  ["serialize", "a", "good_bytes", "good"], ["blob", "a", "truncated", "good_bytes", "truncate"],
                  ["blob", "a", "zeros", "good_bytes", "zeros"]])
    bad = {}
    for label, blob in (("foreign", "other_bytes"), ("truncated", "truncated"), ("zeros", "zeros")):
        bad[label] = len(actions)
        actions += [["deserialize", "a", label, blob], ["read", "a"], ["set_state", "a", label], ["read", "a"],
                    ["step", "a", TS, _row(u, y, 20)]]
    restore = len(actions)
    actions += [["set_state", "a", "good"]] + [["step", "a", TS, _row(u, y, k)] for k in range(20, n)]
    done, names = contract(tmp_path, {"fdi": ex53["fmu"], "other": other_fmu}, actions)
    reasons = {"foreign": "FMU state of", "truncated": "truncated FMU state", "zeros": "bad magic"}
    for label, i in bad.items():
        deser, read_before, set_, read_after, step = done[i:i + 5]
        assert deser["status"] == 0 and set_["status"] == 0  # the status pythonfmu can give
        assert "fmi2SetFMUstate refused, instance unchanged" in _errors(set_), label
        assert reasons[label] in _errors(set_), _errors(set_)
        assert read_after["values"] == read_before["values"], label
        assert step["status"] == 2 and "the last fmi2SetFMUstate was refused" in _errors(step), label
    assert done[restore]["status"] == 0 and not _errors(done[restore])
    run = done[restore + 1:]
    assert [a["status"] for a in run] == [0] * (n - 20)
    host = {nm: [a["values"][j] for a in run] for j, nm in enumerate(names)}
    assert_matches(host, ref[20:], names, shift=0)
