"""Run an FMU in several hosts, each in its own process, and read the results back.

Every runner starts a fresh process (``python -I`` for the Python hosts: no script folder,
no user site, no PYTHON* variables on ``sys.path``), so nothing the caller imported can stand
in for what the FMU bundles (pythonfmu resolves the slave's imports through ``sys.path`` of
the process that loads it). Results come back as numpy structured arrays with a ``time``
field, the layout fmpy uses.

Hosts, and the order each uses around ``fmi2DoStep`` (it decides which sample an output with
direct feedthrough shows; see docs/fmu-hosts.md and docs/fmu-internals.md):

================  =====================================================  ====================
runner            host                                                    row k holds
================  =====================================================  ====================
run_fmpy_cli      ``fmpy simulate`` with a CSV input file                 outputs after step
                                                                          k-1, before inputs
                                                                          of t_k are set
run_fmu2slave     fmpy ``FMU2Slave`` loop (set inputs, get, doStep)       inputs of t_k
run_libcosim      DNV OSP libcosim (libcosimpy), fixed step               after step k-1
run_container     fmpy container FMU simulated by fmpy                    after step k-1 and
                                                                          the internal
                                                                          transfer
run_c_host        ``c_host.c``: dlopen, no Python in the host             inputs of t_k
================  =====================================================  ====================
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

WORKER = Path(__file__).with_name("host_worker.py")


class HostError(RuntimeError):
    """A host process failed; the message carries its exit status and output."""


def _run(args, *, env=None, timeout=120.0, cwd=None) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(a) for a in args], env=env, cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0:
        raise HostError(f"{' '.join(map(str, args))} exited with {proc.returncode}\n"
                        f"--- stdout ---\n{proc.stdout[-4000:]}\n--- stderr ---\n{proc.stderr[-4000:]}")
    return proc


def python_env(extra: Mapping[str, str] | None = None) -> dict:
    """Environment for a Python host process: the caller's, without PYTHONPATH/PYTHONHOME."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(extra or {})
    return env


# ---- CSV ------------------------------------------------------------------------------------
def write_csv(path: str | os.PathLike, data: np.ndarray) -> Path:
    """Write a structured array as CSV (header of names; floats as ``repr``: exact)."""
    path = Path(path)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(data.dtype.names)
        for row in data:
            w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else
                        int(v) if isinstance(v, (bool, np.bool_, int, np.integer)) else v for v in row])
    return path


def read_csv(path: str | os.PathLike) -> np.ndarray:
    """Read a CSV written by fmpy, :func:`write_csv` or the C host into a structured array.

    Columns whose values are all ``True``/``False`` become bool, all-integer literals int64,
    the rest float64 (parsed with ``float``: exact for repr-formatted numbers).
    """
    with Path(path).open(newline="") as fh:
        rows = list(csv.reader(fh))
    names = [n.strip().strip('"') for n in rows[0]]
    cols = list(zip(*rows[1:])) if len(rows) > 1 else [[] for _ in names]
    arrays, dtypes = [], []
    for name, col in zip(names, cols):
        col = [c.strip() for c in col]
        if col and all(c in ("True", "False", "true", "false") for c in col):
            arrays.append([c in ("True", "true") for c in col])
            dtypes.append((name, np.bool_))
        elif col and name != "time" and all(c.lstrip("-").isdigit() for c in col):
            arrays.append([int(c) for c in col])
            dtypes.append((name, np.int64))
        else:
            arrays.append([float(c) for c in col])
            dtypes.append((name, np.float64))
    out = np.empty(len(rows) - 1, dtype=dtypes)
    for (name, _), values in zip(dtypes, arrays):
        out[name] = values
    return out


