"""Drive a native diagnostic FMU with fmpy's FMU2Slave / FMU3Slave (test worker, run in ``python -I``).

    python -I native_worker.py SPEC.json

SPEC: ``fmu``, ``inputs`` (.npy, N x (nu + ny), u then y), ``step``, ``save_at``, ``restore_at``
(rows), ``scale_at``, ``scale`` (threshold_scale set before that row), ``out`` (.npz to write). Per row k: set the inputs, doStep(t_k, h), read every output
(row k = the diagnosis of sample k). At row ``save_at`` (before its inputs are set) the FMU
state is saved and serialized; at ``restore_at`` it is restored and rows save_at..restore_at-1
are run again (``replay``); a second instance deserializes the bytes and runs save_at..N-1
(``second``); after the loop fmiReset and a fresh run of the first rows (``after_reset``).
Also records: the serialized bytes, the bytes re-serialized after deserializing them, statuses.
Imports fmpy and numpy only.
"""
import json
import sys

import numpy as np


def main(spec_path):
    from fmpy import extract, read_model_description

    spec = json.loads(open(spec_path).read())
    md = read_model_description(spec["fmu"])
    v3 = md.fmiVersion.startswith("3")
    data = np.load(spec["inputs"])
    h = float(spec["step"])
    ins = [v.valueReference for v in md.modelVariables if v.causality == "input"]
    scale_vr = next(v.valueReference for v in md.modelVariables if v.name == "threshold_scale")
    scale_at, scale = int(spec.get("scale_at", -1)), float(spec.get("scale", 1.0))
    outs = [v for v in md.modelVariables if v.causality == "output"]
    kinds = {"Real": "Real", "Float64": "Real", "Boolean": "Boolean", "Integer": "Integer", "Int32": "Integer"}
    groups = {k: [(i, v.valueReference) for i, v in enumerate(outs) if kinds[v.type] == k]
              for k in ("Real", "Boolean", "Integer")}
    unzip = extract(spec["fmu"])
    log = []
    keep = []  # ctypes callbacks must outlive the instances

    def new(name):
        if v3:
            from fmpy.fmi3 import FMU3Slave

            f = FMU3Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName=name)
            f.instantiate(loggingOn=True, logMessage=lambda env, status, cat, msg: log.append(
                [int(status), cat.decode(), msg.decode()]))
            f.enterInitializationMode(startTime=0.0)
        else:
            from fmpy import calloc, free
            from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                                   fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

            f = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName=name)
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: log.append(
                [int(status), cat.decode(), msg.decode().replace("%%", "%")]))
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            keep.append(cb)
            f.instantiate(loggingOn=True, callbacks=cb)
            f.setupExperiment(startTime=0.0)
            f.enterInitializationMode()
        f.exitInitializationMode()
        return f

    def get(f, kind, vrs):
        if kind == "Real":
            return f.getFloat64(vrs) if v3 else f.getReal(vrs)
        if kind == "Boolean":
            return f.getBoolean(vrs)
        return f.getInt32(vrs) if v3 else f.getInteger(vrs)

    def run(f, rows):
        res = np.zeros((len(rows), len(outs)))
        for j, k in enumerate(rows):
            values = [float(x) for x in data[k]]
            if k == scale_at:
                (f.setFloat64 if v3 else f.setReal)([scale_vr], [scale])
            if v3:
                f.setFloat64(ins, values)
            else:
                f.setReal(ins, values)
            f.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
            for kind, pairs in groups.items():
                if pairs:
                    got = get(f, kind, [vr for _, vr in pairs])
                    for (i, _), x in zip(pairs, got):
                        res[j, i] = float(x)
        return res

    n = len(data)
    s0, s1 = int(spec["save_at"]), int(spec["restore_at"])
    f = new("first")
    first = [run(f, range(s0))]
    state = f.getFMUState() if v3 else f.getFMUstate()
    blob = bytes(f.serializeFMUState(state) if v3 else f.serializeFMUstate(state))
    first.append(run(f, range(s0, s1)))
    (f.setFMUState if v3 else f.setFMUstate)(state)
    replay = run(f, range(s0, s1))
    first.append(run(f, range(s1, n)))
    again = (f.deserializeFMUState if v3 else f.deSerializeFMUstate)(blob)
    blob2 = bytes(f.serializeFMUState(again) if v3 else f.serializeFMUstate(again))
    (f.freeFMUState if v3 else f.freeFMUstate)(again)
    (f.freeFMUState if v3 else f.freeFMUstate)(state)
    f.reset()
    if v3:
        f.enterInitializationMode(startTime=0.0)
    else:
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
    f.exitInitializationMode()
    after_reset = run(f, range(s1))
    f.terminate()
    f.freeInstance()
    g = new("second")
    st = (g.deserializeFMUState if v3 else g.deSerializeFMUstate)(blob)
    (g.setFMUState if v3 else g.setFMUstate)(st)
    (g.freeFMUState if v3 else g.freeFMUstate)(st)
    second = run(g, range(s0, n))
    g.terminate()
    g.freeInstance()
    np.savez(spec["out"], first=np.vstack(first), replay=replay, second=second, after_reset=after_reset,
             blob=np.frombuffer(blob, np.uint8), blob2=np.frombuffer(blob2, np.uint8))
    print(json.dumps({"names": [v.name for v in outs], "log": log}))


if __name__ == "__main__":
    main(sys.argv[1])
