"""The diagnoser at run time: generator → evaluation → thresholds → decision, per sample.

``DiagnoserRuntime(design)`` reads a design dict (the JSON design file, see
docs/design-file.md) and processes plant samples. It is the single implementation of
the step logic: ``Diagnoser.step``/``run`` call it in Python and the diagnostic FMU
bundles this package and calls it inside the host.

Timing convention: one call of :meth:`advance` consumes the plant signals sampled at
time t and returns the diagnosis of that sample; a communication step h that is an
integer multiple of the design sample time Ts runs h/Ts sub-steps with the inputs held;
any other h uses an exact zero-order-hold re-discretisation of the continuous design
(cached per h), and a design that exists only in discrete time refuses it.

Invalid samples (NaN/Inf in u or y) are not fed to the generator: ``input_invalid`` is
set, every other output holds its last value and the states stay as they were.
"""
from __future__ import annotations

import math

import numpy as np

from .decision import Decision
from .evaluation import Evaluator
from .expm import zoh
from .generators import make_generator
from .thresholds import Threshold

FORMAT = "fmu-fdi-design/1"


class StepSizeError(ValueError):
    """The requested communication step cannot be served exactly."""


def output_names(n_residuals: int, n_groups: int) -> list[str]:
    return ([f"residual_{k + 1}" for k in range(n_residuals)] + [f"evaluation_{k + 1}" for k in range(n_groups)]
            + [f"threshold_{k + 1}" for k in range(n_groups)] + [f"alarm_{k + 1}" for k in range(n_groups)]
            + ["fault_detected", "isolated_fault", "input_invalid"])


