"""Run plant FMUs with fmpy's low-level API in a process of their own.

Usage: ``python fmu_runner.py JOBS.json RESULT.json``. Tests start this script in a
subprocess so their own imports (plant_fmus, its physics modules) cannot shadow the
modules the FMUs bundle. All FMUs of all jobs are loaded into this one process, as a
co-simulation host would.

JOBS.json: ``[{"fmu": path, "runs": [run, ...]}, ...]`` with ``run`` =
``{"dt": h, "steps": N, "params": {name: value}, "inputs": {name: value or [N values]},
"outputs": [names]}``. Input value k is set before ``doStep`` k (value 0 also during
initialisation). RESULT.json: per job, per run ``{"t": [...], "outputs": {name: [N+1]},
"status": "ok" | "error", "message": ..., "code": fmi2Status, "log": [[instance, status,
message], ...] (messages above fmi2OK), "seconds": wall time}``; floats are written with
``repr`` so values round-trip exactly.
"""
import json
import shutil
import sys
import time
from ctypes import byref

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE,
                       fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)

LOG = []


def _logger(component, instance, status, category, message):
    LOG.append([instance.decode(), int(status), message.decode()])


CALLBACKS = fmi2CallbackFunctions()
CALLBACKS.logger = fmi2CallbackLoggerTYPE(_logger)
CALLBACKS.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
CALLBACKS.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
try:  # formats printf-style messages; as fmpy itself does, go on without it if unavailable
    from fmpy.logging import addLoggerProxy

    addLoggerProxy(byref(CALLBACKS))
except Exception:  # noqa: BLE001
    pass


def run_one(md, unzipdir, run, index):
    vars_ = {v.name: v for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=f"run{index}")
    dt, steps = float(run["dt"]), int(run["steps"])
    inputs = {k: (v if isinstance(v, list) else [v] * steps) for k, v in run.get("inputs", {}).items()}
    outputs = run["outputs"]
    refs = [vars_[n].valueReference for n in outputs]
    types = {vars_[n].type for n in outputs}
    result = {"t": [], "outputs": {n: [] for n in outputs}, "status": "ok"}

    def setv(name, value):
        v = vars_[name]
        if v.type == "Real":
            fmu.setReal([v.valueReference], [float(value)])
        elif v.type == "Integer":
            fmu.setInteger([v.valueReference], [int(value)])
        elif v.type == "Boolean":
            fmu.setBoolean([v.valueReference], [bool(value)])
        else:
            raise TypeError(f"cannot set {v.type} variable {name}")

    getters = {"Real": fmu.getReal, "Integer": fmu.getInteger, "Boolean": fmu.getBoolean}

    def record(t):
        result["t"].append(t)
        if types == {"Real"}:
            values = fmu.getReal(refs)
        else:
            values = [getters[vars_[n].type]([r])[0] for n, r in zip(outputs, refs)]
        for n, val in zip(outputs, values):
            result["outputs"][n].append(val)

    started = time.perf_counter()
    fmu.instantiate(callbacks=CALLBACKS, loggingOn=True)
    del LOG[:]
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        for name, value in run.get("params", {}).items():
            setv(name, value)
        for name, series in inputs.items():
            setv(name, series[0])
        fmu.exitInitializationMode()
        t = 0.0
        record(t)
        for k in range(steps):
            for name, series in inputs.items():
                setv(name, series[k])
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=dt)
            t = (k + 1) * dt
            record(t)
        fmu.terminate()
    except FMICallException as exc:
        result.update(status="error", message=str(exc), code=int(exc.status))
    finally:
        fmu.freeInstance()
    result["log"] = [entry for entry in LOG if entry[1] > 0]
    result["seconds"] = time.perf_counter() - started
    return result


def main(jobs_path, result_path):
    with open(jobs_path) as fh:
        jobs = json.load(fh)
    results = []
    for job in jobs:
        md = read_model_description(job["fmu"])
        unzipdir = extract(job["fmu"])
        try:
            results.append([run_one(md, unzipdir, run, i) for i, run in enumerate(job["runs"])])
        finally:
            shutil.rmtree(unzipdir, ignore_errors=True)
    with open(result_path, "w") as fh:
        json.dump(results, fh)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
