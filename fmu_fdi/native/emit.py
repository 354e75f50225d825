"""Emit a validated design as C constant data (``design_data.c``) for the native runtime.

``emit_design_c(design)`` turns a design dict (``fmu-fdi-design/1``, checked by
:func:`fmu_fdi.designfile.validate_design`) into one C99 translation unit that defines
``const fdi_design FDI_DESIGN`` with the layout of ``c/fdi_design.h``. Every number is
written as a C99 hexadecimal float literal (``float.hex``), so the C runtime starts from
the very doubles the Python runtime uses; the derived constants (the stacked generator
matrix ``[[C, D], [A, B]]``, whitening matrices, normalised fault directions, the RLS
clipping horizon) are taken from a :class:`~fmu_fdi.runtime.engine.DiagnoserRuntime` built
from the same dict, so both runtimes start bit-identical.

A design the C runtime cannot express is refused here, at build time, with
:class:`NativeDesignError` naming the item — never a wrong FMU.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np

from ..designfile import validate_design
from ..errors import DesignError
from ..runtime.engine import DiagnoserRuntime, valid_ranges

#: What the C runtime implements (fdi_design.h); anything else is refused.
GENERATORS = ("lti", "rls")
EVALUATORS = ("norm", "rms", "ewrms", "peak", "narendra", "chi2", "cusum", "glr")
THRESHOLDS = ("fixed", "adaptive", "majorant")
ISOLATIONS = ("none", "structure", "direction")
RLS_POLICIES = ("none", "floor", "periodic")
#: Counts the C runtime sizes its fixed memory block by (docs/semantics.md, S5).
MAX_COUNT = 100_000

_EVAL_CODE = {k: i for i, k in enumerate(EVALUATORS)}
_THR_CODE = {k: i for i, k in enumerate(THRESHOLDS)}
_ISO_CODE = {k: i for i, k in enumerate(ISOLATIONS)}
_POLICY_CODE = {k: i for i, k in enumerate(RLS_POLICIES)}
_NO_BOUND = float.fromhex("0x1.fffffffffffffp+1023")  # DBL_MAX: inputs are finite, so "no bound"


class NativeDesignError(DesignError):
    """The design cannot be expressed by the native (C) runtime; the message names the item."""


def _hex(x) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise NativeDesignError(f"non-finite constant {x!r} cannot be emitted")
    return x.hex()


class _Emitter:
    def __init__(self):
        self.lines: list[str] = []
        self.n = 0

    def _name(self, stem: str) -> str:
        self.n += 1
        return f"{stem}_{self.n}"

    def doubles(self, values, stem: str = "d") -> str:
        vals = np.asarray(values, float).ravel()
        if vals.size == 0:
            return "NULL"
        name = self._name(stem)
        texts = list(map(float.hex, vals.tolist())) if np.isfinite(vals).all() else [_hex(v) for v in vals]
        body = ",\n    ".join(", ".join(texts[i:i + 4]) for i in range(0, len(texts), 4))
        self.lines.append(f"static const double {name}[{vals.size}] = {{\n    {body}}};")
        return name

    def longs(self, values, stem: str = "l") -> str:
        vals = [int(v) for v in np.asarray(values).ravel()]
        if not vals:
            return "NULL"
        name = self._name(stem)
        self.lines.append(f"static const long {name}[{len(vals)}] = {{{', '.join(map(str, vals))}}};")
        return name

    def bytes_(self, values, stem: str = "b") -> str:
        vals = [1 if v else 0 for v in np.asarray(values).ravel()]
        if not vals:
            return "NULL"
        name = self._name(stem)
        self.lines.append(f"static const unsigned char {name}[{len(vals)}] = {{{', '.join(map(str, vals))}}};")
        return name


def _count(value, what: str, lo: int = 1) -> int:
    v = int(value)
    if not lo <= v <= MAX_COUNT:
        raise NativeDesignError(f"{what} = {v} is outside [{lo}, {MAX_COUNT}], the range the native runtime "
                                f"sizes its memory for")
    return v


def _eval_def(em: _Emitter, ev, where: str) -> str:
    if ev.kind not in _EVAL_CODE:
        raise NativeDesignError(f"{where}: evaluation kind {ev.kind!r} is not implemented in C")
    window = _count(ev.n, f"{where}.window") if hasattr(ev, "n") else 1
    lam = getattr(ev, "lam", 0.0)
    alpha, beta, gamma = (getattr(ev, k, 0.0) for k in ("alpha", "beta", "gamma"))
    delta = getattr(ev, "delta", 0.0)
    W = em.doubles(ev.W, "W") if hasattr(ev, "W") else "NULL"
    return (f"{{{_EVAL_CODE[ev.kind]}, {window}L, {_hex(lam)}, {_hex(alpha)}, {_hex(beta)}, {_hex(gamma)}, "
            f"{_hex(delta)}, {W}}}")


def _digest64(text: str) -> int:
    """64 bits of the SHA-256 of ``text``: the emitted data's identity, which guards FMU state images
    (a byte-wise FNV-1a in Python took 0.3 s per megabyte of a large design's data)."""
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little")


def emit_design_c(design: dict, source: str = "design") -> str:
    """C99 source of ``const fdi_design FDI_DESIGN`` for ``design`` (raises NativeDesignError)."""
    validate_design(design, source)
    rt = DiagnoserRuntime(design, checked=True)  # validated just above
    em = _Emitter()
    g = design["generator"]
    kind = g["discrete"].get("kind")
    if kind not in GENERATORS:
        raise NativeDesignError(f"{source}: generator kind {kind!r} is not implemented in C")
    nu, ny, nr, ng = rt.nu, rt.ny, rt.n_residuals, rt.n_groups
    nf = len(rt.faults)
    f: dict[str, str] = {}
    f["n_u"], f["n_y"], f["n_r"], f["n_groups"], f["n_faults"] = (f"{v}L" for v in (nu, ny, nr, ng, nf))
    f["Ts"] = _hex(rt.Ts)
    f["u0"], f["y0"] = em.doubles(rt.u0, "u0"), em.doubles(rt.y0, "y0")
    lo, hi = _valid_range(design, rt, source)
    f["lo"], f["hi"] = em.doubles(lo, "lo"), em.doubles(hi, "hi")
    f["gen_kind"] = "FDI_GEN_LTI" if kind == "lti" else "FDI_GEN_RLS"
    if kind == "lti":
        gen = rt.generator
        f["n_x"] = f"{gen.A.shape[0]}L"
        f["M"] = em.doubles(gen.M, "M")
        cont = g.get("continuous")
        if cont is not None:
            Ac = np.asarray(cont["A"], float).reshape(len(cont["A"]), -1) if cont["A"] else np.zeros((0, 0))
            n = Ac.shape[0]
            D = np.atleast_2d(np.asarray(cont["D"], float))
            f["has_cont"] = "1"
            f["n_xc"] = f"{n}L"
            f["Ac"], f["Bc"] = em.doubles(Ac, "Ac"), em.doubles(np.asarray(cont["B"], float).reshape(n, D.shape[1]), "Bc")
            f["Cc"], f["Dc"] = em.doubles(np.asarray(cont["C"], float).reshape(D.shape[0], n), "Cc"), em.doubles(D, "Dc")
    else:
        _emit_rls(em, rt.generator, f, source)
    starts, idx = [0], []
    for grp in rt.groups:
        idx.extend(grp)
        starts.append(len(idx))
    f["group_start"], f["group_idx"] = em.longs(starts, "gs"), em.longs(idx, "gi")
    evals, thrs = [], []
    for i, (ev, th) in enumerate(zip(rt.evaluators, rt.thresholds)):
        where = f"{source}: evaluation[{i}]"
        evals.append(_eval_def(em, ev, f"{where}.evaluator"))
        thrs.append(_threshold_def(em, th, f"{where}.threshold"))
    f["evals"] = _array(em, "fdi_eval_def", evals, "ev")
    f["thr"] = _array(em, "fdi_threshold_def", thrs, "th")
    dec = rt.decision
    if dec.mode not in _ISO_CODE:
        raise NativeDesignError(f"{source}: decision.isolation {dec.mode!r} is not implemented in C")
    f["k_of"] = f"{_count(dec.k_of, f'{source}: decision.persistence k')}L"
    f["n_of"] = f"{_count(dec.n_of, f'{source}: decision.persistence n')}L"
    f["latch"] = "1" if dec.latch else "0"
    f["isolation"] = str(_ISO_CODE[dec.mode])
    if dec.mode == "structure":
        f["S"] = em.bytes_(dec.S, "S")
    if dec.mode == "direction":
        f["Ddir"], f["Dvalid"] = em.doubles(dec.D, "Ddir"), em.bytes_(dec.valid, "Dvalid")
        f["min_margin"] = _hex(dec.min_margin)
    body = "\n".join(em.lines)
    fields = ",\n    ".join(f".{k} = {v}" for k, v in f.items())
    h = _digest64(body + fields)
    return (f"/* design_data.c - generated by fmu_fdi.native.emit from design {design.get('name', '')!r}; "
            f"do not edit. */\n#include <stddef.h>\n\n#include \"fdi_design.h\"\n\n{body}\n\n"
            f"const fdi_design FDI_DESIGN = {{\n    .hash = 0x{h:016x}ULL,\n    {fields}}};\n")


def _array(em: _Emitter, ctype: str, items: list[str], stem: str) -> str:
    name = em._name(stem)
    em.lines.append(f"static const {ctype} {name}[{len(items)}] = {{\n    " + ",\n    ".join(items) + "};")
    return name


def _threshold_def(em: _Emitter, th, where: str) -> str:
    if th.kind not in _THR_CODE:
        raise NativeDesignError(f"{where}: threshold kind {th.kind!r} is not implemented in C")
    value = getattr(th, "value0", 0.0)
    J0, a = getattr(th, "J0", 0.0), getattr(th, "a", 0.0)
    ev = th.u_eval if th.kind == "adaptive" else getattr(th, "b_eval", None)
    evdef = _eval_def(em, ev, f"{where}.evaluation") if ev is not None else "{0, 1L, 0, 0, 0, 0, 0, NULL}"
    taps = getattr(th, "taps", np.zeros(0))
    n_taps = _count(taps.size, f"{where}.taps (count)") if th.kind == "majorant" else 0
    tail = getattr(th, "tail", 0.0)
    return (f"{{{_THR_CODE[th.kind]}, {_hex(value)}, {_hex(J0)}, {_hex(a)}, {evdef}, {n_taps}L, "
            f"{em.doubles(taps, 'taps') if n_taps else 'NULL'}, {_hex(tail)}}}")


def _emit_rls(em: _Emitter, gen, f: dict, source: str) -> None:
    if gen.policy not in _POLICY_CODE:
        raise NativeDesignError(f"{source}: rls reset policy {gen.policy!r} is not implemented in C")
    ests = []
    for i, e in enumerate(gen.estimators):
        where = f"{source}: generator.discrete.estimators[{i}]"
        skip, warmup = int(e.skip), int(e.warmup)
        if not 0 <= skip <= warmup < 2**31:
            raise NativeDesignError(f"{where}: skip {skip} and warmup {warmup} must satisfy 0 <= skip <= warmup < 2^31")
        ests.append(
            f"{{{e.inputs.size}L, {e.npar}L, {e.nx}L, {em.longs(e.inputs, 'in')}, {em.doubles(e.A, 'rA')}, "
            f"{em.doubles(e.B, 'rB')}, {em.doubles(e.C, 'rC')}, {em.doubles(e.D, 'rD')}, "
            f"{em.doubles(e.theta0, 'th0')}, {skip}L, {warmup}L, {_hex(e.sigma_floor)}, {_hex(e.trace_max)}, "
            f"{_hex(e.trace_min)}}}")
    f["rls_n_est"] = f"{len(ests)}L"
    f["rls_est"] = _array(em, "fdi_rls_est_def", ests, "est")
    f["rls_mu"], f["rls_P0"] = _hex(gen.mu), _hex(gen.P0)
    f["rls_sigma_rel"], f["rls_mu_sigma"], f["rls_clip"] = _hex(gen.sigma_rel), _hex(gen.mu_sigma), _hex(gen.clip)
    f["rls_policy"] = str(_POLICY_CODE[gen.policy])
    period = gen.period if gen.policy == "periodic" else 1
    if not 1 <= period < 2**31:
        raise NativeDesignError(f"{source}: rls reset period {period} is outside [1, 2^31)")
    f["rls_period"] = f"{period}L"
    if math.isinf(gen.clip_after):
        f["rls_clip_after_inf"], f["rls_clip_after"] = "1", "0L"
    else:
        if not 0 <= gen.clip_after < 2**31:
            raise NativeDesignError(f"{source}: rls clipping horizon {gen.clip_after} is outside [0, 2^31)")
        f["rls_clip_after_inf"], f["rls_clip_after"] = "0", f"{int(gen.clip_after)}L"


def _valid_range(design: dict, rt, source: str):
    """Per signal (u then y) the valid range [lo, hi] as the runtime reads it (S2,
    :func:`fmu_fdi.runtime.engine.valid_ranges`); DBL_MAX where the design sets none (inputs
    are finite when compared, so that is no bound)."""
    u_lo, u_hi, y_lo, y_hi = valid_ranges(design["signals"])
    lo = [x if math.isfinite(x) else -_NO_BOUND for x in u_lo + y_lo]
    hi = [x if math.isfinite(x) else _NO_BOUND for x in u_hi + y_hi]
    return lo, hi
