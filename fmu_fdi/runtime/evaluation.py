"""Residual evaluation functions (Frank, section 7; Basseville & Nikiforov 1993).

Each evaluator turns the residual vector r(k) of one residual group into a scalar
evaluation J(k), one sample at a time, with O(1) (or O(window)) work per step:

=========  =====================================================================
kind       J(k)
=========  =====================================================================
norm       ``||r(k)||``
rms        ``sqrt(1/N Σ_{i=k-N+1..k} ||r(i)||²)`` (sliding window, running sum)
ewrms      ``sqrt((1-λ) Σ_{i≤k} λ^{k-i} ||r(i)||²)`` (exponentially weighted)
peak       ``max_{i=k-N+1..k} ||r(i)||`` (monotonic deque)
narendra   ``α ||r(k)|| + β re(k)``, ``re(k+1) = γ re(k) + ||r(k)||`` (Varga's FDSystem)
chi2       ``Σ_{i=k-N+1..k} ||W r(i)||²`` with ``W = Σ^{-1/2}`` (χ² with N·dim dof under H0)
cusum      two-sided CUSUM for a mean jump of known size δ (in σ units) per whitened
           component: ``g± = max(0, g± ± δ z - δ²/2)``, J = max over components and signs
glr        ``max_{k-M<j≤k} ||Σ_{i=j..k} W r(i)||² / (2 (k-j+1))``: GLR for a jump of
           unknown magnitude and onset within the last M samples
=========  =====================================================================

All are monotone in the sequence ``||r||`` except the statistical tests, which is what
the adaptive threshold selector relies on. The state (``get_state``) is complete and
JSON-serialisable; ``reset`` returns to the state after construction.
"""
from __future__ import annotations

import math

import numpy as np

KINDS = ("norm", "rms", "ewrms", "peak", "narendra", "chi2", "cusum", "glr")
MONOTONE = ("norm", "rms", "ewrms", "peak", "narendra")


class _Ring:
    """Fixed-length ring buffer of floats with an exact running sum.

    The sum is recomputed from the buffer once per wrap-around so rounding cannot
    accumulate (amortised O(1) per push).
    """

    def __init__(self, n: int):
        self.buf = [0.0] * n
        self.i = 0
        self.count = 0
        self.sum = 0.0

    def push(self, x: float) -> None:
        buf, i = self.buf, self.i
        self.sum += x - buf[i]
        buf[i] = x
        i += 1
        if self.count < i:
            self.count = i
        if i == len(buf):
            i = 0
            self.sum = _exact_sum(buf)
        self.i = i

    def finite(self) -> bool:
        """The running sum and the value pushed last are finite (the others were when pushed)."""
        return math.isfinite(self.sum) and math.isfinite(self.buf[self.i - 1])

    def state(self) -> dict:
        return {"buf": list(self.buf), "i": self.i, "count": self.count, "sum": self.sum}

    def load(self, s: dict) -> None:
        """Restore :meth:`state`: a state a run leaves (count = min(pushes, n), index = count
        until the ring is full, unfilled slots 0, values >= 0: squares); ValueError otherwise."""
        buf, i, count = list(map(float, s["buf"])), int(s["i"]), int(s["count"])
        n = len(self.buf)
        if len(buf) != n or not 0 <= i < n or not 0 <= count <= n or (count < n and i != count):
            raise ValueError(f"ring state of length {len(buf)} (index {i}, count {count}) for a window of {n}")
        if not all(x >= 0.0 and math.isfinite(x) for x in buf) or any(x != 0.0 for x in buf[count:]):
            raise ValueError("ring buffer holds a negative, NaN or Inf value, or a filled slot beyond its count")
        self.buf, self.i, self.count, self.sum = buf, i, count, float(s["sum"])


#: sample counters stay below 2^53, where every integer is a float (the peak evaluator stores
#: sample indices as floats); a state claiming more is refused (docs/semantics.md §10)
EXACT_MAX = 2 ** 53


