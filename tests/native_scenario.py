"""Conformance scenarios: operation sequences run on the Python runtime and on the native one.

A scenario is a list of operations (JSON-ready):

- ``["step", u, y, h]``: one call with plant inputs u, outputs y and communication step h;
- ``["save", slot]`` / ``["restore", slot]``: FMU state get / set (roll-back);
- ``["reset"]``: back to the initial state (the FMU: fmi2Reset and initialisation again);
- ``["scale", s]``: set the tunable parameter threshold_scale.

Each runner returns one entry per step: the outputs (list) or ``"discard"`` when the step
was refused. ``python_outputs`` is the reference (``Diagnoser`` / ``DiagnoserRuntime``).
"""
import copy
import math

import numpy as np

from fmu_fdi.diagnoser import Diagnoser
from fmu_fdi.runtime.engine import DiagnoserRuntime, StepSizeError

Real, Boolean, Integer = "Real", "Boolean", "Integer"


def make_scenario(design, rng, n_steps=3000, steps=None, scale=None):
    """Random inputs around the operating point with NaN/Inf bursts, out-of-range and overflowing
    samples (numeric reset), threshold_scale changes, resets and roll-backs; ``steps``: a list of
    communication steps to draw h from (default: Ts only); ``scale``: the input amplitude
    (default :func:`input_scale`)."""
    sig = design["signals"]
    nu, ny = len(sig["u"]), len(sig["y"])
    op = design.get("operating_point") or {}
    u0 = np.asarray(op.get("u", [0.0] * nu), float)
    y0 = np.asarray(op.get("y", [0.0] * ny), float)
    Ts = float(design["generator"]["dt"])
    steps = steps or [Ts]
    u_scale = y_scale = input_scale(design, rng) if scale is None else scale
    ops, saved, burst = [], set(), 0
    h_now = Ts
    for k in range(n_steps):
        u = u0 + u_scale * rng.standard_normal(nu)
        y = y0 + y_scale * rng.standard_normal(ny)
        if burst > 0:  # NaN burst in one signal
            burst -= 1
            (y if ny and rng.random() < 0.7 else u if nu else y)[0] = math.nan
        r = rng.random()
        if r < 0.01:
            burst = int(rng.integers(1, 6))
        elif r < 0.015:
            y[int(rng.integers(ny))] = math.inf if rng.random() < 0.5 else -math.inf
        elif r < 0.02:
            y[int(rng.integers(ny))] = 1e300 * (1 if rng.random() < 0.5 else -1)  # squares overflow: S1
        elif r < 0.025 and nu:
            u[int(rng.integers(nu))] = 1e200
        elif r < 0.03 and nu:
            u[nu - 1] = u0[nu - 1] + 3.5  # outside a valid range where one is set
        h = h_now
        if rng.random() < 0.03:  # a new step size: kept if it is served, one call only if refused
            h = steps[int(rng.integers(len(steps)))]
            if python_step_ok(design, h):
                h_now = h
        ops.append(["step", u.tolist(), y.tolist(), h])
        r = rng.random()
        if r < 0.01:
            slot = int(rng.integers(3))
            ops.append(["save", slot])
            saved.add(slot)
        elif r < 0.02 and saved:
            ops.append(["restore", sorted(saved)[int(rng.integers(len(saved)))]])
        elif r < 0.023:
            ops.append(["reset"])
        elif r < 0.03:
            ops.append(["scale", float(rng.choice([0.0, 0.5, 1.0, 1.0, 2.0, 7.0]))])
    return ops


def input_scale(design, rng, n=300):
    """Input amplitude that puts the evaluations near their thresholds (alarms rise and fall):
    1 / the median ratio J / J_th over a pilot run with unit amplitude."""
    rt = DiagnoserRuntime(design)
    op = design.get("operating_point") or {}
    u0 = np.asarray(op.get("u", [0.0] * rt.nu), float)
    y0 = np.asarray(op.get("y", [0.0] * rt.ny), float)
    nr, ng = rt.n_residuals, rt.n_groups
    ratios = []
    for k in range(n):
        out = rt.advance(u0 + rng.standard_normal(rt.nu), y0 + rng.standard_normal(rt.ny))
        if k >= n // 3:
            ratios.extend(e / t for e, t in zip(out[nr:nr + ng], out[nr + ng:nr + 2 * ng]) if t > 0)
    med = float(np.median(ratios)) if ratios else 1.0
    return 1.0 / med if med > 0 and math.isfinite(med) else 1.0


def python_step_ok(design, h):
    """Whether a fresh Python runtime serves step h (to keep refused steps one-offs)."""
    try:
        DiagnoserRuntime(design).set_step(h)
    except StepSizeError:
        return False
    return True


def python_outputs(design, ops, runtime=None):
    """The reference: the Python runtime of ``Diagnoser.from_design`` (or ``runtime``, e.g. a
    scheduled one) on the operations."""
    rt = Diagnoser.from_design(design).runtime if runtime is None else runtime
    saved, out = {}, []
    for op in ops:
        if op[0] == "step":
            try:
                out.append(list(rt.advance(op[1], op[2], op[3])))
            except StepSizeError:
                out.append("discard")
        elif op[0] == "save":
            saved[op[1]] = copy.deepcopy(rt.get_state())
        elif op[0] == "restore":
            rt.set_state(copy.deepcopy(saved[op[1]]))
        elif op[0] == "reset":
            rt.reset()
        elif op[0] == "scale":
            rt.threshold_scale = float(op[1])
    return out


def compare(names, types, ref, got, rtol=1e-12):
    """Largest deviation |a - b| / max(1, |a|) over the Real outputs (docs/semantics.md: relative to
    the size of each output, absolute below 1); Boolean and Integer outputs and refused steps must
    agree exactly. Returns (max deviation, list of mismatch descriptions)."""
    worst, bad = 0.0, []
    assert len(ref) == len(got), f"{len(ref)} reference steps, {len(got)} native"
    for k, (a, b) in enumerate(zip(ref, got)):
        if a == "discard" or b == "discard":
            if a != b:
                bad.append(f"step {k}: python {a if a == 'discard' else 'ok'}, native {b if b == 'discard' else 'ok'}")
            continue
        for name, typ, x, z in zip(names, types, a, b):
            if typ == Real:
                dev = abs(x - z) / max(1.0, abs(x))
                worst = max(worst, dev)
                if not dev <= rtol:
                    bad.append(f"step {k} {name}: python {x!r}, native {z!r} (deviation {dev:.3g})")
            elif float(x) != float(z):
                bad.append(f"step {k} {name}: python {x!r}, native {z!r}")
        if len(bad) > 10:
            break
    return worst, bad
