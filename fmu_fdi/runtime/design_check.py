"""The one validation of a design dict (``fmu-fdi-design/1``), with explicit ranges.

Every entry point runs this routine: :class:`.engine.DiagnoserRuntime` calls it first
in its constructor, so ``Diagnoser``/``Diagnoser.load``, ``fmu-fdi build``, the CLI and
the diagnostic FMU (which bundles this package) accept and refuse exactly the same
designs. :func:`fmu_fdi.designfile.validate_design` adds the checks that need the full
toolkit (the embedded model) and turns the error into a ``DesignFileError``.

Rules (docs/design-file.md lists them with the keys):

- every value has its JSON type: no string or Boolean where a number belongs, no
  number where a name belongs; unknown keys are refused (typos cannot pass silently);
- numbers are finite with ``|x| <= 1e150`` (:data:`.schema.MAX_ABS`);
- windows (``rms``, ``peak``, ``chi2``, ``glr``), the persistence ``[k, n]`` and the
  number of majorant taps are integers in ``[1, 100000]`` (:data:`MAX_SAMPLES`): they
  size buffers allocated at instantiation, so the C runtime may rely on the bound;
- every parameter whose zero, NaN or infinity would switch detection off is refused:
  CUSUM ``delta`` > 0, whitening ``sigma`` > 0 or a nonsingular ``W``, Narendra
  ``alpha + beta`` > 0, thresholds finite and reachable (:func:`check_reachable`: no threshold
  above the largest evaluation its evaluator can produce); forgetting factors in their open ranges;
- shapes agree: the generator reads ``ny + nu`` signals, the groups partition its
  residuals, one evaluation per group, a structure matrix of groups × faults;
- ``generator.discrete.dt`` (when written) equals ``generator.dt``;
- ``generator.continuous`` (when written) is the same filter: ``generator.discrete`` is its
  zero-order hold at ``dt`` (same order, same coordinates, to :data:`ZOH_RTOL`).
"""
from __future__ import annotations

import math
import re
import sys

import numpy as np

from . import schema as S
from .expm import zoh

FORMAT = "fmu-fdi-design/1"
#: windows, persistence and tap counts: integers in [1, MAX_SAMPLES] (semantics decision S5)
MAX_SAMPLES = 100_000
#: counters without memory cost (RLS skip/warmup/reset period): a C ``int``
MAX_COUNT = 2**31 - 1
#: names the FMU uses for its own variables (active_member: a scheduled design's, docs/semantics.md
#: §12, whose members are plain designs); a signal may not take them
RESERVED = re.compile(r"^(residual|evaluation|threshold|alarm)_\d+$|^(fault_detected|isolated_fault|input_invalid|"
                      r"numeric_reset|threshold_scale|active_member)$")

_TOP_REQUIRED = ("format", "name", "signals", "generator", "evaluation", "decision", "faults")
_TOP_ALLOWED = set(_TOP_REQUIRED) | {"units", "operating_point", "model", "created_by", "description", "report"}
_GEN_REQUIRED = ("method", "dt", "discrete", "groups", "residual_names")
_GEN_ALLOWED = set(_GEN_REQUIRED) | {"continuous", "info"}
_EVALUATOR_KEYS = {"norm": set(), "rms": {"window"}, "ewrms": {"lambda"}, "peak": {"window"},
                   "narendra": {"alpha", "beta", "gamma"}, "chi2": {"window", "W", "sigma"},
                   "cusum": {"delta", "W", "sigma"}, "glr": {"window", "W", "sigma"}}
_MONOTONE = ("norm", "rms", "ewrms", "peak", "narendra")
_THRESHOLD_KEYS = {"fixed": {"value"}, "adaptive": {"J0", "a", "evaluation"}, "majorant": {"J0", "taps", "tail"}}
_RLS_KEYS = {"kind", "version", "dt", "n_inputs", "forgetting", "P0", "reset", "noise_forgetting", "sigma_clip",
             "sigma_rel", "estimators"}