# ---- a. fmpy command line ------------------------------------------------------------------
def run_fmpy_cli(fmu: str | os.PathLike, *, input_csv: str | os.PathLike | None, output_csv: str | os.PathLike,
                 output_interval: float, stop_time: float, start_time: float = 0.0,
                 output_variables: Sequence[str] | None = None, debug_logging: bool = False,
                 python: str | None = None, timeout: float = 120.0) -> tuple[np.ndarray, str]:
    """``fmpy simulate FMU --input-file CSV --output-interval Ts --output-file OUT`` → (result, stdout).

    ``output_interval`` is also the communication step: without it fmpy takes the
    DefaultExperiment stepSize and doubles it until at most 1000 steps remain, or picks an
    "auto" interval, and a Real input CSV is then linearly interpolated between its rows.
    With canHandleVariableCommunicationStepSize="true" fmpy also shortens a step to land on
    an input event (a repeated time, or a change of a discrete/tunable input) off the grid.
    """
    args = [python or sys.executable, "-I", "-m", "fmpy", "simulate", fmu,
            "--start-time", repr(float(start_time)), "--stop-time", repr(float(stop_time)),
            "--output-interval", repr(float(output_interval)), "--output-file", output_csv]
    if input_csv is not None:
        args += ["--input-file", input_csv]
    if output_variables:
        args += ["--output-variables", *output_variables]
    if debug_logging:
        args += ["--debug-logging"]
    proc = _run(args, env=python_env(), timeout=timeout)
    return read_csv(output_csv), proc.stdout


# ---- b. fmpy FMU2Slave loop ---------------------------------------------------------------
def run_worker(command: str, spec: Mapping, *, python: str | None = None, timeout: float = 120.0) -> dict:
    """Run ``host_worker.py COMMAND`` on ``spec`` in a fresh ``python -I``; return its JSON answer.

    Arrays in the answer are structured arrays read from the .npy files the worker wrote.
    """
    with tempfile.TemporaryDirectory(prefix="fmufdi_host_") as tmp:
        spec = dict(spec, workdir=tmp)
        spec_path = Path(tmp) / "spec.json"
        spec_path.write_text(json.dumps(spec))
        proc = _run([python or sys.executable, "-I", WORKER, command, spec_path], env=python_env(),
                    timeout=timeout)
        answer = json.loads((Path(tmp) / "answer.json").read_text())
        for key, value in list(answer.items()):
            if isinstance(value, str) and value.endswith(".npy") and value.startswith(tmp):
                answer[key] = np.load(value, allow_pickle=False)
        answer["stdout"] = proc.stdout
        answer["stderr"] = proc.stderr
        return answer


def run_fmu2slave(fmu: str | os.PathLike, inputs: np.ndarray, *, step: float,
                  outputs: Sequence[str] | None = None, parameters: Mapping[str, float] | None = None,
                  log_categories: Sequence[str] | None = None, timeout: float = 120.0) -> dict:
    """Drive ``fmu`` with fmpy's ``FMU2Slave``: per row k set inputs, read outputs, doStep(t_k, step).

    ``inputs`` is a structured array with ``time`` (t_k = t_0 + k step is checked) and one
    field per input or tunable parameter. ``parameters`` are set before initialization.
    ``log_categories``: None switches logging off; a list (empty: all) switches it on.
    Returns ``{"result": structured array, "log": [[status, category, message], ...],
    "statuses": ...}``.
    """
    with tempfile.TemporaryDirectory(prefix="fmufdi_in_") as tmp:
        path = Path(tmp) / "inputs.npy"
        np.save(path, inputs, allow_pickle=False)
        return run_worker("fmu2slave", {
            "fmu": str(fmu), "inputs": str(path), "step": float(step), "outputs": list(outputs or []),
            "parameters": dict(parameters or {}), "log_categories": log_categories,
        }, timeout=timeout)


# ---- c. libcosim -----------------------------------------------------------------------------
def run_libcosim(components: Mapping[str, str | os.PathLike], connections: Sequence[tuple[str, str, str, str]], *,
                 step: float, stop_time: float, observe: Mapping[str, Sequence[str]],
                 initial_values: Mapping[str, Mapping[str, float]] | None = None,
                 timeout: float = 120.0) -> dict:
    """Co-simulate with libcosimpy: ``components`` name → FMU, ``connections`` of Real
    variables ``(src, src_var, dst, dst_var)``, a fixed step. Returns ``{name: array}`` of
    the ``observe``d variables per component, one row per communication point from t_0."""
    return run_worker("libcosim", {
        "components": {k: str(v) for k, v in components.items()}, "connections": [list(c) for c in connections],
        "step": float(step), "stop_time": float(stop_time), "observe": {k: list(v) for k, v in observe.items()},
        "initial_values": {k: dict(v) for k, v in (initial_values or {}).items()},
    }, timeout=timeout)


