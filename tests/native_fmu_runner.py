"""Run conformance scenarios on native diagnostic FMUs with fmpy, in a process of their own.

Usage: ``python native_fmu_runner.py JOBS.json RESULT.json``. JOBS.json: a list of
``{"fmu": path, "fmi": 2 | 3, "ops": [...]}`` with the operations of tests/native_scenario.py.
RESULT.json: per job ``{"outputs": [[...] | "discard", ...], "names": [...], "log": [...]}``,
one entry per step (floats written with repr, so values round-trip exactly).

The FMU is driven as a co-simulation master would: inputs set before each doStep(t, h);
``save``/``restore`` are getFMUstate/setFMUstate (every other save also serialised and
deserialised); ``reset`` is fmiReset followed by initialisation (threshold_scale, a tunable
parameter that fmiReset returns to its start value, is set again); ``scale`` sets
threshold_scale.
"""
import json
import shutil
import sys

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException


def run_job(job):
    md = read_model_description(job["fmu"])
    unzip = extract(job["fmu"])
    fmi3 = job["fmi"] == 3
    vars_ = {v.name: v for v in md.modelVariables}
    if fmi3:
        from fmpy.fmi3 import FMU3Slave

        fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                        instanceName="conformance")
        fmu.instantiate()
        set_real, get_real, get_bool, get_int = fmu.setFloat64, fmu.getFloat64, fmu.getBoolean, fmu.getInt32
    else:
        from fmpy.fmi2 import FMU2Slave

        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                        instanceName="conformance")
        fmu.instantiate()
        set_real, get_real, get_bool, get_int = fmu.setReal, fmu.getReal, fmu.getBoolean, fmu.getInteger
    inputs = [v for v in md.modelVariables if v.causality == "input"]
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    scale_vr = vars_["threshold_scale"].valueReference
    kinds = {"Real": [], "Float64": [], "Boolean": [], "Integer": [], "Int32": []}
    for i, v in enumerate(outputs):
        kinds[v.type].append((i, v.valueReference))
    getters = [(get_real, kinds["Real"] + kinds["Float64"]), (get_bool, kinds["Boolean"]),
               (get_int, kinds["Integer"] + kinds["Int32"])]

    def initialise():
        if not fmi3:
            fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()

    def read():
        vals = [None] * len(outputs)
        for get, pairs in getters:
            if pairs:
                for (i, _), x in zip(pairs, get([vr for _, vr in pairs])):
                    vals[i] = float(x)
        return vals

    initialise()
    t, scale, saved, out, n_save = 0.0, 1.0, {}, [], 0
    for op in job["ops"]:
        if op[0] == "step":
            u, y, h = op[1], op[2], op[3]
            set_real([v.valueReference for v in inputs], list(u) + list(y))
            try:
                fmu.doStep(t, h) if fmi3 else fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            except FMICallException as exc:
                if int(exc.status) != 2:  # only Discard is an expected refusal
                    raise
                out.append("discard")
                continue
            t += h
            out.append(read())
        elif op[0] == "save":
            state = fmu.getFMUState()
            n_save += 1
            if n_save % 2 == 0:  # a serialisation round trip
                ser = fmu.serializeFMUState(state)
                fmu.freeFMUState(state)
                state = fmu.deserializeFMUState(ser)
            if op[1] in saved:
                fmu.freeFMUState(saved[op[1]][0])
            saved[op[1]] = (state, t, scale)  # the scale is part of the FMU state
        elif op[0] == "restore":
            state, t, scale = saved[op[1]]
            fmu.setFMUState(state)
        elif op[0] == "reset":
            fmu.reset()
            initialise()
            set_real([scale_vr], [scale])
        elif op[0] == "scale":
            scale = float(op[1])
            set_real([scale_vr], [scale])
    for state, _, _ in saved.values():
        fmu.freeFMUState(state)
    fmu.terminate()
    fmu.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    return {"outputs": out, "names": [v.name for v in outputs]}


def main(jobs_path, result_path):
    with open(jobs_path, encoding="utf-8") as f:
        jobs = json.load(f)
    results = [run_job(job) for job in jobs]
    with open(result_path, "w", encoding="utf-8") as f:
        json.dump(results, f)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