_RLS_EST_KEYS = {"output", "inputs", "A", "B", "C", "D", "theta0", "scale", "names", "skip", "warmup",
                 "sigma_floor", "trace_max", "trace_min"}


class DesignCheckError(ValueError):
    """A design dict breaks a rule of :mod:`.design_check`; the message names the item."""


E = DesignCheckError


def check_design(d, source: str = "design") -> dict:
    """Check a design dict against the schema and its ranges; return it unchanged.

    Raises
    ------
    DesignCheckError
        One line naming the key and the rule, prefixed by ``source``.
    """
    S.check_format(d, FORMAT, source, E, "design format")
    S.check_depth(d, source, E)
    S.check_keys(d, _TOP_REQUIRED, _TOP_ALLOWED, source, E)
    S.text(d["name"], f"{source}: name", E)
    for key in ("created_by", "description"):
        if key in d:
            S.text(d[key], f"{source}: {key}", E, empty=True)
    if "report" in d:
        S.table(d["report"], f"{source}: report", E)
    if "model" in d:
        S.table(d["model"], f"{source}: model", E)
    nu, ny, signals = _signals(d, source)
    faults = _faults(d["faults"], f"{source}: faults")
    nr, groups = _generator(S.table(d["generator"], f"{source}: generator", E), f"{source}: generator", ny + nu)
    ev = S.array(d["evaluation"], f"{source}: evaluation", E)
    if len(ev) != len(groups):
        raise E(f"{source}: evaluation must list one entry per residual group ({len(groups)}), got {len(ev)}")
    for i, entry in enumerate(ev):
        where = f"{source}: evaluation[{i}]"
        S.check_keys(S.table(entry, where, E), ("evaluator", "threshold"), ("evaluator", "threshold"), where, E)
        evaluator = check_evaluator(entry["evaluator"], f"{where}.evaluator", len(groups[i]))
        check_threshold(entry["threshold"], f"{where}.threshold", evaluator)
        check_reachable(entry["threshold"], f"{where}.threshold", evaluator)
    _decision(S.table(d["decision"], f"{source}: decision", E), f"{source}: decision", len(groups), len(faults), nr)
    return d


# ----------------------------------------------------------------- signals
def _signals(d: dict, source: str) -> tuple[int, int, list[str]]:
    sig = S.table(d["signals"], f"{source}: signals", E)
    S.check_keys(sig, ("u", "y"), ("u", "y", "valid_range"), f"{source}: signals", E)
    u = S.names(sig["u"], f"{source}: signals.u", E)
    y = S.names(sig["y"], f"{source}: signals.y", E)
    if not y:
        raise E(f"{source}: signals.y must name at least one measured output")
    both = u + y
    if len(set(both)) != len(both):
        raise E(f"{source}: signal names must be distinct, {sorted(set(u) & set(y))} are both input and output")
    bad = [s for s in both if not S.SIGNAL_NAME.match(s)]
    if bad:
        raise E(f"{source}: signal names {bad} are not valid variable names (letters, digits, '_'; an array "
                f"element 'y[2]')")
    clash = [s for s in both if RESERVED.match(s)]
    if clash:
        raise E(f"{source}: signal names {clash} collide with the diagnostic FMU's own variable names")
    if sig.get("valid_range") is not None:  # S2 (docs/semantics.md); engine.valid_ranges only converts
        rng = sig["valid_range"]
        where = f"{source}: signals.valid_range"
        if not isinstance(rng, dict):
            raise E(f"{where} must map signal names to [lo, hi], got {type(rng).__name__}")
        for name, pair in rng.items():
            if name not in both:
                raise E(f"{where} names {name!r}, which is not a signal (u: {u}, y: {y})")
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise E(f"{where}[{name!r}] must be [lo, hi], got {pair!r}")
            for side, v in zip(("lo", "hi"), pair):
                if v is not None and not _finite_number(v):
                    raise E(f"{where}[{name!r}] {side} must be a finite number or null, got {S.type_name(v)}")
            if None not in pair and not pair[0] <= pair[1]:
                raise E(f"{where}[{name!r}] needs lo <= hi, got [{pair[0]!r}, {pair[1]!r}]")
    if "units" in d:
        for name, unit in S.table(d["units"], f"{source}: units", E).items():
            S.text(unit, f"{source}: units.{name}", E, empty=True)
    op = d.get("operating_point")
    if op is not None:
        S.check_keys(S.table(op, f"{source}: operating_point", E), (), ("u", "y"), f"{source}: operating_point", E)
        if "u" in op:
            S.vector(op["u"], f"{source}: operating_point.u", E, size=len(u))
        if "y" in op:
            S.vector(op["y"], f"{source}: operating_point.y", E, size=len(y))
    return len(u), len(y), both


