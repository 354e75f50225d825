"""Binary array sidecar of a model file (``fmu-fdi-model/2``, docs/model-file.md).

A model of n = 1000 states holds a million numbers; as TOML text that is 22 MB and 28 s
of parsing. The sidecar keeps the file readable (names, signals, faults stay text) and
puts the matrices into one ``.npz`` beside it (numpy's zip of ``.npy`` arrays, written
and read with ``allow_pickle=False``: data, never code). The model file names the
sidecar by a plain file name in its own folder and records its SHA-256, and each matrix
by its entry name and shape::

    [arrays]
    file = "plant.toml.npz"
    sha256 = "9f86d0..."

    [matrices]
    A = {array = "A", shape = [1000, 1000]}

On reading, a missing or changed sidecar (digest), an entry that is absent, not float64
or of another shape than recorded, an object (pickled) array or a non-finite entry is a
one-line error naming the model file, the sidecar and the entry.
"""
from __future__ import annotations

import hashlib
import zipfile
from pathlib import Path

import numpy as np

from .runtime.schema import MAX_ABS, check_keys, text, type_name

#: above this many matrix entries in all, :meth:`FDIModel.to_file` writes the matrices to a
#: sidecar by default (about n = 300 states; a TOML file of this size reads in ~2 s)
SIDECAR_MIN_ENTRIES = 100_000
SUFFIX = ".npz"


def is_reference(value) -> bool:
    """Whether a matrix value of a model dict is a sidecar reference ``{array, shape}``."""
    return isinstance(value, dict) and "array" in value


def sidecar_path(model_path) -> Path:
    """The sidecar written beside ``model_path``: ``plant.toml`` → ``plant.toml.npz`` (the
    whole name, so ``plant.json`` beside it keeps its own)."""
    model_path = Path(model_path)
    return model_path.with_name(model_path.name + SUFFIX)


def sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def write(path, arrays: dict[str, np.ndarray]) -> dict:
    """Write ``arrays`` (float64, little-endian, C order) to the ``.npz`` at ``path``; the
    model file's ``[arrays]`` table (file name and digest) is returned."""
    path = Path(path)
    data = {k: np.ascontiguousarray(v, dtype="<f8") for k, v in arrays.items()}
    with open(path, "wb") as fh:
        np.savez(fh, allow_pickle=False, **data)
    return {"file": path.name, "sha256": sha256(path)}


def reference(name: str, value: np.ndarray) -> dict:
    """The model file's entry for a matrix stored in the sidecar under ``name``."""
    return {"array": name, "shape": [int(s) for s in np.shape(value)]}


def resolve(d: dict, base, source: str, error: type[Exception]) -> dict:
    """The model dict ``d`` with every sidecar reference (in ``matrices`` and in the
    faults' matrices) replaced by its checked float64 array; ``d`` itself is not changed.

    ``base`` is the folder of the model file (None for a model embedded in another file,
    which cannot use a sidecar).
    """
    refs = _references(d)
    table_ = d.get("arrays")
    if table_ is None:
        if refs:
            where, _ = refs[0]
            raise error(f"{source}: {where} refers to a sidecar array but the file has no [arrays] table")
        return d
    if not isinstance(table_, dict):
        raise error(f"{source}: arrays must be a table (file, sha256), got {type_name(table_)}")
    check_keys(table_, ("file", "sha256"), ("file", "sha256"), f"{source}: arrays", error)
    name = text(table_["file"], f"{source}: arrays.file", error)
    digest = text(table_["sha256"], f"{source}: arrays.sha256", error)
    if base is None:
        raise error(f"{source}: matrices in a sidecar file ({name}) can only be read from a model file on disk "
                    f"(FDIModel.from_file), not from an embedded model")
    if Path(name).name != name or name in (".", ".."):
        raise error(f"{source}: arrays.file must be a file name in the model file's folder, got {name!r}")
    path = Path(base) / name
    if not path.is_file():
        raise error(f"{source}: its sidecar {path} is missing (keep the model file and {name} together)")
    actual = sha256(path)
    if actual != digest.lower():
        raise error(f"{source}: its sidecar {path} is corrupt or was changed: SHA-256 {actual}, the model file "
                    f"records {digest}")
    out = dict(d)
    out["matrices"] = dict(d.get("matrices") or {})
    out["faults"] = [dict(f) if isinstance(f, dict) else f for f in d.get("faults", [])]
    try:
        npz = np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:  # not a zip: np.load would try a pickle
        raise error(f"{source}: its sidecar {path} is not a valid .npz (a zip of .npy arrays): "
                    f"{str(exc).splitlines()[0][:120]}") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):  # a single .npy array
        raise error(f"{source}: its sidecar {path} is not a valid .npz (a zip of .npy arrays): it is one .npy array")
    with npz:
        for where, (container, key) in refs:
            target = out["matrices"] if container is None else out["faults"][container]
            target[key] = _entry(npz, target[key], path, f"{source}: {where}", error)
    return out


def _references(d: dict) -> list[tuple[str, tuple[int | None, str]]]:
    """``(where, (fault index or None, key))`` of every sidecar reference in ``d``."""
    refs = []
    mats = d.get("matrices")
    if isinstance(mats, dict):
        refs += [(f"matrix {k}", (None, k)) for k, v in mats.items() if is_reference(v)]
    faults = d.get("faults")
    if isinstance(faults, list):
        for i, f in enumerate(faults):
            if isinstance(f, dict):
                refs += [(f"faults[{i}].{k}", (i, k)) for k, v in f.items() if is_reference(v)]
    return refs


def _entry(npz, ref: dict, path: Path, where: str, error: type[Exception]) -> np.ndarray:
    check_keys(ref, ("array", "shape"), ("array", "shape"), where, error)
    key = text(ref["array"], f"{where}.array", error)
    shape = ref["shape"]
    if not (isinstance(shape, list) and len(shape) == 2
            and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape)):
        raise error(f"{where}.shape must be [rows, columns] (two integers >= 0), got {shape!r}")
    if key not in npz.files:
        raise error(f"{where}: array {key!r} is not in the sidecar {path} (it holds {sorted(npz.files)})")
    try:
        value = npz[key]
    except ValueError as exc:  # an object array: loading it would unpickle
        raise error(f"{where}: array {key!r} of the sidecar {path} cannot be read without pickle ({exc}); "
                    f"sidecar arrays are float64 data") from None
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise error(f"{where}: array {key!r} of the sidecar {path} is damaged: {exc}") from None
    if value.dtype != np.dtype("<f8") and value.dtype != np.dtype(">f8"):
        raise error(f"{where}: array {key!r} of the sidecar {path} is {value.dtype}, expected float64")
    if value.shape != tuple(shape):
        raise error(f"{where}: array {key!r} of the sidecar {path} has shape {value.shape}, the model file "
                    f"records {tuple(shape)}")
    value = value.astype(float, copy=False)
    bad = ~(np.abs(value) <= MAX_ABS)  # NaN too
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise error(f"{where}: array {key!r} of the sidecar {path} has a non-finite or too large entry "
                    f"[{i + 1}][{j + 1}] = {value[i, j]!r}")
    return value


