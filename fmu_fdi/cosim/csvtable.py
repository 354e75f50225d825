"""One reader for the CSV tables of co-simulation: input signals and results.

A table is a header line with a ``time`` column and rows of numbers. Blank lines and ``#``
comment lines (e.g. the ``# incomplete: ...`` line of a failed streamed run) are skipped.
Every failure is a one-line :class:`CoSimulationError` naming the file and what is wrong.
"""
from __future__ import annotations

import csv
import io
from typing import Callable

import numpy as np

from .._schema import read_text
from .errors import CoSimulationError


def read_table(path, what: str, number: Callable[[str], float] = float) -> tuple[list[str], np.ndarray]:
    """``(column names, rows × columns float array)`` of the CSV table at ``path``.

    ``what`` names the file in messages (``"input CSV"``); ``number`` converts one cell
    (raises ValueError for a cell that is not a number).
    """
    text = read_text(path, "CSV file", CoSimulationError)  # missing, binary, UTF-16, FMU: one line
    try:
        rows = [r for r in csv.reader(io.StringIO(text, newline=""))
                if any(cell.strip() for cell in r) and not r[0].lstrip().startswith("#")]
    except csv.Error as exc:
        raise CoSimulationError(f"{what} {path}: not a valid CSV file: {exc}") from None
    if not rows:
        raise CoSimulationError(f"{what} {path}: the file is empty (no header line)")
    names = [h.strip().strip('"') for h in rows[0]]
    if "time" not in names:
        raise CoSimulationError(f"{what} {path}: no 'time' column in the header {names[:8]}")
    data = np.empty((len(rows) - 1, len(names)))
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(names):
            raise CoSimulationError(f"{what} {path}, line {i}: {len(row)} fields for {len(names)} columns")
        try:
            data[i - 2] = [number(cell) for cell in row]
        except ValueError as exc:
            raise CoSimulationError(f"{what} {path}, line {i}: a value is not a number: {exc}") from None
    return names, data