def _finite_number(v) -> bool:
    try:
        return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
    except OverflowError:  # an integer beyond the float range
        return False


def _faults(value, where: str) -> list[str]:
    out = []
    for i, f in enumerate(S.array(value, where, E)):
        w = f"{where}[{i}]"
        S.check_keys(S.table(f, w, E), ("name",), ("name", "kind", "description"), w, E)
        out.append(S.text(f["name"], f"{w}.name", E))
        for key in ("kind", "description"):
            if key in f:
                S.text(f[key], f"{w}.{key}", E, empty=True)
    if len(set(out)) != len(out):
        raise E(f"{where}: fault names must be distinct, got {out}")
    return out


# --------------------------------------------------------------- generator
def _lti(spec, where: str, n_in: int, extra=()) -> int:
    """A, B, C, D of ``x+ = A x + B v``, ``r = C x + D v`` with v of size n_in; returns rows of D."""
    S.check_keys(S.table(spec, where, E), ("A", "B", "C", "D"), {"A", "B", "C", "D", *extra}, where, E)
    A = S.matrix(spec["A"], f"{where}.A", E)
    n = len(A)
    if A and len(A[0]) != n:
        raise E(f"{where}.A must be square, got {n}x{len(A[0])}")
    D = S.matrix(spec["D"], f"{where}.D", E, cols=n_in)
    p = len(D)
    if p == 0:
        raise E(f"{where}.D has no rows: the generator has no residual")
    S.matrix(spec["B"], f"{where}.B", E, rows=n, cols=n_in)
    S.matrix(spec["C"], f"{where}.C", E, rows=p, cols=n)
    return p


#: largest relative difference between generator.discrete and the zero-order hold of
#: generator.continuous at dt: two Padé/scaling-and-squaring exponentials of the same matrix
#: agree to ~1e-13 relative (n·eps·||A h|| growth), so 1e-8 only refuses realisations that are
#: not the same filter (another order, other coordinates, an edited matrix)
ZOH_RTOL = 1e-8


def _zoh_consistent(cont: dict, disc: dict, dt: float, where: str) -> None:
    """``generator.discrete`` must be the zero-order hold of ``generator.continuous`` at ``dt`` in
    the same coordinates: a step of another size re-discretises the continuous one and carries
    the discrete state over (docs/semantics.md), which only means something if they agree."""
    n_c, n_d = len(cont["A"]), len(disc["A"])
    if n_c != n_d:
        raise E(f"{where}.continuous has order {n_c} but generator.discrete has order {n_d}: a step of another "
                f"size could not carry the state over; re-design instead of editing one of them")
    if n_c == 0:
        pairs = [("D", cont["D"], disc["D"])]
    else:
        Ac = np.asarray(cont["A"], float)
        Bc = np.asarray(cont["B"], float)
        with np.errstate(all="ignore"):
            try:
                Ad, Bd = zoh(Ac, Bc, dt)
            except (np.linalg.LinAlgError, ValueError):
                raise E(f"{where}.continuous: its zero-order hold at dt = {dt!r} cannot be computed") from None
        pairs = [("A", Ad, disc["A"]), ("B", Bd, disc["B"]), ("C", cont["C"], disc["C"]), ("D", cont["D"], disc["D"])]
    for key, want, got in pairs:
        want, got = np.asarray(want, float), np.asarray(got, float)
        scale = max(1.0, float(np.max(np.abs(want), initial=0.0)))
        err = float(np.max(np.abs(want - got), initial=0.0))
        if not err <= ZOH_RTOL * scale:
            raise E(f"{where}.discrete.{key} is not the zero-order hold of {where}.continuous at dt = {dt!r} "
                    f"(largest difference {err:.3g}, allowed {ZOH_RTOL * scale:.3g}): the two realisations are not "
                    f"the same filter; re-design instead of editing one of them")


