"""Detection and isolation performance of a diagnoser run (DAMADICS indices).

The figures follow the DAMADICS actuator benchmark (Bartys et al. 2006, section 5):
a run is scored over a *benchmark zone* ``[t_from, t_hor)`` in which the fault is
switched on at ``t_on`` (and, here, optionally off again at ``t_off``). The zone splits
into the *faulty part* ``F = [t_on, min(t_off, t_hor))`` and the *fault-free part*
``H = [t_from, t_hor) \\ F``. With ``a(t)`` the alarm (``fault_detected``) and ``i(t)``
the isolation output (``isolated_fault``: 0 none, ``j`` = 1-based fault, −1 unknown or
several), and ``j*`` the fault actually injected:

==========  ======================================================================
figure      definition
==========  ======================================================================
t_dt        ``inf{t ∈ F : a(t) = 1} − t_on``: detection time (∞ when missed)
r_fd        ``|{t ∈ H : a(t) = 1}| / |H|``: false detection rate
r_td        ``|{t ∈ F : a(t) = 1}| / |F|``: true detection rate
t_it        ``inf{t ∈ F : i(t) = j*} − t_on``: isolation time (∞ when never)
r_fi        ``|{t ∈ H : i(t) ≥ 1}| / |H|``: false isolation rate (a fault named while
            none is present)
r_ti        ``|{t ∈ F : i(t) = j*}| / |F|``: true isolation rate
r_mi        ``|{t ∈ F : i(t) ≥ 1, i(t) ≠ j*}| / |F|``: mis-isolation rate (another
            fault named)
r_ui        ``|{t ∈ F : i(t) = −1}| / |F|``: share of F alarmed but not isolated
missed      no alarm anywhere in F
mtbfa       ``|H| / n_fa``, ``n_fa`` the number of rising edges of ``a`` in H
            (∞ when ``n_fa = 0``): mean time between false alarms
==========  ======================================================================

``|·|`` is duration. Bartys et al. define their isolation signals per fault; with a
single integer output, ``r_ti + r_mi + r_ui`` plus the unalarmed share of F is 1, and
an alarm whose isolation is −1 counts as a detection, not as a (false) isolation.

Time convention: sample k (time ``t_k``) holds over ``[t_k, t_{k+1})`` — the diagnoser's
outputs are held between communication points — and the last sample holds for the last
step. Every duration above is an exact integral of these step signals, so non-uniform
time grids are scored correctly and, on a uniform grid, rates are sample fractions.

References
----------
M. Bartys, R. Patton, M. Syfert, S. de las Heras, J. Quevedo, "Introduction to the
DAMADICS actuator FDI benchmark study", Control Engineering Practice 14 (2006) 577-596.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

_NAN = float("nan")
_INF = float("inf")


@dataclass(frozen=True)
class DiagnosisMetrics:
    """Detection and isolation figures of one run (see :mod:`fmu_fdi.metrics`).

    Times are in the unit of the record's ``time`` field. NaN means "not applicable"
    (no faulty part in the zone, no fault index given, an empty fault-free part); ∞ means
    "did not happen" (missed detection, never isolated, no false alarm).
    """

    t_from: float
    t_hor: float
    t_on: float
    t_off: float
    fault: int | None
    fault_free_time: float
    faulty_time: float
    t_dt: float
    r_fd: float
    r_td: float
    missed_detection: bool | None
    alarm_at_onset: bool | None
    t_it: float
    r_fi: float
    r_ti: float
    r_mi: float
    r_ui: float
    false_alarms: int
    mtbfa: float

    COLUMNS = ("t_dt", "r_fd", "r_td", "t_it", "r_fi", "r_ti", "r_mi", "mtbfa")

    def to_dict(self) -> dict:
        """Plain dict of every figure (JSON-ready except NaN/∞, which stay floats)."""
        return dataclasses.asdict(self)

    @classmethod
    def table_header(cls, label: str = "run", width: int = 12) -> str:
        """Header matching :meth:`table_row`."""
        return f"{label:<{width}}" + "".join(f"{c:>10}" for c in cls.COLUMNS)

    def table_row(self, label: str = "", width: int = 12) -> str:
        """One fixed-width table row: label then :attr:`COLUMNS` (``-`` NaN, ``inf`` ∞)."""

        def fmt(name: str, v: float) -> str:
            if math.isnan(v):
                return f"{'-':>10}"
            if math.isinf(v):
                return f"{'inf':>10}"
            return f"{v:>10.3f}" if name.startswith("r_") else f"{v:>10.4g}"

        return f"{label:<{width}}" + "".join(fmt(c, getattr(self, c)) for c in self.COLUMNS)


# ---------------------------------------------------------------------- helpers
def _fields(result) -> list[str]:
    names = getattr(getattr(result, "dtype", None), "names", None)
    if names is not None:
        return list(names)
    if hasattr(result, "keys"):
        return list(result.keys())
    raise TypeError(f"result must be a numpy structured array or a mapping of arrays, got {type(result).__name__}")


def _column(result, name: str, n: int, fields: list[str]) -> np.ndarray:
    if name not in fields:
        raise KeyError(f"result has no field {name!r}; fields are {fields}")
    col = np.asarray(result[name], dtype=float).ravel()
    if col.size != n:
        raise ValueError(f"field {name!r} has {col.size} samples but 'time' has {n}")
    if not np.all(np.isfinite(col)):
        raise ValueError(f"field {name!r} contains NaN or Inf at sample {int(np.flatnonzero(~np.isfinite(col))[0])}")
    return col


class _Grid:
    """Sample intervals ``[t_k, e_k)`` of a held signal, and exact integrals over them."""

    def __init__(self, t: np.ndarray, t_end: float):
        self.t = t
        self.e = np.append(t[1:], t_end)

    def overlap(self, lo: float, hi: float) -> np.ndarray:
        return np.clip(np.minimum(self.e, hi) - np.maximum(self.t, lo), 0.0, None)

    def measure(self, mask: np.ndarray, parts) -> float:
        return float(sum(np.sum(self.overlap(lo, hi)[mask]) for lo, hi in parts))

    def first(self, mask: np.ndarray, lo: float, hi: float) -> float:
        """First instant in ``[lo, hi)`` where the held signal ``mask`` is true (∞ if none)."""
        k = np.flatnonzero(mask & (self.overlap(lo, hi) > 0))
        return max(float(self.t[k[0]]), lo) if k.size else _INF


def _resolve(fields: list[str], name: str, what: str) -> str:
    """A field by exact name, else the one field ``<instance>.<name>`` (a co-simulation column)."""
    if name in fields:
        return name
    hits = [f for f in fields if f.endswith("." + name)]
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise ValueError(f"several {what} fields {hits}: choose one by its full name")
    raise KeyError(f"result has no field {name!r} (nor one ending in '.{name}'); fields are {fields}")


def _schedule_from_indicator(result, fields, n, indicator):
    """(t_on, t_off) from a fault indicator column; (None, inf) when it never switches on."""
    if indicator is not None:
        # a column, or a fault name of a co-simulation result: fault.<name>.active, fault.<name>
        named = [c for c in (indicator, f"fault.{indicator}.active", f"fault.{indicator}") if c in fields]
        if not named:
            raise KeyError(f"no indicator column {indicator!r} (nor fault.{indicator}.active, fault.{indicator}); "
                           f"fields are {fields}")
        indicator = named[0]
    else:
        # the co-simulation's activity flags when present: a fault's value column can be zero while it acts
        cands = [f for f in fields if f.startswith("fault.") and f.endswith(".active")]
        cands = cands or [f for f in fields if f.startswith("fault.")]
        if not cands:
            return None, _INF
        active = [f for f in cands if np.any(_column(result, f, n, fields) != 0)]
        if len(active) > 1:
            raise ValueError(f"several fault indicator columns switch on ({active}); choose one with indicator=")
        indicator = active[0] if active else cands[0]
    x = _column(result, indicator, n, fields) != 0
    t = np.asarray(result["time"], float).ravel()
    if not x.any():
        return None, _INF
    edges = np.flatnonzero(np.diff(x.astype(int)))
    ons = [k + 1 for k in edges if x[k + 1]] + ([0] if x[0] else [])
    if len(ons) > 1:
        raise ValueError(f"fault indicator {indicator!r} switches on {len(ons)} times; score each episode "
                         "with its own zone and explicit t_on/t_off")
    k_on = int(np.argmax(x))
    k_offs = np.flatnonzero(~x[k_on:])
    t_off = float(t[k_on + k_offs[0]]) if k_offs.size else _INF
    return float(t[k_on]), t_off


# --------------------------------------------------------------------- public
def _record(result, alarm, isolation, fault):
    """Stage of :func:`metrics`: the time column checked, the alarm flags and the isolation
    indices read; returns ``(fields, t, n, alarm flags, isolation indices)``."""
    fields = _fields(result)
    if "time" not in fields:
        raise KeyError(f"result has no 'time' field; fields are {fields}")
    t = np.asarray(result["time"], dtype=float).ravel()
    n = t.size
    if n == 0:
        raise ValueError("result has no samples")
    if not np.all(np.isfinite(t)):
        raise ValueError("time contains NaN or Inf")
    if n > 1 and not np.all(np.diff(t) > 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"time must be strictly increasing; t[{k + 1}] = {t[k + 1]} follows t[{k}] = {t[k]}")
    alarm, isolation = _resolve(fields, alarm, "alarm"), _resolve(fields, isolation, "isolation")
    a = _column(result, alarm, n, fields) != 0
    iso_raw = _column(result, isolation, n, fields)
    iso = np.rint(iso_raw).astype(int)
    if np.any(iso != iso_raw) or np.any(iso < -1):
        raise ValueError(f"field {isolation!r} must hold integers >= -1 (0 none, j fault, -1 unknown)")
    if fault is not None and (isinstance(fault, bool) or not isinstance(fault, (int, np.integer)) or fault < 1):
        raise ValueError(f"fault must be a 1-based fault index (int >= 1), got {fault!r}")
    return fields, t, n, a, iso


def _zone(t, zone):
    """Stage of :func:`metrics`: the evaluation zone ``[t_from, t_hor)`` inside the record
    ``[t0, t_end)``; returns ``(t_from, t_hor, t_end)``."""
    # zone -------------------------------------------------------------------
    n = t.size
    if n > 1:
        t_end = float(t[-1] + (t[-1] - t[-2]))
    elif zone is not None:
        t_end = float(zone[1])
    else:
        raise ValueError("a one-sample record has no duration: give zone=(t_from, t_hor)")
    if zone is not None and np.shape(zone) != (2,):
        raise ValueError(f"zone must be a pair (t_from, t_hor), got {zone!r}")
    t_from, t_hor = (float(t[0]), t_end) if zone is None else (float(zone[0]), float(zone[1]))
    slack = 1e-9 * max(abs(t_end), abs(float(t[0])), t_end - float(t[0]), 1e-300)
    if not (math.isfinite(t_from) and math.isfinite(t_hor) and t_from < t_hor):
        raise ValueError(f"zone must be finite with t_from < t_hor, got ({t_from}, {t_hor})")
    if t_from < t[0] - slack or t_hor > t_end + slack:
        raise ValueError(f"zone [{t_from}, {t_hor}) is not inside the record [{t[0]}, {t_end})")
    t_hor = min(t_hor, t_end)
    return t_from, t_hor, t_end


def _fault_windows(result, fields, n, indicator, t_on, t_off, t_from, t_hor):
    """Stage of :func:`metrics`: the fault's schedule (given, or read from the indicator) and the
    zone split into its faulty and healthy windows; returns ``(t_on, t_off, faulty, healthy)``."""
    # fault schedule ---------------------------------------------------------
    if t_on is None:
        if t_off is not None:
            raise ValueError("t_off given without t_on")
        t_on_v, t_off_v = _schedule_from_indicator(result, fields, n, indicator)
    else:
        t_on_v, t_off_v = float(t_on), _INF if t_off is None else float(t_off)
        if not math.isfinite(t_on_v):
            raise ValueError(f"t_on must be finite, got {t_on}")
        if not t_off_v > t_on_v:
            raise ValueError(f"t_off = {t_off_v} must come after t_on = {t_on_v}")
    if t_on_v is not None and t_on_v < t_from and t_off_v > t_from:
        raise ValueError(f"the fault is on at the zone start (t_on = {t_on_v} < t_from = {t_from}): detection "
                         "time is undefined; start the zone at or before t_on")
    if t_on_v is None or t_on_v >= t_hor or t_off_v <= t_from:
        faulty: list[tuple[float, float]] = []
    else:
        faulty = [(t_on_v, min(t_off_v, t_hor))]
    if faulty:
        healthy = [(lo, hi) for lo, hi in ((t_from, t_on_v), (faulty[0][1], t_hor)) if hi > lo]
    else:
        healthy = [(t_from, t_hor)]
    return t_on_v, t_off_v, faulty, healthy


def metrics(result, *, t_on: float | None = None, t_off: float | None = None, fault: int | None = None,
            zone: tuple[float, float] | None = None, indicator: str | None = None,
            alarm: str = "fault_detected", isolation: str = "isolated_fault") -> DiagnosisMetrics:
    """DAMADICS detection and isolation figures of one diagnoser run.

    Parameters
    ----------
    result : numpy structured array or mapping of 1-D arrays
        The run: a ``time`` field (strictly increasing, any spacing) and the diagnoser
        outputs named by ``alarm`` and ``isolation`` — as :meth:`Diagnoser.run` returns
        them, or as a co-simulation :class:`~fmu_fdi.cosim.Result` records them
        (``<instance>.fault_detected``: a unique field with that suffix is found).
    t_on, t_off : float, optional
        When the fault is switched on and (optionally) off again. Without ``t_on`` the
        schedule is read from a fault indicator column (see ``indicator``); without
        either, or with ``t_on ≥ t_hor``, the zone is fault-free and only the false-alarm
        figures are defined.
    fault : int, optional
        1-based index of the injected fault in the model's fault list, as
        ``isolated_fault`` reports it. Without it the isolation figures that need the
        true fault (``t_it``, ``r_ti``, ``r_mi``) are NaN.
    zone : (t_from, t_hor), optional
        Benchmark zone; default the whole record ``[t_0, t_end)``, where the last sample
        holds for one more (last) step. Must lie inside the record and, when a fault is
        scheduled inside it, start no later than ``t_on``.
    indicator : str, optional
        Column that is nonzero while the fault is present, or the name of a
        co-simulation fault (``"leak"`` reads ``fault.leak.active``, else
        ``fault.leak``). Default: the one ``fault.*.active`` column (else ``fault.*``
        column) that switches on, if any. It must switch on at most once. Ignored
        when ``t_on`` is given.
    alarm, isolation : str
        Fields holding the alarm (nonzero = alarm) and the isolation output; pass
        e.g. ``alarm="alarm_2"`` to score one residual group.

    Returns
    -------
    DiagnosisMetrics
        All figures; definitions in the module docstring. ``alarm_at_onset`` tells
        when an alarm raised before ``t_on`` was still up at ``t_on`` (then ``t_dt = 0``
        although the fault did not cause it; ``r_fd`` shows the false part).

    Notes
    -----
    A detection or isolation is *true* only inside the faulty part ``F``: an alarm after
    ``t_off`` is a false alarm, and ``t_dt`` / ``t_it`` look in ``F`` only. False-alarm
    onsets counted for ``mtbfa`` are the rising edges of the alarm inside the fault-free
    part, plus an alarm already up at ``t_from`` when the zone starts fault-free; an
    alarm that was raised in ``F`` and is still up after ``t_off`` adds to ``r_fd`` but
    is not a new onset.

    References
    ----------
    Bartys et al. (2006), Control Engineering Practice 14, 577-596, section 5.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(10.0)
    >>> run = {"time": t, "fault_detected": t >= 6, "isolated_fault": np.where(t >= 7, 2, 0)}
    >>> m = metrics(run, t_on=4.0, fault=2)
    >>> m.t_dt, m.r_td, m.t_it, m.r_ti
    (2.0, 0.6666666666666666, 3.0, 0.5)
    """
    fields, t, n, a, iso = _record(result, alarm, isolation, fault)
    t_from, t_hor, t_end = _zone(t, zone)
    t_on_v, t_off_v, faulty, healthy = _fault_windows(result, fields, n, indicator, t_on, t_off, t_from, t_hor)

    g = _Grid(t, t_end)
    H = sum(hi - lo for lo, hi in healthy)
    F = sum(hi - lo for lo, hi in faulty)

    def rate(mask, parts, size):
        return g.measure(mask, parts) / size if size > 0 else _NAN

    # detection --------------------------------------------------------------
    r_fd = rate(a, healthy, H)
    r_td = rate(a, faulty, F)
    if faulty:
        lo, hi = faulty[0]
        t_dt = g.first(a, lo, hi) - t_on_v
        missed = bool(math.isinf(t_dt))
        # the sample holding at t_on was raised before t_on (it started earlier, or its
        # predecessor was already up)
        k = int(np.searchsorted(t, t_on_v, side="right")) - 1
        at_onset = bool(t_on_v > t_from and a[k] and (t[k] < t_on_v or (k > 0 and a[k - 1])))
    else:
        t_dt, missed, at_onset = _NAN, None, None

    # false-alarm onsets: rising edges (a sample up whose predecessor in the zone was down)
    inzone = g.overlap(t_from, t_hor) > 0
    prev_up = np.concatenate([[False], a[:-1]]) & np.concatenate([[False], inzone[:-1]])
    onset_times = np.maximum(t[a & ~prev_up & inzone], t_from)
    n_fa = int(sum(any(lo <= s < hi for lo, hi in healthy) for s in onset_times))
    mtbfa = (H / n_fa if n_fa else _INF) if H > 0 else _NAN

    # isolation --------------------------------------------------------------
    named = iso >= 1
    r_fi = rate(named, healthy, H)
    r_ui = rate(iso == -1, faulty, F)
    if faulty and fault is not None:
        correct = iso == int(fault)
        t_it = g.first(correct, *faulty[0]) - t_on_v
        r_ti = rate(correct, faulty, F)
        r_mi = rate(named & ~correct, faulty, F)
    else:
        t_it = r_ti = r_mi = _NAN

    return DiagnosisMetrics(
        t_from=t_from, t_hor=t_hor, t_on=_NAN if t_on_v is None else t_on_v, t_off=t_off_v,
        fault=None if fault is None else int(fault), fault_free_time=float(H), faulty_time=float(F),
        t_dt=float(t_dt), r_fd=r_fd, r_td=r_td, missed_detection=missed, alarm_at_onset=at_onset,
        t_it=float(t_it), r_fi=r_fi, r_ti=r_ti, r_mi=r_mi, r_ui=r_ui, false_alarms=n_fa, mtbfa=mtbfa)
