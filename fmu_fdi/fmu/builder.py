"""Build the diagnostic FMU (FMI 2.0 co-simulation, pythonfmu) from a Diagnoser or design file.

The FMU carries in ``resources/``: the design file, the numpy-only runtime copied as a
package whose name is unique to this FMU (``fdirt_<hash>``), and the slave script (module
``fdi_<hash>``). Several diagnostic FMUs therefore load in one process without module
clashes (pythonfmu issue 228), and the FMU never imports scipy, control or an installed
``fmu_fdi``. After pythonfmu writes the archive, the model description is completed
(units, variabilities, ModelStructure with dependencies, capability flags) so that
``fmpy validate`` reports no problem.
"""
from __future__ import annotations

import hashlib
import json
import re
import shutil
import sys
import tempfile
from pathlib import Path

from ..designfile import DesignFileError, load_design, validate_design
from ..runtime.engine import output_names
from .slave_template import TEMPLATE

RUNTIME_DIR = Path(__file__).resolve().parent.parent / "runtime"
RESERVED = re.compile(r"^(residual|evaluation|threshold|alarm)_\d+$|^(fault_detected|isolated_fault|input_invalid|"
                      r"threshold_scale)$")


def _design_of(diagnoser_or_path) -> dict:
    from ..diagnoser import Diagnoser

    if isinstance(diagnoser_or_path, Diagnoser):
        return validate_design(json.loads(json.dumps(diagnoser_or_path.design)), "diagnoser")
    if isinstance(diagnoser_or_path, dict):
        return validate_design(diagnoser_or_path, "design")
    return load_design(diagnoser_or_path)


def _identifier(name: str, digest: str) -> str:
    base = re.sub(r"[^A-Za-z0-9_]", "_", name) or "fdi"
    if base[0].isdigit():
        base = "fdi_" + base
    return f"{base}_{digest[:8]}"


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
        The design is malformed, or a signal name collides with an FMU output name.
    """
    design = _design_of(diagnoser_or_path)
    fmu_path = Path(fmu_path)
    if fmu_path.suffix != ".fmu":
        raise DesignFileError(f"the FMU file name must end in .fmu, got {fmu_path.name}")
    signals = list(design["signals"]["u"]) + list(design["signals"]["y"])
    clash = [s for s in signals if RESERVED.match(s)]
    if clash:
        raise DesignFileError(f"signal names {clash} collide with the diagnostic FMU's own variable names")
    bad = [s for s in signals if not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", s)]
    if bad:
        raise DesignFileError(f"signal names {bad} are not valid FMU variable names")
    runtime_src = sorted(RUNTIME_DIR.glob("*.py"))
    h = hashlib.sha256(json.dumps(design, sort_keys=True).encode())
    for f in runtime_src:
        h.update(f.read_bytes())
    digest = h.hexdigest()
    ident = _identifier(design["name"], digest)
    rt_pkg = f"fdirt_{digest[:12]}"
    module = f"fdi_{digest[:12]}"
    design_name = f"design_{digest[:12]}.json"

    from pythonfmu.builder import FmuBuilder

    saved_path = list(sys.path)
    with tempfile.TemporaryDirectory(prefix="fmu_fdi_build_") as tmp:
        tmp = Path(tmp)
        src = tmp / "src"
        src.mkdir()
        pkg = src / rt_pkg
        pkg.mkdir()
        for f in runtime_src:
            shutil.copy2(f, pkg / f.name)
        (src / design_name).write_text(json.dumps(design), encoding="utf-8")
        code = (TEMPLATE.replace("__RT__", rt_pkg).replace("__CLASS__", ident)
                .replace("__DESIGN__", design_name)
                .replace("__DESCRIPTION__", repr(f"fmu-fdi diagnoser '{design['name']}' "
                                                 f"({design['generator']['method']}, Ts={design['generator']['dt']:g} s)")))
        script = src / f"{module}.py"
        script.write_text(code, encoding="utf-8")
        out_dir = tmp / "out"
        try:
            built = FmuBuilder.build_FMU(script, dest=out_dir / f"{ident}.fmu", project_files=[pkg, src / design_name],
                                         needsExecutionTool="true", canHandleVariableCommunicationStepSize="true",
                                         canGetAndSetFMUstate="true", canSerializeFMUstate="true")
        finally:
            sys.path[:] = saved_path
            for name in [m for m in sys.modules if m == module or m == rt_pkg or m.startswith(rt_pkg + ".")]:
                del sys.modules[name]
        from .model_description import finalize_model_description

        finalize_model_description(built, design)
        fmu_path.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(built), fmu_path)
    return fmu_path


def fmu_output_names(design: dict) -> list[str]:
    g = design["generator"]
    return output_names(len(g["residual_names"]), len(g["groups"]))