def _generator(g: dict, where: str, n_in: int) -> tuple[int, list[list[int]]]:
    S.check_keys(g, _GEN_REQUIRED, _GEN_ALLOWED, where, E)
    S.text(g["method"], f"{where}.method", E)
    dt = S.real(g["dt"], f"{where}.dt", E)
    if dt <= 0:
        raise E(f"{where}.dt must be a positive sample time, got {dt!r}")
    disc = S.table(g["discrete"], f"{where}.discrete", E)
    kind = disc.get("kind")
    if kind == "lti":
        nr = _lti(disc, f"{where}.discrete", n_in, extra=("kind", "dt"))
    elif kind == "rls":
        nr = _rls(disc, f"{where}.discrete", n_in)
    else:
        raise E(f"{where}.discrete.kind must be 'lti' or 'rls', got {S.type_name(kind)}")
    if "dt" in disc:
        ddt = S.real(disc["dt"], f"{where}.discrete.dt", E, lo=0.0, lo_open=True)
        if abs(ddt - dt) > 1e-12 * dt:
            raise E(f"{where}.dt = {dt!r} differs from the sample time {ddt!r} the discrete generator was "
                    f"computed for (generator.discrete.dt): re-design instead of editing dt")
    if g.get("continuous") is not None:
        if kind != "lti":
            raise E(f"{where}.continuous is only meaningful for an 'lti' generator")
        if _lti(g["continuous"], f"{where}.continuous", n_in) != nr:
            raise E(f"{where}.continuous has a different number of residuals than generator.discrete ({nr})")
        _zoh_consistent(g["continuous"], disc, dt, where)
    names = S.names(g["residual_names"], f"{where}.residual_names", E)
    if len(names) != nr:
        raise E(f"{where}: {len(names)} residual names for {nr} residuals")
    groups = S.array(g["groups"], f"{where}.groups", E)
    flat = []
    for i, grp in enumerate(groups):
        members = S.array(grp, f"{where}.groups[{i}]", E)
        if not members:
            raise E(f"{where}.groups[{i}] is empty")
        flat += [S.integer(j, f"{where}.groups[{i}][{k}]", E, 0, max(nr - 1, 0)) for k, j in enumerate(members)]
    if sorted(flat) != list(range(nr)):
        raise E(f"{where}.groups must partition the residuals 0..{nr - 1} (each in exactly one group), got {groups}")
    if "info" in g and g["info"] is not None:
        S.table(g["info"], f"{where}.info", E)
    return nr, [list(map(int, grp)) for grp in groups]


