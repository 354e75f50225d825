"""Fault scenarios: what a faulty signal or parameter looks like over time.

A :class:`Fault` turns the nominal value ``v(t)`` of its target into the faulty value
``v_f(t)``. It is active for ``onset <= t < end`` (``end`` None: to the end of the run); outside
that window ``v_f = v``. With ``m`` the magnitude and ``t0`` the onset, while active:

============  ===========================================  ====================================
kind          faulty value ``v_f(t)``                      magnitude ``m``
============  ===========================================  ====================================
abrupt        ``v + m``                                    offset (bias)
incipient     ``v + m · min(1, (t − t0) / ramp)``          offset reached after ``ramp`` seconds
intermittent  ``v + m`` while on, ``v`` while off; on for  offset while on
              the first ``duty · period`` of every
              ``period`` from ``t0``
stuck         ``v(t0)`` (frozen at onset) if ``m`` None,   frozen value, or None
              else ``m``
gain          ``m · v``                                    factor
drift         ``v + m · (t − t0)``                         rate (units per second)
parameter     ``m``                                        new value
============  ===========================================  ====================================

The master evaluates faults at communication points only, so ``t0`` and ``end`` take effect at
the first point at or after them, and the frozen value of a stuck fault is the nominal value at
that point. Comparisons allow a relative 1e-9 so that a grid point such as ``100 × 0.1``
counts as ``10``. The target (``"fmu.variable"``) and how the master applies the fault are
described in :class:`~fmu_fdi.cosim.master.CoSimulation`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..faults import identifier_of
from .errors import CoSimulationError

KINDS = ("abrupt", "incipient", "intermittent", "stuck", "gain", "drift", "parameter")
ALIASES = {"step": "abrupt", "bias": "abrupt", "ramp": "incipient", "stuck-at": "stuck",
           "frozen": "stuck", "set": "parameter"}
_EPS = 1e-9  # relative slack of time comparisons (see module docstring)


def _slack(t: float) -> float:
    return _EPS * max(1.0, abs(t))


@dataclass(frozen=True)
class Fault:
    """One fault scenario on one target variable.

    Parameters
    ----------
    kind : str
        One of ``abrupt``, ``incipient``, ``intermittent``, ``stuck``, ``gain``, ``drift``,
        ``parameter`` (aliases: ``step``/``bias``, ``ramp``, ``stuck-at``/``frozen``, ``set``).
    target : str
        ``"fmu.variable"``: an output (the master alters the value it passes on along every
        connection from it), an input (the value the FMU receives), or a parameter.
    onset : float
        Time the fault appears.
    magnitude : float or None
        See the table in the module docstring; None only for ``stuck`` (freeze at onset).
    end : float or None
        Time the fault disappears; None for a permanent fault.
    name : str or None
        Name of the recorded columns ``fault.<name>``; default ``<kind>_<fmu>_<variable>``.
    ramp : float or None
        ``incipient`` only: time to reach the magnitude; default ``end − onset``.
    period, duty : float
        ``intermittent`` only: pattern period (required) and on-fraction in (0, 1] (default 0.5).

    Examples
    --------
    >>> Fault("gain", "plant.h1", onset=10.0, magnitude=0.8, end=20.0).apply(15.0, 2.0)
    1.6
    """

    kind: str
    target: str
    onset: float
    magnitude: float | None = None
    end: float | None = None
    name: str | None = None
    ramp: float | None = None
    period: float | None = None
    duty: float = 0.5

    def __post_init__(self):
        kind = ALIASES.get(self.kind, self.kind)
        if kind not in KINDS:
            raise CoSimulationError(f"fault kind {self.kind!r} is unknown; use one of {', '.join(KINDS)}")
        object.__setattr__(self, "kind", kind)
        if not isinstance(self.target, str) or "." not in self.target:
            raise CoSimulationError(f"fault target {self.target!r} must read 'fmu.variable'")
        onset = _number(self.onset, "onset", self.target)
        object.__setattr__(self, "onset", onset)
        if self.end is not None:
            end = _number(self.end, "end", self.target)
            if not end > onset:
                raise CoSimulationError(f"fault on {self.target}: end {end:g} must be after onset {onset:g}")
            object.__setattr__(self, "end", end)
        if self.magnitude is None:
            if kind != "stuck":
                raise CoSimulationError(f"{kind} fault on {self.target} needs a magnitude")
        else:
            object.__setattr__(self, "magnitude", _number(self.magnitude, "magnitude", self.target))
        self._check_shape(kind)
        name = self.name if self.name is not None else f"{kind}_{identifier_of(self.target)}"  # plant.y[2]: plant_y_2
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise CoSimulationError(f"fault name {name!r} is not valid: use letters, digits and '_'")
        object.__setattr__(self, "name", name)

    def _check_shape(self, kind):
        if kind == "incipient":
            ramp = self.ramp if self.ramp is not None else (
                None if self.end is None else self.end - self.onset)
            if ramp is None or not _number(ramp, "ramp", self.target) > 0:
                raise CoSimulationError(f"incipient fault on {self.target} needs ramp > 0 "
                                        f"(or an end, giving ramp = end − onset)")
            object.__setattr__(self, "ramp", float(ramp))
        elif self.ramp is not None:
            raise CoSimulationError(f"{kind} fault on {self.target}: 'ramp' applies to incipient faults only")
        if kind == "intermittent":
            if self.period is None or not _number(self.period, "period", self.target) > 0:
                raise CoSimulationError(f"intermittent fault on {self.target} needs period > 0")
            if not 0 < _number(self.duty, "duty", self.target) <= 1:
                raise CoSimulationError(f"intermittent fault on {self.target}: duty {self.duty} "
                                        f"must lie in (0, 1]")
            object.__setattr__(self, "period", float(self.period))
            object.__setattr__(self, "duty", float(self.duty))
        elif self.period is not None:
            raise CoSimulationError(f"{kind} fault on {self.target}: 'period' applies to "
                                    f"intermittent faults only")

    # -- shorthands ------------------------------------------------------------------------------

    @classmethod
    def abrupt(cls, target, onset, magnitude, end=None, name=None):
        """Step (bias) ``v + magnitude`` from ``onset``."""
        return cls("abrupt", target, onset, magnitude, end, name)

    @classmethod
    def incipient(cls, target, onset, magnitude, ramp=None, end=None, name=None):
        """Ramp from 0 to ``magnitude`` over ``ramp`` seconds, then hold."""
        return cls("incipient", target, onset, magnitude, end, name, ramp=ramp)

    @classmethod
    def intermittent(cls, target, onset, magnitude, period, duty=0.5, end=None, name=None):
        """Offset ``magnitude`` during the first ``duty · period`` of every ``period``."""
        return cls("intermittent", target, onset, magnitude, end, name, period=period, duty=duty)

    @classmethod
    def stuck(cls, target, onset, value=None, end=None, name=None):
        """Frozen at its value at onset, or at ``value``."""
        return cls("stuck", target, onset, value, end, name)

    @classmethod
    def gain(cls, target, onset, factor, end=None, name=None):
        """Multiplied by ``factor``."""
        return cls("gain", target, onset, factor, end, name)

    @classmethod
    def drift(cls, target, onset, rate, end=None, name=None):
        """``v + rate · (t − onset)``."""
        return cls("drift", target, onset, rate, end, name)

    @classmethod
    def parameter(cls, target, onset, value, end=None, name=None):
        """Replaced by ``value`` (a parameter change such as a drop in efficiency)."""
        return cls("parameter", target, onset, value, end, name)

    # -- evaluation ------------------------------------------------------------------------------

    @property
    def fmu(self) -> str:
        """Instance name part of the target."""
        return self.target.split(".", 1)[0]

    @property
    def variable(self) -> str:
        """Variable name part of the target."""
        return self.target.split(".", 1)[1]

    def active(self, t: float) -> bool:
        """True while the fault acts at time ``t`` (the intermittent pattern included)."""
        if t < self.onset - _slack(self.onset):
            return False
        if self.end is not None and t >= self.end - _slack(self.end):
            return False
        if self.kind == "intermittent":
            cycles = (t - self.onset) / self.period
            phase = cycles - math.floor(cycles + _slack(cycles))
            return phase < self.duty - _slack(cycles)
        return True

    def apply(self, t: float, value: float, at_onset: float | None = None) -> float:
        """Faulty value at time ``t`` of a target whose nominal value is ``value``.

        ``at_onset`` is the nominal value when the fault appeared (used by ``stuck`` without a
        magnitude; defaults to ``value``).
        """
        if not self.active(t):
            return value
        faulty = _faulty_value(self)
        if faulty is None:  # stuck at the value at onset
            return value if at_onset is None else at_onset
        return faulty(t, value)

    def constant_from(self, t: float) -> bool:
        """True if the faulty value is the same function of ``v`` at every time from ``t`` on
        (so it can be applied once, e.g. to a fixed parameter before initialisation)."""
        return (self.kind in ("abrupt", "stuck", "gain", "parameter") and self.end is None
                and self.active(t))


class FaultChannel:
    """A :class:`Fault` during one run on the grid ``t_j = start + j·h``, ``j = 0 … N``.

    Evaluates the fault where :meth:`Fault.active` and :meth:`Fault.apply` say, at grid points
    only, with two things the run needs and the fault alone cannot know: the nominal value at
    the first active point (what ``stuck`` without a magnitude freezes; the first evaluation
    at an active point fixes it, and every evaluation at a point sees the same value there), and
    the grid indices where the fault is active. Outside the intermittent pattern the active
    points are one range ``on <= j < off`` (``t_j`` grows with ``j``), found once by bisection
    with :meth:`Fault.active` itself, so a step asks two integer comparisons; :meth:`values`
    evaluates the fault on many points at once (the recorded columns) with the same formulas.
    """

    def __init__(self, fault: Fault, start: float = 0.0, step: float = 1.0, n_steps: int = 0):
        self.fault = fault
        self.at_onset = None
        self.start, self.step = start, step
        f = fault
        self.on = _first(lambda j: f.onset - _slack(f.onset) <= start + j * step, n_steps)
        self.off = n_steps + 1 if f.end is None else _first(lambda j: start + j * step >= f.end - _slack(f.end),
                                                            n_steps)
        self.pattern = f.kind == "intermittent"
        self._faulty = _faulty_value(f)

    def active_at(self, j: int, t: float) -> bool:
        """:meth:`Fault.active` at grid point ``j`` (time ``t``)."""
        return self.on <= j < self.off and (not self.pattern or self.fault.active(t))

    def at(self, j: int, t: float, value: float) -> float:
        """Faulty value at grid point ``j`` (time ``t``) of nominal ``value``."""
        if j < self.on or j >= self.off or (self.pattern and not self.fault.active(t)):
            return value
        if self.at_onset is None:
            self.at_onset = value
        return self._faulty(t, value) if self._faulty is not None else self.at_onset

    def apply(self, t: float, value: float) -> float:
        """Faulty value at time ``t`` (any time: :meth:`Fault.active` decides)."""
        if self.at_onset is None and self.fault.active(t):
            self.at_onset = value
        return self.fault.apply(t, value, self.at_onset)

    def active_rows(self, rows: np.ndarray) -> np.ndarray:
        """:meth:`Fault.active` at the grid points ``rows`` (an integer array)."""
        act = (rows >= self.on) & (rows < self.off)
        if self.pattern:
            times = self.start + rows * self.step
            act &= np.fromiter((self.fault.active(float(t)) for t in times), bool, len(rows))
        return act

    def values(self, rows: np.ndarray, value: np.ndarray) -> np.ndarray:
        """Faulty values at the grid points ``rows`` of the nominal values ``value`` (arrays):
        :meth:`at` on each point in order, with :meth:`Fault.apply`'s formulas on arrays."""
        f, m = self.fault, self.fault.magnitude
        act = self.active_rows(rows)
        if not act.any():
            return value
        if self.at_onset is None:
            self.at_onset = float(value[np.argmax(act)])
        t = self.start + rows * self.step
        if f.kind in ("abrupt", "intermittent"):
            faulty = value + m
        elif f.kind == "incipient":
            faulty = value + m * np.minimum(1.0, np.maximum(0.0, t - f.onset) / f.ramp)
        elif f.kind == "stuck":
            faulty = np.full_like(value, self.at_onset if m is None else m)
        elif f.kind == "gain":
            faulty = m * value
        elif f.kind == "drift":
            faulty = value + m * np.maximum(0.0, t - f.onset)
        else:
            faulty = np.full_like(value, m)
        return np.where(act, faulty, value)


