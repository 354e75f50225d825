"""The fault SPEC mini-language of ``fmu-fdi simulate --fault SPEC``.

::

    SPEC      := KIND ":" TARGET ":" ONSET [":" END] ":" MAGNITUDE ("," OPTION)*
    OPTION    := ("ramp" | "period" | "duty" | "name") "=" VALUE

- ``KIND``: ``abrupt`` (``step``, ``bias``), ``incipient`` (``ramp``), ``intermittent``,
  ``stuck``, ``gain``, ``drift``, ``parameter`` (``set``); see :mod:`fmu_fdi.cosim.faults`.
- ``TARGET``: ``fmu.variable``, e.g. ``plant.h1`` or ``diagnoser.h1`` (variable names that
  contain ``:`` or ``,`` cannot be written here; use the Python API).
- ``ONSET``, ``END``: seconds; ``END`` may be left empty or written ``inf`` for a permanent fault.
- ``MAGNITUDE``: the offset added (``abrupt``; ``incipient``: reached after ``ramp`` seconds,
  default ``END − ONSET``; ``intermittent``: while on, for the first ``duty`` (default 0.5) of
  every ``period`` seconds), the factor (``gain``), the rate per second (``drift``), the value
  taken (``parameter``, ``stuck``); for ``stuck`` the word ``hold`` freezes the signal at its
  value at onset.
- ``name=``: the result columns are ``fault.<name>`` and ``fault.<name>.active``; default
  ``<kind>_<fmu>_<variable>``.

Examples::

    abrupt:plant.h1:10:0.5                 bias of +0.5 from t = 10 s on
    gain:plant.h1:10:20:0.8                factor 0.8 from 10 s to 20 s
    stuck:plant.h1:10:hold                 frozen at its value at 10 s
    stuck:plant.h1:10:20:5                 reads 5 from 10 s to 20 s
    incipient:plant.h1:10:2,ramp=50        ramp to +2 over 50 s, then hold
    drift:plant.h1:10::0.01                +0.01 per second from 10 s
    intermittent:plant.h1:10:60:1,period=4,duty=0.25
    parameter:plant.eta_dt:4000:4200:0.92,name=efficiency
"""
from __future__ import annotations

import math

from .errors import CoSimulationError
from .faults import Fault

_OPTIONS = {"ramp": float, "period": float, "duty": float, "name": str}


def parse_fault(spec: str) -> Fault:
    """Parse one fault SPEC (grammar in the module docstring) into a :class:`Fault`.

    Raises
    ------
    CoSimulationError
        With the SPEC and what is wrong in it.

    Examples
    --------
    >>> parse_fault("gain:plant.h1:10:20:0.8")
    Fault(kind='gain', target='plant.h1', onset=10.0, magnitude=0.8, end=20.0, name='gain_plant_h1', ramp=None, period=None, duty=0.5)
    """
    if not isinstance(spec, str):
        raise CoSimulationError(f"fault SPEC must be a string, got {spec!r}")
    head, *options = spec.strip().split(",")
    fields = head.split(":")
    if len(fields) not in (4, 5):
        raise CoSimulationError(f"fault SPEC {spec!r}: expected KIND:TARGET:ONSET[:END]:MAGNITUDE, "
                                f"got {len(fields)} ':'-separated fields")
    kind, target, onset = fields[0].strip(), fields[1].strip(), fields[2].strip()
    end = fields[3].strip() if len(fields) == 5 else ""
    magnitude = fields[-1].strip()
    kwargs = {}
    for option in options:
        key, sep, value = option.partition("=")
        key = key.strip()
        if not sep or key not in _OPTIONS:
            raise CoSimulationError(f"fault SPEC {spec!r}: option {option!r} is not one of "
                                    f"{', '.join(k + '=...' for k in _OPTIONS)}")
        kwargs[key] = _field(spec, key, value.strip(), _OPTIONS[key])
    return Fault(kind, target,
                 onset=_field(spec, "ONSET", onset, float),
                 end=None if end in ("", "inf") else _field(spec, "END", end, float),
                 magnitude=None if magnitude == "hold" else _field(spec, "MAGNITUDE", magnitude, float),
                 **kwargs)


def format_fault(fault: Fault) -> str:
    """The SPEC of ``fault``; ``parse_fault(format_fault(f)) == f``."""
    magnitude = "hold" if fault.magnitude is None else repr(fault.magnitude)
    end = "" if fault.end is None else repr(fault.end)
    text = f"{fault.kind}:{fault.target}:{fault.onset!r}:{end}:{magnitude}"
    if fault.kind == "incipient":
        text += f",ramp={fault.ramp!r}"
    if fault.kind == "intermittent":
        text += f",period={fault.period!r},duty={fault.duty!r}"
    return text + f",name={fault.name}"


def _field(spec, what, text, cast):
    try:
        value = cast(text)
    except ValueError:
        raise CoSimulationError(f"fault SPEC {spec!r}: {what} {text!r} is not a "
                                f"{'number' if cast is float else 'name'}") from None
    if cast is float and not math.isfinite(value):
        raise CoSimulationError(f"fault SPEC {spec!r}: {what} must be finite")
    return value