def _rls(spec: dict, where: str, n_in: int) -> int:
    """Types and ranges of an RLS spec; fmu_fdi/runtime/rls.py checks the remaining relations."""
    S.check_keys(spec, ("kind", "n_inputs", "forgetting", "P0", "estimators"), _RLS_KEYS, where, E)
    if S.integer(spec["n_inputs"], f"{where}.n_inputs", E, 1, MAX_COUNT) != n_in:
        raise E(f"{where}.n_inputs = {spec['n_inputs']} but the design lists {n_in} signals (outputs + inputs)")
    S.real(spec["forgetting"], f"{where}.forgetting", E, lo=0.0, hi=1.0, lo_open=True)
    S.real(spec["P0"], f"{where}.P0", E, lo=0.0, lo_open=True)
    if "noise_forgetting" in spec:
        S.real(spec["noise_forgetting"], f"{where}.noise_forgetting", E, lo=0.0, hi=1.0, lo_open=True)
    for key in ("sigma_clip", "sigma_rel"):
        if key in spec:
            S.real(spec[key], f"{where}.{key}", E, lo=0.0)
    if "version" in spec:
        S.integer(spec["version"], f"{where}.version", E, 1, 1)
    if "reset" in spec and spec["reset"] is not None:
        reset = S.table(spec["reset"], f"{where}.reset", E)
        S.check_keys(reset, (), ("policy", "period"), f"{where}.reset", E)
        if "policy" in reset:
            S.text(reset["policy"], f"{where}.reset.policy", E)
        if "period" in reset:
            S.integer(reset["period"], f"{where}.reset.period", E, 0, MAX_COUNT)
    ests = S.array(spec["estimators"], f"{where}.estimators", E)
    if not ests:
        raise E(f"{where}.estimators must list at least one estimator")
    nr = 0
    for i, est in enumerate(ests):
        w = f"{where}.estimators[{i}]"
        S.check_keys(S.table(est, w, E), ("inputs", "A", "B", "C", "D", "theta0"), _RLS_EST_KEYS, w, E)
        inputs = S.array(est["inputs"], f"{w}.inputs", E)
        if not inputs:
            raise E(f"{w}.inputs must list at least one signal index")
        for k, j in enumerate(inputs):
            S.integer(j, f"{w}.inputs[{k}]", E, 0, n_in - 1)
        npar = len(S.vector(est["theta0"], f"{w}.theta0", E))
        if npar == 0:
            raise E(f"{w}.theta0 must hold at least one parameter")
        A = S.matrix(est["A"], f"{w}.A", E)
        nx = len(A)
        S.matrix(est["A"], f"{w}.A", E, rows=nx, cols=nx)
        S.matrix(est["B"], f"{w}.B", E, rows=nx, cols=len(inputs))
        S.matrix(est["C"], f"{w}.C", E, rows=npar + 1, cols=nx)
        S.matrix(est["D"], f"{w}.D", E, rows=npar + 1, cols=len(inputs))
        if "scale" in est:
            S.vector(est["scale"], f"{w}.scale", E, size=npar, lo=0.0, lo_open=True)
        for key in ("skip", "warmup"):
            if key in est:
                S.integer(est[key], f"{w}.{key}", E, 0, MAX_COUNT)
        for key in ("sigma_floor", "trace_min"):
            if key in est:
                S.real(est[key], f"{w}.{key}", E, lo=0.0)
        if "trace_max" in est:
            S.real(est["trace_max"], f"{w}.trace_max", E, lo=0.0, lo_open=True)
        if "output" in est:
            S.text(est["output"], f"{w}.output", E)
        if "names" in est:
            S.names(est["names"], f"{w}.names", E)
        nr += npar
    return nr


# -------------------------------------------------------------- evaluation
def _whitening(spec: dict, where: str, dim: int) -> None:
    if "W" in spec and "sigma" in spec:
        raise E(f"{where}: give either W or sigma, not both")
    if "W" in spec:
        W = np.array(S.matrix(spec["W"], f"{where}.W", E, rows=dim, cols=dim), dtype=float).reshape(dim, dim)
        s = np.linalg.svd(W, compute_uv=False)
        # rank with the usual tolerance relative to the largest singular value
        if dim and not s[-1] > dim * np.finfo(float).eps * s[0]:
            raise E(f"{where}.W must be nonsingular (a whitening matrix), smallest/largest singular value "
                    f"{s[-1]:.3g}/{s[0]:.3g}")
    elif "sigma" in spec:
        sig = spec["sigma"]
        if isinstance(sig, (list, tuple)):
            S.vector(sig, f"{where}.sigma", E, size=dim, lo=0.0, lo_open=True)
        else:
            S.real(sig, f"{where}.sigma", E, lo=0.0, lo_open=True)


