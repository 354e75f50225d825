"""Make the modelDescription.xml of a pythonfmu-built FMU complete and truthful.

pythonfmu 0.7.0 writes variables with only the attributes the slave passed, no units, no
``InitialUnknowns`` and ``Outputs`` without dependencies, and capability flags from its
defaults. :func:`patch_fmu` rewrites the XML inside the .fmu so that ``fmpy validate`` finds
nothing and a master can rely on every statement:

* every variable gets an explicit ``variability``: parameters keep ``fixed``/``tunable``
  (default ``fixed``), Integer/Boolean/String variables are ``discrete``, Real ones
  ``continuous`` unless the slave said otherwise;
* every variable but the inputs gets an explicit ``initial``: ``exact`` for parameters,
  ``calculated`` for outputs and locals (their start values are removed, as FMI 2.0 requires).
  FMI 2.0 (section 2.2.7) forbids ``initial`` on inputs; they keep their required start value;
* ``UnitDefinitions`` with one ``Unit`` per distinct unit, and ``unit`` on Real variables;
* ``description`` on variables;
* ``ModelStructure``: ``Outputs`` lists every output with its ``dependencies`` (the inputs
  with direct feedthrough), ``InitialUnknowns`` lists exactly the outputs with
  ``initial="calculated"``/``"approx"`` and the calculated parameters, with their
  dependencies on inputs and exact parameters;
* ``CoSimulation`` capability flags as given.

What ``fmpy validate`` checks (fmpy 0.3.32, ``fmpy/validation.py`` and
``model_description.read_model_description``): no backslash in zip paths; the XML schema;
variable names against the grammar of the declared naming convention ("structured" here);
unique names; non-Real variables not ``continuous``; start values present for
``exact``/``approx``/inputs and absent for ``calculated``; the (causality, variability,
initial) combination is legal; every unit used is defined; ``Outputs`` holds exactly the
outputs; ``InitialUnknowns`` holds exactly the expected set; ``dependencies`` and
``dependenciesKind`` agree in length. It does not check that dependencies are true, that
Outputs/InitialUnknowns are in ascending order, nor capability flags: this module sorts and
checks the dependency names itself.
"""
from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path
from typing import Mapping, Sequence
from xml.etree import ElementTree as ET

from ..outpath import write_atomically

TYPE_TAGS = ("Real", "Integer", "Boolean", "String", "Enumeration")

#: FMI 2.0 co-simulation capability attributes and their meaning for a master.
CAPABILITIES = (
    "needsExecutionTool", "canHandleVariableCommunicationStepSize", "canInterpolateInputs",
    "maxOutputDerivativeOrder", "canRunAsynchronuously", "canBeInstantiatedOnlyOncePerProcess",
    "canNotUseMemoryManagementFunctions", "canGetAndSetFMUstate", "canSerializeFMUstate",
    "providesDirectionalDerivative",
)

# Element order of fmiModelDescription in the FMI 2.0 schema.
_TOP_ORDER = ("ModelExchange", "CoSimulation", "UnitDefinitions", "TypeDefinitions", "LogCategories",
              "DefaultExperiment", "VendorAnnotations", "ModelVariables", "ModelStructure")


class _Var:
    """One ScalarVariable with its 1-based index in ModelVariables."""

    def __init__(self, index: int, element: ET.Element):
        self.index = index
        self.element = element
        self.value = next(c for c in element if c.tag in TYPE_TAGS)
        self.name = element.get("name")
        self.type = self.value.tag
        self.causality = element.get("causality", "local")


