"""Build the native diagnostic FMU: C99 sources and a compiled binary, FMI 2.0 or FMI 3.0 co-simulation.

The FMU holds no Python: the per-sample runtime (``c/fdi_runtime*.c``), the FMI glue
(``c/fdi_glue.c`` and ``c/fmi2.c`` or ``c/fmi3.c``), the design as generated constant data
(``design_data.c``, written by :mod:`fmu_fdi.native.emit`) and the model's variable table
(``fdi_model.h``, written here), compiled at build time with the system C compiler
(``$CC``, else ``cc``, else ``gcc``)::

    modelDescription.xml
    binaries/linux64/<id>.so          (FMI 2.0)   binaries/x86_64-linux/<id>.so   (FMI 3.0)
    sources/*.c, *.h                  with the FMI headers shipped by fmpy
    sources/buildDescription.xml      (FMI 3.0; FMI 2.0 lists the files in <SourceFiles>)

The variables are those of the pythonfmu target, with the same names, descriptions and units
(:func:`fmu_fdi.designinfo.variable_descriptions`, :func:`fmu_fdi.runtime.engine.output_names`):
the plant inputs u then outputs y (Real inputs, start = operating point), the tunable
parameter ``threshold_scale``, and the outputs (Real residuals, evaluations, thresholds;
Boolean alarms and flags; Integer ``isolated_fault``), all discrete with no direct
feedthrough (outputs change at doStep only). FMI 3.0 adds the independent variable ``time``.
Value references: time 0, u/y 1..n, threshold_scale n+1, outputs from n+2 (``c/fdi_glue.h``).

The runtime's own units (``RUNTIME_SOURCES``, which read no header of the design) are compiled once
per compiler, flags and sources into a per-user object cache (:mod:`.objcache`; folder
``$FMU_FDI_NATIVE_CACHE``, ``off`` to compile every source each time) and linked into each FMU.

Nothing is written when anything fails (no compiler, a compiler error, a design the C runtime
cannot express): the FMU is assembled in a temporary file and moved into place at the end.
"""
from __future__ import annotations

import hashlib
import io
import os
import shutil
import subprocess
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from ..designfile import DesignFileError, design_resources
from ..errors import DesignError
from ..outpath import write_atomically
from ..runtime.engine import BOOLEAN_OUTPUTS, output_names
from . import C_DIR, RUNTIME_HEADERS, RUNTIME_SOURCES, objcache