class DiagnoserRuntime:
    """Per-sample diagnosis from a design dict (numpy only)."""

    def __init__(self, design: dict):
        if design.get("format") != FORMAT:
            raise ValueError(f"design format must be {FORMAT!r}, got {design.get('format')!r}")
        self.design = design
        sig = design["signals"]
        self.u_names, self.y_names = list(sig["u"]), list(sig["y"])
        self.nu, self.ny = len(self.u_names), len(self.y_names)
        op = design.get("operating_point") or {}
        self.u0 = np.asarray(op.get("u", [0.0] * self.nu), float).reshape(self.nu)
        self.y0 = np.asarray(op.get("y", [0.0] * self.ny), float).reshape(self.ny)
        g = design["generator"]
        self.Ts = float(g["dt"])
        if not (self.Ts > 0 and math.isfinite(self.Ts)):
            raise ValueError(f"generator sample time must be positive, got {g['dt']!r}")
        self.gen_spec = g["discrete"]
        self.cont = g.get("continuous")
        self.groups = [list(map(int, grp)) for grp in g["groups"]]
        self.faults = [f["name"] for f in design.get("faults", [])]
        self.eval_specs = [e["evaluator"] for e in design["evaluation"]]
        self.thr_specs = [e["threshold"] for e in design["evaluation"]]
        if len(self.eval_specs) != len(self.groups):
            raise ValueError(f"{len(self.eval_specs)} evaluation entries for {len(self.groups)} residual groups")
        self.generator = make_generator(self.gen_spec)
        if self.generator.n_inputs != self.ny + self.nu:
            raise ValueError(f"generator reads {self.generator.n_inputs} signals but the design lists "
                             f"{self.ny} outputs + {self.nu} inputs")
        self.n_residuals = self.generator.n_outputs
        flat = sorted(i for grp in self.groups for i in grp)
        if flat != list(range(self.n_residuals)):
            raise ValueError(f"residual groups {self.groups} must partition 0..{self.n_residuals - 1}")
        self.n_groups = len(self.groups)
        self.names = output_names(self.n_residuals, self.n_groups)
        self.threshold_scale = 1.0
        self._native = (self.generator, None)
        self._plans: dict[float, tuple] = {}
        self.h = self.Ts
        self._build_stage(1.0)
        self.decision = Decision(design.get("decision", {}), self.n_groups, len(self.faults))
        self.reset()

    # ------------------------------------------------------------- structure
    def _build_stage(self, ratio: float) -> None:
        if ratio == 1.0:
            self.evaluators = [Evaluator(s, len(g)) for s, g in zip(self.eval_specs, self.groups)]
            self.thresholds = [Threshold(t, s) for t, s in zip(self.thr_specs, self.eval_specs)]
        else:
            self.evaluators = [Evaluator(s, len(g)).resampled(ratio) for s, g in zip(self.eval_specs, self.groups)]
            self.thresholds = [Threshold(t, s).resampled(ratio, e.spec)
                               for t, s, e in zip(self.thr_specs, self.eval_specs, self.evaluators)]

    def _plan(self, h: float):
        """(substeps, generator) for communication step h; raises StepSizeError."""
        if not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
            raise StepSizeError(f"communication step must be a positive number, got {h!r}")
        ratio = h / self.Ts
        k = round(ratio)
        if k >= 1 and abs(ratio - k) <= 1e-9 * ratio:
            return k, self._native[0], 1.0
        if h in self._plans:
            return self._plans[h]
        if self.cont is None or self.gen_spec.get("kind") != "lti":
            raise StepSizeError(
                f"step {h:g} s is not an integer multiple of the design sample time {self.Ts:g} s and the design "
                f"exists only in discrete time, so it cannot be re-discretised exactly")
        Ac = np.asarray(self.cont["A"], float).reshape(len(self.cont["A"]), -1) if self.cont["A"] else np.zeros((0, 0))
        n = Ac.shape[0]
        D = np.atleast_2d(np.asarray(self.cont["D"], float))
        Bc = np.asarray(self.cont["B"], float).reshape(n, D.shape[1])
        Cc = np.asarray(self.cont["C"], float).reshape(D.shape[0], n)
        Ad, Bd = zoh(Ac, Bc, h)
        gen = make_generator({"kind": "lti", "A": Ad, "B": Bd, "C": Cc, "D": D})
        try:
            for s, g in zip(self.eval_specs, self.groups):
                Evaluator(s, len(g)).resampled(ratio)
            for t, s in zip(self.thr_specs, self.eval_specs):
                Threshold(t, s).resampled(ratio, s)
        except ValueError as exc:
            raise StepSizeError(f"step {h:g} s differs from the design sample time {self.Ts:g} s: {exc}") from None
        plan = (1, gen, ratio)
        self._plans[h] = plan
        return plan

    def set_step(self, h: float) -> None:
        """Prepare for communication steps of size h (raises StepSizeError if impossible).

        The generator state carries over; evaluation windows restart when the effective
        sample time changes (a re-discretised design evaluates at h, not Ts).
        """
        _, gen, ratio = self._plan(h)
        if h == self.h:
            return
        prev_ratio = self._plan(self.h)[2]
        state = self.generator.get_state()
        self.generator = gen
        if gen.kind == "lti" and len(state.get("x", [])) == gen.A.shape[0]:
            gen.set_state(state)
        if ratio != prev_ratio:
            self._build_stage(ratio)
        self.h = h

    # ----------------------------------------------------------------- state
    def reset(self) -> None:
        self.generator = self._native[0]
        self.generator.reset()
        self.h = self.Ts
        self._build_stage(1.0)
        self.decision.reset()
        self.outputs = np.zeros(len(self.names))
        self.n_samples = 0

    def get_state(self) -> dict:
        return {"h": self.h, "generator": self.generator.get_state(),
                "evaluators": [e.get_state() for e in self.evaluators],
                "thresholds": [t.get_state() for t in self.thresholds],
                "decision": self.decision.get_state(), "outputs": self.outputs.tolist(),
                "n_samples": self.n_samples, "threshold_scale": self.threshold_scale}

    def set_state(self, s: dict) -> None:
        self.set_step(float(s["h"]))
        self.generator.set_state(s["generator"])
        for e, es in zip(self.evaluators, s["evaluators"]):
            e.set_state(es)
        for t, ts in zip(self.thresholds, s["thresholds"]):
            t.set_state(ts)
        self.decision.set_state(s["decision"])
        self.outputs = np.array(s["outputs"], float)
        self.n_samples = int(s["n_samples"])
        self.threshold_scale = float(s["threshold_scale"])

    # ------------------------------------------------------------------ step
    def _sample(self, v: np.ndarray, unorm: float) -> None:
        r = self.generator.step(v)
        nr, ng = self.n_residuals, self.n_groups
        out = self.outputs
        out[:nr] = r
        scale = self.threshold_scale
        for i, grp in enumerate(self.groups):
            out[nr + i] = self.evaluators[i].step(r[grp])
            out[nr + ng + i] = scale * self.thresholds[i].step(unorm)
        self.decision.step(out[nr:nr + ng], out[nr + ng:nr + 2 * ng], r)
        out[nr + 2 * ng:nr + 3 * ng] = self.decision.alarms
        out[-3] = float(any(self.decision.alarms))
        out[-2] = float(self.decision.isolated)

    def advance(self, u, y, h: float | None = None) -> np.ndarray:
        """Diagnose the sample (u, y) over a communication step h (default: Ts)."""
        if h is not None and h != self.h:
            self.set_step(h)
        substeps = self._plan(self.h)[0]
        u = np.asarray(u, float).reshape(self.nu)
        y = np.asarray(y, float).reshape(self.ny)
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            self.outputs[-1] = 1.0
            return self.outputs.copy()
        du = u - self.u0
        v = np.concatenate([y - self.y0, du])
        unorm = float(np.linalg.norm(du))
        for _ in range(substeps):
            self._sample(v, unorm)
        self.outputs[-1] = 0.0
        self.n_samples += 1
        return self.outputs.copy()

    def step(self, u, y) -> np.ndarray:
        return self.advance(u, y, None)
