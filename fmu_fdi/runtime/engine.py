"""The diagnoser at run time: generator → evaluation → thresholds → decision, per sample.

``DiagnoserRuntime(design)`` reads a design dict (the JSON design file, see
docs/design-file.md) and processes plant samples. It is the single implementation of
the step logic: ``Diagnoser.step``/``run`` call it in Python and the diagnostic FMU
bundles this package and calls it inside the host. The semantics of one call, which the
native C runtime implements too, are written down in docs/semantics.md:

* one call of :meth:`advance` consumes the plant signals sampled at time t and returns the
  diagnosis of that sample;
* a communication step h equal to the previous one within 1e-9 (relative) is the same step;
  an integer multiple k ≤ 10000 of Ts runs k sub-steps with the inputs held; any other h in
  [Ts/16, 10000 Ts] uses an exact zero-order-hold re-discretisation of the continuous design
  (at most 8 cached); anything else raises :class:`StepSizeError` and changes nothing;
* invalid samples (NaN/Inf, or outside ``signals.valid_range``) set ``input_invalid``; every
  other output holds its last value and the states stay as they were;
* a non-finite value inside the runtime (e.g. the square of one y = 1e300) is an overflow:
  the sub-sample is discarded, generator, evaluators and thresholds restart from their
  initial state, the raw test of every group whose evaluation overflowed fires (the value is
  evidence of a fault), and ``numeric_reset`` and ``input_invalid`` are set for that call.
"""
from __future__ import annotations

import math

import numpy as np

from .decision import Decision
from .design_check import check_design
from .evaluation import EXACT_MAX, MONOTONE, Evaluator
from .expm import zoh
from .generators import make_generator
from .thresholds import Threshold

FORMAT = "fmu-fdi-design/1"
#: most sub-steps one call may run (S3): a larger multiple of Ts is refused
MAX_SUBSTEPS = 10000
#: step sizes within this relative distance are one step size (S3)
STEP_RTOL = 1e-9
#: re-discretisations kept (least recently used evicted)
CACHE_SIZE = 8
#: the smallest re-discretised step, as a fraction of Ts (windows grow as Ts/h)
MIN_STEP_RATIO = 1.0 / 16.0


class StepSizeError(ValueError):
    """The requested communication step cannot be served exactly; nothing was changed."""


def sample_signals(u, y, nu: int, ny: int) -> tuple[list[float], list[float]]:
    """One sample's inputs and outputs as float lists, or ValueError for vectors of the wrong
    length (nothing has changed then); the one check of every runtime's ``advance``."""
    u = list(map(float, u))
    y = list(map(float, y))
    if len(u) != nu or len(y) != ny:
        raise ValueError(f"expected {nu} inputs and {ny} outputs, got {len(u)} and {len(y)}")
    return u, y


def output_names(n_residuals: int, n_groups: int) -> list[str]:
    return ([f"residual_{k + 1}" for k in range(n_residuals)] + [f"evaluation_{k + 1}" for k in range(n_groups)]
            + [f"threshold_{k + 1}" for k in range(n_groups)] + [f"alarm_{k + 1}" for k in range(n_groups)]
            + ["fault_detected", "isolated_fault", "input_invalid", "numeric_reset"])


#: positions of the trailing outputs (counted from the end of the output list)
FAULT_DETECTED, ISOLATED_FAULT, INPUT_INVALID, NUMERIC_RESET = -4, -3, -2, -1
BOOLEAN_OUTPUTS = ("fault_detected", "input_invalid", "numeric_reset")


def output_type(name: str) -> str:
    """FMI type of an output: 'Boolean' (alarms, flags), 'Integer' (isolated_fault, a scheduled
    design's active_member) or 'Real'."""
    if name.startswith("alarm_") or name in BOOLEAN_OUTPUTS:
        return "Boolean"
    return "Integer" if name in ("isolated_fault", "active_member") else "Real"


