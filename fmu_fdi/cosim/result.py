"""Co-simulation results: a numpy structured array with one row per communication point.

Columns: ``time``; ``<fmu>.<output>`` for every scalar output of every FMU (Real as float64,
Integer and Enumeration as int64, Boolean as bool; String outputs are not recorded);
with ``record_inputs``, ``<fmu>.<input>`` for every input the master sets (from a connection, an external signal or a
fault), holding the value of its source at ``t_k`` with the faults applied; for every
fault ``fault.<name>`` (float64:
the faulty minus the nominal value of its target, i.e. the true additive fault signal) and
``fault.<name>.active`` (bool: the fault acts at that time). Row ``k`` holds the outputs at
``t_k`` and the fault signals applied at ``t_k``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


class Result(np.ndarray):
    """Structured array of a co-simulation run, saved with :meth:`to_csv`.

    ``result["plant.y"]`` is a plain float array; slicing rows keeps the type.

    Examples
    --------
    >>> r = Result.empty(["time", "plant.y"], ["real", "real"], 2)
    >>> r.names
    ('time', 'plant.y')
    """

    def __new__(cls, data):
        arr = np.asarray(data)
        if arr.dtype.names is None or "time" not in arr.dtype.names:
            raise ValueError("a Result needs a structured array with a 'time' field")
        return arr.view(cls)

    @classmethod
    def empty(cls, names, kinds, rows: int) -> "Result":
        """Zeros with ``rows`` rows and a column per name; kinds are ``real``/``integer``/``boolean``."""
        dtype = {"real": np.float64, "integer": np.int64, "boolean": np.bool_}
        return cls(np.zeros(rows, dtype=[(n, dtype[k]) for n, k in zip(names, kinds)]))

    def __getitem__(self, key):
        out = super().__getitem__(key)
        # a single column is a signal, not a result: hand out a plain array
        return out.view(np.ndarray) if isinstance(key, str) else out

    @property
    def names(self) -> tuple:
        """Column names, ``time`` first."""
        return self.dtype.names

    def to_csv(self, path) -> Path:
        """Write the FMI cross-check CSV style: a header ``"time","var1",...`` then one row per
        time; floats in the shortest form that reads back exactly, Booleans as 0/1."""
        with CsvWriter(path, self.names) as w:
            w.write(self)
        return Path(path)

    @classmethod
    def from_csv(cls, path) -> "Result":
        """Read a CSV written by :meth:`to_csv`, by :class:`CsvWriter` or by ``fmpy simulate``
        (Booleans as True/False); every column comes back as float64. Comment lines
        (``# incomplete: ...``) are skipped."""
        from .csvtable import read_table

        names, data = read_table(path, "result CSV", _number)
        out = np.zeros(len(data), dtype=[(n, np.float64) for n in names])
        for j, n in enumerate(names):
            out[n] = data[:, j]
        return cls(out)


class CsvWriter:
    """Writes result rows to a CSV as they come, so a run of any length needs bounded memory.

    The file is opened (and its header written) on construction: an unwritable path fails
    before anything runs. Rows are structured arrays (chunks of a :class:`Result`). If the
    writer is closed with a ``reason`` (or left by an exception), a last line
    ``# incomplete: <reason>`` says that the rows stop early and why; readers that honour
    ``#`` comments (numpy, fmpy, :meth:`Result.from_csv`) skip it, others see a short row.
    """

    def __init__(self, path, names):
        self.path = Path(path)
        self.names = tuple(names)
        self.rows = 0
        self._file = open(self.path, "w", newline="")  # OSError names the path and the reason
        self._file.write(",".join(f'"{n}"' for n in self.names) + "\n")

    def write(self, rows) -> None:
        columns = []
        for name in self.names:
            col = rows[name]
            if col.dtype == np.bool_:
                columns.append(["1" if v else "0" for v in col.tolist()])
            elif np.issubdtype(col.dtype, np.integer):
                columns.append([str(v) for v in col.tolist()])
            else:
                columns.append([repr(v) for v in col.tolist()])
        self._file.writelines(",".join(row) + "\n" for row in zip(*columns))
        self.rows += len(rows)

    def close(self, reason: str | None = None) -> None:
        if self._file.closed:
            return
        if reason is not None:
            self._file.write("# incomplete: " + " ".join(str(reason).split()) + "\n")
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        self.close(None if kind is None else f"interrupted by {kind.__name__}: {exc}")


def _number(text: str) -> float:
    text = text.strip()
    if text in ("True", "true"):
        return 1.0
    if text in ("False", "false"):
        return 0.0
    return float(text)
