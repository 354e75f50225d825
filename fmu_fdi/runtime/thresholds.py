"""Decision thresholds evaluated at run time (Frank, section 7; Ding 2008, ch. 10).

=============  ==================================================================
kind           J_th(k)
=============  ==================================================================
fixed          ``value``
adaptive       ``J0 + a · E_u(k)``: Frank's adaptive threshold; ``E_u`` is an
               evaluator (normally the residual's own) applied to ``||u(k) - u0||``
majorant       ``J0 + E(b)(k)`` with ``b(k) = Σ_{j<M} m_j ||u(k-j)|| + t · max_{i≤k-M} ||u(i)||``:
               a pointwise bound ``||r(k)|| ≤ b(k)`` pushed through the residual's own
               (monotone) evaluator E — the ℓ∞ counterpart of ``adaptive``
=============  ==================================================================

The design-time threshold selector (:mod:`fmu_fdi.evaluation.selector`) computes
``a`` / ``m``, ``t`` and ``J0`` and documents the guarantee each one gives.
"""
from __future__ import annotations

import math

import numpy as np

from .evaluation import MONOTONE, Evaluator

KINDS = ("fixed", "adaptive", "majorant")


class Threshold:
    def __init__(self, spec: dict, residual_eval: dict):
        kind = spec.get("kind")
        if kind not in KINDS:
            raise ValueError(f"unknown threshold kind {kind!r}; use one of {KINDS}")
        self.kind, self.spec = kind, dict(spec)
        if kind == "fixed":
            self.value0 = float(spec["value"])
            if not np.isfinite(self.value0) or self.value0 < 0:
                raise ValueError(f"fixed threshold must be finite and >= 0, got {self.value0}")
        else:
            self.J0 = float(spec.get("J0", 0.0))
            if not np.isfinite(self.J0) or self.J0 < 0:
                raise ValueError(f"threshold offset J0 must be finite and >= 0, got {self.J0}")
        if kind in ("adaptive", "majorant"):
            ev = spec.get("evaluation", residual_eval) if kind == "adaptive" else residual_eval
            if ev.get("kind") not in MONOTONE:
                raise ValueError(f"an {kind} threshold needs a norm-based evaluation ({', '.join(MONOTONE)}), "
                                 f"not {ev.get('kind')!r}")
        if kind == "adaptive":
            self.a = float(spec["a"])
            if not (self.a >= 0 and np.isfinite(self.a)):
                raise ValueError(f"adaptive threshold gain a must be finite and >= 0, got {self.a}")
            self.u_eval = Evaluator(spec.get("evaluation", residual_eval), 1)
        if kind == "majorant":
            self.taps = np.asarray(spec["taps"], float)
            self.tail = float(spec.get("tail", 0.0))
            if self.taps.ndim != 1 or self.taps.size < 1 or np.any(self.taps < 0) or self.tail < 0:
                raise ValueError("majorant taps must be a non-empty list of non-negative numbers, tail >= 0")
            self.b_eval = Evaluator(residual_eval, 1)
        self.reset()

    def reset(self) -> None:
        self.value = self.value0 if self.kind == "fixed" else self.J0
        if self.kind == "adaptive":
            self.u_eval.reset()
        if self.kind == "majorant":
            self.b_eval.reset()
            self.hist = [0.0] * self.taps.size  # ||u(k-j)||, j = 0..M-1
            self.old_max = 0.0

    def step(self, unorm: float) -> float:
        if self.kind == "fixed":
            return self.value
        if self.kind == "adaptive":
            self.value = self.J0 + self.a * self.u_eval.step_sq(unorm * unorm)
        elif self.kind == "majorant":
            M = self.taps.size
            self.old_max = max(self.old_max, self.hist[-1]) if M else self.old_max
            self.hist = [unorm] + self.hist[:-1]
            b = float(np.dot(self.taps, self.hist)) + self.tail * self.old_max
            self.value = self.J0 + self.b_eval.step_sq(b * b)
        return self.value

    def finite(self) -> bool:
        """Every value written by the last step is finite (S1, docs/semantics.md §8)."""
        isf = math.isfinite
        if not isf(self.value):
            return False
        if self.kind == "adaptive":
            return self.u_eval.finite()
        if self.kind == "majorant":
            return isf(self.hist[0]) and isf(self.old_max) and self.b_eval.finite()
        return True

    def get_state(self) -> dict:
        s: dict = {"value": self.value}
        if self.kind == "adaptive":
            s["u_eval"] = self.u_eval.get_state()
        if self.kind == "majorant":
            s.update({"b_eval": self.b_eval.get_state(), "hist": list(self.hist), "old_max": self.old_max})
        return s

    def set_state(self, s: dict) -> None:
        self.value = float(s["value"])
        if self.kind == "adaptive":
            self.u_eval.set_state(s["u_eval"])
        if self.kind == "majorant":
            self.b_eval.set_state(s["b_eval"])
            hist = list(map(float, s["hist"]))
            if len(hist) != self.taps.size or not all(map(math.isfinite, hist)):
                raise ValueError(f"majorant state: {len(hist)} finite input norms expected {self.taps.size}")
            self.hist = hist
            self.old_max = float(s["old_max"])
        if self.kind == "fixed" and self.value != self.value0:
            raise ValueError(f"fixed threshold state {self.value!r} differs from the design's {self.value0!r}")
        if not self.finite():
            raise ValueError(f"{self.kind} threshold state holds NaN or Inf")
        # J_th is what its evaluator's value gives (the same operations as step); the input norms >= 0
        if ((self.kind == "adaptive" and self.value != self.J0 + self.a * self.u_eval.value)
                or (self.kind == "majorant" and (self.value != self.J0 + self.b_eval.value
                                                 or min(self.hist + [self.old_max]) < 0.0))):
            raise ValueError(f"{self.kind} threshold state: the value {self.value!r} does not fit its evaluator")

    def resampled(self, ratio: float, residual_eval: dict) -> "Threshold":
        if self.kind == "majorant":
            raise ValueError("a majorant threshold is an impulse-response bound at the design sample time and "
                             "cannot run at another step size")
        s = dict(self.spec)
        if self.kind == "adaptive":
            s["evaluation"] = self.u_eval.resampled(ratio).spec
        return Threshold(s, residual_eval)