def _kind(spec, where: str, what: str, keys: dict) -> str:
    """The spec is an object with a known ``kind`` and only that kind's keys."""
    S.table(spec, where, E)
    kind = spec.get("kind")
    if not isinstance(kind, str) or kind not in keys:
        raise E(f"{where}: unknown {what} kind {S.type_name(kind)}; use one of {tuple(keys)}")
    S.check_keys(spec, ("kind",), {"kind"} | keys[kind], where, E)
    return kind


def check_evaluator(spec, where: str, dim: int) -> dict:
    """One evaluation function for a residual group of dimension ``dim``; returns the spec."""
    kind = _kind(spec, where, "evaluation", _EVALUATOR_KEYS)
    if "window" in spec:
        S.integer(spec["window"], f"{where}.window", E, 1, MAX_SAMPLES)
    if kind == "ewrms":
        if "lambda" not in spec:
            raise E(f"{where}: ewrms needs its forgetting factor 'lambda'")
        S.real(spec["lambda"], f"{where}.lambda", E, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    if kind == "narendra":
        alpha = S.real(spec.get("alpha", 0.0), f"{where}.alpha", E, lo=0.0)
        beta = S.real(spec.get("beta", 1.0), f"{where}.beta", E, lo=0.0)
        S.real(spec.get("gamma", 0.9), f"{where}.gamma", E, lo=0.0, hi=1.0, hi_open=True)
        if not alpha + beta > 0:
            raise E(f"{where}: narendra needs alpha + beta > 0 (with both zero the evaluation is always 0)")
    if kind == "cusum":
        S.real(spec.get("delta", 1.0), f"{where}.delta", E, lo=0.0, lo_open=True)
    if kind in ("chi2", "cusum", "glr"):
        _whitening(spec, where, dim)
    return spec


def check_threshold(spec, where: str, evaluator: dict) -> None:
    """One threshold; ``evaluator`` is the (checked) evaluation of the same group."""
    kind = _kind(spec, where, "threshold", _THRESHOLD_KEYS)
    if kind == "fixed":
        if "value" not in spec:
            raise E(f"{where}: a fixed threshold needs 'value'")
        # only compared, never multiplied: any finite value (a probe design uses 1e300)
        S.real(spec["value"], f"{where}: fixed threshold value", E, lo=0.0, limit=math.inf)
        return
    S.real(spec.get("J0", 0.0), f"{where}.J0", E, lo=0.0, limit=math.inf)
    if evaluator.get("kind") not in _MONOTONE:
        raise E(f"{where}: an {kind} threshold needs a norm-based evaluation ({', '.join(_MONOTONE)}) of the "
                f"residual, not {evaluator.get('kind')!r}")
    if kind == "adaptive":
        if "a" not in spec:
            raise E(f"{where}: an adaptive threshold needs its gain 'a'")
        S.real(spec["a"], f"{where}.a", E, lo=0.0)
        u_eval = check_evaluator(spec.get("evaluation", evaluator), f"{where}.evaluation", 1)
        if u_eval["kind"] not in _MONOTONE:
            raise E(f"{where}.evaluation must be norm-based ({', '.join(_MONOTONE)}), not {u_eval['kind']!r}")
    else:
        if "taps" not in spec:
            raise E(f"{where}: a majorant threshold needs 'taps'")
        taps = S.array(spec["taps"], f"{where}.taps", E)
        if not 1 <= len(taps) <= MAX_SAMPLES:
            raise E(f"{where}.taps must hold between 1 and {MAX_SAMPLES} numbers, got {len(taps)}")
        S.vector(taps, f"{where}.taps", E, lo=0.0)
        S.real(spec.get("tail", 0.0), f"{where}.tail", E, lo=0.0)


#: the largest evaluation a norm-based kind can give: it squares the residual, and a square
#: that overflows is an overflow (docs/semantics.md §8), not an evaluation
NORM_EVALUATION_MAX = math.sqrt(sys.float_info.max)  # 1.34e154


def evaluation_max(evaluator: dict) -> float:
    """The largest finite evaluation J the (checked) ``evaluator`` can produce: sqrt(DBL_MAX) for
    norm, rms, ewrms and peak (each is the square root of a finite square or mean of squares);
    (alpha + beta / (1 - gamma)) sqrt(DBL_MAX) for narendra (re sums x gamma^j); DBL_MAX for the
    statistical tests (sums of whitened squares, CUSUM and GLR statistics)."""
    kind = evaluator["kind"]
    if kind in ("norm", "rms", "ewrms", "peak"):
        return NORM_EVALUATION_MAX
    if kind == "narendra":
        alpha, beta, gamma = (float(evaluator.get(k, v)) for k, v in (("alpha", 0.0), ("beta", 1.0), ("gamma", 0.9)))
        return min(sys.float_info.max, (alpha + beta / (1.0 - gamma)) * NORM_EVALUATION_MAX)
    return sys.float_info.max


def check_reachable(spec: dict, where: str, evaluator: dict) -> None:
    """A group must be able to alarm: its threshold's least value at threshold_scale 1 (fixed:
    ``value``; adaptive, majorant: ``J0``) may not exceed the largest evaluation its evaluator can
    produce (:func:`evaluation_max`). A threshold beyond is no threshold: only an overflow (§8)
    could raise that alarm, and the design would pass as a detector that never detects."""
    least = float(spec["value"] if spec["kind"] == "fixed" else spec.get("J0", 0.0))
    top = evaluation_max(evaluator)
    if least > top:
        raise E(f"{where}: {spec['kind']} threshold {least:g} can never be reached: a {evaluator['kind']} evaluation "
                f"is at most {top:.3g} (larger values overflow), so this group could never alarm; give a threshold "
                f"from the design's noise and fault sizes (fmu-fdi design --threshold)")


# ---------------------------------------------------------------- decision
def _decision(dec: dict, where: str, n_groups: int, n_faults: int, n_residuals: int) -> None:
    S.check_keys(dec, (), ("persistence", "latch", "isolation", "structure", "directions", "min_margin"), where, E)
    if "persistence" in dec:
        pers = S.array(dec["persistence"], f"{where}.persistence", E)
        if len(pers) != 2:
            raise E(f"{where}.persistence must be [k, n], got {len(pers)} entries")
        k = S.integer(pers[0], f"{where}.persistence k", E, 1, MAX_SAMPLES)
        n = S.integer(pers[1], f"{where}.persistence n", E, 1, MAX_SAMPLES)
        if k > n:
            raise E(f"{where}.persistence must be [k, n] with k <= n, got [{k}, {n}]")
    if "latch" in dec:
        S.flag(dec["latch"], f"{where}.latch", E)
    mode = dec.get("isolation", "none")
    if mode not in ("structure", "direction", "none"):
        raise E(f"{where}.isolation must be 'structure', 'direction' or 'none', got {S.type_name(mode)}")
    if mode == "structure":
        if "structure" not in dec:
            raise E(f"{where}: isolation 'structure' needs the structure matrix")
        rows = S.matrix(dec["structure"], f"{where}.structure", E, rows=n_groups, cols=n_faults)
        if any(x not in (0.0, 1.0) for row in rows for x in row):
            raise E(f"{where}.structure must hold only 0 and 1")
    if mode == "direction":
        if "directions" not in dec:
            raise E(f"{where}: isolation 'direction' needs the fault directions")
        D = S.matrix(dec["directions"], f"{where}.directions", E, rows=n_residuals, cols=n_faults)
        if not any(x != 0 for row in D for x in row):
            raise E(f"{where}.directions: every fault direction is zero, nothing to isolate by direction")
        S.real(dec.get("min_margin", 0.1), f"{where}.min_margin", E, lo=0.0, hi=math.pi / 2)
    for key in ("structure", "directions", "min_margin"):
        if key in dec and mode != {"structure": "structure", "directions": "direction",
                                   "min_margin": "direction"}[key]:
            raise E(f"{where}.{key} is given but isolation is {mode!r}")
