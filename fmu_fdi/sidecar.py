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
import io
import tokenize
import zipfile
from pathlib import Path

import numpy as np
from numpy.lib import format as npy

from .outpath import write_atomically
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


def encode(arrays: dict[str, np.ndarray]) -> bytes:
    """The ``.npz`` bytes of ``arrays`` (float64, little-endian, C order; no pickle)."""
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **{k: np.ascontiguousarray(v, dtype="<f8") for k, v in arrays.items()})
    return buf.getvalue()


def table(name: str, data: bytes) -> dict:
    """The ``[arrays]`` table naming the sidecar ``name`` with the bytes ``data``."""
    return {"file": name, "sha256": hashlib.sha256(data).hexdigest()}


def write(path, arrays: dict[str, np.ndarray]) -> dict:
    """Write ``arrays`` (:func:`encode`) to the ``.npz`` at ``path``; the model file's ``[arrays]``
    table (file name and digest) is returned. The file is written under a temporary name and
    renamed: a reader never sees half a sidecar."""
    path = Path(path)
    data = encode(arrays)
    write_atomically(path, lambda part: part.write_bytes(data))
    return table(path.name, data)


def store(file_path, arrays: dict[str, np.ndarray] | None) -> dict | None:
    """The sidecar of the model or design file ``file_path``: ``arrays`` written beside it (:func:`write`)
    and its ``[arrays]`` table returned; with ``None``, a sidecar an earlier save left under that name
    (it would describe another model) is removed and None returned."""
    side = sidecar_path(file_path)
    if arrays is not None:
        return write(side, arrays)
    side.unlink(missing_ok=True)
    return None


def reference(name: str, value: np.ndarray) -> dict:
    """The model file's entry for a matrix stored in the sidecar under ``name``."""
    return {"array": name, "shape": [int(s) for s in np.shape(value)]}


#: the matrices of a fault entry (docs/model-file.md)
FAULT_MATRICES = ("Bf", "Df", "dA", "dB", "dC")


def externalise(d: dict, arrays: dict) -> dict:
    """A copy of the model dict ``d`` whose matrices (in ``matrices`` and the faults' ``Bf``, ``Df``,
    ``dA``, ``dB``, ``dC``: every two-dimensional one) are references, their values added to
    ``arrays`` under ``A``, ``Bu``, ... and ``faults.<name>.<key>`` (``d`` is not changed). The
    caller writes ``arrays`` with :func:`write` and records its table as ``arrays`` of the copy."""
    def stored(value, name):
        if isinstance(value, list) and not value:
            return value
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return value  # not numbers: left for the model's validation to name
        if array.ndim != 2:
            return value  # a fault column written as a list stays text
        arrays[name] = array
        return reference(name, array)

    out = dict(d)
    out["matrices"] = {k: stored(v, k) for k, v in (d.get("matrices") or {}).items()}
    out["faults"] = [dict(f, **{k: stored(f[k], f"faults.{f['name']}.{k}") for k in FAULT_MATRICES if k in f})
                     for f in d.get("faults", [])]
    return out


def entries(d: dict) -> int:
    """How many matrix entries the model dict ``d`` holds (lists or arrays)."""
    mats = list((d.get("matrices") or {}).values())
    mats += [f[k] for f in d.get("faults", []) if isinstance(f, dict) for k in FAULT_MATRICES if k in f]
    return sum(int(np.size(v)) if isinstance(v, np.ndarray) else sum(len(r) if isinstance(r, list) else 1 for r in v)
               for v in mats if isinstance(v, (list, np.ndarray)))


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
    damaged = f"{where}: array {key!r} of the sidecar {path} is damaged"
    try:  # the header first: an object (pickled) array is refused before any of its data is read
        with npz.zip.open(f"{key}.npy") as fh:
            version = npy.read_magic(fh)
            header = {(1, 0): npy.read_array_header_1_0, (2, 0): npy.read_array_header_2_0}.get(version)
            if header is None:
                raise ValueError(f".npy format version {version[0]}.{version[1]}")
            stored, _, dtype = header(fh)
    except _DAMAGE as exc:
        raise error(f"{damaged}: {_first_line(exc)}") from None
    if dtype.hasobject:
        raise error(f"{where}: array {key!r} of the sidecar {path} cannot be read without pickle (an object "
                    f"array); sidecar arrays are float64 data")
    if dtype != np.dtype("<f8") and dtype != np.dtype(">f8"):
        raise error(f"{where}: array {key!r} of the sidecar {path} is {dtype}, expected float64")
    if stored != tuple(shape):
        raise error(f"{where}: array {key!r} of the sidecar {path} has shape {stored}, the model file "
                    f"records {tuple(shape)}")
    try:
        value = npz[key]
    except _DAMAGE as exc:  # e.g. fewer data bytes than the header announces
        raise error(f"{damaged}: {_first_line(exc)}") from None
    value = value.astype(float, copy=False)
    finite(value, f"{where}: array {key!r} of the sidecar {path}", error)
    return value


def finite(value: np.ndarray, where: str, error: type[Exception]) -> None:
    """Every entry of ``value`` is finite and within a file number's range (:data:`MAX_ABS`), else a
    one-line ``error`` naming the first bad entry (1-based, as a file's rows and columns)."""
    bad = ~(np.abs(value) <= MAX_ABS)  # NaN too
    if bad.any():
        at = tuple(int(k) for k in np.argwhere(bad)[0])
        raise error(f"{where} has a non-finite or too large entry {''.join(f'[{k + 1}]' for k in at)} = "
                    f"{float(value[at])!r}")




#: what numpy and zipfile raise for a damaged ``.npy`` member (a bad header is parsed by tokenize)
_DAMAGE = (ValueError, SyntaxError, OSError, EOFError, KeyError, zipfile.BadZipFile, tokenize.TokenError)


def _first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0][:160]
