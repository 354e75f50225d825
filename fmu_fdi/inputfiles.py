"""Input files checked before they are parsed: present, a file, readable, UTF-8 text.

Loaders of text formats (TOML/JSON model and design files, CSV logs) otherwise fail deep in
a decoder with a message that names neither the file nor the problem. An FMU (a zip
archive) given where a model is expected is named as such, with the way from an FMU to a
model file.
"""
from __future__ import annotations

import codecs
from pathlib import Path

from .errors import InputFileError

_ZIP_MAGIC = b"PK\x03\x04"
_BOMS = {codecs.BOM_UTF16_LE: "UTF-16", codecs.BOM_UTF16_BE: "UTF-16", codecs.BOM_UTF32_LE: "UTF-32",
         codecs.BOM_UTF32_BE: "UTF-32"}


def check_input_file(path, what: str = "input file") -> Path:
    """Return ``path`` as a Path if it is a readable UTF-8 text file, else raise.

    Raises
    ------
    InputFileError
        Naming the file and the condition: missing, a folder, unreadable, an FMU or other zip
        archive, UTF-16/32, binary (NUL bytes), or not UTF-8 (with the byte offset).
    """
    path = Path(path)
    if not path.exists():
        raise InputFileError(f"{what} {str(path)!r} does not exist")
    if path.is_dir():
        raise InputFileError(f"{what} {str(path)!r} is a folder, not a file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(8192)
            if head.startswith(_ZIP_MAGIC):
                kind = "an FMU" if path.suffix.lower() == ".fmu" else "a zip archive"
                hint = ""
                if "model" in what:
                    hint = ("; to get a model file from a plant FMU, linearise it with 'fmu-fdi model' "
                            "(docs/model-file.md)")
                raise InputFileError(f"{what} {str(path)!r} is {kind}, not a text {what}{hint}")
            bom = next((name for b, name in _BOMS.items() if head.startswith(b)), None)
            if bom:
                raise InputFileError(f"{what} {str(path)!r} is {bom} text; save it as UTF-8")
            if b"\0" in head:
                raise InputFileError(f"{what} {str(path)!r} is a binary file (NUL bytes), not a text {what}")
            decoder = codecs.getincrementaldecoder("utf-8")()
            offset, chunk = 0, head
            while chunk:
                try:
                    decoder.decode(chunk)
                except UnicodeDecodeError as exc:
                    raise InputFileError(f"{what} {str(path)!r} is not UTF-8 text (byte 0x{chunk[exc.start]:02x} "
                                         f"at offset {offset + exc.start})") from None
                offset += len(chunk)
                chunk = fh.read(1 << 20)
            try:
                decoder.decode(b"", final=True)
            except UnicodeDecodeError:
                raise InputFileError(f"{what} {str(path)!r} is not UTF-8 text (truncated at its end)") from None
    except OSError as exc:
        raise InputFileError(f"cannot read {what} {str(path)!r}: {exc.strerror or exc}") from None
    return path
