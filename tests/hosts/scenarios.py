"""Scenario scripts for the FMU host tests, each run as ``python -I scenarios.py NAME spec.json``.

They drive fmpy's ``FMU2Slave`` directly (numpy and fmpy only, nothing of fmu_fdi in the
process) and write ``answer.json`` plus .npy arrays next to the spec:

* ``state``: save the FMU state, run, restore, run again (twice), serialize, restore the bytes
  into a second instance, restore bytes written by another process, reset, a corrupt state;
* ``clash``: two FMUs in one process, stepped with the same inputs (pythonfmu issue 228);
* ``contract``: any call sequence, legal or not, on one or more instances (the FMI-contract
  tests of issue 12): ``spec["actions"]`` is a list of ``[op, instance, *args]`` with ops
  ``instantiate`` (args: key of ``spec["fmus"]``), ``setup``, ``enter``, ``exit``,
  ``terminate``, ``reset``, ``step`` (args: h, {input: value}; sets the inputs, steps, reads
  every output; t advances only when the step was accepted), ``read``, ``get_state`` /
  ``set_state`` (args: slot), ``serialize`` (args: blob, slot), ``deserialize`` (args: slot,
  blob), ``blob`` (args: new, source, "truncate" | "zeros"). answer.json: per action
  ``{"status": fmi2Status, "values": outputs or null, "log": [[status, category, message]]}``.
"""
import json
import sys
from ctypes import byref
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE, fmi2Terminated)
from fmpy import calloc, free
from fmpy.logging import addLoggerProxy

LOG = []


def _logger(env, instance, status, category, message):
    LOG.append([(instance or b"").decode(), int(status), (category or b"").decode(), (message or b"").decode()])


CALLBACKS = fmi2CallbackFunctions()
CALLBACKS.logger = fmi2CallbackLoggerTYPE(_logger)
CALLBACKS.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
CALLBACKS.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
addLoggerProxy(byref(CALLBACKS))


class Instance:
    """One FMU2Slave with the stand-in's inputs and outputs by name."""

    def __init__(self, fmu, name, unzipdir=None):
        self.md = read_model_description(fmu)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.unzipdir = unzipdir or extract(fmu)
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=CALLBACKS, loggingOn=True)
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.t = 0.0

    def init(self, row, h):
        self.h = h
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.set(row)
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def set(self, row):
        for name, value in row.items():
            self.fmu.setReal([self.vars[name].valueReference], [float(value)])

    def read(self):
        vals = []
        for n in self.outputs:
            v = self.vars[n]
            get = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger, "Boolean": self.fmu.getBoolean}[v.type]
            vals.append(float(get([v.valueReference])[0]))
        return vals

    def run(self, rows):
        """Set, read, step for each row; returns (n × outputs) float array."""
        out = []
        for row in rows:
            self.set(row)
            out.append(self.read())
            self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=self.h)
            self.t += self.h
        return np.array(out)


def rows(data, start, stop):
    """Input rows by name: every field of ``data`` but ``time``."""
    names = [n for n in data.dtype.names if n != "time"]
    return [{n: data[n][k] for n in names} for k in range(start, stop)]


def state(spec):
    data = np.load(spec["inputs"], allow_pickle=False)
    h = spec["step"]
    a = Instance(spec["fmu"], "a")
    a.init(rows(data, 0, 1)[0], h)
    a.run(rows(data, 0, 50))
    t_saved = a.t
    saved = a.fmu.getFMUstate()
    first = a.run(rows(data, 50, 150))
    repeats = []
    for _ in range(2):  # the same saved state restored twice: saving must not alias
        a.fmu.setFMUstate(saved)
        a.t = t_saved
        repeats.append(a.run(rows(data, 50, 150)))
    blob = a.fmu.serializeFMUstate(saved)
    a.fmu.freeFMUstate(saved)
    Path(spec["workdir"], "state.bin").write_bytes(blob)

    # bytes into a second instance of the same FMU in this process (fresh, initialized)
    b = Instance(spec["fmu"], "b", unzipdir=a.unzipdir)
    b.init(rows(data, 0, 1)[0], h)
    restored = b.fmu.deSerializeFMUstate(blob)
    b.fmu.setFMUstate(restored)
    b.fmu.freeFMUstate(restored)
    b.t = t_saved
    second = b.run(rows(data, 50, 150))

    # bytes written by another process
    foreign = None
    if spec.get("foreign_state"):
        c = Instance(spec["fmu"], "c", unzipdir=a.unzipdir)
        c.init(rows(data, 0, 1)[0], h)
        st = c.fmu.deSerializeFMUstate(Path(spec["foreign_state"]).read_bytes())
        c.fmu.setFMUstate(st)
        c.fmu.freeFMUstate(st)
        c.t = t_saved
        foreign = c.run(rows(data, 50, 150))

    # fmi2Reset: back to the just-instantiated state (then initialized again like a fresh one)
    a.fmu.reset()
    a.init(rows(data, 0, 1)[0], h)
    after_reset = a.run(rows(data, 0, 100))
    fresh = Instance(spec["fmu"], "fresh", unzipdir=a.unzipdir)
    fresh.init(rows(data, 0, 1)[0], h)
    fresh_out = fresh.run(rows(data, 0, 100))
    reset_state = a.fmu.serializeFMUstate(a.fmu.getFMUstate())
    fresh_state = fresh.fmu.serializeFMUstate(fresh.fmu.getFMUstate())
    Path(spec["workdir"], "reset_state.bin").write_bytes(reset_state)
    Path(spec["workdir"], "fresh_state.bin").write_bytes(fresh_state)

    # a corrupt serialized state must not be fatal: set succeeds, the next step is discarded
    statuses = {}
    bad = fresh.fmu.deSerializeFMUstate(b"definitely not a state")
    fresh.fmu.setFMUstate(bad)
    try:
        fresh.fmu.doStep(currentCommunicationPoint=fresh.t, communicationStepSize=h)
        statuses["after_corrupt"] = 0
    except FMICallException as exc:
        statuses["after_corrupt"] = int(exc.status)
        statuses["terminated"] = bool(fresh.fmu.getBooleanStatus(fmi2Terminated))
    fresh.fmu.reset()  # and reset heals it
    fresh.init(rows(data, 0, 1)[0], h)
    healed = fresh.run(rows(data, 0, 100))

    arrays = dict(first=first, repeat1=repeats[0], repeat2=repeats[1], second=second, after_reset=after_reset,
                  fresh=fresh_out, healed=healed)
    if foreign is not None:
        arrays["foreign"] = foreign
    for inst in (a, b, fresh):
        inst.fmu.terminate()
        inst.fmu.freeInstance()
    answer(spec, arrays, statuses=statuses, outputs=a.outputs, log=LOG)


