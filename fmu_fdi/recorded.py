"""Recorded logs: which CSV column holds which signal, for offline diagnosis and calibration.

A log is a CSV with a ``time`` column and the signals a design reads (the model's u and y
names). Two spellings are accepted, so the output of ``fmu-fdi simulate`` is a log as it is:

- plain: ``Q1``, ``h1`` (as ``fmpy simulate --input-file`` wants them);
- instance-prefixed: ``plant.Q1``, ``diagnoser.h1`` (as a co-simulation result names them).

For a signal ``s`` the rule is: with an explicit ``prefix``, the column ``<prefix>s``;
otherwise the column ``s`` if there is one; otherwise the one column ``<instance>.s``; if
several instances have it, the instance whose diagnoser outputs are in the log (it recorded
the inputs the diagnoser actually read, faults on connections included). Anything else is
ambiguous and an error that lists the candidates.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field

import numpy as np

from .errors import InputFileError


@dataclass
class Log:
    """A log resolved to arrays: ``t`` (N,), ``u`` (N × nu), ``y`` (N × ny)."""

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    columns: dict = field(default_factory=dict)  # signal -> column read

    def describe(self) -> str:
        """One line: how many samples and which column each signal came from."""
        used = ", ".join(s if c == s else f"{s} <- {c}" for s, c in self.columns.items())
        return f"{self.t.size} samples; columns used: time, {used}"


def read_result(path):
    """:meth:`fmu_fdi.cosim.Result.from_csv` with one-line errors that name the file."""
    from .cosim import Result

    try:
        res = Result.from_csv(path)
    except (ValueError, IndexError, csv.Error) as exc:
        raise InputFileError(f"{path}: not a readable CSV of numbers with a header row "
                             f"({' '.join(str(exc).split()) or type(exc).__name__})") from None
    if "time" not in res.dtype.names:
        raise InputFileError(f"{path}: no 'time' column (columns: {', '.join(res.dtype.names)})")
    if len(res) == 0:
        raise InputFileError(f"{path}: no data rows")
    return res


def diagnoser_instances(names) -> list[str]:
    """Prefixes (``"diagnoser."``, or ``""`` for plain columns) that hold diagnoser outputs."""
    return [n[: -len("fault_detected")] for n in names if n.endswith("fault_detected")]


def diagnoser_prefix(result, prefix, source: str) -> str:
    """The column prefix of the diagnoser outputs in ``result`` (given or found)."""
    names = result.dtype.names
    hits = diagnoser_instances(names)
    if prefix is None:
        if len(hits) != 1:
            raise InputFileError(f"{source}: give --prefix, found diagnoser outputs under "
                                 f"{hits or 'no prefix: no fault_detected column'}")
        return hits[0]
    if f"{prefix}fault_detected" not in names:
        raise InputFileError(f"{source}: no column {prefix}fault_detected (diagnoser outputs are under "
                             f"{hits or 'no prefix'})")
    return prefix


def signal_columns(names, signals, prefix: str | None = None, source: str = "log") -> dict:
    """Signal name -> the column of ``names`` that holds it (rule in the module docstring)."""
    names = list(names)
    have = set(names)
    preferred = [p for p in diagnoser_instances(names) if p]
    out, missing = {}, []
    for s in signals:
        if prefix is not None:
            col = f"{prefix}{s}"
            if col not in have:
                missing.append(col)
                continue
            out[s] = col
            continue
        if s in have:
            out[s] = s
            continue
        cands = [n for n in names if n.endswith("." + s) and "." not in n[: -len(s) - 1] and n != f"fault.{s}"]
        if len(cands) > 1:
            best = [c for c in cands if any(c == p + s for p in preferred)]
            cands = best if len(best) == 1 else cands
        if not cands:
            missing.append(s)
        elif len(cands) > 1:
            raise InputFileError(f"{source}: signal {s!r} is in several columns ({', '.join(cands)}); "
                                 f"choose one instance with --prefix")
        else:
            out[s] = cands[0]
    if missing:
        raise InputFileError(f"{source}: no column for {', '.join(missing)} (a log needs 'time' and one column per "
                             f"signal, plain or as INSTANCE.signal; columns: {', '.join(names)})")
    return out


def read_log(source, u_names, y_names, prefix: str | None = None) -> Log:
    """Read a log (CSV path or structured array) into arrays of the given signals.

    Parameters
    ----------
    source : path or structured array
        With a ``time`` field and the signals (plain or instance-prefixed names).
    u_names, y_names : sequence of str
        The known inputs and the measured outputs, in the design's order.
    prefix : str, optional
        Read every signal from ``<prefix><name>`` (e.g. ``"plant."``).

    Returns
    -------
    Log
        Arrays and the columns used (:meth:`Log.describe` for a message).

    Raises
    ------
    InputFileError
        The file is unreadable, has no ``time`` column or misses a signal, or a signal is
        ambiguous (several instances have it).
    """
    label = str(source) if not hasattr(source, "dtype") else "log"
    rec = read_result(source) if not hasattr(source, "dtype") else source
    if "time" not in rec.dtype.names:
        raise InputFileError(f"{label}: no 'time' column")
    u_names, y_names = list(u_names), list(y_names)
    cols = signal_columns(rec.dtype.names, u_names + y_names, prefix, label)
    N = len(rec)

    def block(sigs):
        if not sigs:
            return np.zeros((N, 0))
        return np.column_stack([np.asarray(rec[cols[s]], dtype=float) for s in sigs])

    return Log(np.asarray(rec["time"], dtype=float), block(u_names), block(y_names), cols)
