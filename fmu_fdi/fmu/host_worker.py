"""Host processes for :mod:`fmu_fdi.fmu.hosts` (run as ``python -I host_worker.py CMD spec.json``).

A script, not a package module: it imports only numpy, fmpy and libcosimpy, so that the
process that loads the FMU contains nothing of fmu_fdi. It writes ``answer.json`` (and .npy
arrays) into the spec's ``workdir``.
"""
import json
import sys
from ctypes import byref
from pathlib import Path

import numpy as np

_NP = {"Real": np.float64, "Integer": np.int32, "Boolean": np.bool_, "Enumeration": np.int32}


def _answer(spec, **items):
    workdir = Path(spec["workdir"])
    out = {}
    for key, value in items.items():
        if isinstance(value, np.ndarray):
            path = workdir / f"{key}.npy"
            np.save(path, value, allow_pickle=False)
            out[key] = str(path)
        else:
            out[key] = value
    (workdir / "answer.json").write_text(json.dumps(out))


def _fmpy_logger(log):
    """fmi2 callbacks whose logger appends (status, category, message) to ``log``."""
    from fmpy import calloc, free
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                           fmi2CallbackLoggerTYPE)
    from fmpy.logging import addLoggerProxy

    def logger(env, instance, status, category, message):
        log.append([int(status), (category or b"").decode(), (message or b"").decode()])

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(byref(cb))  # formats the printf-style message in C before it reaches Python
    return cb


def _accessors(fmu, variables, names):
    """Getter returning a tuple of values of ``names`` in order, grouped by type."""
    groups = {}
    for i, n in enumerate(names):
        v = variables[n]
        groups.setdefault(v.type, []).append((i, v.valueReference))
    get = {"Real": fmu.getReal, "Integer": fmu.getInteger, "Boolean": fmu.getBoolean, "Enumeration": fmu.getInteger}

    def read():
        row = [None] * len(names)
        for t, items in groups.items():
            for (i, _), val in zip(items, get[t]([vr for _, vr in items])):
                row[i] = val
        return row
    return read


def _setter(fmu, variables, names):
    setters = {"Real": fmu.setReal, "Integer": fmu.setInteger, "Boolean": fmu.setBoolean}

    def write(values):
        for n, val in zip(names, values):
            v = variables[n]
            conv = {"Real": float, "Integer": int, "Boolean": bool}[v.type]
            setters[v.type]([v.valueReference], [conv(val)])
    return write


def cmd_fmu2slave(spec):
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave, fmi2Terminated

    md = read_model_description(spec["fmu"])
    variables = {v.name: v for v in md.modelVariables}
    inputs = np.load(spec["inputs"], allow_pickle=False)
    in_names = [n for n in inputs.dtype.names if n != "time"]
    out_names = spec["outputs"] or [v.name for v in md.modelVariables if v.causality == "output"]
    unzip = extract(spec["fmu"])
    log = []
    cb = _fmpy_logger(log)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="diag")
    categories = spec["log_categories"]
    fmu.instantiate(callbacks=cb, loggingOn=categories is not None)
    if categories:
        fmu.setDebugLogging(True, categories)
    t = inputs["time"]
    h = spec["step"]
    if not np.allclose(t, t[0] + h * np.arange(len(t)), rtol=0, atol=1e-9 * max(1.0, abs(t[-1]))):
        raise ValueError("input times are not t0 + k*step")
    fmu.setupExperiment(startTime=float(t[0]))
    set_par = _setter(fmu, variables, list(spec["parameters"]))
    set_par(list(spec["parameters"].values()))
    set_in = _setter(fmu, variables, in_names)
    read = _accessors(fmu, variables, out_names)
    fmu.enterInitializationMode()
    set_in([inputs[n][0] for n in in_names])
    fmu.exitInitializationMode()
    rows, statuses = [], []
    for k in range(len(t)):
        set_in([inputs[n][k] for n in in_names])
        rows.append((float(t[k]), *read()))
        try:
            fmu.doStep(currentCommunicationPoint=float(t[0] + k * h), communicationStepSize=h)
            statuses.append(0)
        except FMICallException as exc:
            statuses.append(int(exc.status))
            terminated = bool(fmu.getBooleanStatus(fmi2Terminated)) if exc.status == 2 else None
            _answer(spec, result=_table(rows, out_names, variables), log=log, statuses=statuses,
                    terminated=terminated)
            fmu.terminate()
            fmu.freeInstance()
            return
    fmu.terminate()
    fmu.freeInstance()
    _answer(spec, result=_table(rows, out_names, variables), log=log, statuses=statuses, terminated=False)


def _table(rows, names, variables):
    dtype = [("time", np.float64)] + [(n, _NP[variables[n].type]) for n in names]
    return np.array([tuple(r) for r in rows], dtype=dtype)