def clash(spec):
    data = np.load(spec["inputs"], allow_pickle=False)
    h = spec["step"]
    results = {}
    instances = []
    for i, fmu in enumerate(spec["fmus"]):
        inst = Instance(fmu, f"fmu{i}")
        inst.init(rows(data, 0, 1)[0], h)
        instances.append(inst)
        results[f"fmu{i}"] = inst.run(rows(data, 0, 50))
    for inst in instances:
        inst.fmu.terminate()
        inst.fmu.freeInstance()
    answer(spec, results, outputs=instances[0].outputs, log=LOG)


def contract(spec):
    unzipped = {key: extract(path) for key, path in spec["fmus"].items()}
    insts, states, blobs, results = {}, {}, {}, []
    for op, name, *args in spec["actions"]:
        mark = len(LOG)
        status, values = 0, None
        inst = insts.get(name)
        try:
            if op == "instantiate":
                insts[name] = Instance(spec["fmus"][args[0]], name, unzipdir=unzipped[args[0]])
            elif op == "step":
                h, row = args
                inst.set(row)
                try:
                    inst.fmu.doStep(currentCommunicationPoint=inst.t, communicationStepSize=float(h))
                    inst.t += float(h)
                finally:
                    values = inst.read()
            elif op == "step_at":  # doStep from an explicit communication point; the time moves on only if OK
                t, h, row = args
                inst.set(row)
                try:
                    inst.fmu.doStep(currentCommunicationPoint=float(t), communicationStepSize=float(h))
                    inst.t = float(t) + float(h)
                finally:
                    values = inst.read()
            elif op == "scale":
                inst.fmu.setReal([inst.vars["threshold_scale"].valueReference], [float(args[0])])
            elif op == "read":
                values = inst.read()
            elif op == "get_state":
                states[args[0]] = inst.fmu.getFMUstate()
            elif op == "set_state":
                inst.fmu.setFMUstate(states[args[0]])
            elif op == "serialize":
                blobs[args[0]] = bytes(inst.fmu.serializeFMUstate(states[args[1]]))
            elif op == "deserialize":
                states[args[0]] = inst.fmu.deSerializeFMUstate(blobs[args[1]])
            elif op == "blob":
                src = blobs[args[1]]
                blobs[args[0]] = {"truncate": src[: len(src) // 2], "zeros": bytes(len(src))}[args[2]]
            else:
                call = {"setup": lambda: inst.fmu.setupExperiment(startTime=float(args[0]) if args else 0.0),
                        "enter": inst.fmu.enterInitializationMode, "exit": inst.fmu.exitInitializationMode,
                        "terminate": inst.fmu.terminate, "reset": inst.fmu.reset}[op]
                call()
                inst.t = 0.0 if op == "reset" else inst.t
        except FMICallException as exc:
            status = int(exc.status)
        results.append({"status": status, "values": values, "log": [entry[1:] for entry in LOG[mark:]]})
    outputs = next(iter(insts.values())).outputs if insts else []
    for inst in insts.values():
        inst.fmu.freeInstance()
    answer(spec, {}, actions=results, outputs=outputs)


def answer(spec, arrays, **items):
    work = Path(spec["workdir"])
    for name, arr in arrays.items():
        np.save(work / f"{name}.npy", arr, allow_pickle=False)
    (work / "answer.json").write_text(json.dumps(dict(items, arrays=sorted(arrays))))


if __name__ == "__main__":
    spec = json.loads(Path(sys.argv[2]).read_text())
    {"state": state, "clash": clash, "contract": contract}[sys.argv[1]](spec)
