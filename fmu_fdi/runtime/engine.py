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
from .design_check import check_design
from .evaluation import MONOTONE, Evaluator
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
        check_design(design)  # the one validation every entry point shares (raises DesignCheckError)
        sig = design["signals"]
        self.u_names, self.y_names = list(sig["u"]), list(sig["y"])
        self.nu, self.ny = len(self.u_names), len(self.y_names)
        op = design.get("operating_point") or {}
        self.u0 = np.asarray(op.get("u", [0.0] * self.nu), float).reshape(self.nu)
        self.y0 = np.asarray(op.get("y", [0.0] * self.ny), float).reshape(self.ny)
        self._u0, self._y0 = self.u0.tolist(), self.y0.tolist()
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
        self._bind_stage()

    def _bind_stage(self) -> None:
        """Per group: (single residual index or -1, indices, evaluator, norm-based?, threshold)."""
        self._stage = [(g[0] if len(g) == 1 else -1, g, e, e.kind in MONOTONE, t)
                       for g, e, t in zip(self.groups, self.evaluators, self.thresholds)]

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
        substeps, gen, ratio = self._plan(h)
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
        self._substeps = substeps

    # ----------------------------------------------------------------- state
    def reset(self) -> None:
        self.generator = self._native[0]
        self.generator.reset()
        self.h = self.Ts
        self._build_stage(1.0)
        self.decision.reset()
        self.outputs = [0.0] * len(self.names)
        self.n_samples = 0
        self._substeps = 1

    def get_state(self) -> dict:
        return {"h": self.h, "generator": self.generator.get_state(),
                "evaluators": [e.get_state() for e in self.evaluators],
                "thresholds": [t.get_state() for t in self.thresholds],
                "decision": self.decision.get_state(), "outputs": list(self.outputs),
                "n_samples": self.n_samples, "threshold_scale": self.threshold_scale}

    def set_state(self, s: dict) -> None:
        self.set_step(float(s["h"]))
        self.generator.set_state(s["generator"])
        for e, es in zip(self.evaluators, s["evaluators"]):
            e.set_state(es)
        for t, ts in zip(self.thresholds, s["thresholds"]):
            t.set_state(ts)
        self.decision.set_state(s["decision"])
        self.outputs = [float(x) for x in s["outputs"]]
        self.n_samples = int(s["n_samples"])
        self.threshold_scale = float(s["threshold_scale"])

    # ------------------------------------------------------------------ step
    def _sample(self, v, unorm: float) -> None:
        r = self.generator.step(v)
        rl = r.tolist()
        out = self.outputs
        nr, ng = self.n_residuals, self.n_groups
        out[:nr] = rl
        scale = self.threshold_scale
        evals, thrs = [], []
        for single, grp, ev, norm_based, thr in self._stage:
            if single >= 0:
                x = rl[single]
                evals.append(ev.step_sq(x * x) if norm_based else ev.step(r[grp]))
            elif norm_based:
                evals.append(ev.step_sq(sum(rl[j] * rl[j] for j in grp)))
            else:
                evals.append(ev.step(r[grp]))
            thrs.append(scale * thr.step(unorm))
        dec = self.decision
        dec.step(evals, thrs, rl)
        out[nr:nr + ng] = evals
        out[nr + ng:nr + 2 * ng] = thrs
        alarms = dec.alarms
        out[nr + 2 * ng:nr + 3 * ng] = [1.0 if a else 0.0 for a in alarms]
        out[-3] = 1.0 if True in alarms else 0.0
        out[-2] = float(dec.isolated)

    def advance(self, u, y, h: float | None = None) -> list:
        """Diagnose the sample (u, y) over a communication step h (default: Ts).

        Returns the outputs (a new list, in the order of :attr:`names`).
        """
        if h is not None and h != self.h:
            self.set_step(h)
        u = list(map(float, u))
        y = list(map(float, y))
        if len(u) != self.nu or len(y) != self.ny:
            raise ValueError(f"expected {self.nu} inputs and {self.ny} outputs, got {len(u)} and {len(y)}")
        if not (all(map(math.isfinite, u)) and all(map(math.isfinite, y))):
            self.outputs[-1] = 1.0
            return list(self.outputs)
        du = [a - b for a, b in zip(u, self._u0)]
        v = [a - b for a, b in zip(y, self._y0)] + du
        unorm = math.sqrt(sum(d * d for d in du))
        for _ in range(self._substeps):
            self._sample(v, unorm)
        self.outputs[-1] = 0.0
        self.n_samples += 1
        return list(self.outputs)

    def step(self, u, y) -> list:
        return self.advance(u, y, None)
