"""Build the diagnostic FMU (FMI 2.0 co-simulation, pythonfmu) from a Diagnoser or design file.

The FMU's ``resources/`` hold a package whose name is unique to the FMU (a hash of the
design and the code, see :mod:`.packaging`) with: the numpy-only runtime
(:mod:`fmu_fdi.runtime`, copied as it is), the slave module (:mod:`.slave_template`), the
slave base and state codec, and ``design.json``. Several diagnostic FMUs therefore load in
one process without module clashes (pythonfmu issue 228), and the FMU never imports
scipy, control or an installed ``fmu_fdi``. The model description is completed so that
``fmpy validate`` reports no problem: units, descriptions, discrete variability of
outputs, no direct feedthrough (outputs are updated at ``fmi2DoStep``), the
``DefaultExperiment`` (step size Ts, a stop time of :data:`DEFAULT_SAMPLES` samples unless
given), and capability flags that tell the truth. Descriptions say which faults each
residual and evaluation group is sensitive to (the design's structure matrix) and the FMU's
description names the tunable ``threshold_scale`` and the platforms the archive has binaries
for, so ``fmpy info`` shows both.

Units: when every measured output has the same unit U, the residuals (linear combinations
of the outputs with dimensionless weights, plus the input terms that cancel them in the
fault-free case) are in U, and so are the evaluations and thresholds of the kinds that keep
the residual's unit (norm, RMS, exponential RMS, peak, Narendra). Residuals of an RLS
estimator are in standard deviations and χ² statistics are dimensionless: no unit is
claimed for them, nor when the outputs' units differ.
"""
from __future__ import annotations

import math
import os
import re
from pathlib import Path

from ..designfile import DesignFileError, checked_design, design_resources, parse_design_file, validate_design
from ..designinfo import variable_descriptions, variable_type_attributes, variable_types, variable_units
from ..outpath import _clean
from ..runtime.engine import output_names
from ..runtime.schedule import is_scheduled
from .packaging import build_slave_fmu, checked_destination, unique_bundle_name
from .slave_template import TEMPLATE

RUNTIME_DIR = Path(__file__).resolve().parent.parent / "runtime"
#: DefaultExperiment stop time, in samples of the design's Ts, when none is given
DEFAULT_SAMPLES = 1000


def _design_of(diagnoser_or_path) -> dict:
    if isinstance(diagnoser_or_path, (str, os.PathLike)):
        # a file, read once; the diagnoser classes (and the analysis and scipy they import, seconds
        # in a fresh 'fmu-fdi build') are not needed for it
        d = parse_design_file(diagnoser_or_path)
        if is_scheduled(d):
            from ..schedule import validate_scheduled_design

            return validate_scheduled_design(d, str(diagnoser_or_path))
        checked_design(d, str(diagnoser_or_path), base=Path(diagnoser_or_path).parent)
        return d
    from ..diagnoser import Diagnoser
    from ..schedule import design_of  # a scheduled design (fmu_fdi/schedule.py) or None

    scheduled = design_of(diagnoser_or_path)
    if scheduled is not None:
        return scheduled
    if isinstance(diagnoser_or_path, Diagnoser):
        return validate_design(_clean(diagnoser_or_path.design), "diagnoser")  # a JSON-ready copy
    if isinstance(diagnoser_or_path, dict):
        return validate_design(diagnoser_or_path, "design")
    raise DesignFileError(f"build_fmu needs a Diagnoser, a design dict or a design file path, got "
                          f"{type(diagnoser_or_path).__name__}")


