"""Build the diagnostic FMU (FMI 2.0 co-simulation, pythonfmu) from a Diagnoser or design file.

The FMU's ``resources/`` hold a package whose name is unique to the FMU (a hash of the
design and the code, see :mod:`.packaging`) with: the numpy-only runtime
(:mod:`fmu_fdi.runtime`, copied as it is), the slave module (:mod:`.slave_template`), the
slave base and state codec, and ``design.json``. Several diagnostic FMUs therefore load in
one process without module clashes (pythonfmu issue 228), and the FMU never imports
scipy, control or an installed ``fmu_fdi``. The model description is completed so that
``fmpy validate`` reports no problem: units, descriptions, discrete variability of
outputs, no direct feedthrough (outputs are updated at ``fmi2DoStep``), the
``DefaultExperiment`` step size Ts, and capability flags that tell the truth.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from ..designfile import DesignFileError, load_design, validate_design
from ..runtime.engine import output_names
from .packaging import build_slave_fmu, unique_bundle_name
from .slave_template import TEMPLATE

RUNTIME_DIR = Path(__file__).resolve().parent.parent / "runtime"
RESERVED = re.compile(r"^(residual|evaluation|threshold|alarm)_\d+$|^(fault_detected|isolated_fault|input_invalid|"
                      r"threshold_scale)$")
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _design_of(diagnoser_or_path) -> dict:
    from ..diagnoser import Diagnoser

    if isinstance(diagnoser_or_path, Diagnoser):
        return validate_design(json.loads(json.dumps(diagnoser_or_path.design)), "diagnoser")
    if isinstance(diagnoser_or_path, dict):
        return validate_design(diagnoser_or_path, "design")
    return load_design(diagnoser_or_path)


def _descriptions(design: dict) -> dict[str, str]:
    sig, g = design["signals"], design["generator"]
    faults = [f["name"] for f in design["faults"]]
    out = {n: f"plant input {n}" for n in sig["u"]}
    out.update({n: f"plant output (measurement) {n}" for n in sig["y"]})
    out["threshold_scale"] = "factor on every threshold (>= 0)"
    for k, name in enumerate(g["residual_names"]):
        out[f"residual_{k + 1}"] = f"residual {name}"
    for i, grp in enumerate(g["groups"]):
        ev = design["evaluation"][i]
        members = ", ".join(g["residual_names"][j] for j in grp)
        out[f"evaluation_{i + 1}"] = f"{ev['evaluator']['kind']} evaluation of residual group {i + 1} ({members})"
        out[f"threshold_{i + 1}"] = f"{ev['threshold']['kind']} threshold of group {i + 1} (times threshold_scale)"
        out[f"alarm_{i + 1}"] = f"evaluation_{i + 1} >= threshold_{i + 1} (with persistence/latching)"
    out["fault_detected"] = "any alarm"
    legend = ", ".join(f"{j + 1} = {nm}" for j, nm in enumerate(faults)) or "no faults modelled"
    out["isolated_fault"] = f"0 none, -1 unknown or several, else the fault: {legend}"
    out["input_invalid"] = "the last input sample had NaN/Inf (diagnosis held)"
    return out


def build_fmu(diagnoser_or_path, fmu_path) -> Path:
    """Export a diagnoser (object, design dict or design file path) as a co-simulation FMU.

    Parameters
    ----------
    diagnoser_or_path : Diagnoser, dict or path
    fmu_path : path
        Where to write the ``.fmu``; nothing is written when the design is invalid.

    Returns
    -------
    Path of the written FMU.

    Raises
    ------
    DesignFileError
        The design is malformed, or a signal name is no valid FMU variable name or
        collides with one of the FMU's own outputs.
    """
    design = _design_of(diagnoser_or_path)
    fmu_path = Path(fmu_path)
    if fmu_path.suffix != ".fmu":
        raise DesignFileError(f"the FMU file name must end in .fmu, got {fmu_path.name}")
    signals = list(design["signals"]["u"]) + list(design["signals"]["y"])
    bad = [s for s in signals if not _IDENT.match(s)]
    if bad:
        raise DesignFileError(f"signal names {bad} are not valid FMU variable names")
    clash = [s for s in signals if RESERVED.match(s)]
    if clash:
        raise DesignFileError(f"signal names {clash} collide with the diagnostic FMU's own variable names")
    design_bytes = json.dumps(design, sort_keys=True).encode("utf-8")
    modules = {f.name: f.read_text(encoding="utf-8") for f in sorted(RUNTIME_DIR.glob("*.py"))
               if f.name != "__init__.py"}
    base = re.sub(r"[^A-Za-z0-9_]", "_", design["name"]) or "fdi"
    ident = unique_bundle_name(base if base[0].isalpha() else "fdi_" + base, design_bytes.decode(),
                               *(modules[k] for k in sorted(modules)))
    g = design["generator"]
    modules["diagnoser_slave.py"] = TEMPLATE.replace("__CLASS__", ident).replace(
        "__DESCRIPTION__", repr(f"fmu-fdi diagnoser '{design['name']}' ({g['method']}, Ts = {g['dt']:g} s)"))
    names = output_names(len(g["residual_names"]), len(g["groups"]))
    units = {k: v for k, v in (design.get("units") or {}).items() if k in signals}
    return build_slave_fmu(
        modules, f"diagnoser_slave:{ident}", fmu_path, bundle_name=f"{ident}_fmu",
        data_files={"design.json": design_bytes},
        units=units, descriptions=_descriptions(design),
        output_dependencies={n: [] for n in names},
        capabilities={"canGetAndSetFMUstate": True, "canSerializeFMUstate": True,
                      "canHandleVariableCommunicationStepSize": True},
        default_experiment={"startTime": 0.0, "stepSize": float(g["dt"])},
        model_description=f"fmu-fdi diagnoser '{design['name']}'",
    )
