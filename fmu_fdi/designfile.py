"""The design file: a diagnoser as versioned JSON (format ``fmu-fdi-design/1``).

A design file holds everything the run-time needs and nothing executable: signal names
and units, the operating point, the discrete generator (and the continuous one when the
design has it, for exact re-discretisation at another step size), one evaluator and one
threshold per residual group, the decision logic, and the fault names. The schema is
documented in ``docs/design-file.md``. Files are read strictly: an unknown version, a
missing key or a matrix of the wrong shape is an error that names the item.
"""
from __future__ import annotations

import json
from pathlib import Path

from ._schema import parse, read_text
from .errors import ModelError
from .outpath import _clean, check_output_path, write_atomically
from .runtime.design_check import FORMAT, DesignCheckError, check_design  # noqa: F401


class DesignFileError(ModelError):
    """A design file (or design dict) is malformed; the message names the item."""


def validate_design(d, source: str = "design") -> dict:
    """Check a design dict; returns it unchanged or raises DesignFileError (one line).

    The rules and ranges are those of :func:`fmu_fdi.runtime.design_check.check_design`,
    which the run-time (and so the diagnostic FMU) applies itself; here the design is
    also instantiated (which checks what only the run-time objects know, e.g. an RLS
    estimator's relations) and an embedded model (``"model"``) is read as a model file.
    """
    from .runtime.engine import DiagnoserRuntime

    try:
        check_design(d, source)
        DiagnoserRuntime(d, checked=True)  # d has just passed check_design
    except DesignCheckError as exc:
        raise DesignFileError(str(exc)) from None
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc)
        raise DesignFileError(f"{source}: {what}") from None
    if "model" in d:
        from .model import FDIModel

        try:
            model = FDIModel.from_dict(d["model"], source=f"{source}: model")
        except ModelError as exc:
            raise DesignFileError(str(exc)) from None
        _check_model_agrees(d, model, source)
    return d


def _check_model_agrees(d: dict, model, source: str) -> None:
    """The embedded model is the one the generator was designed for: same signals, faults
    and (when discrete) sample time, so ``Diagnoser.load`` can rebuild the generator."""
    sig = d["signals"]
    if model.u_names != sig["u"] or model.y_names != sig["y"]:
        raise DesignFileError(f"{source}: the embedded model's signals u={model.u_names}, y={model.y_names} differ "
                              f"from the design's u={sig['u']}, y={sig['y']}")
    names = [f["name"] for f in d["faults"]]
    if model.fault_names != names:
        raise DesignFileError(f"{source}: the embedded model's faults {model.fault_names} differ from the design's "
                              f"{names}")
    dt = d["generator"]["dt"]
    if model.is_discrete and abs(model.dt - dt) > 1e-12 * dt:
        raise DesignFileError(f"{source}: the embedded model is discrete with dt = {model.dt!r} but the generator "
                              f"runs at dt = {dt!r}")


def save_design(d: dict, path) -> Path:
    """Validate and write a design dict as JSON (floats round-trip exactly).

    The path must end in ``.json`` and its folder must accept a file
    (:func:`~fmu_fdi.outpath.check_output_path`); the file is written to a temporary name
    and renamed, so a failure leaves any previous design file as it was.
    """
    d = _clean(d)
    validate_design(d, str(path))
    path = check_output_path(path, (".json",), "design file", error=DesignFileError)
    text = json.dumps(d, indent=1, allow_nan=False)
    return write_atomically(path, lambda part: part.write_text(text, encoding="utf-8"))


def load_design(path) -> dict:
    """Read and validate a design file (UTF-8 JSON, format ``fmu-fdi-design/1``)."""
    text = read_text(path, "design file", DesignFileError)
    return validate_design(parse(text, "json", str(path), DesignFileError), str(path))
