"""Exact, pickle-free byte encoding of an FMU state (numpy and the standard library only).

Bundled into every fmu-fdi FMU next to ``slave_base.py`` and imported from it with a relative
import, so it must not import anything from ``fmu_fdi``.

Layout of an encoded state::

    MAGIC (8 bytes) | header length n (8 bytes, little endian) | header (n bytes, UTF-8 JSON) | buffers |
    SHA-256 of everything before it (32 bytes)

The digest makes any change of the bytes after serialization (a flipped bit, a bad copy) a clean
refusal; what the bytes say is then validated by the slave (``validate_fmu_state``).

The JSON header holds the object tree; numpy arrays, numpy scalars and ``bytes`` are stored as
raw little-endian buffers after it and referenced by index, so every value comes back bit for
bit (Python floats travel as their ``repr``, which round-trips exactly, NaN and -0.0 included).

Why not pickle: a serialized FMU state is handed to the master and may come back from disk or
from another process; decoding it must never execute code. Objects are therefore restored only
for classes whose module is already imported, by ``cls.__new__`` plus ``__dict__`` (their
``__init__`` is not called).
"""
from __future__ import annotations

import enum
import hashlib
import json
import struct
import sys

import numpy as np

MAGIC = b"FDISTAT2"
FORMAT = "fmu-fdi-state/2"
DIGEST = 32  # SHA-256


class StateCodecError(ValueError):
    """A state holds a value this codec cannot encode, or bytes are not an encoded state."""


def encode_state(state) -> bytes:
    """Encode ``state`` (nested containers of scalars, arrays and plain objects) to bytes."""
    buffers: list[bytes] = []
    tree = _encode(state, buffers)
    offsets, pos = [], 0
    for b in buffers:
        offsets.append([pos, len(b)])
        pos += len(b)
    header = json.dumps({"format": FORMAT, "tree": tree, "buffers": offsets},
                        separators=(",", ":")).encode("utf-8")
    body = b"".join([MAGIC, struct.pack("<Q", len(header)), header, *buffers])
    return body + hashlib.sha256(body).digest()


def decode_state(data: bytes):
    """Inverse of :func:`encode_state`; raises :class:`StateCodecError` on foreign bytes."""
    data = bytes(data)
    if len(data) < 16 or data[:8] != MAGIC:
        raise StateCodecError("not an fmu-fdi FMU state (bad magic)")
    (n,) = struct.unpack("<Q", data[8:16])
    if len(data) < 16 + n + DIGEST:
        raise StateCodecError(f"truncated FMU state: {len(data)} bytes, the header and checksum alone need "
                              f"{16 + n + DIGEST}")
    data, digest = data[:-DIGEST], data[-DIGEST:]
    if hashlib.sha256(data).digest() != digest:
        raise StateCodecError("FMU state checksum mismatch: the bytes were changed after serialization (a truncated "
                              "or corrupt copy)")
    try:
        header = json.loads(data[16:16 + n].decode("utf-8"))
    except ValueError as exc:
        raise StateCodecError(f"corrupt FMU state header: {exc}") from None
    if header.get("format") != FORMAT:
        raise StateCodecError(f"FMU state format {header.get('format')!r}, expected {FORMAT!r}")
    base = 16 + n
    buffers = [data[base + off: base + off + size] for off, size in header["buffers"]]
    if any(len(b) != size for b, (_, size) in zip(buffers, header["buffers"])):
        raise StateCodecError(f"truncated FMU state: {len(data)} bytes, its buffers end beyond")
    return _decode(header["tree"], buffers)


def _encode(obj, buffers):
    # order matters: bool before int, numpy and Enum before the generic object branch
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int) and type(obj) is int:
        return obj
    if type(obj) is float:
        return {"f": repr(obj)}
    if isinstance(obj, np.ndarray) or isinstance(obj, np.generic):
        arr = np.asarray(obj)
        if arr.dtype.hasobject:
            raise StateCodecError("numpy arrays of Python objects cannot be encoded")
        dt = arr.dtype.newbyteorder("<") if arr.dtype.byteorder == ">" else arr.dtype
        buffers.append(np.ascontiguousarray(arr, dtype=dt).tobytes())
        return {"nd": len(buffers) - 1, "dtype": dt.str, "shape": list(arr.shape),
                "scalar": isinstance(obj, np.generic)}
    if isinstance(obj, (bytes, bytearray)):
        buffers.append(bytes(obj))
        return {"bytes": len(buffers) - 1, "mutable": isinstance(obj, bytearray)}
    if type(obj) is complex:
        return {"complex": [repr(obj.real), repr(obj.imag)]}
    if type(obj) is list:
        return [_encode(v, buffers) for v in obj]
    if type(obj) is tuple:
        return {"tuple": [_encode(v, buffers) for v in obj]}
    if type(obj) in (set, frozenset):
        return {"set": [_encode(v, buffers) for v in obj], "frozen": type(obj) is frozenset}
    if type(obj) is dict:
        return {"map": [[_encode(k, buffers), _encode(v, buffers)] for k, v in obj.items()]}
    if isinstance(obj, (list, tuple, set, frozenset, dict)):  # a subclass: its items would be lost
        raise StateCodecError(f"cannot encode a {type(obj).__qualname__} (a container subclass) in an FMU state")
    if isinstance(obj, enum.Enum):
        return {"enum": _class_path(type(obj)), "name": obj.name}
    if hasattr(obj, "__dict__") and not isinstance(obj, type) and not callable(obj):
        return {"obj": _class_path(type(obj)), "dict": _encode(dict(vars(obj)), buffers)}
    raise StateCodecError(f"cannot encode a value of type {type(obj).__qualname__} in an FMU state")


def _decode(node, buffers):
    if node is None or isinstance(node, (bool, int, str)):
        return node
    if isinstance(node, list):
        return [_decode(v, buffers) for v in node]
    if "f" in node:
        return float(node["f"])
    if "nd" in node:
        arr = np.frombuffer(buffers[node["nd"]], dtype=np.dtype(node["dtype"]))
        arr = arr.reshape(node["shape"]).copy()  # copy: writable and owning its memory
        return arr[()] if node["scalar"] else arr
    if "bytes" in node:
        b = buffers[node["bytes"]]
        return bytearray(b) if node["mutable"] else b
    if "complex" in node:
        return complex(float(node["complex"][0]), float(node["complex"][1]))
    if "tuple" in node:
        return tuple(_decode(v, buffers) for v in node["tuple"])
    if "set" in node:
        items = [_decode(v, buffers) for v in node["set"]]
        return frozenset(items) if node["frozen"] else set(items)
    if "map" in node:
        return {_decode(k, buffers): _decode(v, buffers) for k, v in node["map"]}
    if "enum" in node:
        return _resolve_class(node["enum"])[node["name"]]
    if "obj" in node:
        cls = _resolve_class(node["obj"])
        obj = cls.__new__(cls)
        obj.__dict__.update(_decode(node["dict"], buffers))
        return obj
    raise StateCodecError(f"unknown node in FMU state: {sorted(node)}")


def _class_path(cls) -> str:
    if "<locals>" in cls.__qualname__:
        raise StateCodecError(f"class {cls.__qualname__} is local to a function; its objects cannot be restored")
    return f"{cls.__module__}:{cls.__qualname__}"


def _resolve_class(path: str):
    module_name, qualname = path.split(":")
    module = sys.modules.get(module_name)
    if module is None:  # never import while decoding: the bytes choose nothing that runs
        raise StateCodecError(f"module {module_name!r} of a state object is not loaded")
    obj = module
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj
