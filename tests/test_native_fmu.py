"""The native diagnostic FMU (issue 8) as shipped, in hosts of its own process: fmpy validate,
fmpy simulate and the FMU2Slave/FMU3Slave loops, a plain C host under valgrind (or ASan), libcosim,
an fmpy container with a plant FMU, the project's master through ``fmu-fdi simulate``; the FMI
state machine under misuse; the build without a C compiler.

Every diagnostic output is compared to ``Diagnoser.run`` on the same samples: Reals to
1e-12 (1 + |value|) (the C runtime does the same operations in the same order as numpy's
runtime to ~1 ulp per operation, O(100) operations per sample on values of order 1; the
conformance suite holds the exact per-kind agreement), Booleans and Integers exactly.
"""
import math
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from fmu_fdi import Diagnoser, FDIModel, build_fmu, luenberger, sensor_fault
from fmu_fdi.fmu import hosts
from fmu_fdi.fmu.model_description import read_fmu_model_description, validate_fmu
from fmu_fdi.fmu.packaging import build_slave_fmu

HERE = Path(__file__).parent / "hosts"
H = 0.01
N = 300
CC = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler: the native target cannot be built")


def host_diagnoser():
    """A diagnoser for the plant stand-in of tests/hosts/plant.py (u1, u2 -> y1, sensor bias at t = 1)."""
    b = math.exp(-H / 0.3)
    model = FDIModel.from_matrices([[b]], [[1.0 - b, 0.0]], [[1.0]], dt=H, u_names=["u1", "u2"], y_names=["y1"],
                                   faults=[sensor_fault("bias_y1", "y1")], units={"y1": "m", "u1": "m3/s"},
                                   name="hostplant")
    return Diagnoser(luenberger(model, poles=[0.3]), evaluation={"kind": "rms", "window": 10}, thresholds=[0.2],
                     decision={"persistence": [2, 3], "isolation": "structure"})


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    d = tmp_path_factory.mktemp("native")
    dg = host_diagnoser()
    v = _plant_rows(np.arange(N) * H)  # the plant stand-in: sensor bias 0.6 from t = 1
    v[40:44, 2] = np.nan  # a NaN burst
    v[90, 0] = np.inf
    return {"dir": d, "dg": dg, "v": v,
            "fmu2": build_fmu(dg, d / "fdi2.fmu", target="native", fmi_version=2),
            "fmu3": build_fmu(dg, d / "fdi3.fmu", target="native", fmi_version=3)}


def reference(dg, v, scale_at=None, scale=1.0):
    """Diagnoser.run on rows v = (u1, u2, y1): row k is the diagnosis of sample k; with
    ``scale_at``, threshold_scale = ``scale`` from that row on (the runtime, sample by sample)."""
    if scale_at is None:
        return dg.run(np.arange(len(v)) * H, v[:, :2], v[:, 2:])
    out = dg.run(np.arange(len(v)) * H, v[:, :2], v[:, 2:])  # for the layout and rows before scale_at
    dg.reset()
    dg.runtime.threshold_scale = 1.0
    for k, row in enumerate(v):
        if k == scale_at:
            dg.runtime.threshold_scale = scale
        values = dg.runtime.advance(row[:2], row[2:])
        for name, x in zip(dg.runtime.names, values):
            out[name][k] = x
    dg.reset()
    dg.runtime.threshold_scale = 1.0  # a parameter: Diagnoser.reset keeps it
    return out


def assert_outputs(got: dict, want, rows=slice(None)):
    for name in want.dtype.names:
        if name == "time" or name not in got:
            continue
        a, b = np.asarray(got[name], float)[rows], np.asarray(want[name], float)[rows]
        if want.dtype[name].kind == "f":
            err = np.abs(a - b) / (1.0 + np.abs(b))
            assert np.all(err <= 1e-12), f"{name}: max rel. error {np.max(err):.3g} at row {int(np.argmax(err))}"
        else:
            bad = np.flatnonzero(a != b)
            assert bad.size == 0, f"{name}: differs at rows {bad[:10]}"


