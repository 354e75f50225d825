"""External input signals: sampled data the master feeds to FMU inputs.

Samples ``(t_i, v_i)`` with non-decreasing ``t_i`` define a signal for all ``t``:

- ``"zoh"`` (zero-order hold, the default): ``v(t) = v_i`` for the last ``i`` with ``t_i <= t``;
  a repeated time ``t_i = t_{i+1}`` is a jump, the later sample counts from ``t_i`` on.
- ``"linear"``: straight lines between neighbouring samples, right-continuous at jumps.

Before the first sample the first value holds, after the last sample the last value holds
(no extrapolation). The master samples each signal at the start of every communication step and
holds it over the step, so with ``"zoh"`` and samples on the communication grid the FMU sees the
samples exactly.

A CSV file has a header row naming the columns (double quotes optional, as in the FMI
cross-check files: ``"time","Q1","Q2"``), a column named ``time``, and one row per sample.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import CoSimulationError

INTERPOLATIONS = ("zoh", "linear")


class InputSignals:
    """Named signals on a common time base.

    Parameters
    ----------
    time : array_like, shape (N,)
        Sample times, non-decreasing, at least one.
    values : mapping of str to array_like, shape (N,)
        Samples of each signal. A name is either a bare variable name (fed to every
        unconnected input of that name, in every FMU) or ``fmu.variable`` (that input only).
    interpolation : {"zoh", "linear"}
        See the module docstring.
    """

    def __init__(self, time, values: dict, interpolation: str = "zoh"):
        if interpolation not in INTERPOLATIONS:
            raise CoSimulationError(f"interpolation {interpolation!r} is not one of {INTERPOLATIONS}")
        t = np.asarray(time, dtype=float)
        if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
            raise CoSimulationError("input time must be a non-empty 1-D array of finite numbers")
        bad = np.flatnonzero(np.diff(t) < 0)
        if bad.size:
            raise CoSimulationError(f"input time must not decrease: sample {bad[0] + 1} "
                                    f"({t[bad[0] + 1]:g}) comes after {t[bad[0]]:g}")
        self.time = t
        self.values = {}
        for name, v in values.items():
            arr = np.asarray(v, dtype=float)
            if arr.shape != t.shape:
                raise CoSimulationError(f"input signal {name!r} has {arr.size} samples for {t.size} times")
            self.values[str(name)] = arr
        if not self.values:
            raise CoSimulationError("no input signals given besides time")
        self.interpolation = interpolation

    @classmethod
    def from_csv(cls, path, interpolation: str = "zoh") -> "InputSignals":
        """Read a CSV file with a ``time`` column (see the module docstring)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"input CSV: no such file {str(path)!r}")
        from .csvtable import read_table

        header, data = read_table(path, "input CSV")
        k = header.index("time")
        return cls(data[:, k], {h: data[:, j] for j, h in enumerate(header) if j != k}, interpolation)

    @classmethod
    def from_array(cls, array, interpolation: str = "zoh") -> "InputSignals":
        """From a structured array with a ``time`` field (as fmpy's ``input`` argument)."""
        names = array.dtype.names or ()
        if "time" not in names:
            raise CoSimulationError(f"input array has no 'time' field (fields: {list(names)})")
        return cls(array["time"], {n: array[n] for n in names if n != "time"}, interpolation)

    @property
    def names(self) -> tuple:
        """Signal names (time excluded)."""
        return tuple(self.values)

    def value(self, name: str, t: float) -> float:
        """Value of signal ``name`` at time ``t``."""
        v = self.values[name]
        i = int(np.searchsorted(self.time, t, side="right")) - 1
        if i < 0:
            return float(v[0])
        if self.interpolation == "zoh" or i == len(v) - 1:
            return float(v[i])
        # searchsorted(side="right") makes t_i the last sample <= t, so t_{i+1} > t_i here
        t0, t1 = self.time[i], self.time[i + 1]
        return float(v[i] + (v[i + 1] - v[i]) * (t - t0) / (t1 - t0))

    def sample(self, name: str, times) -> np.ndarray:
        """Values of signal ``name`` at the times ``times`` (an array): :meth:`value` on each,
        with the same arithmetic."""
        v = self.values[name]
        t = np.asarray(times, dtype=float)
        i = np.searchsorted(self.time, t, side="right") - 1
        before = i < 0
        i = np.maximum(i, 0)
        out = v[i]
        if self.interpolation == "linear":
            inner = ~before & (i < len(v) - 1)
            j = i[inner]
            t0, t1 = self.time[j], self.time[j + 1]
            out = out.copy()
            out[inner] = v[j] + (v[j + 1] - v[j]) * (t[inner] - t0) / (t1 - t0)
        return out

    def function(self, name: str):
        """``t -> value`` of one signal (e.g. for ``fmpy.ssp.simulation.simulate_ssp(input=...)``)."""
        if name not in self.values:
            raise CoSimulationError(f"no input signal {name!r} (signals: {list(self.values)})")
        return lambda t: self.value(name, t)