# ---- d. fmpy container FMU -------------------------------------------------------------------
def build_container_fmu(components: Mapping[str, str | os.PathLike], connections: Sequence[tuple[str, str, str, str]],
                        exposed: Sequence[tuple[str, str]], fmu_path: str | os.PathLike, *, step: float,
                        timeout: float = 120.0) -> Path:
    """Build an fmpy container FMU (``fmpy.container_fmu``, fmpy >= 0.3.30; the older
    ``fmpy.fmucontainer`` is gone) holding ``components`` with internal ``connections``;
    ``exposed`` ``(component, variable)`` pairs become the container's own variables, named
    ``component.variable``. Built in a worker process like the runs."""
    run_worker("container", {
        "components": {k: str(v) for k, v in components.items()}, "connections": [list(c) for c in connections],
        "exposed": [list(e) for e in exposed], "fmu_path": str(fmu_path), "step": float(step),
    }, timeout=timeout)
    return Path(fmu_path)


# ---- e. C host -------------------------------------------------------------------------------
def libpython_path() -> Path:
    """The shared libpython of this interpreter (``LIBDIR/LDLIBRARY``)."""
    libdir = sysconfig.get_config_var("LIBDIR")
    name = sysconfig.get_config_var("LDLIBRARY")
    path = Path(libdir or "", name or "")
    if not (name and name.endswith(".so") or ".so." in (name or "")) or not path.exists():
        raise HostError(f"no shared libpython for {sys.executable}: LIBDIR={libdir!r}, LDLIBRARY={name!r} "
                        "(a Python built without --enable-shared cannot be loaded by a C host)")
    return path


def c_host_env(extra: Mapping[str, str] | None = None) -> dict:
    """Environment in which a non-Python process can load a pythonfmu FMU of this interpreter.

    * ``LD_PRELOAD=<libpython>``: pythonfmu's ``libpythonfmu-export.so`` is not linked
      against libpython (it leaves every ``Py*`` symbol undefined); the symbols must already
      be global in the process.
    * ``PYTHONHOME=<sys.base_prefix>``: where the embedded interpreter finds the standard
      library (it cannot derive it from the executable, which is the C host).
    * ``PYTHONPATH=<site-packages of this environment>``: numpy (and anything else the FMU
      imports besides what it bundles) comes from the virtual environment, which an
      embedded interpreter does not activate. pythonfmu inserts the FMU's resources folder
      before it, so bundled code still wins.
    """
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "LD_PRELOAD")}
    env["LD_PRELOAD"] = str(libpython_path())
    env["PYTHONHOME"] = sys.base_prefix
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys([sysconfig.get_path("purelib"), sysconfig.get_path("platlib")]))
    env.update(extra or {})
    return env


def compile_c_host(source: str | os.PathLike, exe: str | os.PathLike, *, cc: str | None = None) -> Path:
    """Compile the C host (``cc -O2 -std=c99 source -o exe -ldl``); needs only libc and libdl."""
    cc = cc or os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if not cc:
        raise HostError("no C compiler (gcc/cc) found")
    _run([cc, "-O2", "-std=c99", "-Wall", "-Wextra", "-o", exe, source, "-ldl"], timeout=120)
    return Path(exe)


def run_c_host(exe: str | os.PathLike, fmu: str | os.PathLike, input_csv: str | os.PathLike,
               output_csv: str | os.PathLike, *, step: float, env: Mapping[str, str] | None = None,
               timeout: float = 120.0) -> tuple[np.ndarray, str]:
    """Unzip ``fmu`` and run the C host on it: ``exe UNZIPDIR INPUT.csv OUTPUT.csv STEP``.

    Row k of the output holds the outputs read after the inputs of row k were set and
    before ``fmi2DoStep(t_k, step)``; the log of the FMU goes to the host's stdout.
    """
    import zipfile

    with tempfile.TemporaryDirectory(prefix="fmufdi_c_") as tmp:
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(tmp)
        proc = _run([exe, tmp, input_csv, output_csv, repr(float(step))],
                    env=dict(env) if env is not None else c_host_env(), timeout=timeout)
    return read_csv(output_csv), proc.stdout
