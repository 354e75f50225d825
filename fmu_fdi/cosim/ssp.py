"""Export a :class:`~fmu_fdi.cosim.master.CoSimulation` as an SSP 1.0 file.

The ``.ssp`` archive holds ``SystemStructure.ssd`` and every FMU under ``resources/``:

- one ``Component`` per FMU, with a connector for each output and each input the master feeds;
- one ``Connection`` per resolved connection;
- the ``parameters`` as an inline ``ParameterBinding`` on each component (names are the FMU's
  variable names, applied before initialisation as the SSP standard says);
- a system input connector per external signal, connected to the inputs it feeds (an SSD
  carries no signal data: a tool supplies the values, e.g. fmpy's ``input=`` functions from
  :meth:`~fmu_fdi.cosim.signals.InputSignals.function`); a dotted signal name ``plant.Q1``
  becomes the connector ``plant_Q1``;
- the start and stop times as ``DefaultExperiment``, the step and order as an annotation of
  type ``org.fmu-fdi.cosim`` (SSP 1.0 has no standard place for them).

What SSP 1.0 cannot express is not exported: master-side fault scenarios (the export refuses a
co-simulation with faults unless ``drop_faults=True``) and the Gauss–Seidel order.

Running it with ``fmpy.ssp.simulation.simulate_ssp`` (FMI 1/2 components only): that master
steps all components with the connector values of the previous step (Jacobi), starts every
connector at 0.0 rather than at the FMUs' initial outputs, labels the row computed over
``[t_k, t_{k+1}]`` with ``t_k``, and ignores the SSD's parameter bindings; pass
``parameter_set=ssp_parameter_set(path)`` to apply them. So its row ``k`` equals row ``k + 1``
of this package's ``order="jacobi"`` result when the initial outputs feeding connections are 0.
A system input passes through one more connection there, so external signals reach the
components one step later (and 0.0 in the first step) than in this package's master.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from .errors import CoSimulationError

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
}
for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)
_SSC_TYPE = {"real": "Real", "integer": "Integer", "boolean": "Boolean", "string": "String"}


def _q(prefix, tag):
    return f"{{{NS[prefix]}}}{tag}"


def export_ssp(sim, path, *, drop_faults: bool = False) -> Path:
    """Write ``sim`` (a :class:`CoSimulation`) to the SSP file ``path``.

    Parameters
    ----------
    sim : CoSimulation
    path : str or Path
        Destination, conventionally ``*.ssp``.
    drop_faults : bool
        Export a co-simulation that has faults, without them. False (the default) refuses,
        since the SSP would silently describe the fault-free system.

    Returns
    -------
    Path
    """
    if sim.faults and not drop_faults:
        raise CoSimulationError(
            f"SSP cannot express the fault scenarios {', '.join(f.name for f in sim.faults)}; "
            f"pass drop_faults=True to export the fault-free system")
    path = Path(path)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("SystemStructure.ssd", system_structure(sim))
        for name, fmu in sim.fmus.items():
            zf.write(fmu.path, f"resources/{name}.fmu")
    return path


def system_structure(sim) -> bytes:
    """The ``SystemStructure.ssd`` document of ``sim`` (see the module docstring)."""
    w = sim._wiring
    root = ET.Element(_q("ssd", "SystemStructureDescription"), version="1.0", name="fmu_fdi_cosim")
    system = ET.SubElement(root, _q("ssd", "System"), name="fmu_fdi_cosim")
    conns = [(sf, sv, df, dv) for sf, sv, df, dv in w.connections]
    signal_connectors = {}
    for signal, targets in w.signal_targets.items():
        connector = signal.replace(".", "_")
        signal_connectors[signal] = connector
        conns += [(None, connector, f, v) for f, v in targets]
    if signal_connectors:
        box = ET.SubElement(system, _q("ssd", "Connectors"))
        for signal, connector in signal_connectors.items():
            f, v = w.signal_targets[signal][0]
            _connector(box, connector, "input", sim.fmus[f].kind(v))
    elements = ET.SubElement(system, _q("ssd", "Elements"))
    for name, fmu in sim.fmus.items():
        comp = ET.SubElement(elements, _q("ssd", "Component"), name=name,
                             source=f"resources/{name}.fmu", type="application/x-fmu-sharedlibrary")
        box = ET.SubElement(comp, _q("ssd", "Connectors"))
        # only fed inputs get connectors: fmpy's SSP master mis-reads an unconnected input connector
        fed = [dv for _, _, df, dv in conns if df == name]
        for var in fmu.names("input"):
            if var in fed:
                _connector(box, var, "input", fmu.kind(var))
        for var in fmu.names("output"):
            if fmu.kind(var) != "string":
                _connector(box, var, "output", fmu.kind(var))
        _bindings(comp, sim, name)
    box = ET.SubElement(system, _q("ssd", "Connections"))
    for sf, sv, df, dv in conns:
        attrs = {"startConnector": sv, "endElement": df, "endConnector": dv}
        if sf is not None:
            attrs["startElement"] = sf
        ET.SubElement(box, _q("ssd", "Connection"), attrs)
    ET.SubElement(root, _q("ssd", "DefaultExperiment"), startTime=repr(sim.start), stopTime=repr(sim.stop))
    notes = ET.SubElement(ET.SubElement(root, _q("ssd", "Annotations")), _q("ssc", "Annotation"),
                          type="org.fmu-fdi.cosim")
    ET.SubElement(notes, "Master", step=repr(sim.step), order=sim.order)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _connector(parent, name, kind, value_kind):
    c = ET.SubElement(parent, _q("ssd", "Connector"), name=name, kind=kind)
    ET.SubElement(c, _q("ssc", _SSC_TYPE[value_kind]))


def _bindings(comp, sim, name):
    values = {k.split(".", 1)[1]: v for k, v in sim.parameters.items() if k.split(".", 1)[0] == name}
    if not values:
        return
    binding = ET.SubElement(ET.SubElement(comp, _q("ssd", "ParameterBindings")), _q("ssd", "ParameterBinding"))
    pset = ET.SubElement(ET.SubElement(binding, _q("ssd", "ParameterValues")), _q("ssv", "ParameterSet"),
                         version="1.0", name=f"{name}_parameters")
    params = ET.SubElement(pset, _q("ssv", "Parameters"))
    for var, value in values.items():
        kind = sim.fmus[name].kind(var)
        text = (("true" if value else "false") if kind == "boolean" else
                str(int(value)) if kind == "integer" else repr(float(value)) if kind == "real" else str(value))
        p = ET.SubElement(params, _q("ssv", "Parameter"), name=var)
        ET.SubElement(p, _q("ssv", _SSC_TYPE[kind]), value=text)


def ssp_parameter_set(path):
    """The parameter bindings of the SSP at ``path`` as an fmpy ``ParameterSet``.

    fmpy's ``simulate_ssp`` reads the bindings but does not apply them; it applies a
    ``parameter_set`` argument whose names are ``component.variable``. Only inline bindings
    of top-level components are collected (what :func:`export_ssp` writes).
    """
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    ssd = read_ssd(str(path))
    out = ParameterSet(name="bindings")
    for element in ssd.system.elements:
        for binding in element.parameterBindings:
            for pset in binding.parameterValues:
                for p in pset.parameters:
                    value = p.value
                    if p.type == "Boolean":  # fmpy's setter compares with 0.0
                        value = 1.0 if value in ("true", "1") else 0.0
                    out.parameters.append(Parameter(name=f"{element.name}.{p.name}", type=p.type, value=value))
    return out