GLUE_SOURCES = ("fdi_glue.c", "fdi_glue.h", "fdi_schedule.h")
CFLAGS = ("-std=c99", "-pedantic", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall", "-Wextra", "-Werror")
#: the flags that compile one unit into an object (the library is linked with CFLAGS)
COMPILE_FLAGS = tuple(f for f in CFLAGS if f != "-shared")
#: (system, machine) -> binaries/ folder for FMI 2 and FMI 3 (None: the standard names none)
PLATFORMS = {("Linux", "x86_64"): {2: "linux64", 3: "x86_64-linux"},
             ("Linux", "aarch64"): {2: None, 3: "aarch64-linux"}}
FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
#: the logFdiNumeric category's description, in both targets
NUMERIC_LOG = ("Samples that overflowed the evaluation (a value became NaN/Inf): fault evidence, sample discarded, "
               "generator and evaluation restarted (numeric_reset, input_invalid).")
LOG_CATEGORIES = {  # the Python target's (fmu_fdi/fmu/slave_base.py), in fdi_glue.h order
    "logStatusWarning": "Messages with status Warning.",
    "logStatusDiscard": "Messages with status Discard: a step the runtime refused, with the reason.",
    "logStatusError": "Messages with status Error: calls out of order, bad values, refused FMU states.",
    "logStatusFatal": "Messages with status Fatal.",
    "logAll": "All messages without a more specific category.",
    "logFdiEvents": "Diagnostic events: alarms raised and cleared, isolation changes.",
    "logFdiInput": "Inputs rejected as invalid (not finite or outside the valid range).",
    "logFdiState": "FMU state saved and restored.",
    "logFdiNumeric": NUMERIC_LOG,
}


class NativeBuildError(DesignError):
    """The native FMU cannot be built here: no C compiler, or the compiler refused the sources."""


# ---- variables -----------------------------------------------------------------------------------
def output_kind(name: str) -> str:
    """FMI 2.0 type of a diagnostic output: Boolean alarms and flags, Integer isolated_fault, else Real."""
    if name.startswith("alarm_") or name in BOOLEAN_OUTPUTS:
        return "Boolean"
    return "Integer" if name == "isolated_fault" else "Real"


def variables(design: dict) -> list[dict]:
    """The FMU's variables in value-reference order 1, 2, ... (time, vr 0, is added for FMI 3.0).

    Each: ``name, causality, variability, kind (Real/Boolean/Integer), start, unit, description``.
    Names, descriptions and units are the pythonfmu target's.
    """
    from ..designinfo import variable_descriptions, variable_types, variable_units

    if "members" in design:  # a scheduled design: member 1's variables and active_member
        from .schedule_emit import scheduled_variables

        return scheduled_variables(design, variables)
    sig, g = design["signals"], design["generator"]
    desc = variable_descriptions(design)
    units, types = variable_units(design), variable_types(design)
    op = design.get("operating_point") or {}
    starts = list(op.get("u", [0.0] * len(sig["u"]))) + list(op.get("y", [0.0] * len(sig["y"])))
    out = []
    for name, start in zip(list(sig["u"]) + list(sig["y"]), starts):
        out.append(dict(name=name, causality="input", variability="continuous", kind="Real", start=float(start),
                        unit=units.get(name), description=desc[name], declared_type=types.get(name)))
    out.append(dict(name="threshold_scale", causality="parameter", variability="tunable", kind="Real", start=1.0,
                    unit=None, description=desc["threshold_scale"]))
    for name in output_names(len(g["residual_names"]), len(g["groups"])):
        out.append(dict(name=name, causality="output", variability="discrete", kind=output_kind(name),
                        start=0.0, unit=units.get(name), description=desc[name]))
    return out


# ---- generated C --------------------------------------------------------------------------------
def _c_string(text: str) -> str:
    out = []
    for b in text.encode("utf-8"):
        ch = chr(b)
        out.append(ch if 32 <= b < 127 and ch not in '"\\?' else f"\\{b:03o}")
    return '"' + "".join(out) + '"'


def _c_double(x: float) -> str:
    return float(x).hex() if x == x and abs(x) != float("inf") else ("(0.0/0.0)" if x != x else "HUGE_VAL")


def model_header(design: dict, identifier: str, token: str) -> str:
    """``fdi_model.h``: the variable table the glue needs (see ``c/fdi_glue.h``)."""
    vs = variables(design)
    inputs = [v for v in vs if v["causality"] == "input"]
    outputs = [v for v in vs if v["causality"] == "output"]
    names = [o["name"] for o in outputs]
    kinds = {"Real": 0, "Boolean": 1, "Integer": 2}
    faults = [f["name"] for f in design["faults"]]

    def arr(items):
        return "{" + ", ".join(items) + "}" if items else "{0}"

    return "\n".join([
        "/* fdi_model.h - generated by fmu_fdi.native.build: the variables of this FMU. Do not edit. */",
        "#ifndef FDI_MODEL_H", "#define FDI_MODEL_H", "",
        f"#define FDI_MODEL_IDENTIFIER {_c_string(identifier)}",
        f"#define FDI_TOKEN {_c_string(token)}",
        f"#define FDI_N_INPUTS {len(inputs)}",
        f"#define FDI_N_OUTPUTS {len(outputs)}",
        f"#define FDI_N_FAULTS {len(faults)}",
        f"#define FDI_IDX_FAULT_DETECTED {names.index('fault_detected')}",
        f"#define FDI_IDX_ISOLATED_FAULT {names.index('isolated_fault')}",
        f"#define FDI_IDX_INPUT_INVALID {names.index('input_invalid')}",
        f"#define FDI_IDX_NUMERIC_RESET {names.index('numeric_reset') if 'numeric_reset' in names else -1}",
        f"#define FDI_OUTPUT_KINDS {arr([str(kinds[o['kind']]) for o in outputs])}",
        f"#define FDI_INPUT_STARTS {arr([_c_double(v['start']) for v in inputs])}",
        f"#define FDI_VARIABLE_NAMES {arr([_c_string('time')] + [_c_string(v['name']) for v in vs])}",
        f"#define FDI_FAULT_NAMES {arr([_c_string(f) for f in faults])}",
        *(["#define FDI_SCHEDULED 1"] if "members" in design else []),  # c/fdi_schedule.h
        "", "#endif", ""])


def design_source(design: dict) -> str:
    """``design_data.c`` from :mod:`fmu_fdi.native.emit` (raises a DesignError for what C cannot express)."""
    from .emit import emit_design_c

    if "members" in design:  # the schedule; the members: schedule_emit.member_sources
        from .schedule_emit import schedule_source

        return schedule_source(design)
    return emit_design_c(design)


# ---- model description ----------------------------------------------------------------------------
def _fmt(x: float) -> str:
    return repr(float(x))


def model_description(design: dict, identifier: str, token: str, fmi_version: int, sources: list[str],
                      stop_time: float | None = None) -> bytes:
    """modelDescription.xml for FMI 2.0 or 3.0 (see the module docstring)."""
    vs = variables(design)
    g = design["members"][0]["generator"] if "members" in design else design["generator"]
    fmi3 = fmi_version == 3
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0" if fmi3 else "2.0", "modelName": design["name"],
        ("instantiationToken" if fmi3 else "guid"): token,
        "description": (f"fmu-fdi diagnoser '{design['name']}' ({g['method']}, Ts = {g['dt']:g} s), native C; "
                        f"tunable parameter threshold_scale (default 1) multiplies every threshold"),
        "generationTool": "fmu-fdi (native target)", "variableNamingConvention": "structured"})
    cs = ET.SubElement(root, "CoSimulation", {"modelIdentifier": identifier})
    flags = {"canHandleVariableCommunicationStepSize": "true", "canGetAndSetFMUstate": "true",
             "canSerializeFMUstate": "true", "canBeInstantiatedOnlyOncePerProcess": "false",
             "canNotUseMemoryManagementFunctions": "false"}
    if fmi3:
        flags = {"canHandleVariableCommunicationStepSize": "true", "canGetAndSetFMUState": "true",
                 "canSerializeFMUState": "true", "canBeInstantiatedOnlyOncePerProcess": "false",
                 "hasEventMode": "true"}
        cs.attrib.update(flags)
    else:
        cs.attrib.update(flags)
        files = ET.SubElement(cs, "SourceFiles")
        for name in sources:
            if name.endswith(".c"):
                ET.SubElement(files, "File", name=name)
    units = sorted({v["unit"] for v in vs if v["unit"]})
    if units:
        ud = ET.SubElement(root, "UnitDefinitions")
        for u in units:
            ET.SubElement(ud, "Unit", name=u)
    _type_definitions(root, vs, fmi3, design)
    cats = ET.SubElement(root, "LogCategories")
    for name, text in LOG_CATEGORIES.items():
        ET.SubElement(cats, "Category", name=name, description=text)
    experiment = {"startTime": "0.0", "stepSize": _fmt(g["dt"])}
    if stop_time is not None:
        experiment["stopTime"] = _fmt(stop_time)
    ET.SubElement(root, "DefaultExperiment", experiment)
    mv = ET.SubElement(root, "ModelVariables")
    if fmi3:
        ET.SubElement(mv, "Float64", name="time", valueReference="0", causality="independent",
                      variability="continuous", description="simulation time")
    for vr, v in enumerate(vs, start=1):
        attrs = {"name": v["name"], "valueReference": str(vr), "description": v["description"],
                 "causality": v["causality"], "variability": v["variability"]}
        if v["causality"] != "input":
            attrs["initial"] = "exact"
        start = ("true" if v["start"] else "false") if v["kind"] == "Boolean" else (
            str(int(v["start"])) if v["kind"] == "Integer" else _fmt(v["start"]))
        if fmi3:
            tag = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}[v["kind"]]
            el = ET.SubElement(mv, tag, attrs)
            el.set("start", start)
            if v["unit"]:
                el.set("unit", v["unit"])
            if v.get("declared_type"):
                el.set("declaredType", v["declared_type"])
        else:
            el = ET.SubElement(mv, "ScalarVariable", attrs)
            typ = ET.SubElement(el, v["kind"], start=start)
            if v["unit"]:
                typ.set("unit", v["unit"])
            if v.get("declared_type"):
                typ.set("declaredType", v["declared_type"])
    ms = ET.SubElement(root, "ModelStructure")
    outputs = [vr for vr, v in enumerate(vs, start=1) if v["causality"] == "output"]
    if fmi3:  # no direct feedthrough: outputs change at fmi3DoStep only
        for vr in outputs:  # initial="exact": none is an InitialUnknown
            ET.SubElement(ms, "Output", valueReference=str(vr), dependencies="")
    else:  # FMI 2.0 Unknown index = position in ModelVariables (1-based) = vr here
        out_el = ET.SubElement(ms, "Outputs")
        for vr in outputs:
            ET.SubElement(out_el, "Unknown", index=str(vr), dependencies="")
    ET.indent(root, space="  ")
    buf = io.BytesIO()
    ET.ElementTree(root).write(buf, encoding="UTF-8", xml_declaration=True)
    return buf.getvalue()