def valid_ranges(signals: dict) -> tuple[list[float], list[float], list[float], list[float]]:
    """``signals.valid_range`` → (u_lo, u_hi, y_lo, y_hi) with ±inf where unbounded (S2).

    ``signals`` must come from a design that passed :func:`.design_check.check_design`,
    which refuses every malformed range (the range is a safety feature: a typo must not
    switch it off silently); this only converts.
    """
    u, y = list(signals["u"]), list(signals["y"])
    lo = {n: -math.inf for n in u + y}
    hi = {n: math.inf for n in u + y}
    for name, (low, high) in (signals.get("valid_range") or {}).items():
        lo[name] = -math.inf if low is None else float(low)
        hi[name] = math.inf if high is None else float(high)
    return [lo[n] for n in u], [hi[n] for n in u], [lo[n] for n in y], [hi[n] for n in y]


class DiagnoserRuntime:
    """Per-sample diagnosis from a design dict (numpy only); semantics: docs/semantics.md."""

    def __init__(self, design: dict, *, checked: bool = False):
        # The one validation every entry point shares (raises DesignCheckError). ``checked=True``
        # is only for a caller that passes the very dict check_design has just accepted, unchanged
        # (validate_design, and Diagnoser/emit_design_c right after validate_design).
        if not checked:
            check_design(design)
        sig = design["signals"]
        self.u_names, self.y_names = list(sig["u"]), list(sig["y"])
        self.nu, self.ny = len(self.u_names), len(self.y_names)
        self._u_lo, self._u_hi, self._y_lo, self._y_hi = valid_ranges(sig)
        self._ranged = any(math.isfinite(b) for b in self._u_lo + self._u_hi + self._y_lo + self._y_hi)
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
        self._native = self.generator
        self._plans: dict[float, tuple] = {}  # exact h -> (1, generator, h/Ts), least recently used first
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
        self._ratio = ratio
        self._bind_stage()

    def _bind_stage(self) -> None:
        """Per group: (single residual index or -1, indices, evaluator, norm-based?, threshold)."""
        self._stage = [(g[0] if len(g) == 1 else -1, g, e, e.kind in MONOTONE, t)
                       for g, e, t in zip(self.groups, self.evaluators, self.thresholds)]
        # S1 in the hot path: with r, v and unorm finite, a finite evaluation J (and threshold
        # value) implies a finite evaluator state for every kind but these two, whose state
        # holds values J does not depend on (Narendra's re after the output, GLR's NaN-safe max)
        inner = [getattr(t, "u_eval", None) or getattr(t, "b_eval", None) for t in self.thresholds]
        self._hidden = [e for e in self.evaluators + [e for e in inner if e is not None]
                        if e.kind in ("narendra", "glr")]

    def _resolve(self, h, exact: bool = False):
        """The plan ``(substeps, generator, effective ratio)`` for step h, None for the current
        step (S3, docs/semantics.md §9); raises StepSizeError and changes nothing otherwise.
        ``exact``: no same-step tolerance (restoring a saved state)."""
        if isinstance(h, bool) or not isinstance(h, (int, float, np.integer, np.floating)):
            raise StepSizeError(f"communication step must be a positive finite number, got {h!r}")
        h = float(h)
        if not (math.isfinite(h) and h > 0):
            raise StepSizeError(f"communication step must be a positive finite number, got {h!r}")
        if h == self.h or (not exact and abs(h - self.h) <= STEP_RTOL * self.h):
            return None
        ratio = h / self.Ts
        if ratio > MAX_SUBSTEPS + 0.5:
            raise StepSizeError(f"step {h:g} s is {ratio:.6g} design sample times Ts = {self.Ts:g} s: more than "
                                f"{MAX_SUBSTEPS} sub-steps per call")
        k = round(ratio)
        if k >= 1 and abs(ratio - k) <= STEP_RTOL * k:
            if k > MAX_SUBSTEPS:
                raise StepSizeError(f"step {h:g} s = {k} Ts: more than {MAX_SUBSTEPS} sub-steps per call")
            return k, self._native, 1.0
        if self.cont is None or self.gen_spec.get("kind") != "lti":
            raise StepSizeError(
                f"step {h:g} s is not an integer multiple of the design sample time {self.Ts:g} s and the design "
                f"exists only in discrete time, so it cannot be re-discretised exactly")
        if not MIN_STEP_RATIO <= ratio <= MAX_SUBSTEPS:
            raise StepSizeError(f"step {h:g} s is not an integer multiple of the design sample time {self.Ts:g} s "
                                f"and outside the re-discretisation range [Ts/16, {MAX_SUBSTEPS} Ts] = "
                                f"[{self.Ts * MIN_STEP_RATIO:g}, {self.Ts * MAX_SUBSTEPS:g}] s")
        plan = self._plans.pop(h, None)  # a plain dict (the FMU state codec keeps it exactly)
        if plan is not None:
            self._plans[h] = plan  # most recently used last
            return plan
        try:
            for s, g in zip(self.eval_specs, self.groups):
                Evaluator(s, len(g)).resampled(ratio)
            for t, s in zip(self.thr_specs, self.eval_specs):
                Threshold(t, s).resampled(ratio, s)
            Ac = (np.asarray(self.cont["A"], float).reshape(len(self.cont["A"]), -1) if self.cont["A"]
                  else np.zeros((0, 0)))
            n = Ac.shape[0]
            D = np.atleast_2d(np.asarray(self.cont["D"], float))
            Bc = np.asarray(self.cont["B"], float).reshape(n, D.shape[1])
            Cc = np.asarray(self.cont["C"], float).reshape(D.shape[0], n)
            with np.errstate(all="ignore"):
                Ad, Bd = zoh(Ac, Bc, h)
            if not (np.all(np.isfinite(Ad)) and np.all(np.isfinite(Bd))):
                raise ValueError("the zero-order-hold discretisation is not finite")
            gen = make_generator({"kind": "lti", "A": Ad, "B": Bd, "C": Cc, "D": D})
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            raise StepSizeError(f"step {h:g} s differs from the design sample time {self.Ts:g} s: {exc}") from None
        plan = (1, gen, ratio)
        self._plans[h] = plan
        while len(self._plans) > CACHE_SIZE:
            del self._plans[next(iter(self._plans))]
        return plan

    def _adopt(self, h: float, plan) -> None:
        """Switch to a resolved plan (S4): the generator state carries over; evaluators and
        thresholds restart when the effective sample time changes; the decision is kept."""
        substeps, gen, ratio = plan
        if gen is not self.generator:
            gen.set_state(self.generator.get_state())  # LTI only here: same realisation, same x
            self.generator = gen
        if ratio != self._ratio:
            self._build_stage(ratio)
        self.h = float(h)
        self._substeps = substeps

    @property
    def sample_ratio(self) -> float:
        """The effective sample time of evaluation over Ts (1 when sub-stepping at Ts)."""
        return self._ratio

    def set_step(self, h: float) -> None:
        """Prepare for communication steps of size h (raises StepSizeError if impossible,
        leaving everything as it was). See docs/semantics.md §9."""
        plan = self._resolve(h)
        if plan is not None:
            self._adopt(h, plan)

    def set_threshold_scale(self, value) -> None:
        """Set the tunable ``threshold_scale`` (docs/semantics.md §6): a finite number >= 0, else
        ValueError and the scale kept."""
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ValueError(f"threshold_scale must be a finite number >= 0, got {value!r}")
        scale = float(value)
        if not (scale >= 0.0 and math.isfinite(scale)):
            raise ValueError(f"threshold_scale must be a finite number >= 0, got {scale!r}")
        self.threshold_scale = scale

    # ----------------------------------------------------------------- state
    def reset(self) -> None:
        self.generator = self._native
        self.generator.reset()
        self.h = self.Ts
        self._substeps = 1
        self._build_stage(1.0)
        self.decision.reset()
        self.outputs = [0.0] * len(self.names)
        self.n_samples = 0
        self.n_numeric_resets = 0

    def _restart_stages(self) -> None:
        """S1: generator, evaluators and thresholds back to their initial state (plan kept)."""
        self.generator.reset()
        for e in self.evaluators:
            e.reset()
        for t in self.thresholds:
            t.reset()

    def get_state(self) -> dict:
        return {"h": self.h, "generator": self.generator.get_state(),
                "evaluators": [e.get_state() for e in self.evaluators],
                "thresholds": [t.get_state() for t in self.thresholds],
                "decision": self.decision.get_state(), "outputs": list(self.outputs),
                "n_samples": self.n_samples, "n_numeric_resets": self.n_numeric_resets,
                "threshold_scale": self.threshold_scale}

    def set_state(self, s: dict) -> None:
        """Restore :meth:`get_state`; a state that does not fit this design (shapes, lengths,
        non-finite values) raises ValueError and leaves the runtime exactly as it was."""
        before = self.get_state()
        try:
            self._apply_state(s)
        except BaseException as exc:
            self._apply_state(before)
            if isinstance(exc, (ValueError, TypeError, KeyError, IndexError, AttributeError)):
                raise ValueError(f"runtime state does not fit this design: {type(exc).__name__}: {exc}") from None
            raise

    def _apply_state(self, s: dict) -> None:
        plan = self._resolve(s["h"], exact=True)
        if plan is not None:
            self._adopt(s["h"], plan)
        for what, items, objs in (("evaluator", s["evaluators"], self.evaluators),
                                  ("threshold", s["thresholds"], self.thresholds)):
            if len(items) != len(objs):
                raise ValueError(f"{len(items)} {what} states for {len(objs)} groups")
        outputs = [float(x) for x in s["outputs"]]
        if len(outputs) != len(self.names):
            raise ValueError(f"{len(outputs)} outputs, expected {len(self.names)}")
        scale = float(s["threshold_scale"])
        if not (scale >= 0 and math.isfinite(scale)):
            raise ValueError(f"threshold_scale must be finite and >= 0, got {scale!r}")
        self.generator.set_state(s["generator"])
        for e, es in zip(self.evaluators, s["evaluators"]):
            e.set_state(es)
        for t, ts in zip(self.thresholds, s["thresholds"]):
            t.set_state(ts)
        self.decision.set_state(s["decision"])
        self.outputs = outputs
        self.n_samples = int(s["n_samples"])
        self.n_numeric_resets = int(s.get("n_numeric_resets", 0))
        self.threshold_scale = scale
        if not (self._stages_finite() and all(map(math.isfinite, outputs))):
            raise ValueError("the state holds NaN or Inf values")
        self._check_counts_and_outputs()

    def _check_counts_and_outputs(self) -> None:
        """The counters and outputs of a restored state as a run leaves them (docs/semantics.md §10):
        counts below 2^53 (numeric resets at most one per sample); alarms, fault_detected and
        isolated_fault the decision's; the two flags 0 or 1; every evaluation >= 0."""
        out, dec = self.outputs, self.decision
        nr, ng = self.n_residuals, self.n_groups
        if not 0 <= self.n_numeric_resets <= self.n_samples < EXACT_MAX:
            raise ValueError(f"sample counters {self.n_samples} (numeric resets {self.n_numeric_resets}) out of range")
        alarms = [1.0 if a else 0.0 for a in dec.alarms]
        if (out[nr + 2 * ng:nr + 3 * ng] != alarms or out[FAULT_DETECTED] != (1.0 if any(alarms) else 0.0)
                or out[ISOLATED_FAULT] != float(dec.isolated) or out[INPUT_INVALID] not in (0.0, 1.0)
                or out[NUMERIC_RESET] not in (0.0, 1.0) or min(out[nr:nr + ng]) < 0.0):
            raise ValueError("the outputs do not fit the decision state (alarms, fault_detected, isolated_fault, "
                             "flags 0/1, evaluations >= 0)")

    def _stages_finite(self) -> bool:
        return (self.generator.finite() and all(e.finite() for e in self.evaluators)
                and all(t.finite() for t in self.thresholds))

    # ------------------------------------------------------------------ step
    def _sample(self, v, unorm: float) -> bool:
        """One sub-sample; False when a value is not finite (an overflow, §8): the decision has
        then stepped with :meth:`_overflow`'s raw tests and only the decision outputs changed."""
        rl, evals, thrs = None, [], []
        try:
            r = self.generator.step(v)
            rl = r.tolist()
            scale = self.threshold_scale
            for single, grp, ev, norm_based, thr in self._stage:
                if single >= 0:
                    x = rl[single]
                    evals.append(ev.step_sq(x * x) if norm_based else ev.step(r[grp]))
                elif norm_based:
                    evals.append(ev.step_sq(sum(rl[j] * rl[j] for j in grp)))
                else:
                    evals.append(ev.step(r[grp]))
                thrs.append(scale * thr.step(unorm))
        except ArithmeticError:  # e.g. an OverflowError of math.fsum: a non-finite value
            self._overflow(None, evals, thrs)
            return False
        isfinite = math.isfinite
        if not (all(map(isfinite, rl)) and all(map(isfinite, evals)) and all(map(isfinite, thrs))
                and self.generator.finite() and (not self._hidden or all(e.finite() for e in self._hidden))):
            self._overflow(rl, evals, thrs)
            return False
        dec = self.decision
        dec.step(evals, thrs, rl)
        out = self.outputs
        nr, ng = self.n_residuals, self.n_groups
        out[:nr] = rl
        out[nr:nr + ng] = evals
        out[nr + ng:nr + 2 * ng] = thrs
        self._decision_outputs()
        return True

    def _overflow(self, rl, evals, thrs) -> None:
        """The decision step of an overflowed sub-sample (docs/semantics.md §8): group g's raw
        test fires if its evaluation overflowed (a residual of the group, its evaluation J_g or
        its evaluator's state not finite; every group if the generator state or the sample
        offsets are not finite), else it is J_g >= threshold_g as computed; the residual
        direction is unknown. Only the decision outputs change."""
        isfinite = math.isfinite
        if rl is None or len(evals) < self.n_groups or not self.generator.finite():
            fired = [True] * self.n_groups
        else:
            fired = [not (isfinite(e) and all(isfinite(rl[j]) for j in grp) and ev.finite()) or e >= t
                     for (_, grp, ev, _, _), e, t in zip(self._stage, evals, thrs)]
        self.decision.step_fired(fired, None)
        self._decision_outputs()

    def _decision_outputs(self) -> None:
        dec, out = self.decision, self.outputs
        nr, ng = self.n_residuals, self.n_groups
        alarms = dec.alarms
        out[nr + 2 * ng:nr + 3 * ng] = [1.0 if a else 0.0 for a in alarms]
        out[FAULT_DETECTED] = 1.0 if True in alarms else 0.0
        out[ISOLATED_FAULT] = float(dec.isolated)

    def _valid(self, u: list, y: list) -> bool:
        isfinite = math.isfinite
        if not self._ranged:
            return all(map(isfinite, u)) and all(map(isfinite, y))
        return (all(isfinite(x) and lo <= x <= hi for x, lo, hi in zip(u, self._u_lo, self._u_hi))
                and all(isfinite(x) and lo <= x <= hi for x, lo, hi in zip(y, self._y_lo, self._y_hi)))

    def advance(self, u, y, h: float | None = None) -> list:
        """Diagnose the sample (u, y) over a communication step h (default: the current one,
        initially Ts). Returns the outputs (a new list, in the order of :attr:`names`).

        Raises StepSizeError for a step it cannot serve and ValueError for signal vectors of
        the wrong length; in both cases nothing has changed.
        """
        u, y = sample_signals(u, y, self.nu, self.ny)
        if h is not None and h != self.h:
            self.set_step(h)
        out = self.outputs
        out[NUMERIC_RESET] = 0.0
        if not self._valid(u, y):
            out[INPUT_INVALID] = 1.0
            return list(out)
        out[INPUT_INVALID] = 0.0
        du = [a - b for a, b in zip(u, self._u0)]  # Python floats: overflow gives inf, never raises
        v = [a - b for a, b in zip(y, self._y0)] + du
        unorm = math.sqrt(sum(d * d for d in du))
        ok = all(map(math.isfinite, v)) and math.isfinite(unorm)
        if ok:
            for _ in range(self._substeps):
                if not self._sample(v, unorm):
                    ok = False
                    break
        else:
            self._overflow(None, [], [])
        if not ok:  # §8: an overflow is fault evidence (its raw tests fired) and an unusable sample
            self._restart_stages()
            out[NUMERIC_RESET] = 1.0
            out[INPUT_INVALID] = 1.0
            self.n_numeric_resets += 1
        self.n_samples += 1
        return list(out)

    def step(self, u, y) -> list:
        return self.advance(u, y, None)