# ---- the FMU as a file ------------------------------------------------------------------------
@pytest.mark.parametrize("version", [2, 3])
def test_validates_and_ships_sources_and_binary(work, version):
    fmu = work[f"fmu{version}"]
    assert validate_fmu(fmu) == []
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
        root = ET.fromstring(zf.read("modelDescription.xml"))
        ident = root.find("CoSimulation").get("modelIdentifier")
        platform = "linux64" if version == 2 else "x86_64-linux"
        assert f"binaries/{platform}/{ident}.so" in names
        sources = {n[len("sources/"):] for n in names if n.startswith("sources/")}
        assert {"design_data.c", "fdi_model.h", f"fmi{version}.c", f"fmi{version}Functions.h"} <= sources
        c_files = sorted(n for n in sources if n.endswith(".c"))
        if version == 2:
            declared = [f.get("name") for f in root.find("CoSimulation/SourceFiles")]
        else:
            build = ET.fromstring(zf.read("sources/buildDescription.xml"))
            assert build.find("BuildConfiguration").get("modelIdentifier") == ident
            declared = [f.get("name") for f in build.iter("SourceFile")]
        assert sorted(declared) == c_files
    assert os.path.getsize(fmu) < 100_000


def test_fmpy_validate_cli_and_compile_from_sources(work, tmp_path):
    """`fmpy validate` exits 0; the sources as fmpy reads their declaration (FMI 2.0 SourceFiles,
    FMI 3.0 buildDescription.xml) compile alone into a binary that runs: what an importing tool
    on another platform does."""
    from fmpy import read_model_description

    proc = subprocess.run([sys.executable, "-I", "-m", "fmpy", "validate", str(work["fmu3"])],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for version in (2, 3):
        fmu = work[f"fmu{version}"]
        unzip = tmp_path / f"u{version}"
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(unzip)
        shutil.rmtree(unzip / "binaries")
        md = read_model_description(str(unzip))
        (config,) = md.buildConfigurations
        (files,) = config.sourceFileSets
        ident = config.modelIdentifier
        out = unzip / "binaries" / ("linux64" if version == 2 else "x86_64-linux") / f"{ident}.so"
        out.parent.mkdir(parents=True)
        subprocess.run([CC, "-std=c99", "-O0", "-fPIC", "-shared", f"-I{unzip / 'sources'}", "-o", str(out),
                        *[str(unzip / "sources" / f) for f in files.sourceFiles], "-lm"], check=True, timeout=120)
        rebuilt = tmp_path / f"rebuilt{version}.fmu"
        shutil.make_archive(str(rebuilt.with_suffix("")), "zip", unzip)
        rebuilt.with_suffix(".zip").rename(rebuilt)
        (tmp_path / "w").mkdir(exist_ok=True)
        ans = _worker(rebuilt, work["v"][:60], tmp_path / "w")
        assert_outputs(ans, reference(work["dg"], work["v"][:60]))


def test_same_variables_as_the_pythonfmu_target(work):
    py = build_fmu(work["dg"], work["dir"] / "python.fmu")

    def table(path):
        root = ET.fromstring(read_fmu_model_description(path))
        out = {}
        for sv in root.find("ModelVariables"):
            if root.get("fmiVersion") == "2.0":
                typ = sv[0]
                kind, unit = typ.tag, typ.get("unit")
            else:
                kind = {"Float64": "Real", "Int32": "Integer"}.get(sv.tag, sv.tag)
                unit = sv.get("unit")
            out[sv.get("name")] = (kind, sv.get("causality"), sv.get("variability"), sv.get("description"), unit)
        return out

    want = table(py)
    for version in (2, 3):
        got = table(work[f"fmu{version}"])
        got.pop("time", None)  # FMI 3.0: the independent variable
        assert got == want
    assert want["y1"][4] == "m" and want["u1"][4] == "m3/s"


def test_signal_named_time_refused_for_fmi3(tmp_path):
    from fmu_fdi.designfile import DesignFileError

    model = FDIModel.from_matrices([[0.5]], [[1.0]], [[1.0]], dt=H, u_names=["time"], y_names=["y"],
                                   faults=[sensor_fault("s", "y")])
    dg = Diagnoser(luenberger(model, poles=[0.2]), evaluation={"kind": "norm"}, thresholds=[1.0])
    with pytest.raises(DesignFileError, match=r"\['time'\] collide.*FMI 3.0 independent variable"):
        build_fmu(dg, tmp_path / "t.fmu", target="native", fmi_version=3)
    assert list(tmp_path.iterdir()) == []


def test_pythonfmu_target_is_fmi2_only(work, tmp_path):
    from fmu_fdi.designfile import DesignFileError

    with pytest.raises(DesignFileError, match="FMI 2 only"):
        build_fmu(work["dg"], tmp_path / "x.fmu", fmi_version=3)
    assert not (tmp_path / "x.fmu").exists()


# ---- hosts ------------------------------------------------------------------------------------
def _worker(fmu, v, tmp_path, save_at=None, restore_at=None, scale_at=-1, scale=1.0):
    import json

    np.save(tmp_path / "in.npy", v)
    spec = {"fmu": str(fmu), "inputs": str(tmp_path / "in.npy"), "step": H, "out": str(tmp_path / "out.npz"),
            "save_at": save_at or len(v) // 3, "restore_at": restore_at or len(v) // 2, "scale_at": scale_at,
            "scale": scale}
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    proc = subprocess.run([sys.executable, "-I", str(HERE / "native_worker.py"), str(tmp_path / "spec.json")],
                          capture_output=True, text=True, timeout=120, env=hosts.python_env())
    assert proc.returncode == 0, proc.stderr[-3000:]
    meta = json.loads(proc.stdout.strip().splitlines()[-1])
    arrays = dict(np.load(tmp_path / "out.npz"))
    ans = {name: arrays["first"][:, j] for j, name in enumerate(meta["names"])}
    ans["_arrays"], ans["_log"] = arrays, meta["log"]
    return ans


@pytest.mark.parametrize("version", [2, 3])
def test_fmpy_slave_loop_state_rollback_serialize_reset(work, tmp_path, version):
    v = work["v"]
    ans = _worker(work[f"fmu{version}"], v, tmp_path, scale_at=N // 4, scale=0.5)  # tunable threshold_scale
    assert_outputs(ans, reference(work["dg"], v, scale_at=N // 4, scale=0.5))
    assert np.all(ans["threshold_1"][N // 4:] == 0.5 * ans["threshold_1"][0])
    a = ans["_arrays"]
    s0, s1 = N // 3, N // 2
    assert np.array_equal(a["replay"], a["first"][s0:s1])    # restored state: the same rows again, bit for bit
    assert np.array_equal(a["second"], a["first"][s0:])      # serialized bytes into another instance
    assert np.array_equal(a["after_reset"], a["first"][:s1])  # reset = freshly instantiated
    assert np.array_equal(a["blob2"], a["blob"])              # deserialize + serialize: byte-exact round trip
    cats = {c for _, c, _ in ans["_log"]}
    assert {"logFdiInput", "logFdiEvents", "logFdiState"} <= cats
    assert any("fault detected, isolated as 'bias_y1'" in m for _, _, m in ans["_log"])


@pytest.mark.parametrize("version", [2, 3])
def test_fmpy_simulate(work, tmp_path, version):
    v = work["v"][95:]  # finite rows: fmpy interpolates its input file linearly, a NaN would smear
    data = np.zeros(len(v), dtype=[("time", float), ("u1", float), ("u2", float), ("y1", float)])
    data["time"] = np.arange(len(v)) * H
    data["u1"], data["u2"], data["y1"] = v.T
    csv = hosts.write_csv(tmp_path / "in.csv", data)
    out, _ = hosts.run_fmpy_cli(work[f"fmu{version}"], input_csv=csv, output_csv=tmp_path / "out.csv",
                                output_interval=H, stop_time=(len(v) - 1) * H)
    # fmpy records the outputs right after each doStep: row k + 1 = diagnosis of sample k
    ref = reference(work["dg"], v)
    assert_outputs({n: out[n][1:] for n in out.dtype.names}, ref[:-1])


def test_plain_c_host_under_valgrind(work, tmp_path):
    """FMI 2.0 and 3.0 in a C process (no Python, no LD_PRELOAD): misuse checks, the run, FMU state
    through serialize/deserialize, clean under valgrind (leaks included) or, without it, ASan."""
    import fmpy

    exe = tmp_path / "native_c_host"
    valgrind = shutil.which("valgrind")
    flags = [] if valgrind else ["-fsanitize=address,undefined", "-fno-omit-frame-pointer"]
    subprocess.run([CC, "-std=c99", "-O1", "-g", "-Wall", "-Wextra", "-Werror", "-pedantic", *flags,
                    f"-I{Path(fmpy.__file__).parent / 'c-code'}", str(HERE / "native_c_host.c"), "-o", str(exe),
                    "-ldl", "-lm", "-lpthread"], check=True, capture_output=True, timeout=60)
    v = work["v"]
    data = np.zeros(N, dtype=[("time", float), ("u1", float), ("u2", float), ("y1", float)])
    data["time"] = np.arange(N) * H
    data["u1"], data["u2"], data["y1"] = v.T
    csv = hosts.write_csv(tmp_path / "in.csv", data)
    env = {k: val for k, val in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD"))}
    for version in (2, 3):
        unzip = tmp_path / f"u{version}"
        with zipfile.ZipFile(work[f"fmu{version}"]) as zf:
            zf.extractall(unzip)
        cmd = [str(exe), str(version), str(unzip), str(csv), str(tmp_path / "out.csv"), repr(H)]
        if valgrind:
            cmd = [valgrind, "-q", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=all"] + cmd
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        checks = [ln for ln in proc.stdout.splitlines() if ln.startswith("CHECK")]
        assert len(checks) >= 25 and all(ln.endswith(" ok") for ln in checks), checks
        out = hosts.read_csv(tmp_path / "out.csv")
        assert_outputs({n: out[n] for n in out.dtype.names}, reference(work["dg"], v))


@pytest.fixture(scope="module")
def plant(work):
    return build_slave_fmu({"plant.py": (HERE / "plant.py").read_text()}, "plant:Plant", work["dir"] / "Plant.fmu",
                           output_dependencies={"u1": [], "u2": [], "y1": []})


def _plant_rows(times):
    from hosts import reference as ref

    return ref.plant(times, H)


@pytest.mark.skipif(shutil.which("true") is None or __import__("importlib").util.find_spec("libcosimpy") is None,
                    reason="libcosimpy is not installed (test extra)")
def test_libcosim(work, plant):
    names = ("u1", "u2", "y1")
    outs = ["residual_1", "evaluation_1", "alarm_1", "fault_detected", "isolated_fault"]
    ans = hosts.run_libcosim({"plant": plant, "diag": work["fmu2"]}, [("plant", n, "diag", n) for n in names],
                             step=H, stop_time=200 * H, observe={"plant": list(names), "diag": outs})
    times = np.arange(201) * H
    v = _plant_rows(times)
    # libcosim samples after doStep; the diagnoser stepped to t_{k+1} on the plant's values at t_k
    ref = reference(work["dg"], v[:-1])
    assert_outputs({n: ans["diag"][n] for n in outs}, ref)


def test_container_fmu_with_a_plant(work, plant):
    names = ("u1", "u2", "y1")
    outs = ("residual_1", "evaluation_1", "threshold_1", "alarm_1", "fault_detected", "isolated_fault")
    container = hosts.build_container_fmu({"plant": plant, "diag": work["fmu2"]},
                                          [("plant", n, "diag", n) for n in names],
                                          [("plant", n) for n in names] + [("diag", n) for n in outs],
                                          work["dir"] / "Container.fmu", step=H)
    # (fmpy validate finds the container's exposed outputs without the start values our
    # initial="exact" outputs have: fmpy's container builder drops them; not this FMU's business)
    out, _ = hosts.run_fmpy_cli(container, input_csv=None, output_csv=work["dir"] / "container.csv",
                                output_interval=H, stop_time=200 * H)
    v = _plant_rows(np.arange(201) * H)
    # the container passes the plant's outputs to the diagnoser right after each step: aligned rows
    assert_outputs({n: out[f"diag.{n}"][1:] for n in outs}, reference(work["dg"], v)[:-1])


@pytest.mark.parametrize("version", [3])
def test_project_master_via_fmu_fdi_simulate(work, plant, tmp_path, version):
    from fmu_fdi.cosim import Result

    out = tmp_path / "sim.csv"
    proc = subprocess.run([sys.executable, "-m", "fmu_fdi", "simulate", "--plant", f"plant={plant}",
                           "--diagnoser", f"fdi={work[f'fmu{version}']}", "--stop", repr(200 * H), "--step", repr(H),
                           "--order", "jacobi", "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = Result.from_csv(out)
    v = np.column_stack([res[f"plant.{n}"] for n in ("u1", "u2", "y1")])
    # Jacobi: the step to t_{k+1} reads the plant at t_k; row 0 holds the outputs after initialisation
    ref = reference(work["dg"], v[:-1])
    assert_outputs({n: res[f"fdi.{n}"][1:] for n in ("residual_1", "evaluation_1", "alarm_1", "isolated_fault")},
                   ref)
    assert res["fdi.fault_detected"].any()


# ---- the build --------------------------------------------------------------------------------
def test_cli_build_and_no_compiler_clear_error_and_no_file(work, tmp_path, monkeypatch, capsys):
    from fmu_fdi.cli import main

    design = work["dg"].save(tmp_path / "d.json")
    built = tmp_path / "built" / "cli3.fmu"
    assert main(["build", str(design), "-o", str(built), "--target", "native", "--fmi", "3"]) == 0
    assert validate_fmu(built) == []
    shutil.rmtree(built.parent)
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))  # no cc, no gcc
    capsys.readouterr()
    assert main(["build", str(design), "-o", str(tmp_path / "x.fmu"), "--target", "native", "--fmi", "3"]) == 2
    err = capsys.readouterr().err
    assert "no C compiler found" in err and "apt install gcc" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.json"]


def test_missing_cc_named(work, tmp_path, monkeypatch):
    from fmu_fdi.native.build import NativeBuildError

    monkeypatch.setenv("CC", str(tmp_path / "nowhere" / "cc"))
    with pytest.raises(NativeBuildError, match="is not found.*install a C99 compiler"):
        build_fmu(work["dg"], tmp_path / "x.fmu", target="native")
    assert list(tmp_path.iterdir()) == []


def test_unsupported_platform_refused_not_mislabelled(work, tmp_path, monkeypatch):
    """A binary for another OS must not be packed under binaries/linux64: the build refuses."""
    import platform

    from fmu_fdi.native.build import NativeBuildError

    monkeypatch.setattr(platform, "system", lambda: "Darwin")
    with pytest.raises(NativeBuildError, match="Darwin .* no FMI 2 platform name.*pythonfmu target"):
        build_fmu(work["dg"], tmp_path / "x.fmu", target="native")
    assert list(tmp_path.iterdir()) == []


def test_compiler_failure_leaves_no_file(work, tmp_path, monkeypatch):
    from fmu_fdi.native.build import NativeBuildError

    fake = tmp_path / "badcc"
    fake.write_text("#!/bin/sh\necho 'badcc: internal error' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("CC", str(fake))
    with pytest.raises(NativeBuildError, match="badcc: internal error"):
        build_fmu(work["dg"], tmp_path / "x.fmu", target="native")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["badcc"]