def _check_peak(dq: list, k: int, n: int, value: float) -> None:
    """The peak deque as a run leaves it: at most n entries, sample indices integral, increasing,
    the newest k - 1, none older than k - n; values decreasing, >= 0; J the oldest entry's value.
    This bounds every later step's work (a state at k >= 2^53 made the loop that drops old
    entries endless: k and k - n are then the same float)."""
    ok = 0 <= k < EXACT_MAX and len(dq) <= n and (len(dq) == 0) == (k == 0)
    prev_i, prev_v = -1.0, math.inf
    for i, x in dq:
        ok = ok and i == math.floor(i) and prev_i < i and i >= k - n and 0.0 <= x < prev_v
        prev_i, prev_v = i, x
    ok = ok and (value == (dq[0][1] if dq else 0.0)) and (not dq or prev_i == k - 1)
    if not ok:
        raise ValueError(f"peak state: {len(dq)} entries at sample {k} for a window of {n} are not what a run "
                         f"leaves (indices k-n..k-1 increasing, values decreasing, J the oldest)")


def _exact_sum(values) -> float:
    """Correctly rounded sum (``math.fsum``); +-inf or NaN where it overflows (S1 then resets)."""
    try:
        return math.fsum(values)
    except (OverflowError, ValueError):
        return sum(values)


def _window(spec: dict) -> int:
    n = int(spec.get("window", 1))
    if n < 1:
        raise ValueError(f"evaluation window must be at least 1 sample, got {n}")
    return n


def _whitener(spec: dict, dim: int) -> np.ndarray:
    if "W" in spec:
        W = np.atleast_2d(np.asarray(spec["W"], float))
    elif "sigma" in spec:
        W = np.diag(1.0 / np.broadcast_to(np.asarray(spec["sigma"], float), (dim,)))
    else:
        W = np.eye(dim)
    if W.shape != (dim, dim):
        raise ValueError(f"whitening matrix must be {dim}x{dim}, got {W.shape}")
    return W