def _faulty_value(f: Fault):
    """``(t, v) -> faulty value`` of an active fault, :meth:`Fault.apply`'s formula without its
    activity test; None for ``stuck`` without a magnitude (the value at onset)."""
    m = f.magnitude
    if f.kind in ("abrupt", "intermittent"):
        return lambda t, v: v + m
    if f.kind == "incipient":
        onset, ramp = f.onset, f.ramp
        return lambda t, v: v + m * min(1.0, max(0.0, t - onset) / ramp)
    if f.kind == "stuck":
        return None if m is None else (lambda t, v: m)
    if f.kind == "gain":
        return lambda t, v: m * v
    if f.kind == "drift":
        onset = f.onset
        return lambda t, v: v + m * max(0.0, t - onset)
    return lambda t, v: m  # parameter


def _first(pred, n: int) -> int:
    """The least ``j`` in ``0 … n`` with ``pred(j)`` for a predicate false then true; ``n + 1`` if none."""
    lo, hi = 0, n + 1
    while lo < hi:
        mid = (lo + hi) // 2
        if pred(mid):
            hi = mid
        else:
            lo = mid + 1
    return lo


def _number(x, what: str, target: str) -> float:
    try:
        value = float(x)
    except (TypeError, ValueError):
        raise CoSimulationError(f"fault on {target}: {what} {x!r} is not a number") from None
    if not math.isfinite(value):
        raise CoSimulationError(f"fault on {target}: {what} must be finite, got {x!r}")
    return value