def build_fmu(diagnoser_or_path, fmu_path, target: str = "pythonfmu", fmi_version: int = 2, *,
              stop_time: float | None = None) -> Path:
    """Export a diagnoser (object, design dict or design file path) as a co-simulation FMU.

    Parameters
    ----------
    diagnoser_or_path : Diagnoser, dict or path
    fmu_path : path
        Where to write the ``.fmu``. The archive is built and checked (binaries for this
        platform, model description, resources) in a temporary folder, then renamed onto
        ``fmu_path``: nothing is written when the design or the destination is invalid, and
        a failed build leaves a previous file of that name as it was.
    target : {"pythonfmu", "native"}
        ``"pythonfmu"`` (default): the runtime in Python, FMI 2.0, the host needs Python and
        numpy. ``"native"``: C99 sources compiled now, no Python in the host
        (:mod:`fmu_fdi.native.build`, docs/native-fmu.md).
    fmi_version : {2, 3}
        FMI 3.0 needs ``target="native"``.
    stop_time : float, optional
        ``DefaultExperiment`` stop time (s), what ``fmpy simulate`` runs for without
        ``--stop-time``. Default: :data:`DEFAULT_SAMPLES` samples of the design's Ts.

    Returns
    -------
    Path of the written FMU.

    Raises
    ------
    DesignFileError
        The design is malformed, or a signal name is no valid FMU variable name or
        collides with one of the FMU's own outputs.
    BuildError
        ``fmu_path`` does not end in ``.fmu``, is a folder or cannot be written, or the
        archive written is not a loadable FMU for this platform.
    """
    fmu_path = checked_destination(fmu_path)
    design = _design_of(diagnoser_or_path)
    # a scheduled design: the members share signals and residual structure, so member 1
    # describes the variables; active_member is added (fmu_fdi/schedule.py)
    view = design["members"][0] if "members" in design else design
    # signal names are valid identifiers and clash with none of the FMU's own variables:
    # checked with everything else by the one validator (runtime/design_check.py)
    g = view["generator"]
    if stop_time is None:
        stop_time = DEFAULT_SAMPLES * float(g["dt"])
    elif not (isinstance(stop_time, (int, float)) and math.isfinite(stop_time) and stop_time > 0):
        raise DesignFileError(f"stop_time must be a positive finite number of seconds, got {stop_time!r}")
    if target == "native":
        from ..native.build import build_native_fmu

        return build_native_fmu(design, fmu_path, fmi_version=fmi_version, stop_time=float(stop_time))
    if target != "pythonfmu" or fmi_version != 2:
        raise DesignFileError(f"target {target!r} with FMI {fmi_version}: the pythonfmu target is FMI 2 only, "
                              "the native target FMI 2 or 3")
    resources = design_resources(design)
    modules = {f.name: f.read_text(encoding="utf-8") for f in sorted(RUNTIME_DIR.glob("*.py"))
               if f.name != "__init__.py"}
    base = re.sub(r"[^A-Za-z0-9_]", "_", design["name"]) or "fdi"
    ident = unique_bundle_name(base if base[0].isalpha() else "fdi_" + base, resources["design.json"].decode(),
                               *(modules[k] for k in sorted(modules)))
    modules["diagnoser_slave.py"] = TEMPLATE.replace("__CLASS__", ident).replace(
        "__DESCRIPTION__", repr(f"fmu-fdi diagnoser '{design['name']}' ({g['method']}, Ts = {g['dt']:g} s)"))
    names = output_names(len(g["residual_names"]), len(g["groups"]))
    descriptions = variable_descriptions(view)
    if view is not design:
        from ..schedule import scheduled_outputs

        names, descriptions = scheduled_outputs(design, names, descriptions)
    units = variable_units(view)
    dt = float(g["dt"])
    return build_slave_fmu(
        modules, f"diagnoser_slave:{ident}", fmu_path, bundle_name=f"{ident}_fmu",
        data_files=resources,
        units=units, declared_types=variable_types(view), type_attributes=variable_type_attributes(view),
        descriptions=descriptions,
        output_dependencies={n: [] for n in names},
        capabilities={"canGetAndSetFMUstate": True, "canSerializeFMUstate": True,
                      "canHandleVariableCommunicationStepSize": True},
        default_experiment={"startTime": 0.0, "stopTime": float(stop_time), "stepSize": dt},
        model_description=(f"fmu-fdi diagnoser '{design['name']}' ({g['method']}, Ts = {dt:g} s); "
                           f"tunable parameter threshold_scale (default 1) multiplies every threshold"),
    )