class Evaluator:
    """One evaluation function for a residual group of dimension ``dim``."""

    def __init__(self, spec: dict, dim: int):
        kind = spec.get("kind")
        if kind not in KINDS:
            raise ValueError(f"unknown evaluation kind {kind!r}; use one of {KINDS}")
        self.kind, self.spec, self.dim = kind, dict(spec), dim
        if kind in ("rms", "chi2"):
            self.n = _window(spec)
        if kind == "ewrms":
            self.lam = float(spec["lambda"])
            if not 0.0 < self.lam < 1.0:
                raise ValueError(f"ewrms forgetting factor must be in (0, 1), got {self.lam}")
        if kind == "peak":
            self.n = _window(spec)
        if kind == "narendra":
            self.alpha, self.beta, self.gamma = (float(spec.get(k, d)) for k, d in
                                                 (("alpha", 0.0), ("beta", 1.0), ("gamma", 0.9)))
            if not 0.0 <= self.gamma < 1.0 or self.alpha < 0 or self.beta < 0:
                raise ValueError("narendra needs alpha >= 0, beta >= 0 and 0 <= gamma < 1")
        if kind in ("chi2", "cusum", "glr"):
            self.W = _whitener(spec, dim)
        if kind == "cusum":
            self.delta = float(spec.get("delta", 1.0))
            if self.delta <= 0:
                raise ValueError("cusum change magnitude delta must be positive")
        if kind == "glr":
            self.n = _window(spec)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        k = self.kind
        self.value = 0.0
        if k in ("rms", "chi2"):
            self.ring = _Ring(self.n)
        elif k == "ewrms":
            self.acc = 0.0
        elif k == "peak":
            self.deque: list[list[float]] = []  # [sample index, value], values decreasing
            self.k = 0
        elif k == "narendra":
            self.re = 0.0
        elif k == "cusum":
            self.gp = [0.0] * self.dim
            self.gm = [0.0] * self.dim
        elif k == "glr":
            self.hist: list[list[float]] = []  # last n whitened vectors, oldest first

    def get_state(self) -> dict:
        k = self.kind
        s: dict = {"value": self.value}
        if k in ("rms", "chi2"):
            s["ring"] = self.ring.state()
        elif k == "ewrms":
            s["acc"] = self.acc
        elif k == "peak":
            s["deque"] = [list(e) for e in self.deque]
            s["k"] = self.k
        elif k == "narendra":
            s["re"] = self.re
        elif k == "cusum":
            s["gp"], s["gm"] = list(self.gp), list(self.gm)
        elif k == "glr":
            s["hist"] = [list(h) for h in self.hist]
        return s

    def set_state(self, s: dict) -> None:
        """Restore :meth:`get_state`; raises ValueError for a state of another shape or with
        NaN/Inf (the evaluator may then be partly overwritten: callers roll back)."""
        k = self.kind
        self.value = float(s["value"])
        if k in ("rms", "chi2"):
            self.ring.load(s["ring"])
        elif k == "ewrms":
            self.acc = float(s["acc"])
        elif k == "peak":
            dq = [[float(a), float(b)] for a, b in s["deque"]]
            self.deque, self.k = dq, int(s["k"])
            _check_peak(dq, self.k, self.n, self.value)
        elif k == "narendra":
            self.re = float(s["re"])
        elif k == "cusum":
            gp, gm = list(map(float, s["gp"])), list(map(float, s["gm"]))
            if len(gp) != self.dim or len(gm) != self.dim:
                raise ValueError(f"cusum state of dimension {len(gp)}/{len(gm)}, expected {self.dim}")
            self.gp, self.gm = gp, gm
        elif k == "glr":
            hist = [list(map(float, h)) for h in s["hist"]]
            if len(hist) > self.n or any(len(h) != self.dim or not all(map(math.isfinite, h)) for h in hist):
                raise ValueError(f"glr state: {len(hist)} vectors (window {self.n}) of dimension {self.dim} expected, "
                                 f"finite")
            self.hist = hist
        if not self.finite():
            raise ValueError(f"{k} evaluator state holds NaN or Inf")
        self._check_values()

    def _check_values(self) -> None:
        """The value J and the state fit as a run leaves them (docs/semantics.md §10): J >= 0 for
        every kind, and J is what the state gives where it is a function of it."""
        k, v = self.kind, self.value
        if k == "rms":
            ok = v == math.sqrt(max(self.ring.sum, 0.0) / self.n)
        elif k == "chi2":
            ok = v == max(self.ring.sum, 0.0)
        elif k == "ewrms":
            ok = self.acc >= 0.0 and v == math.sqrt(self.acc)
        elif k == "narendra":
            ok = self.re >= 0.0 and v >= 0.0
        elif k == "cusum":
            ok = min(self.gp + self.gm) >= 0.0 and v == max(max(self.gp), max(self.gm))
        else:  # norm, glr (peak: _check_peak)
            ok = v >= 0.0
        if not ok:
            raise ValueError(f"{k} evaluator state: the value {v!r} does not fit the state")

    def finite(self) -> bool:
        """Every value written by the last step is finite (S1, docs/semantics.md §8).

        The state is finite after reset and after every accepted step, so checking what the
        last step wrote is checking the whole state."""
        k, isf = self.kind, math.isfinite
        if not isf(self.value):
            return False
        if k in ("rms", "chi2"):
            return self.ring.finite()
        if k == "ewrms":
            return isf(self.acc)
        if k == "narendra":
            return isf(self.re)
        if k == "peak":
            return not self.deque or isf(self.deque[-1][1])
        if k == "cusum":
            return all(map(isf, self.gp)) and all(map(isf, self.gm))
        if k == "glr":
            return not self.hist or all(map(isf, self.hist[-1]))
        return True

    # ------------------------------------------------------------------- step
    def step_sq(self, sq: float) -> float:
        """Step a norm-based evaluator (``MONOTONE`` kinds) with ``sq = ||r||²``."""
        k = self.kind
        if k == "rms":
            self.ring.push(sq)
            v = math.sqrt(max(self.ring.sum, 0.0) / self.n)
        elif k == "norm":
            v = math.sqrt(sq)
        elif k == "ewrms":
            self.acc = self.lam * self.acc + (1.0 - self.lam) * sq
            v = math.sqrt(self.acc)
        elif k == "narendra":
            x = math.sqrt(sq)
            v = self.alpha * x + self.beta * self.re
            self.re = self.gamma * self.re + x
        elif k == "peak":
            x = math.sqrt(sq)
            dq = self.deque
            while dq and dq[-1][1] <= x:
                dq.pop()
            dq.append([float(self.k), x])
            while dq[0][0] <= self.k - self.n:
                dq.pop(0)
            self.k += 1
            v = dq[0][1]
        else:
            raise ValueError(f"the '{k}' evaluation needs the residual vector, not its norm")
        self.value = v
        return v

    def step(self, r: np.ndarray) -> float:
        """Step with the residual vector r of the group (any kind)."""
        r = np.asarray(r, float)
        if r.shape != (self.dim,):
            raise ValueError(f"residual sample must have shape ({self.dim},), got {r.shape}")
        k = self.kind
        if k in MONOTONE:
            return self.step_sq(sum(x * x for x in r.tolist()))
        with np.errstate(over="ignore", invalid="ignore"):  # overflow → inf/NaN, caught by finite() (S1)
            return self._step_statistical(r)

    def _step_statistical(self, r: np.ndarray) -> float:
        k = self.kind
        if k == "chi2":
            w = self.W @ r
            self.ring.push(float(w @ w))
            v = max(self.ring.sum, 0.0)
        elif k == "cusum":
            z = (self.W @ r).tolist()
            d = self.delta
            for i in range(self.dim):
                self.gp[i] = max(0.0, self.gp[i] + d * z[i] - 0.5 * d * d)
                self.gm[i] = max(0.0, self.gm[i] - d * z[i] - 0.5 * d * d)
            v = max(max(self.gp), max(self.gm))
        else:  # glr
            w = self.W @ r
            self.hist.append(w.tolist())
            if len(self.hist) > self.n:
                self.hist.pop(0)
            acc = np.zeros(self.dim)
            best = 0.0
            for j, h in enumerate(reversed(self.hist)):
                acc += h
                best = max(best, float(acc @ acc) / (2.0 * (j + 1)))
            v = best
        self.value = v
        return v

    def run(self, R: np.ndarray) -> np.ndarray:
        """Evaluate a whole record (rows are samples; a 1-D record of a scalar residual is a
        column): identical to repeated ``step``."""
        R = np.asarray(R, float).reshape(-1, self.dim)
        return np.array([self.step(r) for r in R])

    # --------------------------------------------------------- resampling
    def resampled(self, ratio: float) -> "Evaluator":
        """The same evaluation for a sample time ``ratio`` times the design's.

        Windows keep their duration (``N → round(N / ratio)``), forgetting factors their
        time constant (``λ → λ^ratio``, ``γ → γ^ratio``) and the Narendra filter its
        steady-state gain (``β → β (1-γ') / (1-γ)``). The statistical tests are defined
        per sample of a whitened sequence and cannot be resampled.
        """
        s = dict(self.spec)
        if self.kind in ("chi2", "cusum", "glr"):
            raise ValueError(f"the '{self.kind}' test is defined per design sample and cannot run at another step size")
        if self.kind in ("rms", "peak"):
            s["window"] = max(1, int(round(self.n / ratio)))
        elif self.kind == "ewrms":
            s["lambda"] = self.lam ** ratio
        elif self.kind == "narendra":
            g2 = self.gamma ** ratio
            s["gamma"] = g2
            s["beta"] = self.beta * (1 - g2) / (1 - self.gamma) if self.gamma < 1 else self.beta
        return Evaluator(s, self.dim)