def _type_definitions(root, vs, fmi3: bool, design: dict) -> None:
    """``<TypeDefinitions>``: one Real type per ``declaredType`` of the plant signals (FMI 2.0
    ``<SimpleType><Real/>``, FMI 3.0 ``<Float64Type>``), with the unit its variables share."""
    from ..designinfo import type_definitions, variable_type_attributes

    types = {v["name"]: v["declared_type"] for v in vs if v.get("declared_type")}
    if not types:
        return
    td = ET.SubElement(root, "TypeDefinitions")
    attributes = variable_type_attributes(design)
    for name, attrs in type_definitions(types, {v["name"]: v["unit"] for v in vs}, attributes).items():
        ET.SubElement(td, "Float64Type", name=name, **attrs) if fmi3 else ET.SubElement(
            ET.SubElement(td, "SimpleType", name=name), "Real", attrs)


def build_description(identifier: str, sources: list[str]) -> bytes:
    """sources/buildDescription.xml (FMI 3.0, section 2.5.2)."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    cfg = ET.SubElement(root, "BuildConfiguration", modelIdentifier=identifier,
                        description="C99; link with the math library (-lm)")
    fs = ET.SubElement(cfg, "SourceFileSet", language="C99")
    for name in sources:
        if name.endswith(".c"):
            ET.SubElement(fs, "SourceFile", name=name)
    ET.SubElement(fs, "IncludeDirectory", name=".")
    ET.SubElement(cfg, "Library", name="m", description="C math library (libm)")
    ET.indent(root, space="  ")
    buf = io.BytesIO()
    ET.ElementTree(root).write(buf, encoding="UTF-8", xml_declaration=True)
    return buf.getvalue()


# ---- compiler ----------------------------------------------------------------------------------
def find_compiler() -> list[str]:
    """The C compiler command: ``$CC`` (may carry options), else ``cc``, else ``gcc``."""
    cc = os.environ.get("CC", "").split()
    if cc:
        if shutil.which(cc[0]):
            return cc
        raise NativeBuildError(f"the C compiler CC={os.environ['CC']!r} is not found; the native FMU is compiled "
                               "at build time: install a C99 compiler (e.g. 'apt install gcc') or set CC")
    for name in ("cc", "gcc"):
        if shutil.which(name):
            return [name]
    raise NativeBuildError("no C compiler found (tried $CC, cc, gcc); the native FMU is compiled at build time: "
                           "install a C99 compiler (Debian/Ubuntu: 'apt install gcc', Fedora: 'dnf install gcc', "
                           "macOS: 'xcode-select --install') or set CC, or build the pythonfmu target instead")


def _fmi_headers(fmi_version: int) -> dict[str, bytes]:
    import fmpy

    folder = Path(fmpy.__file__).parent / "c-code"
    missing = [h for h in FMI_HEADERS[fmi_version] if not (folder / h).is_file()]
    if missing:
        raise NativeBuildError(f"the FMI {fmi_version} headers {missing} are not in {folder} (they ship with fmpy "
                               ">= 0.3.20: 'pip install -U fmpy')")
    return {h: (folder / h).read_bytes() for h in FMI_HEADERS[fmi_version]}


def compile_binary(src: Path, out: Path, cc: list[str] | None = None, shared: tuple[str, ...] = (),
                   shared_headers: tuple[str, ...] = ()) -> Path:
    """Compile every .c in ``src`` into the shared library ``out``; NativeBuildError with the log if it fails.

    ``shared`` names units of ``src`` that include no header of ``src`` but ``shared_headers``: their
    objects come from :mod:`.objcache` (compiled once per compiler, flags and sources) and the rest is
    compiled and linked against them. Should that fail, every source is compiled in one command as
    without the cache, so an error message is the compiler's on the full sources.
    """
    cc = cc or find_compiler()
    files = sorted(str(p) for p in src.glob("*.c"))
    objects = objcache.shared_objects(src, shared, shared_headers, cc, COMPILE_FLAGS) if shared else None
    if objects is not None:
        own = [f for f in files if Path(f).name not in shared]
        cmd = [*cc, *CFLAGS, "-I", str(src), "-o", str(out), *own, *(str(o) for o in objects), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        if proc.returncode == 0:
            return out
    cmd = [*cc, *CFLAGS, "-I", str(src), "-o", str(out), *files, "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if proc.returncode == 0 and objects is not None:
        objcache.discard(objects)  # the full sources link but the cached objects did not: stale or damaged
    if proc.returncode != 0:
        raise NativeBuildError(f"compiling the native FMU failed ({' '.join(cc)} exited with {proc.returncode}):\n"
                               f"{(proc.stderr or proc.stdout)[-3000:]}")
    return out


# ---- the FMU ------------------------------------------------------------------------------------
def binary_folder(fmi_version: int) -> str:
    """``binaries/<platform>`` name of this machine for the FMI version, or NativeBuildError."""
    import platform

    key = (platform.system(), platform.machine())
    folder = PLATFORMS.get(key, {}).get(fmi_version)
    if folder is None:
        raise NativeBuildError(f"the native target builds its binary for this machine, {key[0]} {key[1]}, which has no "
                               f"FMI {fmi_version} platform name this builder supports (supported: "
                               f"{', '.join(f'{s} {m} (FMI {sorted(v for v in d if d[v])})' for (s, m), d in PLATFORMS.items())}"
                               "); use the pythonfmu target here")
    return folder


def identifier_of(design: dict, *parts: str) -> str:
    """``<name>_<10 hex digits>``: a C identifier unique to the design and the sources."""
    import re

    base = re.sub(r"[^A-Za-z0-9_]", "_", design["name"]) or "fdi"
    base = base if base[0].isalpha() else "fdi_" + base
    h = hashlib.sha256("\0".join(parts).encode("utf-8")).hexdigest()[:10]
    return f"{base[:40]}_{h}"


def build_native_fmu(design: dict, fmu_path, fmi_version: int = 2, stop_time: float | None = None) -> Path:
    """Write the native diagnostic FMU for a validated design dict (see the module docstring).

    Parameters
    ----------
    design : dict
        A design validated by :func:`fmu_fdi.designfile.validate_design`.
    fmu_path : path
        The ``.fmu`` to write; left untouched if anything fails.
    fmi_version : {2, 3}
    stop_time : float, optional
        ``DefaultExperiment`` stop time (s); :func:`fmu_fdi.build_fmu` passes its default.

    Raises
    ------
    NativeBuildError
        No C compiler, missing FMI headers, or the compiler refused the sources.
    DesignError
        The design holds something the C runtime cannot express (from :mod:`.emit`).
    """
    if fmi_version not in (2, 3):
        raise NativeBuildError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    var_names = [v["name"] for v in variables(design)] + (["time"] if fmi_version == 3 else [])
    clash = sorted({n for n in var_names if var_names.count(n) > 1})
    if clash:
        raise DesignFileError(f"signal names {clash} collide with the native FMU's own variable names "
                              f"({'time is the FMI 3.0 independent variable; ' if 'time' in clash else ''}"
                              "rename the signals in the model)")
    fmu_path = Path(fmu_path)
    folder = binary_folder(fmi_version)
    cc = find_compiler()  # before any work: no compiler, no file
    headers = _fmi_headers(fmi_version)
    glue = f"fmi{fmi_version}.c"
    runtime = {name: (C_DIR / name).read_bytes() for name in (*RUNTIME_SOURCES, *RUNTIME_HEADERS, *GLUE_SOURCES, glue)}
    data = design_source(design).encode("utf-8")
    ident = identifier_of(design, data.decode(), str(fmi_version),
                          *(f"{k}\n{v.decode()}" for k, v in sorted(runtime.items())))
    token = "{" + str(uuid.UUID(hashlib.sha256(ident.encode()).hexdigest()[:32])) + "}"
    sources = dict(runtime)
    sources["design_data.c"] = data
    if "members" in design:  # a scheduled design: member designs and the scheduler
        from .schedule_emit import member_sources

        sources.update(member_sources(design))
    sources["fdi_model.h"] = model_header(design, ident, token).encode("utf-8")
    sources.update(headers)
    names = sorted(sources)
    fmu_path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="fmufdi_native_") as tmp:
        src = Path(tmp, "sources")
        src.mkdir()
        for name, content in sources.items():
            (src / name).write_bytes(content)
        # the runtime's units include only the runtime headers: compiled once, kept in the object cache
        lib = compile_binary(src, Path(tmp, f"{ident}.so"), cc, shared=RUNTIME_SOURCES, shared_headers=RUNTIME_HEADERS)
        members = {"modelDescription.xml": model_description(design, ident, token, fmi_version, names, stop_time)}
        members[f"binaries/{folder}/{ident}.so"] = lib.read_bytes()
        for name in names:
            members[f"sources/{name}"] = sources[name]
        if fmi_version == 3:
            members["sources/buildDescription.xml"] = build_description(ident, names)
        # the design it was built from, where the pythonfmu target keeps it too (campaigns read the
        # fault names and the decision rule from it; the C code does not read it)
        members.update({f"resources/fmu_fdi/{k}": v for k, v in design_resources(design).items()})

        def fill(part):
            with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
                for name, content in members.items():  # float64 arrays do not deflate: stored
                    zf.writestr(name, content, zipfile.ZIP_STORED if name.endswith(".npz") else None)

        write_atomically(fmu_path, fill)
    return fmu_path