def _fmt_bool(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def patch_model_description(
    xml: bytes | str,
    *,
    units: Mapping[str, str] | None = None,
    declared_types: Mapping[str, str] | None = None,
    type_attributes: Mapping[str, Mapping[str, str]] | None = None,
    descriptions: Mapping[str, str] | None = None,
    output_dependencies: Mapping[str, Sequence[str]] | None = None,
    initial_dependencies: Mapping[str, Sequence[str]] | None = None,
    capabilities: Mapping[str, object] | None = None,
    default_experiment: Mapping[str, float] | None = None,
    model_description: str | None = None,
    require_descriptions: bool = False,
) -> bytes:
    """Return the modelDescription ``xml`` completed as described in the module docstring.

    Parameters
    ----------
    xml : bytes or str
        The modelDescription.xml pythonfmu wrote.
    units : mapping, optional
        Variable name → unit string (Real variables only). Each distinct unit becomes a
        ``<Unit name=...>`` without base units (fmpy and FMI accept that).
    declared_types : mapping, optional
        Variable name → ``declaredType`` (Real variables only). Each distinct type becomes a
        ``<SimpleType name=...><Real unit=.../>`` in ``TypeDefinitions``, with the unit its
        variables share (:func:`fmu_fdi.designinfo.type_definitions`).
    type_attributes : mapping, optional
        ``declaredType`` → its type definition's attributes (``quantity`` is written).
    descriptions : mapping, optional
        Variable name → description; replaces any description pythonfmu wrote.
    output_dependencies : mapping, optional
        Output name → names of the inputs it depends on directly (feedthrough). Outputs not
        listed depend on every input, the safe statement for a master that orders calls.
        An empty list states "no direct feedthrough".
    initial_dependencies : mapping, optional
        Initial unknown name → names of inputs and exact parameters it depends on during
        initialization. Default: its output dependencies plus every parameter.
    capabilities : mapping, optional
        CoSimulation attributes (see :data:`CAPABILITIES`) to set, e.g.
        ``{"canGetAndSetFMUstate": True}``.
    default_experiment : mapping, optional
        ``startTime``/``stopTime``/``stepSize``/``tolerance`` for ``DefaultExperiment``
        (replaces the element).
    model_description : str, optional
        The FMU's ``description`` attribute.
    require_descriptions : bool
        Raise if a variable is left without a description.

    Raises
    ------
    ValueError
        A name that is no variable, a unit on a non-Real, a dependency on something that is
        not a known of that structure, an unknown capability, a required start value missing.
    """
    root = ET.fromstring(xml.encode("utf-8") if isinstance(xml, str) else xml)
    if root.get("fmiVersion") != "2.0":
        raise ValueError(f"expected an FMI 2.0 modelDescription, got fmiVersion={root.get('fmiVersion')!r}")
    if model_description is not None:
        root.set("description", model_description)
    variables = [_Var(i + 1, e) for i, e in enumerate(root.find("ModelVariables"))]
    by_name = {v.name: v for v in variables}

    def check_names(kind, names):
        unknown = sorted(set(names) - set(by_name))
        if unknown:
            raise ValueError(f"{kind}: no variable named {', '.join(map(repr, unknown))}")

    units = dict(units or {})
    descriptions = dict(descriptions or {})
    declared_types = dict(declared_types or {})
    check_names("units", units)
    check_names("declared_types", declared_types)
    check_names("descriptions", descriptions)

    for v in variables:
        _fix_variability_and_initial(v)
        if v.name in descriptions:
            v.element.set("description", descriptions[v.name])
        if require_descriptions and not v.element.get("description"):
            raise ValueError(f"variable {v.name!r} has no description")
        if v.name in units:
            if v.type != "Real":
                raise ValueError(f"units: {v.name!r} is {v.type}; FMI 2.0 gives units to Real variables only")
            v.value.set("unit", units[v.name])
        if v.name in declared_types:
            if v.type != "Real":
                raise ValueError(f"declared_types: {v.name!r} is {v.type}; only Real types are written")
            v.value.set("declaredType", declared_types[v.name])

    _set_unit_definitions(root, sorted(set(units.values())))
    _set_type_definitions(root, declared_types, units, type_attributes)
    _set_model_structure(root, variables, by_name, output_dependencies, initial_dependencies, check_names)
    _set_capabilities(root, capabilities or {})
    if default_experiment is not None:
        _set_default_experiment(root, default_experiment)
    _reorder_top(root)
    ET.indent(root, space="  ")
    out = io.BytesIO()
    ET.ElementTree(root).write(out, encoding="UTF-8", xml_declaration=True)
    return out.getvalue()


def _fix_variability_and_initial(v: _Var):
    e = v.element
    var = e.get("variability")
    if v.causality in ("parameter", "calculatedParameter"):
        var = var if var in ("fixed", "tunable") else "fixed"
    elif var is None or (v.type != "Real" and var == "continuous"):
        var = "continuous" if v.type == "Real" else "discrete"
    e.set("variability", var)

    if v.causality == "input":
        e.attrib.pop("initial", None)  # FMI 2.0 2.2.7: initial is not allowed on inputs
        initial = "exact"
    elif v.causality == "parameter" or var == "constant":
        initial = "exact"
    elif v.causality == "calculatedParameter":
        initial = e.get("initial") if e.get("initial") in ("calculated", "approx") else "calculated"
    else:  # output, local
        initial = e.get("initial") or "calculated"
    if v.causality != "input":
        e.set("initial", initial)
    if initial == "calculated":
        v.value.attrib.pop("start", None)
    elif v.value.get("start") is None:
        raise ValueError(f"variable {v.name!r} (causality={v.causality}, initial={initial}) needs a start value")


def _set_unit_definitions(root, unit_names):
    old = root.find("UnitDefinitions")
    if old is not None:
        existing = [u.get("name") for u in old.findall("Unit")]
        root.remove(old)
        unit_names = sorted(set(unit_names) | set(existing))
    if not unit_names:
        return
    ud = ET.SubElement(root, "UnitDefinitions")
    for name in unit_names:
        ET.SubElement(ud, "Unit", name=name)


def _set_type_definitions(root, declared_types, units, attributes=None):
    from ..designinfo import type_definitions

    if not declared_types:
        return
    old = root.find("TypeDefinitions")
    if old is not None:
        root.remove(old)
    td = ET.SubElement(root, "TypeDefinitions")
    for name, attrs in type_definitions(declared_types, units, attributes).items():
        ET.SubElement(ET.SubElement(td, "SimpleType", name=name), "Real", attrs)


def _set_model_structure(root, variables, by_name, output_dependencies, initial_dependencies, check_names):
    inputs = [v for v in variables if v.causality == "input"]
    exact_params = [v for v in variables if v.causality == "parameter"]
    outputs = [v for v in variables if v.causality == "output"]
    output_dependencies = dict(output_dependencies or {})
    initial_dependencies = dict(initial_dependencies or {})
    check_names("output_dependencies", list(output_dependencies) + [n for d in output_dependencies.values() for n in d])
    check_names("initial_dependencies", list(initial_dependencies) + [n for d in initial_dependencies.values() for n in d])
    for name in output_dependencies:
        if by_name[name].causality != "output":
            raise ValueError(f"output_dependencies: {name!r} is not an output")
    input_names = {v.name for v in inputs}
    for name, deps in output_dependencies.items():
        bad = sorted(set(deps) - input_names)
        if bad:
            raise ValueError(f"output_dependencies[{name!r}]: {bad} are not inputs (in co-simulation "
                             "an output can only depend directly on inputs)")

    def out_deps(v):
        names = output_dependencies.get(v.name, [i.name for i in inputs])
        return sorted(by_name[n].index for n in set(names))

    initial_unknowns = [v for v in variables
                        if (v.causality == "output" and v.element.get("initial") in ("calculated", "approx"))
                        or v.causality == "calculatedParameter"]
    knowns = input_names | {v.name for v in exact_params}
    unknown_names = {v.name for v in initial_unknowns}
    for name, deps in initial_dependencies.items():
        if name not in unknown_names:
            raise ValueError(f"initial_dependencies: {name!r} is not an initial unknown "
                             f"(those are {sorted(unknown_names)})")
        bad = sorted(set(deps) - knowns)
        if bad:
            raise ValueError(f"initial_dependencies[{name!r}]: {bad} are neither inputs nor exact parameters")

    def init_deps(v):
        if v.name in initial_dependencies:
            names = set(initial_dependencies[v.name])
        else:
            base = set(output_dependencies.get(v.name, input_names)) if v.causality == "output" else set()
            names = base | {p.name for p in exact_params}
        return sorted(by_name[n].index for n in names)

    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    ms = ET.SubElement(root, "ModelStructure")
    if outputs:
        el = ET.SubElement(ms, "Outputs")
        for v in outputs:  # ModelVariables order = ascending index, as FMI 2.0 requires
            ET.SubElement(el, "Unknown", index=str(v.index), dependencies=" ".join(map(str, out_deps(v))))
    if initial_unknowns:
        el = ET.SubElement(ms, "InitialUnknowns")
        for v in initial_unknowns:
            ET.SubElement(el, "Unknown", index=str(v.index), dependencies=" ".join(map(str, init_deps(v))))


def _set_capabilities(root, capabilities):
    cs = root.find("CoSimulation")
    if cs is None:
        raise ValueError("the modelDescription has no CoSimulation element")
    bad = sorted(set(capabilities) - set(CAPABILITIES))
    if bad:
        raise ValueError(f"unknown CoSimulation capabilities {bad}; known: {list(CAPABILITIES)}")
    for name, value in capabilities.items():
        cs.set(name, _fmt_bool(value))


def _set_default_experiment(root, values):
    allowed = {"startTime", "stopTime", "stepSize", "tolerance"}
    bad = sorted(set(values) - allowed)
    if bad:
        raise ValueError(f"default_experiment: unknown attributes {bad}; allowed {sorted(allowed)}")
    old = root.find("DefaultExperiment")
    if old is not None:
        root.remove(old)
    ET.SubElement(root, "DefaultExperiment", {k: repr(float(v)) for k, v in values.items()})


def _reorder_top(root):
    children = list(root)
    for c in children:
        root.remove(c)
    rank = {tag: i for i, tag in enumerate(_TOP_ORDER)}
    for c in sorted(children, key=lambda c: rank.get(c.tag, len(_TOP_ORDER))):  # stable
        root.append(c)


def read_fmu_model_description(fmu_path: str | os.PathLike) -> bytes:
    """The raw modelDescription.xml of an .fmu."""
    with zipfile.ZipFile(fmu_path) as zf:
        return zf.read("modelDescription.xml")


def patch_fmu(fmu_path: str | os.PathLike, **options) -> Path:
    """Rewrite the modelDescription.xml inside ``fmu_path`` in place.

    ``options`` are those of :func:`patch_model_description`. Every other member of the
    archive is copied unchanged (paths with forward slashes, as FMI requires).
    """
    fmu_path = Path(fmu_path)
    new_xml = patch_model_description(read_fmu_model_description(fmu_path), **options)

    def fill(part: Path):
        with zipfile.ZipFile(fmu_path) as src, zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as dst:
            for info in src.infolist():
                if info.filename == "modelDescription.xml":
                    continue
                dst.writestr(info, src.read(info.filename))
            dst.writestr("modelDescription.xml", new_xml)

    write_atomically(fmu_path, fill, fmu_path.stat().st_mode & 0o777)
    return fmu_path


def validate_fmu(fmu_path: str | os.PathLike) -> list[str]:
    """Problems ``fmpy validate`` reports for ``fmu_path`` (empty list: none)."""
    from fmpy.validation import validate_fmu as _validate

    return list(_validate(str(fmu_path)))
