"""Excitation experiments on a co-simulation plant FMU, run through fmu_fdi.cosim.

The plant first *settles* for ``settle`` seconds with every input at its operating value,
then the excitation runs for ``samples`` communication steps of ``step`` seconds; inputs are
held over each step (zero-order hold), so the record (u_k, y_k) is what a sampled model
``x(k+1) = A x(k) + B u(k)`` expects.

Signals (per excited input, amplitude a, deviation from the operating value):

- ``"multisine"``: a sum of sines on the DFT grid f_k = k / (samples·step) of the record
  (periodic, no leakage), lines log-spaced from the lowest grid frequency up to
  ``band``·Nyquist, assigned to the inputs in turn (no two inputs share a line, so they are
  uncorrelated), random phases (seed); scaled to peak a.
- ``"prbs"``: a maximum-length binary sequence ±a (scipy.signal.max_len_seq) held for
  ``period`` steps, each input starting at a different seeded offset of the sequence. With
  ``slow_period`` (a stiff plant, :mod:`fmu_fdi.identify.design`) the signal is the sum
  (a/2)(s_fast + s_slow) of two such sequences, clocks ``period`` and ``slow_period``, peak a:
  the slow one puts power below the slow modes' corners, where a single fast PRBS, flat
  over 0 … 0.44/(period·step) Hz, has too little of it.

Checks that make a bad experiment an error rather than a wrong model: excitation beyond an
input's declared min/max; a recorded output beyond its declared min/max; a Boolean output
(limit or mode flag, e.g. a tank's ``overflow``) switching during the experiment; the FMU
failing a step; outputs still drifting at the end of settling.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import IdentificationError

SIGNALS = ("multisine", "prbs")


@dataclass
class Excitation:
    """How the plant is excited (configuration only; see the module docstring).

    A field left at None is chosen by the automatic experiment design
    (:mod:`fmu_fdi.identify.design`) when the model is made with ``fmu_fdi.model_from_fmu``; a bare
    :func:`run_experiment` uses the fixed fallbacks :data:`FALLBACK` instead.

    Parameters
    ----------
    signal : {'multisine', 'prbs'}, optional
    amplitude : float or dict of str to float, optional
        Peak deviation per excited input in its unit (a float: the same for all). Fallback
        5 % of the operating value; an input at 0 needs an explicit amplitude.
    samples : int, optional
        Number of recorded steps.
    settle : float, optional
        Seconds at the operating point before recording (fallback 200 steps).
    band : float
        Highest multisine frequency as a fraction of the Nyquist frequency.
    period : int, optional
        PRBS clock period in steps.
    seed : int
    slow_period : int, optional
        PRBS: clock of a second, slow sequence added at half the amplitude (module docstring);
        None: a single sequence.
    """

    signal: str | None = None
    amplitude: float | dict | None = None
    samples: int | None = None
    settle: float | None = None
    band: float = 0.5
    period: int | None = None
    seed: int = 0
    slow_period: int | None = None

    def check(self):
        if self.signal is not None and self.signal not in SIGNALS:
            raise IdentificationError(f"excitation signal {self.signal!r} is not one of {SIGNALS}")
        if self.samples is not None and (int(self.samples) != self.samples or self.samples < 10):
            raise IdentificationError(f"samples must be an integer >= 10, got {self.samples!r}")
        if not 0 < self.band <= 1:
            raise IdentificationError(f"band must be in (0, 1] (fraction of Nyquist), got {self.band!r}")
        if self.period is not None and (int(self.period) != self.period or self.period < 1):
            raise IdentificationError(f"PRBS period must be a positive integer, got {self.period!r}")
        if self.slow_period is not None and (int(self.slow_period) != self.slow_period or self.slow_period < 1):
            raise IdentificationError(f"slow PRBS period must be a positive integer, got {self.slow_period!r}")
        if self.settle is not None and not (np.isfinite(self.settle) and self.settle >= 0):
            raise IdentificationError(f"settle must be a non-negative number of seconds, got {self.settle!r}")

    def resolved(self) -> "Excitation":
        """A copy with the fixed fallbacks (:data:`FALLBACK`) in place of the fields left at None."""
        return Excitation(**{k: (FALLBACK[k] if v is None and k in FALLBACK else v) for k, v in self.__dict__.items()})


#: what a bare run_experiment uses for fields left at None (no automatic design)
FALLBACK = {"signal": "multisine", "samples": 2000, "period": 1}


def excitation_signals(exc: Excitation, names, amplitudes) -> np.ndarray:
    """``samples × len(names)`` deviations (module docstring)."""
    exc = exc.resolved()
    N, m = int(exc.samples), len(names)
    rng = np.random.default_rng(exc.seed)
    out = np.zeros((N, m))
    if exc.signal == "multisine":
        k_hi = max(int(exc.band * N / 2), m)
        lines = np.unique(np.round(np.geomspace(1, k_hi, num=min(k_hi, 40 * m))).astype(int))
        if lines.size < m:
            raise IdentificationError(f"{N} samples leave too few multisine lines for {m} inputs: record more")
        k = np.arange(N)
        for j in range(m):
            mine = lines[j::m]
            phases = rng.uniform(0, 2 * np.pi, mine.size)
            sig = np.cos(2 * np.pi * np.outer(k, mine) / N + phases).sum(axis=1)
            out[:, j] = sig / np.max(np.abs(sig))
    else:
        out = _prbs(N, m, exc.period, rng)
        if exc.slow_period is not None:
            out = 0.5 * (out + _prbs(N, m, exc.slow_period, rng))
    return out * np.asarray(amplitudes, float)


def _prbs(N, m, period, rng) -> np.ndarray:
    """``N × m`` maximum-length sequences ±1 held ``period`` steps, each at a seeded offset."""
    from scipy.signal import max_len_seq

    nbits = max(int(np.ceil(np.log2(N / period + 1))), 3)
    seq = max_len_seq(nbits)[0].astype(float) * 2 - 1
    out = np.empty((N, m))
    for j in range(m):
        shift = int(rng.integers(seq.size))
        out[:, j] = np.resize(np.repeat(np.roll(seq, shift), period), N)
    return out


@dataclass
class Record:
    """A recorded experiment: absolute samples and the operating point they vary around."""

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    u0: np.ndarray
    y0: np.ndarray
    u_names: list
    y_names: list
    excited: dict = field(default_factory=dict)
    #: outputs over the settle phase (operating point, no excitation): the noise level is read there
    settle_y: np.ndarray | None = field(default=None, repr=False)
    #: wall-clock seconds of the run and the number of communication steps it took
    seconds: float = 0.0
    steps: int = 0
    #: the applied excitation (deviations of the excited inputs, columns in the order of ``excited``):
    #: the instruments of a plant in its own loop (:mod:`fmu_fdi.identify.closed_loop`)
    r: np.ndarray | None = field(default=None, repr=False)


def run_experiment(path, inputs, outputs, *, excite=None, at=None, parameters=None, step: float,
                   excitation: Excitation | None = None, noise_std=None, check_settle: bool = True) -> Record:
    """Settle, excite and record a co-simulation plant FMU.

    Parameters
    ----------
    path : str or Path
        Plant FMU (FMI 2 or 3 co-simulation).
    inputs : list of str
        Signals recorded as model inputs (u then d): FMU inputs, or FMU outputs for a plant
        with its own controller (then excite its references).
    outputs : list of str
        FMU outputs recorded as y.
    excite : list of str, optional
        FMU inputs to excite (default: those of ``inputs`` that are FMU inputs).
    at : dict, optional
        Operating values of FMU inputs (default: their start values).
    parameters : dict, optional
        Parameter values (e.g. ``{"noise_enable": False}``).
    step : float
        Communication step = sample time of the record.
    excitation : Excitation
    noise_std : array_like, optional
        The outputs' noise std at the operating point, measured beforehand (pre-test): a drift
        within 3 of them at the end of settling is noise wandering (coloured noise), not drift.
    check_settle : bool
        Check that the outputs settled (off for a pre-test that measures the noise).

    Raises
    ------
    IdentificationError
        See the module docstring's checks.
    """
    from ..cosim import CoSimulation, InputSignals
    from ..cosim.errors import CoSimulationError, SimulationFailed
    from ..cosim.instance import FMUInstance

    exc = excitation or Excitation()
    exc.check()
    exc = exc.resolved()
    try:
        fmu = FMUInstance("plant", path)
    except (CoSimulationError, FileNotFoundError) as err:
        raise IdentificationError(str(err)) from None
    fmu_inputs, excite = _checked_signals(path, fmu, inputs, outputs, excite)
    at = dict(at or {})
    params = dict(parameters or {})
    # inputs that are not continuous Reals (Integer, Boolean, discrete) change only at events: held at
    # their values from ``at``, set before initialisation like a parameter (FMI 3.0 sec. 4.2.4)
    for nm in [k for k in at if k not in fmu_inputs and k in fmu.variables
               and fmu.variable(k).causality == "input"]:
        params[nm] = at.pop(nm)
    v0 = {}
    for nm in fmu_inputs:
        start = fmu.start_value(nm)
        v0[nm] = float(at[nm]) if nm in at else float(start if start is not None else 0.0)
    amps = _amplitudes(path, fmu, exc, excite, v0)
    settle = float(exc.settle) if exc.settle is not None else 200 * step
    n_settle = int(round(settle / step))
    N = int(exc.samples)
    dev = excitation_signals(exc, excite, amps)
    t = np.arange(n_settle + N + 1) * step
    values = {nm: np.full(t.size, v0[nm]) for nm in fmu_inputs if nm in at or nm in excite}
    for j, nm in enumerate(excite):
        values[nm][n_settle:n_settle + N] += dev[:, j]
    bool_outs = [n for n in fmu.names("output") if fmu.kind(n) == "boolean"]
    import time

    clock = time.perf_counter()
    try:
        sim = CoSimulation({"plant": path}, None, InputSignals(t, values), step=step, stop=float(t[-1]),
                           parameters={f"plant.{k}": v for k, v in params.items()})
        res = sim.run()
        clock = time.perf_counter() - clock
    except SimulationFailed as err:
        raise IdentificationError(f"{path}: the plant FMU failed during the experiment ({err}); lower the "
                                  f"amplitude or check the operating point") from None
    except CoSimulationError as err:
        raise IdentificationError(f"{path}: {err}") from None
    for nm in bool_outs:
        col = np.asarray(res[f"plant.{nm}"]).astype(bool)
        if np.any(col != col[0]):
            k = int(np.flatnonzero(col != col[0])[0])
            raise IdentificationError(
                f"{path}: the experiment drove the plant out of its limits: Boolean output {nm!r} switched to "
                f"{bool(col[k])} at t = {t[k]:g} s (excitation {dict(zip(excite, amps))}); lower the amplitude "
                f"or move the operating point")
    def col(nm):
        return np.asarray(res[f"plant.{nm}"], float)
    for nm in [*outputs, *(n for n in inputs if n not in fmu_inputs)]:  # every signal the model reads
        bad = ~np.isfinite(col(nm))
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            raise IdentificationError(f"{path}: the plant's output {nm!r} is {col(nm)[k]} at t = {t[k]:g} s "
                                      f"(excitation {dict(zip(excite, amps))}): the plant FMU computes no number "
                                      f"there; check the operating point and the amplitude")
    # sample k of the record: inputs held over [t_k, t_k+1), outputs at t_k
    rows = slice(n_settle, n_settle + N)
    u = np.column_stack([values[nm][rows] if nm in fmu_inputs and nm in values else
                         (np.full(N, v0[nm]) if nm in fmu_inputs else col(nm)[rows]) for nm in inputs]) \
        if inputs else np.zeros((N, 0))
    y = np.column_stack([col(nm)[rows] for nm in outputs])
    for j, nm in enumerate(outputs):
        var = fmu.variable(nm)
        lo, hi = _limit(var.min), _limit(var.max)
        if (lo is not None and y[:, j].min() < lo) or (hi is not None and y[:, j].max() > hi):
            raise IdentificationError(f"{path}: output {nm!r} left its declared range [{lo}, {hi}] during the "
                                      f"experiment ({y[:, j].min():g} .. {y[:, j].max():g}): lower the amplitude")
    u0 = np.array([v0[nm] if nm in fmu_inputs else col(nm)[n_settle] for nm in inputs])
    tail = slice(max(n_settle - max(n_settle // 4, 1), 0) + 1, n_settle + 1)
    y0 = np.array([col(nm)[tail].mean() for nm in outputs])  # settled value, noise averaged
    if check_settle:
        _check_settled(path, res, outputs, n_settle, y, settle, noise_std)
    settle_y = np.column_stack([col(nm)[1:n_settle + 1] for nm in outputs])
    return Record(t[rows] - t[n_settle], u, y, u0, y0, list(inputs), list(outputs), dict(zip(excite, amps)),
                  settle_y, clock, int(t.size - 1), dev)


def _checked_signals(path, fmu, inputs, outputs, excite):
    """Stage of :func:`run_experiment`: the model inputs and outputs found among the FMU's Real
    variables, and the FMU inputs to excite (default: the model inputs that are FMU inputs).
    Returns ``(the FMU's Real inputs, excited inputs)``."""
    fmu_inputs = [n for n in fmu.names("input") if fmu.kind(n) == "real"]
    fmu_outputs = [n for n in fmu.names("output") if fmu.kind(n) == "real"]
    for nm in inputs:
        if nm not in fmu_inputs and nm not in fmu_outputs:
            raise IdentificationError(f"{path}: model input {nm!r} is neither a Real input nor a Real output of "
                                      f"the FMU; inputs {fmu_inputs}, outputs {fmu_outputs}")
    for nm in outputs:
        if nm not in fmu_outputs:
            raise IdentificationError(f"{path}: output {nm!r} is not a Real output of the FMU; it has {fmu_outputs}")
    if excite is None:
        excite = [n for n in inputs if n in fmu_inputs]
        closed = [n for n in inputs if n not in fmu_inputs]
        if closed:
            raise IdentificationError(f"{path}: model inputs {closed} are FMU outputs (the plant closes its own "
                                      f"loop): name the FMU inputs to excite (e.g. its references) with excite=")
    for nm in excite:
        if nm not in fmu_inputs:
            raise IdentificationError(f"{path}: cannot excite {nm!r}: not a Real input of the FMU; it has {fmu_inputs}")
    if not excite:
        raise IdentificationError(f"{path}: nothing to excite: give the FMU inputs to excite")
    return fmu_inputs, excite


def _amplitudes(path, fmu, exc, excite, v0):
    """Stage of :func:`run_experiment`: each excited input's amplitude (given, or 5 % of its
    operating value), positive and inside the input's declared range."""
    amps = []
    for nm in excite:
        a = exc.amplitude.get(nm) if isinstance(exc.amplitude, dict) else exc.amplitude
        if a is None:
            if v0[nm] == 0.0:
                raise IdentificationError(f"{path}: input {nm!r} operates at 0, so 5 % of it excites nothing: give "
                                          f"its amplitude (amplitude={{'{nm}': ...}} / --amplitude {nm}=A)")
            a = 0.05 * abs(v0[nm])
        a = float(a)
        if not np.isfinite(a) or a <= 0:
            raise IdentificationError(f"amplitude of {nm!r} must be a positive number, got {a!r}")
        var = fmu.variable(nm)
        lo, hi = _limit(var.min), _limit(var.max)
        if (lo is not None and v0[nm] - a < lo) or (hi is not None and v0[nm] + a > hi):
            raise IdentificationError(f"{path}: excitation of {nm!r} spans [{v0[nm] - a:g}, {v0[nm] + a:g}], outside "
                                      f"its declared range [{lo}, {hi}]: lower the amplitude")
        amps.append(a)
    return amps


def _check_settled(path, res, outputs, n_settle, y, settle, noise_std=None):
    """The outputs' drift over the last quarter of settling (least-squares slope times its
    duration) is below 5 % of their spread during the excitation, or within the two-sided
    0.1 % Student-t bound of what white measurement noise alone gives the fitted drift, or within twice the
    spread about the fitted line (coloured noise, e.g. process noise through a slow mode,
    wanders by about its standard deviation over any window, without being a drift), or
    within 3 noise std measured beforehand (``noise_std``, a designed experiment) or 15 % of
    the spread (a designed experiment aims at a response of 10 noise std, so a wander of
    1.5 σ of noise coloured by a slow mode, which no short window tells from drift, stays
    below it; the fitted initial state of the validation absorbs such a transient)."""
    if n_settle < 8:
        return
    from scipy.stats import t as student

    q = n_settle // 4
    t_crit = float(student.ppf(0.9995, max(q - 2, 1)))
    k = np.arange(q, dtype=float)
    k -= k.mean()
    for j, nm in enumerate(outputs):
        tail = np.asarray(res[f"plant.{nm}"], float)[n_settle - q + 1:n_settle + 1]
        slope = float(k @ (tail - tail.mean()) / (k @ k))
        drift = abs(slope) * q
        # the fitted drift's two-sided 0.1 % Student-t bound for white noise of the residual's size
        # (q − 2 degrees of freedom: few samples give a loose estimate of that size)
        resid = float(np.sqrt(np.sum((tail - tail.mean() - slope * k) ** 2) / max(q - 2, 1)))
        noise = resid * max(t_crit * np.sqrt(12.0 / q), 2.0)
        if noise_std is not None:  # designed experiment (signal/noise ≥ 10): coloured noise wanders ~1.5 σ
            noise = max(noise, 3.0 * float(noise_std[j]), 0.15 * float(np.std(y[:, j])))
        spread = float(np.std(y[:, j]))
        if spread > 0 and drift > max(0.05 * spread, noise):
            raise IdentificationError(
                f"{path}: output {nm!r} was still moving at the end of settling ({drift:.3g} over the last "
                f"{q} steps, vs an excitation response of std {spread:.3g}): settle longer (settle > {settle:g} s) "
                f"or start at a steady state")


def _limit(v):
    try:
        return None if v is None else float(v)
    except (TypeError, ValueError):
        return None
