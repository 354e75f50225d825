"""Exceptions of the co-simulation master.

Two kinds, because they call for different reactions:

- :class:`CoSimulationError` (a ``ValueError``): the set-up is wrong — an unknown variable in a
  connection, fault or parameter, mismatched types, a bad step, a malformed fault SPEC. It is
  raised before any FMU is instantiated, and the message names the offending item.
- :class:`SimulationFailed` (a ``RuntimeError``): an FMU refused to go on during the run (its
  ``doStep`` returned Discard, Error or Fatal, FMI 3 asked to terminate, or initialisation
  failed). The message names the FMU and the time; the part of the run completed so far is
  attached as :attr:`SimulationFailed.result`, so a caller can still look at it or save it.

A missing FMU file raises the built-in ``FileNotFoundError`` (naming the instance and path).
"""
from __future__ import annotations


class CoSimulationError(ValueError):
    """A co-simulation set-up (FMUs, connections, inputs, faults, parameters, step) is invalid."""


class SimulationFailed(RuntimeError):
    """An FMU stopped the run; the partial result is attached.

    Attributes
    ----------
    fmu : str
        Instance name of the FMU that failed.
    time : float
        Communication point at which the failing call started.
    result : Result or None
        Rows from the start time up to the last communication point every FMU completed
        (None when the run streamed its rows to a CSV: they are there, marked incomplete).
    rows_written : int or None
        Rows in that CSV (streamed runs only).
    log : list of str
        The last log messages the failing FMU sent to the master.
    warnings : list of str
        Warnings (and worse) every FMU logged during the run, one line per distinct message.
    """

    def __init__(self, message: str, *, fmu: str, time: float, log=()):
        super().__init__(message)
        self.fmu = fmu
        self.time = time
        self.log = list(log)
        self.result = None
        self.rows_written = None
        self.warnings = []