def cmd_libcosim(spec):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel[spec.get("log_level", "WARNING")])  # its default prints debug
    ns = round(spec["step"] * 1e9)  # libcosim counts time in integer nanoseconds
    ex = CosimExecution.from_step_size(step_size=ns)
    index, variables, slaves = {}, {}, []
    for name, path in spec["components"].items():
        slave = CosimLocalSlave(fmu_path=path, instance_name=name)
        slaves.append(slave)  # keep alive: the C side owns nothing until added
        index[name] = ex.add_local_slave(local_slave=slave)
        if index[name] < 0:
            raise RuntimeError(f"libcosim could not add {path}")
        variables[name] = {v.name.decode(): v for v in ex.slave_variables(index[name])}
    for name, values in spec["initial_values"].items():
        for var, value in values.items():
            ex.real_initial_value(index[name], variables[name][var].reference, float(value))
    for src, svar, dst, dvar in spec["connections"]:
        rc = ex.connect_real_variables(index[src], variables[src][svar].reference, index[dst], variables[dst][dvar].reference)
        if rc != 0:
            raise RuntimeError(f"libcosim could not connect {src}.{svar} -> {dst}.{dvar}")
    obs = CosimObserver.create_last_value()
    ex.add_observer(observer=obs)
    n_steps = int(round(spec["stop_time"] / spec["step"]))
    kinds = {0: "Real", 1: "Integer", 3: "Boolean"}  # CosimVariableType (2 is String)
    tables = {}
    for name, names in spec["observe"].items():
        tables[name] = {"names": names, "rows": []}

    def sample(time):
        for name, t in tables.items():
            row = [time]
            for var in t["names"]:
                v = variables[name][var]
                kind = kinds[v.type]
                get = {"Real": obs.last_real_values, "Integer": obs.last_integer_values,
                       "Boolean": obs.last_boolean_values}[kind]
                row.append(get(index[name], [v.reference])[0])
            t["rows"].append(row)

    for k in range(n_steps):
        if not ex.step():
            raise RuntimeError(f"libcosim step {k} failed")
        sample(ex.status().current_time * 1e-9)
    out = {}
    for name, t in tables.items():
        dtype = [("time", np.float64)] + [(var, _NP[kinds[variables[name][var].type]]) for var in t["names"]]
        out[name] = np.array([tuple(r) for r in t["rows"]], dtype=dtype)
    _answer(spec, **out)


def cmd_container(spec):
    from fmpy import read_model_description
    from fmpy.container_fmu import Configuration
    from fmpy.container_fmu.cli import create_container_fmu
    from fmpy.container_fmu.config import Component, Connection
    from fmpy.model_description import CoSimulation, DefaultExperiment, ModelDescription, ModelVariable, Unknown
    import tempfile
    import uuid

    comps, mds = [], {}
    for name, path in spec["components"].items():
        md = read_model_description(path)
        mds[name] = {v.name: v for v in md.modelVariables}
        comps.append(Component(name=name, filename=Path(path), modelDescription=md))
    by_name = {c.name: c for c in comps}
    connections = [Connection(startElement=by_name[s], startConnectors=[mds[s][sv]],
                              endElement=by_name[d], endConnectors=[mds[d][dv]])
                   for s, sv, d, dv in spec["connections"]]
    container = ModelDescription(fmiVersion="2.0", modelName="Container",
                                 instantiationToken="{" + str(uuid.uuid4()) + "}",
                                 variableNamingConvention="structured")
    container.coSimulation = CoSimulation(modelIdentifier="container_fmu", fixedInternalStepSize=spec["step"])
    container.defaultExperiment = DefaultExperiment(stepSize=str(spec["step"]))
    # the container binary answers value reference 0 with its own time and maps reference
    # i > 0 to entry i-1 of its variable list: the first variable must be the independent one
    container.modelVariables.append(ModelVariable(name="time", valueReference=0, type="Real",
                                                  causality="independent", variability="continuous"))
    mappings = {}
    for comp, var in spec["exposed"]:
        inner = mds[comp][var]
        start = inner.start if inner.causality in ("input", "parameter") else None
        v = ModelVariable(name=f"{comp}.{var}", valueReference=len(container.modelVariables), type=inner.type,
                          causality=inner.causality, variability=inner.variability,
                          initial=None if inner.causality == "input" else inner.initial, start=start)
        v.description = inner.description
        container.modelVariables.append(v)
        mappings[v] = [(by_name[comp], inner)]
    for v in container.modelVariables:
        if v.causality == "output":
            container.outputs.append(Unknown(variable=v))
            if v.initial in ("calculated", "approx"):
                container.initialUnknowns.append(Unknown(variable=v))
    config = Configuration(parallelDoStep=False, modelDescription=container, components=comps,
                           connections=connections, variableMappings=mappings)
    with tempfile.TemporaryDirectory() as unzipdir:
        create_container_fmu(config, Path(unzipdir), Path(spec["fmu_path"]))
    _fix_container(Path(spec["fmu_path"]))
    _answer(spec, fmu=spec["fmu_path"])


def _fix_container(path):
    """Work around two slips of fmpy 0.3.32's container writer.

    * ``connections[].variableType`` is the FMI 2 type name ("Real", "Integer") while the
      container binary only knows FMI 3 names: instantiation fails with "unknown variant
      `Real`". Variables are mapped correctly; connections are mapped here the same way.
    * ``shutil.make_archive`` runs inside the folder it archives, so a truncated
      ``Container.zip`` ends up in the FMU; it is dropped.
    """
    import zipfile

    fmi3 = {"Real": "Float64", "Integer": "Int32", "Enumeration": "Int32"}
    with zipfile.ZipFile(path) as zf:
        members = [(i, zf.read(i.filename)) for i in zf.infolist() if i.filename != "Container.zip"]
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for info, data in members:
            if info.filename == "resources/container.json":
                conf = json.loads(data)
                for c in conf["connections"]:
                    c["variableType"] = fmi3.get(c["variableType"], c["variableType"])
                data = json.dumps(conf, indent=2).encode("utf-8")
            zf.writestr(info, data)


if __name__ == "__main__":
    command, spec_path = sys.argv[1], sys.argv[2]
    spec = json.loads(Path(spec_path).read_text())
    {"fmu2slave": cmd_fmu2slave, "libcosim": cmd_libcosim, "container": cmd_container}[command](spec)
