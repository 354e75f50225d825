"""The design file: a diagnoser as versioned JSON (format ``fmu-fdi-design/1``).

A design file holds everything the run-time needs and nothing executable: signal names
and units, the operating point, the discrete generator (and the continuous one when the
design has it, for exact re-discretisation at another step size), one evaluator and one
threshold per residual group, the decision logic, and the fault names. The schema is
documented in ``docs/design-file.md``. Files are read strictly: an unknown version, a
missing key or a matrix of the wrong shape is an error that names the item.

The embedded model of a large plant (more than :data:`fmu_fdi.sidecar.SIDECAR_MIN_ENTRIES`
matrix entries, about n = 300 states) keeps its matrices in a binary sidecar beside the
design file, ``design.json.npz``, exactly as a model file does (format ``fmu-fdi-model/2``,
:mod:`fmu_fdi.sidecar`: float64 arrays without pickle, checked by SHA-256, shape and value).
A design read from such a file holds the model's matrices as float64 arrays.
"""
from __future__ import annotations

import json
from pathlib import Path

from . import sidecar
from ._schema import parse, read_text
from .errors import ModelError
from .outpath import _clean, check_output_path, json_text, write_atomically
from .runtime.design_check import FORMAT, DesignCheckError, check_design  # noqa: F401


class DesignFileError(ModelError):
    """A design file (or design dict) is malformed; the message names the item."""


def validate_design(d, source: str = "design", *, base=None) -> dict:
    """Check a design dict; returns it or raises DesignFileError (one line).

    The rules and ranges are those of :func:`fmu_fdi.runtime.design_check.check_design`,
    which the run-time (and so the diagnostic FMU) applies itself; here the design is
    also instantiated (which checks what only the run-time objects know, e.g. an RLS
    estimator's relations) and an embedded model (``"model"``) is read as a model file.
    ``base`` is the design file's folder, where the embedded model's sidecar lies: its
    references are replaced in ``d`` by the arrays read (see the module docstring).
    """
    checked_design(d, source, base=base)
    return d


def checked_design(d, source: str = "design", *, base=None):
    """:func:`validate_design`, returning the embedded model (an :class:`~fmu_fdi.model.FDIModel`)
    or None: one validation serves the caller that needs the model too."""
    from .runtime.engine import DiagnoserRuntime

    try:
        check_design(d, source)
        DiagnoserRuntime(d, checked=True)  # d has just passed check_design
    except DesignCheckError as exc:
        raise DesignFileError(str(exc)) from None
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc)
        raise DesignFileError(f"{source}: {what}") from None
    if "model" not in d:
        return None
    from .model import FDIModel

    try:
        d["model"] = _resolved(d["model"], base, f"{source}: model")
        model = FDIModel.from_dict(d["model"], source=f"{source}: model")
    except ModelError as exc:
        raise DesignFileError(str(exc)) from None
    _check_model_agrees(d, model, source)
    return model


def _resolved(m, base, source: str):
    """The embedded model dict with its sidecar's arrays in place of the references (format
    ``fmu-fdi-model/1`` then, no ``arrays`` table); any other dict as it is, for the model's
    own validation to judge."""
    from .model import FORMAT as MODEL, FORMAT_SIDECAR

    if not (isinstance(m, dict) and m.get("format") == FORMAT_SIDECAR and "arrays" in m):
        return m
    out = sidecar.resolve(m, base, source, ModelError)
    del out["arrays"]
    out["format"] = MODEL
    return out


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
    and renamed, so a failure leaves any previous design file as it was. An embedded model of
    more than :data:`~fmu_fdi.sidecar.SIDECAR_MIN_ENTRIES` matrix entries goes to the sidecar
    ``<path>.npz`` (written first, the same way); a design saved without one removes the
    sidecar an earlier save left under that name.
    """
    d = _clean(d)
    validate_design(d, str(path))
    path = check_output_path(path, (".json",), "design file", error=DesignFileError)
    d, arrays = _split(d)
    table = sidecar.store(path, arrays)
    if table is not None:
        d["model"]["arrays"] = table
    text = json_text(d)
    return write_atomically(path, lambda part: part.write_text(text, encoding="utf-8"))


def _split(d: dict) -> tuple[dict, dict | None]:
    """A validated, JSON-ready design and the arrays of its sidecar: ``(d, None)`` when the embedded
    model is small (or absent), else a copy whose model (format ``fmu-fdi-model/2``) refers to
    ``arrays``; the caller writes them and records their table as the model's ``arrays``."""
    if "model" not in d or sidecar.entries(d["model"]) <= sidecar.SIDECAR_MIN_ENTRIES:
        return d, None
    from .model import FORMAT_SIDECAR

    arrays: dict = {}
    d = dict(d)
    d["model"] = sidecar.externalise(d["model"], arrays)
    d["model"]["format"] = FORMAT_SIDECAR
    return d, arrays


def parse_design_file(path) -> dict:
    """A design file's JSON, read as UTF-8 and parsed, NOT yet validated (single or scheduled: the
    caller validates by its kind); unreadable or malformed text is a :class:`DesignFileError`."""
    return parse(read_text(path, "design file", DesignFileError), "json", str(path), DesignFileError)


def read_design(path):
    """Read and validate a design file: ``(design dict, embedded model or None)``."""
    d = parse_design_file(path)
    return d, checked_design(d, str(path), base=Path(path).parent)


def load_design(path) -> dict:
    """Read and validate a design file (UTF-8 JSON, format ``fmu-fdi-design/1``; the embedded
    model's matrices may be in a sidecar, see the module docstring)."""
    return read_design(path)[0]


def design_resources(d: dict) -> dict[str, bytes]:
    """The design file as the diagnostic FMUs carry it in their resources (the run-time reads
    ``design.json``; campaigns read its faults and decision rule): compact JSON with sorted keys
    and, for a large embedded model, its sidecar ``design.json.npz`` beside it, as
    :func:`save_design` would write them."""
    d, arrays = _split(d)  # d is validated: a model read from a sidecar keeps its checked arrays
    d = _clean(d)
    files = {}
    if arrays:
        side = sidecar.sidecar_path("design.json").name
        files[side] = sidecar.encode(arrays)
        d["model"]["arrays"] = sidecar.table(side, files[side])
    return {"design.json": json.dumps(d, sort_keys=True, allow_nan=False).encode("utf-8"), **files}
