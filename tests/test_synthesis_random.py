"""Seeded property test of the exact synthesis over ill-scaled random models (issue 17, "Show").

Every model of :func:`random_case` is handed to ``nullspace_design``, to ``structured_bank`` with
the rows ``achievable_structure`` lists, and to the dedicated/generalized banks where the model has
two faults of a kind. Each returned design is judged by :func:`judge`, an independent computation
with numpy/scipy only (no fmu_fdi analysis, post-condition or LTI code):

* frequency responses ``Q(λ)`` and ``Ge(λ) = [Gu Gd Gw Gf; I 0 0 0](λ)`` from the state-space data,
  ``D + C (λI − A)⁻¹ B`` by ``numpy.linalg.solve`` after a diagonal balancing of A (which undoes the
  eight-decade state scaling without changing the transfer function), on a dense grid;
* ``R = Q·Ge`` point by point; each residual group is scaled so that its smallest required fault
  peak gain is 1 (Varga's normalisation) and then ``‖R_u‖, ‖R_d‖`` (and ``‖R_w‖`` when the design
  says w is decoupled exactly, and every fault the row excludes) must be ≤ ``DEC_TOL = 1e-7``
  absolute on the grid;
* R and Q stable: the unstable or marginal eigenvalues of the series realisation of ``Q·Ge`` (and
  of Q) must be uncontrollable or unobservable (PBH rank tests written here), i.e. not poles of a
  minimal realisation;
* Q not numerically zero; every required fault visible above the rounding level of ``|Q|·|Gf|``.

Every refusal must be a :class:`fmu_fdi.errors.DesignError` (not a ValueError, LinAlgError, ...),
and a request the rank test says is achievable (a row ``achievable_structure`` lists, or the
all-ones row for ``nullspace_design``) must be designed.

The models (seeded, :func:`random_case`): continuous and discrete; n = 0 (static plants) to 30;
1–4 outputs with m > p in half the cases (many actuators, few sensors); 0–2 unknown inputs d; 0–1
noise input w; sensor, actuator and component faults, the component fault with an unstable or
marginal pole (+1, 0, ±2j, or their discrete images) that u and d do not excite; half of the
models with a diagonal state scaling spread over eight decades.

The default suite runs ``N_FAST`` models with n ≤ 10 (up to 4 listed rows per bank); ``N_SLOW``
more, n up to 30 and up to 6 rows, run under ``-m slow``.
``benchmarks/synthesis_random_judged.py`` prints the counts ok / refused / broken.
"""
from __future__ import annotations

import sys
import time
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import FDIModel, actuator_fault, sensor_fault
from fmu_fdi.design.problems.achievable import achievable_structure
from fmu_fdi.design import dedicated_bank, generalized_bank, nullspace_design, structured_bank
from fmu_fdi.errors import DesignError
from fmu_fdi.faults import component_fault

# Decoupling tolerance of issue 17 on the normalised internal form (smallest required fault peak = 1).
DEC_TOL = 1e-7
# Visibility: a required fault's peak gain must exceed the rounding level of the product Q·Gf at the
# points where it is evaluated. The evaluation error of one entry of R is about
# k·eps·cond(λI − A_balanced)·|Q||Gf| with k ≲ 60 terms and cond ≲ 1e5 after balancing on this grid
# (grid points stay ≥ 1e-3 relative away from poles) — 60·2.2e-16·1e5 ≈ 1.3e-9. (A Boeing 747 row
# whose fault peak 2e-2 is 3.6e-9 of |Q||Gf| = 5.7e6 is visible: its rounding is ~1e-9 absolute.)
VIS_TOL = 1e-9
# Q is numerically zero when its peak gain is below 1e-10: the models' transfer functions have
# gains between ~1e-4 and 1e4 (the state scaling cancels in them), so such a filter maps every signal
# the plant can produce to below 1e-6 of the fault effect of a unit fault — rounding residue.
ZERO_Q = 1e-10
# PBH: a mode is uncontrollable (unobservable) when sigma_min[λI − A, B] (resp. [λI − A; C]) is below
# PBH_TOL relative to max(1, ‖A‖) with B and C scaled to unit norm. The computed λ of a simple,
# well-separated eigenvalue of the balanced matrix is accurate to ~eps·‖A‖·cond ≲ 1e-10, so a true
# cancellation gives sigma_min ≲ 1e-10; a mode weighted above 1e-8 of the signal is a pole of R.
PBH_TOL = 1e-8
# A pole counts as unstable/marginal when Re λ ≥ −STAB_TOL·max(1, |λ|) (continuous) or
# |λ| ≥ 1 − STAB_TOL (discrete): the marginal poles we plant (0, ±2j, 1, e^{±0.5j}) are computed to
# ~1e-12 from the balanced data; a genuine stable pole of a design is far inside.
STAB_TOL = 1e-9

N_FAST = 20
N_SLOW = 24  # benchmarks/synthesis_random_judged.py runs any number (e.g. 200)


# ------------------------------------------------------------------------------------------ models
def random_case(seed: int) -> FDIModel:
    """A seeded, possibly ill-scaled random FDI model (see the module docstring)."""
    rng = np.random.default_rng(10_000 + seed)
    discrete = bool(seed % 2)
    static = seed % 10 in (4, 5)
    p = int(rng.integers(1, 5))
    m = p + int(rng.integers(1, 4)) if (seed // 2) % 2 else int(rng.integers(1, p + 1))
    nd = int(rng.integers(0, min(2, p - 1) + 1)) if p > 1 else 0
    nw = int(rng.integers(0, 2))
    dt = 0.1 if discrete else 0.0
    # fault-only mode: 0 none, 1 unstable real, 2 marginal real (integrator), 3 marginal pair
    special = 0 if static else int(rng.integers(0, 4))
    n_extra = {0: 0, 1: 1, 2: 1, 3: 2}[special]
    # the default suite keeps n ≤ 10 (speed: a 30-state model costs ~30 s of design calls); the slow
    # set goes to n = 30, every 8th model with n ≥ 20
    big = seed >= N_FAST
    n_max = 30 if big else 10
    n_min = 20 if big and seed % 8 == 0 else (max(1, 4 - n_extra) if seed % 3 else 1)
    n_stable = 0 if static else int(rng.integers(n_min, n_max + 1 - n_extra))
    n = n_stable + n_extra

    eig = []
    while len(eig) < n_stable:
        if n_stable - len(eig) >= 2 and rng.random() < 0.4:
            re, im = -10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1)
            eig += [complex(re, im), complex(re, -im)]
        else:
            eig.append(complex(-10 ** rng.uniform(-1.5, 1), 0))
    J = np.zeros((n, n))
    i = 0
    while i < n_stable:
        lam = np.exp(eig[i] * dt) if discrete else eig[i]
        if abs(eig[i].imag) > 0:
            J[i:i + 2, i:i + 2] = [[lam.real, lam.imag], [-lam.imag, lam.real]]
            i += 2
        else:
            J[i, i] = lam.real
            i += 1
    if special == 1:
        J[n - 1, n - 1] = np.exp(1.0 * dt) if discrete else 1.0
    elif special == 2:
        J[n - 1, n - 1] = 1.0 if discrete else 0.0
    elif special == 3:
        w0 = 2.0
        c, s_ = (np.cos(w0 * dt), np.sin(w0 * dt)) if discrete else (0.0, w0)
        J[n - 2:, n - 2:] = [[c, s_], [-s_, c]]
    # u, d and w do not excite the fault-only modes; the component fault does
    Bu = rng.standard_normal((n, m))
    Bd = rng.standard_normal((n, nd))
    Bw = rng.standard_normal((n, nw))
    Bc = rng.standard_normal((n, 1))
    for B in (Bu, Bd, Bw):
        B[n_stable:, :] = 0.0
    C = rng.standard_normal((p, n))
    Du = rng.standard_normal((p, m)) * (rng.random() < 0.5)
    Dd = rng.standard_normal((p, nd)) * (static or rng.random() < 0.3)
    Dw = rng.standard_normal((p, nw)) * (static or rng.random() < 0.5)
    Dc = rng.standard_normal((p, 1)) * (static or rng.random() < 0.3)
    if static and not np.any(Du):
        Du = rng.standard_normal((p, m))
    if n:
        U, _ = np.linalg.qr(rng.standard_normal((n, n)))
        A = U @ J @ U.T
        Bu, Bd, Bw, Bc, C = U @ Bu, U @ Bd, U @ Bw, U @ Bc, C @ U.T
        if seed % 4 in (2, 3):  # eight decades of state scaling x -> T x
            t = 10 ** rng.uniform(-4, 4, n)
            A = (t[:, None] * A) / t[None, :]
            Bu, Bd, Bw, Bc, C = t[:, None] * Bu, t[:, None] * Bd, t[:, None] * Bw, t[:, None] * Bc, C / t[None, :]
    else:
        A = np.zeros((0, 0))
    y = [f"y{k + 1}" for k in range(p)]
    u = [f"u{k + 1}" for k in range(m)]
    faults = [sensor_fault(f"fs{k + 1}", y[k]) for k in range(min(2, p))]
    faults += [actuator_fault(f"fa{k + 1}", u[k]) for k in range(min(2, m))]
    if n_extra or rng.random() < 0.3:
        faults.append(component_fault("fc", Bc, Dc))
    return FDIModel.from_matrices(A, Bu, C, Du, Bd=Bd if nd else None, Dd=Dd if nd else None,
                                  Bw=Bw if nw else None, Dw=Dw if nw else None, faults=faults, dt=dt,
                                  u_names=u, y_names=y, name=f"rand{seed}")


# ------------------------------------------------------------------------------------------- judge
def _one_blas_thread(fn):
    """Run the judge's numpy work with one BLAS thread (threadpoolctl, as the library's designs run). The
    judge solves thousands of small systems; OpenBLAS's threaded zgetrf spin-waits on a loaded 2-core machine:
    1500 solves of a 100-state system took 29–47 s with the default threads and 1.4–2.0 s with one (measured
    beside the audits at load ~10; the audits' slow models were mostly the judge waiting)."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper


def _balanced(A, B, C):
    """Diagonal similarity (LAPACK gebal scaling, no permutation) of (A, B, C): same transfer function."""
    if A.shape[0] == 0:
        return A, B, C
    _, (scale, _) = sla.matrix_balance(A, permute=False, separate=True)
    return (A * scale[None, :]) / scale[:, None], B / scale[:, None], C * scale[None, :]


def observed_states(A, C) -> np.ndarray:
    """States of ``(A, C)`` with a path to an output through the exact non-zero pattern (``C[:, j] ≠ 0``, or
    ``A[i, j] ≠ 0`` for an observed i), in order: the others are unobservable whatever the values (no rank decision,
    no tolerance), so dropping them keeps the transfer function. A bank's Q is the block-diagonal stack of its
    members: a row observes its own member's states only."""
    A, C = np.asarray(A, float), np.asarray(C, float)
    seen = np.any(C != 0, axis=0) if C.size else np.zeros(A.shape[0], bool)
    frontier, nz = seen.copy(), A != 0
    while frontier.any():
        new = np.any(nz[frontier, :], axis=0) & ~seen
        seen |= new
        frontier = new
    return np.flatnonzero(seen)


@_one_blas_thread
def _freqresp(A, B, C, D, lam: np.ndarray) -> np.ndarray:
    """``D + C (λI − A)⁻¹ B`` at every point of ``lam``; shape (len(lam), p, m). The output rows observing the same
    states (:func:`observed_states`) are read together on those states only: a bank's rows on their own member
    (seed 412's bank of order 439: 163 s → seconds, benchmarks/audit_judge_speed.py)."""
    A, B, C, D = (np.asarray(X, float) for X in (A, B, C, D))
    out = np.empty((lam.size,) + D.shape, complex)
    sets: dict[tuple, list[int]] = {}
    for r in range(C.shape[0]):
        sets.setdefault(tuple(observed_states(A, C[r:r + 1])), []).append(r)
    for keep, rows in sets.items():
        k = list(keep)
        out[:, rows, :] = _freqresp_dense(A[np.ix_(k, k)], B[k, :], C[np.ix_(rows, k)], D[rows, :], lam)
    return out


def _freqresp_dense(A, B, C, D, lam: np.ndarray) -> np.ndarray:
    """:func:`_freqresp` on every state of the realisation (one dense solve of its order per point; the points in
    stacks of 256, which numpy.linalg.solve loops over in C — the same LAPACK solve per point, byte for byte the
    values of a Python loop over the points, ~40 % less time: benchmarks/transfer_values_speed.py measures the
    library's twin, freqresp.dense_values, which this judge does not call)."""
    A, B, C = _balanced(np.asarray(A, float), np.asarray(B, float), np.asarray(C, float))
    n = A.shape[0]
    out = np.empty((lam.size,) + D.shape, complex)
    out[:] = D
    if n == 0:
        return out
    diag = np.arange(n)
    for s in range(0, lam.size, 256):
        part = lam[s:s + 256]
        M = np.empty((part.size, n, n), complex)  # λI − A
        M[:] = -A
        M[:, diag, diag] += part[:, None]
        out[s:s + part.size] = D + C @ np.linalg.solve(M, np.broadcast_to(B, (part.size,) + B.shape))
    return out


def _extended(model: FDIModel):
    """State-space data of ``Ge = [Gu Gd Gw Gf; I 0 0 0]`` (inputs u, d, w, f; outputs y, u)."""
    m = model.nu
    B = np.hstack([model.Bu, model.Bd, model.Bw, model.Bf])
    D = np.hstack([model.Du, model.Dd, model.Dw, model.Df])
    Ce = np.vstack([model.C, np.zeros((m, model.n))])
    De = np.vstack([D, np.hstack([np.eye(m), np.zeros((m, D.shape[1] - m))])])
    return model.A, B, Ce, De


def _grid(model: FDIModel, extra_poles=()) -> np.ndarray:
    """Dense evaluation points on the stability boundary, ≥ 1e-3 (relative) away from every pole
    of the model and of the filter (a marginal pole of Gf is cancelled by a correct Q, but the
    product evaluated at the pole itself is 0·∞)."""
    if model.dt:
        lam = np.exp(1j * np.linspace(0.0, np.pi, 600))
    else:
        lam = 1j * np.r_[0.0, np.logspace(-4, 4, 600)]
    poles = np.r_[np.linalg.eigvals(model.A) if model.n else np.zeros(0), np.asarray(extra_poles, complex)]
    if poles.size:
        dist = np.min(np.abs(lam[:, None] - poles[None, :]), axis=1)
        lam = lam[dist > 1e-3 * np.maximum(1.0, np.abs(lam))]
    return lam


@_one_blas_thread
def _pbh_poles(A, B, C, dt: float, D=None) -> np.ndarray:
    """Unstable or marginal poles of a minimal realisation of (A, B, C): the eigenvalues outside
    the open stability region that pass both PBH rank tests (controllable and observable).

    With ``D``, B and C are scaled by ``max(||B||, ||D||)`` and ``max(||C||, ||D||)`` instead of their own norms:
    a mode's residue is then judged against the size of the whole transfer function. (A static row that
    annihilates every state, ``Q_y C ≈ 1e-16``, has a series ``C_R`` of rounding only; scaled to unit norm that
    rounding read as full observability — random seed 129's rows [0 1 1 1 0]: "R has the pole 1.105", its residue
    1.9e-16 of a unit fault gain.)"""
    n = A.shape[0]
    if n == 0:
        return np.zeros(0, complex)
    A, B, C = _balanced(A, B, C)
    nD = 0.0 if D is None else float(np.linalg.norm(np.asarray(D, float), 2)) if np.size(D) else 0.0
    B = B / max(np.linalg.norm(B, 2), nD, 1e-300)
    C = C / max(np.linalg.norm(C, 2), nD, 1e-300)
    ev = np.linalg.eigvals(A)
    bad = np.abs(ev) >= 1 - STAB_TOL if dt else ev.real >= -STAB_TOL * np.maximum(1.0, np.abs(ev))
    scale = max(1.0, np.linalg.norm(A, 2))
    kept = []
    for lam in ev[bad]:
        M = lam * np.eye(n) - A
        ctrb = np.linalg.svd(np.hstack([M, B]), compute_uv=False)[-1] if B.size else 0.0
        obsv = np.linalg.svd(np.vstack([M, C]), compute_uv=False)[-1] if C.size else 0.0
        if ctrb > PBH_TOL * scale and obsv > PBH_TOL * scale:
            kept.append(lam)
    return np.array(kept, complex)


def _series(Q, model: FDIModel):
    """State-space data of ``R = Q·Ge`` (series connection, states [x_Q; x_G]) and its feedthrough, Q on the states
    its rows observe (:func:`observed_states`: a bank row group's own member; the PBH tests cost the cube of the
    series order)."""
    k = observed_states(Q.A, Q.C)
    return _series_whole(SimpleNamespace(A=Q.A[np.ix_(k, k)], B=Q.B[k, :], C=Q.C[:, k], D=Q.D), model)


def _series_whole(Q, model: FDIModel):
    """:func:`_series` on every state of Q's realisation."""
    A, B, Ce, De = _extended(model)
    nq, n = Q.A.shape[0], A.shape[0]
    AR = np.block([[Q.A, Q.B @ Ce], [np.zeros((n, nq)), A]])
    BR = np.vstack([Q.B @ De, B])
    CR = np.hstack([Q.C, Q.D @ Ce])
    return AR, BR, CR, Q.D @ De


def judge(gen, model: FDIModel, S, names, w_decoupled: bool = False) -> list[str]:
    """Violations of issue 17's judge for a returned generator or bank (empty list: a correct design).

    ``S[i]`` is the structure row over ``names`` of residual group i (``gen.groups[i]``).
    """
    out = []
    S = np.atleast_2d(np.asarray(S, int))
    if len(gen.groups) != S.shape[0]:
        return [f"{len(gen.groups)} residual groups for {S.shape[0]} structure rows"]
    A, B, Ce, De = _extended(model)
    nu, nd, nw = model.nu, model.nd, model.nw
    sl_u, sl_d, sl_w = slice(0, nu), slice(nu, nu + nd), slice(nu + nd, nu + nd + nw)
    f0 = nu + nd + nw
    fcols = {f.name: f0 + np.arange(model.nf)[f.columns] for f in model.faults}
    Qall = gen.Q
    for lam in _pbh_poles(Qall.A, Qall.B, Qall.C, model.dt):
        out.append(f"Q has the unstable/marginal pole {lam:.4g}")
    qpoles = np.linalg.eigvals(Qall.A) if Qall.A.shape[0] else np.zeros(0)
    lam = _grid(model, qpoles)
    Gv = _freqresp(A, B, Ce, De, lam)                          # (N, p+m, m+nd+nw+nf)
    Qv = _freqresp(Qall.A, Qall.B, Qall.C, Qall.D, lam)        # (N, rows, p+m)
    Rv = Qv @ Gv

    for i, g in enumerate(gen.groups):
        Rg, Qg = Rv[:, g, :], Qv[:, g, :]
        qpk = _peak(Qg)
        if qpk < ZERO_Q:
            out.append(f"group {i}: Q is numerically zero (peak gain {qpk:.2e})")
            continue
        req = [nm for nm, s in zip(names, S[i]) if s]
        gains = {nm: _peak(Rg[:, :, fcols[nm]]) for nm in req}
        for nm in req:
            bound = float(np.max(np.linalg.norm(Qg, 2, axis=(1, 2))
                                 * np.linalg.norm(Gv[:, :, fcols[nm]], 2, axis=(1, 2))))
            if gains[nm] <= VIS_TOL * bound:
                out.append(f"group {i}: required fault {nm} invisible (peak {gains[nm]:.2e} vs |Q||Gf| {bound:.2e})")
        gmin = min(gains.values()) if gains else 0.0
        if gmin <= 0:
            continue
        blocks = [("u", sl_u), ("d", sl_d)] + ([("w", sl_w)] if w_decoupled else [])
        blocks += [(f"excluded fault {nm}", fcols[nm]) for nm, s in zip(names, S[i]) if not s]
        out += row_violations(Qall, g, model, Rv, 1.0 / gmin, blocks, f"group {i}")
    return out


def _peak(X) -> float:
    """The largest 2-norm over the points of ``X`` (shape (points, rows, columns)); 0 for an empty block."""
    return float(np.linalg.norm(X, 2, axis=(1, 2)).max()) if X.size else 0.0


def row_violations(Q, rows, model: FDIModel, Rv: np.ndarray, scale: float, blocks, tag: str) -> list[str]:
    """The per-row part of issue 17's judge, shared by this file's :func:`judge` and test_approximate_random's
    judges: for the residual rows ``rows`` of Q (a group, normalised by ``scale`` = 1 / its smallest required fault
    peak), every block ``(name, columns of R)`` of ``blocks`` — u, d, w when decoupled, the faults the row excludes
    — must have ``scale·max_k ‖R(λ_k)[rows, columns]‖ ≤ DEC_TOL`` on the points of ``Rv`` (``R = Q·Ge``
    there, shape (points, Q's rows, Ge's columns)), and the series realisation of ``Q[rows]·Ge`` may have no
    unstable or marginal pole that passes both PBH tests (:func:`_pbh_poles`)."""
    out = []
    for what, cols in blocks:
        leak = scale * _peak(Rv[:, rows][:, :, cols])
        if leak > DEC_TOL:
            out.append(f"{tag}: ‖R_{what}‖ = {leak:.2e} on the normalised form (> {DEC_TOL:g})")
    Qsub = type("Qsub", (), {"A": Q.A, "B": Q.B, "C": Q.C[rows], "D": Q.D[rows]})
    AR, BR, CR, DR = _series(Qsub, model)
    for p_ in _pbh_poles(AR, BR, CR, model.dt, DR):
        out.append(f"{tag}: R = Q·Ge has the unstable/marginal pole {p_:.4g}")
    return out


# ------------------------------------------------------------------------------------------ driver
#: seconds per design call (0: none); the audit benchmarks set it (SIGALRM, main thread) to time-box a run
CALL_TIMEOUT = 0


class CallTimeout(Exception):
    """A design call that ran longer than :data:`CALL_TIMEOUT`."""


def _alarm(signum, frame):
    raise CallTimeout(f"no answer within {CALL_TIMEOUT} s")


def _call(fn, *args, **kw):
    """('ok', gen) | ('refused', DesignError) | ('crash', other exception) | ('timeout', CallTimeout) —
    the last only with :data:`CALL_TIMEOUT` set (this file's and test_approximate_random's audits)."""
    import signal

    if CALL_TIMEOUT:
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(int(CALL_TIMEOUT))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return "ok", fn(*args, **kw)
    except CallTimeout as exc:
        return "timeout", exc
    except DesignError as exc:
        return "refused", exc
    except Exception as exc:  # noqa: BLE001 - any other exception type is the failure under test
        return "crash", exc
    finally:
        if CALL_TIMEOUT:
            signal.alarm(0)


def _rows_in(S, listed) -> bool:
    have = {tuple(r) for r in np.asarray(listed, int)}
    return all(tuple(r) in have for r in np.asarray(S, int))


def check_case(seed: int, max_rows: int | None = 6) -> list[tuple[str, str, str]]:
    """Run every design call on model ``seed``; returns (call, 'ok'|'refused'|'broken', detail)."""
    results = []
    try:
        model = random_case(seed)
    except Exception as exc:  # noqa: BLE001
        return [("model", "broken", f"the model cannot be built: {type(exc).__name__}: {exc}")]
    names = model.fault_names
    st, listed = _call(achievable_structure, model)
    if st == "timeout":
        return [("achievable_structure", "timeout", str(listed))]
    if st != "ok":
        return [("achievable_structure", "broken", f"{type(listed).__name__}: {listed}")]
    listed = np.asarray(listed, int).reshape(-1, len(names))
    rng = np.random.default_rng(seed)
    rows = listed if max_rows is None or len(listed) <= max_rows else listed[np.sort(rng.choice(len(listed),
                                                                                               max_rows, False))]
    calls = [("nullspace_design", lambda: nullspace_design(model), np.ones((1, len(names)), int), names)]
    if len(rows):
        calls.append(("structured_bank", lambda: structured_bank(model, rows), rows, names))
    for kind, fn in (("sensor", dedicated_bank), ("actuator", dedicated_bank), ("sensor", generalized_bank),
                     ("actuator", generalized_bank)):
        kn = [f.name for f in model.faults if f.kind == kind]
        if len(kn) >= 2:
            k = len(kn)
            Sk = np.eye(k, dtype=int) if fn is dedicated_bank else 1 - np.eye(k, dtype=int)
            # the bank's rows over all faults: faults of other kinds are don't-care, so the row is
            # achievable when some listed row agrees on the kind's faults
            calls.append((f"{fn.__name__}({kind})", lambda fn=fn, kind=kind: fn(model, kind), Sk, kn))
    for what, fn, S, nm in calls:
        status, res = _call(fn)
        if nm is names:
            achievable = _rows_in(S, listed)
        else:
            idx = [names.index(x) for x in nm]
            achievable = all(any(np.array_equal(r[idx], s) for r in listed) for s in S)

        def judged(res, S=S, nm=nm):
            wdec = bool(model.nw) and all(g.info.get("noise") == "decoupled exactly"
                                          for g in getattr(res, "members", [res]))
            return judge(res, model, S, nm, w_decoupled=wdec)

        results.append((what,) + verdict(status, res, achievable, judged))
    return results


def verdict(status: str, res, achievable: bool, judged) -> tuple[str, str]:
    """``(status, detail)`` of one design call from :func:`_call`'s answer (this file's and
    test_approximate_random's audits): another exception than DesignError is broken; a refusal is broken when
    the request is ``achievable``; a returned design is broken when ``judged(res)`` lists violations."""
    if status == "timeout":
        return "timeout", str(res)
    if status == "crash":
        return "broken", f"{type(res).__name__} instead of DesignError: {str(res)[:300]}"
    if status == "refused":
        why = ("achievable request refused: " if achievable else "") + str(res)[:300]
        return ("broken" if achievable else "refused"), why
    bad = judged(res)
    return ("broken" if bad else "ok"), "; ".join(bad[:4])


def _describe(seed: int) -> str:
    try:
        m = random_case(seed)
        return f"n={m.n} p={m.ny} m={m.nu} nd={m.nd} nw={m.nw} faults={m.fault_names} {'disc' if m.dt else 'cont'}"
    except Exception as exc:  # noqa: BLE001
        return f"(model not built: {exc})"


def _assert_case(seed: int, max_rows: int = 4):
    res = check_case(seed, max_rows)
    broken = [f"{what}: {detail}" for what, st, detail in res if st == "broken"]
    assert not broken, f"seed {seed} ({_describe(seed)}):\n" + "\n".join(broken)


# -------------------------------------------------------------------------------------------- tests
def test_judge_rejects_leaking_unstable_and_zero_filters():
    """The judge can fail: a filter that passes y straight through leaks u; a static filter on a
    plant with an unstable fault-only mode keeps the pole in R; a zero filter is zero."""
    from fmu_fdi.lti import LTI

    class Gen:
        def __init__(self, Q):
            self.Q, self.groups = Q, [list(range(Q.D.shape[0]))]

    # y = 1/(s+1) u + f (sensor); Q = [1 0] (r = y) sees u
    m1 = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], faults=[sensor_fault("f", "y1")], u_names=["u1"],
                                y_names=["y1"])
    bad = judge(Gen(LTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), np.array([[1.0, 0.0]]))), m1,
                [[1]], ["f"])
    assert any("R_u" in b for b in bad)
    # the exact filter r = y − 1/(s+1) u passes
    good = LTI(np.array([[-1.0]]), np.array([[0.0, 1.0]]), np.array([[-1.0]]), np.array([[1.0, 0.0]]))
    assert judge(Gen(good), m1, [[1]], ["f"]) == []
    # Gf = [1/(s-1); 1/(s+2)], no u: r = y1 keeps the pole +1
    m2 = FDIModel.from_matrices(np.diag([1.0, -2.0]), np.zeros((2, 0)), np.eye(2),
                                faults=[component_fault("f", [[1.0], [1.0]])])
    bad = judge(Gen(LTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), np.array([[1.0, 0.0]]))), m2,
                [[1]], ["f"])
    assert any("pole" in b for b in bad), bad
    # r = y2 has a stable fault response
    assert judge(Gen(LTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), np.array([[0.0, 1.0]]))), m2,
                 [[1]], ["f"]) == []
    # a zero filter
    bad = judge(Gen(LTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), np.array([[3e-16, 0.0]]))), m2,
                [[1]], ["f"])
    assert any("zero" in b for b in bad)


@pytest.mark.parametrize("seed", [2, 3, 6, 7, 10, 11, 18, 19, 22, 23])
def test_judge_is_accurate_on_ill_scaled_models(seed, monkeypatch):
    """The judge's own rounding stays far below DEC_TOL on the ill-scaled models: the exact filter
    r = y − Gu u realised with the model's own (ill-scaled, partly unstable) A,
    Q = (A, [0 −Bu], C, [I −Du]), has R_u = 0; the judge must see ≤ 1e-9 of the fault gain, and the
    unstable fault-only modes of A, not excited through Q's inputs, are not poles of Q."""
    from fmu_fdi.lti import LTI

    model = random_case(seed)
    p = model.ny
    Q = LTI(model.A, np.hstack([np.zeros((model.n, p)), -model.Bu]), model.C, np.hstack([np.eye(p), -model.Du]),
            model.dt)

    class Gen:
        groups = [list(range(p))]

    Gen.Q = Q
    sens = [f.name for f in model.faults if f.kind == "sensor"]
    names = sens[:1]
    monkeypatch.setattr(sys.modules[__name__], "DEC_TOL", 1e-9)
    msgs = judge(Gen, model, [[1]], names)
    # d is not decoupled by this filter (only u is): ignore R_d, everything else must pass
    msgs = [x for x in msgs if "R_d" not in x]
    assert msgs == [], msgs


def test_random_models_cover_the_requested_classes():
    """The seeded set holds what issue 17 asks for (so the property test cannot quietly shrink)."""
    ms = [random_case(s) for s in range(N_FAST + N_SLOW) if s % 10 not in (4, 5)]
    assert any(m.dt for m in ms) and any(not m.dt for m in ms)
    assert any(m.nu > m.ny for m in ms) and any(m.nd for m in ms) and any(m.nw for m in ms)
    assert max(m.n for m in ms) >= 25
    ev = np.concatenate([np.linalg.eigvals(m.A) for m in ms if not m.dt and m.n])
    assert np.any(np.isclose(ev, 1.0)) and np.any(np.isclose(ev, 0.0)) and np.any(np.isclose(ev, 2j))


def _siso_cases():
    """The small cases issue 17 names, as (label, model): one or two outputs, no u/d."""
    def model(A, B, C, Bw=None, name="case"):
        A, B, C = np.atleast_2d(A).astype(float), np.atleast_2d(B).astype(float), np.atleast_2d(C).astype(float)
        return FDIModel.from_matrices(A, np.zeros((A.shape[0], 0)), C, Bw=Bw,
                                      faults=[component_fault("f", B, np.zeros((C.shape[0], 1)))], name=name)
    osc = np.array([[0.0, 2.0], [-2.0, 0.0]])  # poles ±2j
    return [
        # y = f/s + w/(s²+4): a zero filter 2.9e-16 was returned
        ("Gf=1/s, Gw=1/(s^2+4)", model(sla.block_diag([[0.0]], osc), [[1.0], [0], [0]], [[1.0, 1.0, 0.0]],
                                       Bw=np.array([[0.0], [0.0], [1.0]]))),
        # y = f/s + w/(s+2): LinAlgError
        ("Gf=1/s, Gw=1/(s+2)", model(np.diag([0.0, -2.0]), [[1.0], [0.0]], [[1.0, 1.0]],
                                     Bw=np.array([[0.0], [1.0]]))),
        # Gf = [1/(s-1); 1/(s+2)], [1/s; 1/(s+2)], [1/(s²+4); 1/(s+2)]: R kept the pole
        ("Gf=[1/(s-1); 1/(s+2)]", model(np.diag([1.0, -2.0]), [[1.0], [1.0]], np.eye(2))),
        ("Gf=[1/s; 1/(s+2)]", model(np.diag([0.0, -2.0]), [[1.0], [1.0]], np.eye(2))),
        ("Gf=[1/(s^2+4); 1/(s+2)]", model(sla.block_diag(osc, [[-2.0]]), [[0.0], [1.0], [1.0]],
                                          [[0.5, 0.0, 0.0], [0.0, 0.0, 1.0]])),
        # Gf = [1/s; 1/(s²+4)]: ValueError in nullspace.py
        ("Gf=[1/s; 1/(s^2+4)]", model(sla.block_diag([[0.0]], osc), [[1.0], [0.0], [1.0]],
                                      [[1.0, 0.0, 0.0], [0.0, 0.5, 0.0]])),
    ]


@pytest.mark.parametrize("label", [c[0] for c in _siso_cases()])
def test_issue17_small_cases(label):
    """The issue's own small cases: each is designable (a stable R exists: Q cancels the marginal or
    unstable fault poles; w is a noise input, not decoupled), so nullspace_design must return a
    design that meets the judge — R stable, Q not zero — and never raise anything but DesignError."""
    model = dict(_siso_cases())[label]
    status, res = _call(nullspace_design, model)
    assert status != "crash", f"{type(res).__name__} instead of DesignError: {res}"
    assert status == "ok", f"refused a designable case: {res}"
    assert judge(res, model, [[1]], ["f"]) == []


# Seeds whose designs break the judge on main AND on main + core + judge + matching (merged 11:25 UTC,
# issue 17): the first breakage of the merged state. strict: a fix makes the test XPASS, so remove the entry.
KNOWN_BROKEN: dict[int, str] = {
    # 33 (fixed, issue 17): the bank's rows cancel z = 1 (3.9e-3 from the plant pole 0.9961) to ~1e-13 of the fault
    # gain; the judge reads the minimal realisation of R (postconditions._without_cancelled_modes: ≤ 0.11 of the
    # design's rounding δ_i = N·eps·(4||A||/sep·||Q_i(p)|| ||Ce|| + max||Q_i|| ||c_p||)), a residue above it stays
    # (ε = 1e-13: 11 δ_i, 1e-12: 113 δ_i), and each bank row from its own states (stacked, one row read 5.5e-8)
}


def _seeds(seeds):
    return [pytest.param(s, marks=pytest.mark.xfail(strict=True, reason="issue 17: " + KNOWN_BROKEN[s]))
            if s in KNOWN_BROKEN else s for s in seeds]


@pytest.mark.parametrize("seed", _seeds(range(N_FAST)))
def test_random_design_meets_the_judge(seed):
    _assert_case(seed)


def test_judge_verdict_does_not_depend_on_the_solver_next_to_an_integrator(monkeypatch):
    """Seed 10's row [1 1 0 1 0] decouples fc, whose integrator the plant's rounding puts at ~1e-17; its
    pencil row cancels it to 2e-16 of |Q(0)||res|. The library judge read that rounding through points
    down to 1e-9 rad/s as a leak of ε/ω: it passed with the dense LU solve of small models and refused
    the row with the Schur-form solve of large ones (freqresp.SCHUR_MIN_ORDER = 0: the pencil row read as
    u+d leak 1.59e-7, the polynomial fallback as "R = Q·Ge keeps the plant pole 8.9e-18"). The judge keeps its points BOUNDARY_GAP·||A|| away from poles on the
    boundary, so both solvers give the same verdict — and the design meets the independent judge."""
    import fmu_fdi.freqresp as freqresp

    monkeypatch.setattr(freqresp, "SCHUR_MIN_ORDER", 0)
    freqresp.clear_caches()  # values kept from a dense-solve run must not be reused
    try:
        _assert_case(10)
    finally:
        freqresp.clear_caches()


@pytest.mark.parametrize("eps, leaks", [(0.0, False), (1e-12, True), (1e-9, True)])
def test_library_judge_gap_hides_no_inexact_cancellation(eps, leaks):
    """The library judge keeps its points BOUNDARY_GAP·||A|| (1e-6) away from a pole on the boundary; a row
    that cancels the pole only to a residue ε still reads ε/δ ≥ ε·1e6 beside it. y1 = d/s + u/(s + 2) + f,
    y2 = d/s + u/(s + 2): r = (y1 − (1 + ε) y2)/(s + 1) has R_f = 1/(s + 1), R_u = −ε/((s + 1)(s + 2)) and
    R_d = −ε/(s(s + 1)). The exact row passes; ε = 1e-12 (seed 33's rows show 3e-14 relative to the fault
    gain) and above is refused — by the leak ε/δ read beside the gap, or as a pole of R kept."""
    from fmu_fdi.design.toolkit.postconditions import check_generator
    from fmu_fdi.generator import ResidualGenerator
    from fmu_fdi.lti import LTI

    model = FDIModel.from_matrices(np.diag([0.0, -2.0]), [[0.0], [1.0]], np.ones((2, 2)), Bd=[[1.0], [0.0]],
                                   faults=[sensor_fault("f", "y1")])
    Q = LTI(np.array([[-1.0]]), np.array([[1.0, -(1.0 + eps), 0.0]]), np.array([[1.0]]), np.zeros((1, 3)))
    fig = check_generator(ResidualGenerator(Q, model, "test"), raise_error=False)
    assert bool(fig.get("failures")) == leaks, fig
    # the numpy judge agrees on the clear cases (its grid stops at ω = 1e-4: ε/1e-4 > 1e-7 from ε = 1e-11)
    if eps >= 1e-9 or eps == 0:
        assert bool(judge(type("G", (), {"Q": Q, "groups": [[0]]}), model, [[1]], ["f"])) == leaks


@pytest.mark.parametrize("dt", [0.0, 0.1])
@pytest.mark.parametrize("eps, leaks", [(0.0, False), (1e-15, False), (1e-11, True)])
def test_library_judge_reads_an_undamped_pair_beside_its_gap(dt, eps, leaks):
    """As above with d exciting an undamped pair (±2j; discrete e^{±0.5j}, 0.5 rad per sample): y1 = d·Gm + u/(s + 2) + f, y2 = d·Gm + u/(s + 2), r = (y1 − (1 + ε) y2)·F. The log-spaced grid
    steps 10 % past the pair, so a kept residue ρ read only ~ρ/0.2 (ε = 1e-11: 7.8e-11, passed); the judge now reads
    two gaps beside it (ρ/(2·gap), gap = 1e-6·||A||): ε = 1e-11 (residue 4.5e-12 of the unit fault gain, a resonant
    input's response growing 4.5e-12·t) reads ~1e-6 > dec_tol and is refused, while ε = 1e-15 (0.09 of the design's
    rounding δ_i, removed as cancelled) and the exact row pass."""
    from fmu_fdi.design.toolkit.postconditions import check_generator
    from fmu_fdi.generator import ResidualGenerator
    from fmu_fdi.lti import LTI

    c, s_ = (np.cos(0.5), np.sin(0.5)) if dt else (0.0, 2.0)
    A = sla.block_diag([[c, s_], [-s_, c]], [[0.5 if dt else -2.0]])
    model = FDIModel.from_matrices(A, [[0.0], [0.0], [1.0]], np.ones((2, 3)), Bd=[[1.0], [0.0], [0.0]],
                                   faults=[sensor_fault("f", "y1")], dt=dt)
    Q = LTI(np.array([[0.3 if dt else -1.0]]), np.array([[1.0, -(1.0 + eps), 0.0]]), np.array([[1.0]]),
            np.zeros((1, 3)), dt)
    fig = check_generator(ResidualGenerator(Q, model, "test"), raise_error=False)
    assert bool(fig.get("failures")) == leaks, fig
    if leaks:
        assert any("leak" in f for f in fig["failures"]), fig["failures"]


@pytest.mark.parametrize("eps, removed", [(0.0, True), (2.0 ** -50, True), (1e-13, False), (1e-12, False)])
def test_judge_reads_the_minimal_realisation_of_a_cancelled_boundary_mode(eps, removed):
    """The plant of the test above; a residue ε of the integrator at rounding level is removed as the minimal
    realisation removes it: R_d = −ε/(λ(λ + 1)) = −ε/λ + ε/(λ + 1) becomes ε/(λ + 1), while R_u =
    −ε/((λ + 1)(λ + 2)) and R_f = −1/(λ + 1) (the fault is on the second output, named y1) keep their values
    (closed forms, not the library's evaluation; R = Q·Ge given in closed form too).
    The rounding of the row's zero (postconditions._without_cancelled_modes) is, by hand: N = 2 + 1 states,
    ||A|| = sep = 2, ||Q(0)|| = max ||Q|| = √2, ||Ce|| = 2, ||c_0|| = √2:
    δ = 3·eps·(4·(2/2)·√2·2 + √2·√2) = 8.9e-15. ε = 2⁻⁵⁰ = 8.9e-16 (exact in 1 + ε) is 0.1 δ: removed;
    ε = 1e-13 (11 δ) and 1e-12 (113 δ) are real leaks: the row keeps its pole part (and the judge refuses it,
    test above)."""
    from fmu_fdi.design.toolkit.postconditions import _without_cancelled_modes
    from fmu_fdi.lti import LTI

    model = FDIModel.from_matrices(np.diag([0.0, -2.0]), [[0.0], [1.0]], np.ones((2, 2)), Bd=[[1.0], [0.0]],
                                   faults=[sensor_fault("f", "y1")])
    Q = LTI(np.array([[-1.0]]), np.array([[1.0, -(1.0 + eps), 0.0]]), np.array([[1.0]]), np.zeros((1, 3)))
    lam = 1j * np.logspace(-6, 2, 33)  # the judge reads no point within 1e-6·||A|| of the integrator
    Qv = (np.array([1.0, -(1.0 + eps), 0.0])[None, :] / (lam + 1)[:, None])[:, None, :]
    one, zero = np.ones_like(lam), np.zeros_like(lam)
    Ge = np.stack([np.stack([1 / (lam + 2), 1 / lam, zero], -1), np.stack([1 / (lam + 2), 1 / lam, one], -1),
                   np.stack([one, zero, zero], -1)], 1)               # inputs u, d, f; outputs y0, y1, u
    R = Qv @ Ge
    removals = _without_cancelled_modes(model, Q, [[0]], lam, R, Qv, Ge)
    # the integrator is removed from R_d where the row cancels it (d excites it: column 1 of Ge's inputs u, d, f)
    assert any(abs(p) < 1e-12 and mask[0, 1] for p, mask in removals) == removed, removals
    if removed:
        want = np.stack([-eps / ((lam + 1) * (lam + 2)), eps / (lam + 1), -1 / (lam + 1)], axis=1)
        # the removal subtracts the pole part from R as given: R keeps its own rounding, that of Q·Ge with
        # ||Ge|| ~ 1/|λ| (2 eps per entry of the product, |Q| ≤ √2, two terms: ≤ 6 eps/|λ|), plus 1e-15 absolute
        err = np.abs(R[:, 0, :] - want)
        assert np.all(err <= 1e-15 + 6 * np.finfo(float).eps / np.abs(lam)[:, None]), np.max(err * np.abs(lam)[:, None])


def _exact_sylvester(A, B, C) -> np.ndarray:
    """The exact solution of ``A X − X B = C`` for the floating-point data given (rational Gauss–Jordan on the
    Kronecker system ``(I ⊗ A − Bᵀ ⊗ I) vec X = vec C``, Python fractions), rounded once to float."""
    from fractions import Fraction

    n, k = A.shape[0], B.shape[0]
    K = np.kron(np.eye(k), A) - np.kron(B.T, np.eye(n))  # entries a_ij or a_ii − b_jj: exact only if that difference is
    K = [[Fraction(float(v)) for v in row] for row in K]
    for j in range(k):                                    # ... so the diagonal blocks are rebuilt exactly
        for i in range(n):
            for r in range(n):
                K[j * n + i][j * n + r] = Fraction(float(A[i, r])) - (Fraction(float(B[j, j])) if i == r else 0)
    M = [row + [Fraction(float(c))] for row, c in zip(K, C.T.reshape(-1))]
    N = n * k
    for i in range(N):
        piv = max(range(i, N), key=lambda r: abs(M[r][i]))
        M[i], M[piv] = M[piv], M[i]
        for r in range(N):
            if r != i and M[r][i] != 0:
                f = M[r][i] / M[i][i]
                M[r] = [x - f * y for x, y in zip(M[r], M[i])]
    return np.array([float(M[i][N] / M[i][i]) for i in range(N)]).reshape(k, n).T


@pytest.mark.parametrize("k", [10, 20])
def test_sylvester_forward_error_bound_holds_on_an_ill_conditioned_equation(k):
    """postconditions._sylvester's bound (Higham ch. 16: the computed residual over sep, plus the residual's own
    rounding) holds on non-normal, ill-separated equations: A = [[1, 2^k], [0, 1]] + 0.1·noise against a B with
    eigenvalues 0.05 … 0.2 from A's (sep 0.025 at k = 10, 8e-3 at 20), seeded; the reference is the exact solution
    for the same floating-point data (:func:`_exact_sylvester`). The bound must hold and say something (below
    ||X||); it is pessimistic, as norm-wise bounds on non-normal operators are (measured 1e5 … 1e9 times the error)."""
    from fmu_fdi.design.toolkit.postconditions import _sylvester

    eps = np.finfo(float).eps
    rng = np.random.default_rng(5 + k)
    A = np.array([[1.0, 2.0 ** k], [0.0, 1.0]]) + 0.1 * rng.standard_normal((2, 2))
    for B in (np.array([[1.1]]), np.array([[1.05, 0.7], [0.0, 0.9]]) + 0.01 * rng.standard_normal((2, 2))):
        C = rng.standard_normal((2, B.shape[0]))
        X = _exact_sylvester(A, B, C)
        Xh, bound = _sylvester(A.astype(complex), B.astype(complex), C.astype(complex), 4 * eps)
        err = float(np.linalg.norm(Xh - X))
        assert 0 <= err <= bound < np.linalg.norm(X), (err, bound)


def _non_normal_plant(eta: float, dt: float):
    """y = M [c; c] x + (sensor fault f on y1): d excites an undamped pair (±2j, discrete e^{±0.2j}) and a stable
    pole (−0.05) through the basis ``T = [[1, 0, 1], [0, 1, 1], [0, 0, η]]`` (eigenvector condition ~3/η: 2.8e6 at
    η = 1e-6, 2.8e8 at 1e-8, VTOL's ~4e8), u a pole −2 of its own; M mixes the outputs, so the decoupling row
    ``[1 −(1 + ε)] M⁻¹`` is inexact in floating point even for ε = 0. Returns the model and (J, T, M, Bd) for the
    closed forms."""
    J = sla.block_diag([[0.0, 2.0], [-2.0, 0.0]], [[-0.05]])
    T = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, eta]])
    Jd = sla.expm(J * dt) if dt else J
    A = sla.block_diag(T @ Jd @ np.linalg.inv(T), [[np.exp(-2 * dt) if dt else -2.0]])
    M = np.array([[0.7, 0.2], [-0.3, 1.1]])
    C = M @ np.array([[1.0, 0.3, 0.0, 1.0], [1.0, 0.3, 0.0, 1.0]])
    Bd = np.array([[0.0], [1.0], [1.0], [0.0]])
    model = FDIModel.from_matrices(A, [[0.0], [0.0], [0.0], [1.0]], C, Bd=Bd, faults=[sensor_fault("f", "y1")], dt=dt)
    return model, (Jd, T, M, Bd)


def _exact_row_through_the_stable_mode(q: np.ndarray, C: np.ndarray, T: np.ndarray, Jd: np.ndarray, Bd: np.ndarray,
                                       lam: np.ndarray) -> np.ndarray:
    """``|c_row t_s · (T⁻¹ b_d)_s / (λ − λ_s)|`` with ``c_row = q·C`` formed exactly (Fractions, from the floating-point
    q and C the filter and the model hold): the part of R_d through the plant's stable pole λ_s = J[2, 2], which no
    removal of boundary modes may discount (the pair is the only boundary mode). ``(T⁻¹ b_d)_s = 1/η`` (T
    triangular, b_d = [0 1 1]) is what makes a rounding-size c_row·t_s a visible leak."""
    from fractions import Fraction

    c_row = np.array([float(sum(Fraction(float(q[0, k])) * Fraction(float(C[k, j])) for k in range(C.shape[0])))
                      for j in range(C.shape[1])])
    return np.abs(float(c_row[:3] @ T[:, 2]) * np.linalg.solve(T, Bd[:3, 0])[2] / (lam - Jd[2, 2]))


@pytest.mark.parametrize("eta, dt, exact_row_leaks", [
    (1e-5, 0.1, False), (1e-6, 0.0, False), (1e-8, 0.0, True), (1e-8, 0.1, True)])
def test_judge_on_a_non_normal_plant_refuses_leaks_not_rounding(eta, dt, exact_row_leaks):
    """The VTOL-like case (issue 17: the DOS sensor bank was refused for the rounding of the mode-free reading,
    ``Y ~ 1/sep``): an undamped pair a row cancels, next to a stable pole, in a basis of eigenvector condition
    up to 2.8e8. The row ``r = F·[1 −(1 + ε)] M⁻¹ y``, F = 1/(λ + 1) (discrete 1/(z − 0.3)), has, in closed form
    (modal coordinates, numpy, not the library's evaluation): R_u = 0 and
    ``R_d = −ε F(λ) c T (λI − J)⁻¹ T⁻¹ b_d`` (c = [1 0.3 0]) for the exact M⁻¹. ε = 1e-12 is a true leak whose
    closed-form peak on the numpy judge's grid (≥ 1e-3 away from the poles) already exceeds dec_tol 25 … 2e5
    times, and must be refused.

    ε = 0 is exact only in exact arithmetic: the floating-point row ``q = [1 −1]·inv(M)`` against the floating-point
    ``C = M·[c; c]`` leaves ``q·C`` of 3e-16, which the stable pole's ``(T⁻¹ b_d)_s = 1/η`` turns into a true leak
    (:func:`_exact_row_through_the_stable_mode`, q·C formed exactly): 4.7e-9 (η = 1e-6, continuous), 4.7e-9
    (1e-5, discrete), 4.7e-7 and 4.7e-6 (1e-8) of the fault gain. The judge must pass the first two — its own
    rounding (the mode-free reading's, of bound up to 1e-5 here) may not be read as a leak — and refuse the last
    two: the previous reading (largest lower bound, kept at 0 where every reading's bound exceeded its size)
    accepted them with ``decoupling`` 0. Measured figures: 9.3e-10 … 8.2e-6, 1.4 … 2.0 times the exact stable-mode
    part. (η = 1e-6 discrete, 4.7e-8 exact, reads 1.19e-7, the evaluation's own rounding ``eps·|q|·|Ge_d|`` there
    being ~1e-7 of the fault gain: not asserted either way.) Whatever the verdict, the judge's figure may not read
    below the exact stable-mode part: both grids hold λ = 0 (z = 1), where that part peaks (|λ − λ_s| smallest),
    and the rest of R_d (the pair, cancelled to q·C ~ 3e-16 and removed by the judge; R_u through the pole −2 at
    3e-16) cannot take away more than half of it at 4.7e-9 and above."""
    from fmu_fdi.design.toolkit.postconditions import DEC_TOL as LIB_DEC_TOL, check_generator
    from fmu_fdi.generator import ResidualGenerator
    from fmu_fdi.lti import LTI

    model, (Jd, T, M, Bd) = _non_normal_plant(eta, dt)
    a_f = 0.3 if dt else -1.0
    lam = _grid(model)
    F = 1.0 / (lam - a_f)
    Ti_b = np.linalg.solve(T, Bd[:3, 0])                      # T⁻¹ b_d: T is triangular with entries 1, η
    cT = np.array([1.0, 0.3, 0.0]) @ T
    modal = np.array([cT @ np.linalg.solve(x * np.eye(3) - Jd, Ti_b) for x in lam])
    gain = np.abs(F * (np.linalg.inv(M)[0, 0]))             # |R_f|: the sensor fault on y1 through the row
    Cy = model.augmented().C[: model.ny]
    for eps in (0.0, 1e-12):
        q = np.array([[1.0, -(1.0 + eps)]]) @ np.linalg.inv(M)
        Q = LTI(np.array([[a_f]]), np.hstack([q, [[0.0]]]), np.array([[1.0]]), np.zeros((1, 3)), dt)
        true_leak = float(np.max(np.abs(eps * F * modal)) / np.max(gain))
        stable = float(np.max(np.abs(F) * _exact_row_through_the_stable_mode(q, Cy, T, Jd, Bd, lam)) / np.max(gain))
        leaks = exact_row_leaks if eps == 0 else True
        if eps:
            assert true_leak > 25 * LIB_DEC_TOL, true_leak
        else:  # the parametrisation's verdict, from the exact figure with a factor 2 either way
            assert (stable > 2 * LIB_DEC_TOL) if leaks else (stable < LIB_DEC_TOL / 2), stable
        fig = check_generator(ResidualGenerator(Q, model, "test"), raise_error=False)
        assert bool(fig.get("failures")) == leaks, (eps, fig.get("failures"), fig["decoupling"], stable)
        if leaks:
            assert any("leak" in f for f in fig["failures"]), fig["failures"]
        else:
            assert fig["decoupling"] <= LIB_DEC_TOL and fig["fault_gain"] == pytest.approx(1.0, rel=1e-6)
        if not eps:
            assert fig["decoupling"] >= 0.5 * stable, (fig["decoupling"], stable)


def test_boeing747_unstable_row_is_judged_by_its_leak_not_by_an_undecided_reading():
    """Boeing 747 (plant pole 3.1e-5, just unstable), row [0 0 0 0 1]: the first candidate (filter peak 5.2e5,
    |Q|·|Gf| 1.87e10) cancels the pole only to δ_i = 2.3e-5, and every reading of its mode-free R_u had an error
    bound above its size (0.27 beside the pole against 8e-8 … 2e-5). The largest-lower-bound reading kept 0 there
    and returned that candidate with ``decoupling`` 0.0 while numpy reads a u leak 5.5e-7 > dec_tol; the judge must
    refuse it and the design return a row the independent numpy judge passes (measured: the order-1 row, peak 447,
    ``decoupling`` 1.6e-12)."""
    from test_synthesis_published import boeing747

    model = boeing747()
    row = [[0, 0, 0, 0, 1]]
    gen = structured_bank(model, row, faults=model.fault_names)
    assert judge(gen, model, row, model.fault_names) == []
    assert gen.info["postconditions"]["decoupling"] <= DEC_TOL


def test_seed149_row_with_an_undecided_reading_is_designed():
    """Random seed 149, row [1 1 0 0 1] (listed achievable): the largest-lower-bound reading read fc's peak, R_u and
    R_d as exactly 0 (every reading dominated by its bound) and refused the row as numerically zero, where numpy
    reads u/d 2e-14 and fault peaks 6.1e-4, 6.8e-4, 3.2e-2. A value whose readings are all undecided is kept as the
    most accurate reading says: the row is designed and passes the independent numpy judge."""
    model = random_case(149)
    row = [[1, 1, 0, 0, 1]]
    assert row[0] in np.asarray(achievable_structure(model)).tolist()
    gen = structured_bank(model, row)
    assert judge(gen, model, row, model.fault_names) == []


def test_seed149_listed_row_is_designed():
    """Audit of seeds 60-159 (benchmarks/synthesis_random_judged.py 100 60): the one achievable row the corrected
    judge refused, and rightly — the candidate's R_fc drifted (z = 1 kept with a residue 5e4 times the rounding:
    the stable factorisation took the pole to cancel from the series realisation Q·Ge, 1.85e-10 off the plant's
    own z = 1). Designable iff achievable: the row is designed and passes the independent judge."""
    model = random_case(149)
    row = [[1, 0, 0, 1, 1]]
    assert row[0] in np.asarray(achievable_structure(model)).tolist()
    gen = structured_bank(model, row)
    assert judge(gen, model, row, model.fault_names) == []


def _minimal_order(A, B, C) -> int:
    """McMillan degree of ``C (λI − A)⁻¹ B`` for an A with distinct eigenvalues: the eigenvalues passing
    both PBH tests (numpy only, on the balanced data; the test's own PBH_TOL)."""
    A, B, C = _balanced(A, B, C)
    B = B / max(np.linalg.norm(B, 2), 1e-300)
    C = C / max(np.linalg.norm(C, 2), 1e-300)
    scale = max(1.0, np.linalg.norm(A, 2))
    n = A.shape[0]
    count = 0
    for lam in np.linalg.eigvals(A):
        M = lam * np.eye(n) - A
        if (np.linalg.svd(np.hstack([M, B]), compute_uv=False)[-1] > PBH_TOL * scale
                and np.linalg.svd(np.vstack([M, C]), compute_uv=False)[-1] > PBH_TOL * scale):
            count += 1
    return count


def test_seed21_row_is_least_order():
    """Seed 21 (discrete, one output, one input, poles within 5e-3 of z = 1 and a fault-only mode at
    z = 1): every proper row decoupling u is ``h·[1 −Gu]``, of order at least deg Gu = 9 (PBH, here), and
    ``R_fc = Q·Gfc`` keeps z = 1 unless ``h(1) = 0``: one state more (a proper h with a zero at 1 needs
    a pole). The least order of a design with a stable R is deg Gu + 1 = 10 — reached only by
    construction: the basis is of index 9 (TB01PD's staircase kept the uncontrollable z = 1 among the
    clustered poles: index 10, the pole moved by accident) and the stable factorisation of [Q R] adds
    the one moved pole."""
    model = random_case(21)
    deg_gu = _minimal_order(model.A, model.Bu, model.C)
    ev = np.linalg.eigvals(model.A)
    boundary = int(np.sum(np.abs(ev) >= 1 - STAB_TOL))
    assert deg_gu == 9 and boundary == 1
    gen = nullspace_design(model)
    assert gen.Q.n == deg_gu + boundary, gen.info
    assert gen.info["left_minimal_indices"] == [deg_gu]
    assert judge(gen, model, [[1] * len(model.faults)], model.fault_names) == []


def test_seed22_row_keeps_its_fault_pair_cancelled():
    """Seed 22's row [0 1 1 1 1] (continuous, noise w, fault fc alone excites an undamped pair at ±2j): the
    stable factorisation gives Q the zero ``Q(±2j) c = 0`` that keeps the pair out of ``R_fc``; the numerator
    refinement of the u/d leak that follows must keep it (it constrained only the boundary modes u or d
    excite, and its correction of the balanced realisation left the pair in R: the row was refused).
    Judged independently: PBH poles of the series realisation of ``R = Q·Ge`` (:func:`judge`), and
    ``R_f`` bounded beside the pair — a kept pole reads ``|residue|/δ``, 100× larger at δ = 1e-6 than
    at 1e-4, a cancelled one the same value (a factor 1.5 allows the slope of a smooth R)."""
    model = random_case(22)
    row = [[0, 1, 1, 1, 1]]
    assert model.fault_names == ["fs1", "fs2", "fa1", "fa2", "fc"]
    ev = np.linalg.eigvals(model.A)
    assert np.any(np.abs(ev - 2j) < 1e-9)
    gen = structured_bank(model, row)
    assert judge(gen, model, row, model.fault_names) == []
    A, B, Ce, De = _extended(model)
    fsl = slice(model.nu + model.nd + model.nw, None)
    Q = gen.Q
    r = [np.linalg.norm(_freqresp(Q.A, Q.B, Q.C, Q.D, np.array([x]))[0]
                        @ _freqresp(A, B, Ce, De, np.array([x]))[0][:, fsl], 2) for x in 2j * (1 + np.array([1e-4, 1e-6]))]
    assert r[1] <= 1.5 * r[0], r


def test_seed173_row_keeps_its_unstable_fault_mode_cancelled():
    """Audit of seeds 160-319: seed 173 (discrete, n = 28, noise w; fault fc alone excites z = 1.105), row
    [1 1 1 0 1] (fa2 decoupled), listed by achievable_structure, was refused: "R = Q·Ge keeps the plant pole(s)
    [1.105]". The stable factor had cancelled it (Q(1.105)·c = 0), and the numerator refinement of the u/d leak
    that follows moved that zero: its residue constraints held only modes on the boundary, and the refinement
    reads no point of R_f. Designable iff achievable: the row is designed and the independent judge (PBH poles
    of the series realisation of R) passes it."""
    model = random_case(173)
    row = [[1, 1, 1, 0, 1]]
    assert row[0] in np.asarray(achievable_structure(model)).tolist()
    ev = np.linalg.eigvals(model.A)
    assert np.any(np.abs(ev - np.exp(0.1)) < 1e-9)
    gen = structured_bank(model, row)
    assert judge(gen, model, row, model.fault_names) == []


def test_grid_points_beside_poles_are_judged_by_each_pole_scale():
    """freqresp.beside_poles, the one "grid point on a plant pole" test of the designs (nullspace's peaks, noise
    combination and refinement skip such points; approximate matching moves them): within 1e-6 of the pole's own
    magnitude, a pole at 0 (below sqrt(eps) of the median magnitude: an integrator computed 1e-17 off) at the
    scale of the smallest other pole. A far pole (an H∞ filter's at 4e9) must neither widen the others'
    neighbourhoods nor make the poles ~1 count as zero (approximate matching options seed 26)."""
    from fmu_fdi.freqresp import beside_poles

    poles = np.array([1e-17, -0.5 + 1j, -0.5 - 1j, -1.0, -4e9])
    pts = 1j * np.array([0.0, 4e-7, 1e-5, 1.0 + 1e-6, 1.0 + 1e-4, 4e9, 1e3, 1e-3])
    on, radius = beside_poles(pts, poles)
    # |-0.5 ± 1j| = 1.118: the point j(1 + 1e-6) is 0.5 away from it; 1e-3·j is 1e-3 from the zero pole
    # (radius 1e-6 × the smallest other magnitude 1.0): beside nothing
    assert on.tolist() == [True, True, False, False, False, False, False, False], on
    assert radius[0] == pytest.approx(1e-6) and radius[5] == pytest.approx(4e3)
    on, _ = beside_poles([-0.5 + 1j * (1 + 1e-7), -1.0 + 2e-6j, -4e9 + 3e3j], poles)
    assert on.tolist() == [True, False, True], on
    # discrete: points on |z| = 1, a pole at z = 1 (rounded) and the scale 1
    on, _ = beside_poles(np.exp(1j * np.array([0.0, 5e-7, 5e-6])), [1.0 - 1e-15, 0.5], dt=0.1)
    assert on.tolist() == [True, True, False], on


def test_repeated_pole_targets_are_made_distinct():
    """The pencil basis moves its unstable eigenvalues one Schur block at a time; two real blocks given one
    conjugate pair as targets took the pair's speed twice. With one input that double eigenvalue is a Jordan
    block, computed ~sqrt(eps) apart (random seed 218's row [1 1 0 1 0]: -0.41995 twice; seed 207's: 0.999
    twice, which split to 1.0009 ± 0.0038j beyond the margin and were moved 15 times). Here, in closed form: a
    single-input controllable pair (a companion matrix with eigenvalues 2, 3, -0.5, -4) whose bad eigenvalues 2
    and 3 get the targets -1 ± 1j: every eigenvalue after the feedback (numpy's eig of a + b F) lies in the
    region, the moved ones apart by more than 1e-3 (a Jordan block's computed pair is ~1e-8 apart), the kept
    ones where they were (to 1e-9)."""
    from fmu_fdi.design.toolkit.pencil import assign_poles

    coeffs = np.poly([2.0, 3.0, -0.5, -4.0])
    a = np.zeros((4, 4))
    a[0, :] = -coeffs[1:]
    a[1:, :3] = np.eye(3)
    b = np.array([[1.0], [0.0], [0.0], [0.0]])
    F, moved = assign_poles(a, b, 0.0, lambda bad: np.array([-1 + 1j, -1 - 1j])[:bad.size],
                            lambda re, im: re < 0)
    ev = np.sort_complex(np.linalg.eigvals(a + b @ F))
    assert moved == 2 and np.all(ev.real < 0), ev
    new = [z for z in ev if min(abs(z + 0.5), abs(z + 4)) > 1e-6]
    assert len(new) == 2 and abs(new[0] - new[1]) > 1e-3, ev
    assert min(abs(ev + 0.5)) < 1e-9 and min(abs(ev + 4)) < 1e-9, ev


@pytest.mark.parametrize("seed, row, what", [
    # Audit of seeds 199-258 (benchmarks/synthesis_random_judged.py 60 199): three listed rows refused.
    (207, [1, 1, 0, 1, 0], "discrete, n = 13, noise w; fc (decoupled) excites an undamped pair on |z| = 1: the one "
                           "row that decouples w too (order 12) needs a feedback of norm 2.4e5 (the least possible) "
                           "to move a basis pole 48 of controllability 2e-4; formed as a + bF it leaked 1.9e-6 of the "
                           "weakest fault gain, realised in the closed loop's Schur coordinates it decouples w "
                           "(tests/test_synthesis_pencil.py::test_random_seed207_row_decouples_noise_exactly)"),
    (218, [1, 1, 0, 1, 0], "continuous, n = 25: the pencil basis sent two real blocks to one target -0.41995 (a pair's "
                           "speed taken twice), a defective double pole; leak 1.1e-7"),
    (239, [0, 1, 0, 0, 1], "discrete, n = 21, plant poles within 8e-3 of fc's z = 1: the numerator refinement lowered "
                           "the leak 4 % on its 77 points and raised it 28 times between them (Q(1)·c from 2.5e-8 to "
                           "1.4e-5: z = 1 back in R_fc); it is kept only when the judge reads it better"),
    # Audit of seeds 259-318 (benchmarks/synthesis_random_judged.py 60 259): the one listed row refused.
    (307, [0, 1, 1, 0, 1], "discrete, n = 19, fc's fault-only z = 1, w not decouplable; was refused: 'R = Q·Ge keeps "
                           "the plant pole 1: residue ||Q_1(p) c_p|| = 1.07e-12 > δ_i = 8.38e-13'. The stable factor "
                           "(order 19) cancelled z = 1 to 1.2e-14 against δ_i = 6.7e-12; the noise normaliser's "
                           "product fac·Q1 (order 39) read 1.1e-13 and its balanced re-realisation "
                           "(stable_factor.conditioned_realisation, order 24) kept it against δ_i = 9.6e-14. "
                           "nullspace._boundary_modes_cancelled re-imposes Q(p) c_p = 0 exactly "
                           "(refine.cancel_residues, [B_q; D_q] moved by 3.9e-15 relative)"),
    # Audit of seeds 319-348 (benchmarks/synthesis_random_judged.py 30 319), on the code before that stage.
    (319, [1, 0, 1, 1, 1], "discrete, n = 27, p = 4, m = 6, nd = 2, noise w not decouplable, fc's fault-only z = 1; "
                           "was refused: 'residue ||Q_1(p) c_p|| = 1.54e-12 > δ_i = 1.1e-12'. The noise "
                           "normaliser's product (order 48) kept the stable factor's zero (7.4e-15 against δ_i "
                           "2.7e-12); the balanced re-realisation of conditioned_realisation (order 48 → 42, at "
                           "unit fault peak) raised the residue 38-fold to 2.8e-13 against δ_i 2.0e-13. The exact "
                           "cancellation after it (nullspace._boundary_modes_cancelled) designs the row"),
])
def test_audited_listed_rows_are_designed(seed, row, what):
    """Audits of the random seeds (benchmarks/synthesis_random_judged.py): rows achievable_structure lists that
    structured_bank refused or returned failing the judge (each case's story is its ``what``). Designable iff
    achievable: each is designed and passes the independent numpy judge."""
    model = random_case(seed)
    assert row in np.asarray(achievable_structure(model)).tolist()
    gen = structured_bank(model, [row])
    assert judge(gen, model, [row], model.fault_names) == [], what


def test_audit_349_378_seed359_listed_row_is_designed():
    """Audit of seeds 349-378 (benchmarks/synthesis_random_judged.py 30 349): seed 359's row [0 1 1 0 0] (discrete,
    n = 9, p = 4, m = 7, fc's undamped pair e^{±0.2j} decoupled) was refused: "u+d leak 7.99e-07 × the weakest fault
    gain". The row's order-8 filter has a pole pair 0.0058 from the pair it must cancel and computes Q(p) = 70 from
    terms of size 4.3e7 (componentwise condition κ; amplification 3961, below conditioned_realisation's 1e4): its
    residue 1.1e-12 is within its rounding bound δ_i = 1.6e-7, but R_u, read two of the judge's gaps beside p,
    leaks 8e-7. Its balanced realisation (κ = 747) reads 3.0e-8 (nullspace._boundary_modes_cancelled). The library's
    own judge decides here (numpy's grid stays 1e-3 from the poles and passed both), so the returned row's
    post-conditions are asserted as well as numpy's verdict."""
    model = random_case(359)
    row = [[0, 1, 1, 0, 0]]
    assert row[0] in np.asarray(achievable_structure(model)).tolist()
    gen = structured_bank(model, row)
    assert judge(gen, model, row, model.fault_names) == []
    assert gen.info["postconditions"]["decoupling"] <= 1e-7


@pytest.mark.slow
def test_seed218_bank_of_every_listed_row_is_designed():
    """Audit of seeds 199-258, rechecked after the fixes: seed 218's structured_bank over every listed row. Was refused
    for row 11 [1 1 0 1 0]: its excluded fault fc read 1.18e-7 of the weakest required fault gain in the 16-row bank
    (the bank's one grid, from every member's poles, put a point at ω = 2.07e-5 beside the plant's integrator), 3.3e-8
    alone; every row group is now read on its own filter and grid (postconditions._figures_by_group)."""
    model = random_case(218)
    rows = np.asarray(achievable_structure(model), int)
    gen = structured_bank(model, rows)
    assert judge(gen, model, rows, model.fault_names) == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", [51, 58, 60])
def test_approximate_audit_detection_row_references_are_matched(seed):
    """Audit of the approximate designs, seeds 40-63 (benchmarks/approximate_random_judged.py 24 40, on f08e977):
    matching the fault response of an exact detection row (an admissible filter: the error 0 is attainable up to the
    noise) was refused or broken. Seed 51 (discrete, n = 29, plant poles 0.9912 … 0.9959 next to z = 1): Y (order
    67, peak 9e4) Φ Q0 leaked u at 1.1e-12 of the strongest fault gain, the shipped order-98 realisation at 8.6e-11
    (2.7e-7 on the normalised form, numpy) and was refused for decoupling; seed 58: R kept the fault-only mode +1
    (residue 3.87e-9 against its rounding bound 4.22e-12) and leaked u; seed 60: "error response differs from the
    designed one by 5.43 (relative 0.628)". All three pass the numpy judge with the reduced problem's realisations of
    this session (approximate_matching._observer_basis: the basis moves only the plant's poles outside the margin;
    _shipped_filter reads the shipped response as the post-conditions read R) — measured: with those alone all three
    pass, with the exact cancellation (_plant_mode_cancellation) alone none does."""
    from test_approximate_random import check_case as approximate_case

    res = approximate_case(seed, calls=("amm_ref",))
    assert res and all(st == "ok" for _, st, _ in res), res


@pytest.mark.slow
def test_seed163_listed_row_is_designed():
    """Audit of seeds 160-319 (benchmarks/synthesis_random_judged.py): seed 163 (discrete, n = 24, p = 3, m = 5,
    noise w) row [1 1 0 0] (fa1, fa2 decoupled), listed by achievable_structure, was refused (at 1a76c91): "u+d leak 1.47e-07 ×
    the weakest fault gain". The design (co-outer normalised, order 72) is clean: numpy reads ‖R_u‖ = 1.5e-9 of the
    fault gain (1.6e-9 at the library's worst point, 3.0e-10 by an 80-bit LU solve there). The library judge reads
    Q by the Schur form of its balanced A, whose backward error, through an eigenvalue pair of condition 1.9e7
    next to the point, puts 1.6e-8 (5e-10 relative) into Q(z) — times ‖Ge‖ = 432 a false leak. Designable iff
    achievable: the row must be designed and pass the independent judge. (Since integ4 the row's filter has order
    46 and is read by dense solves; the order-72 reading is the freqresp.py test of the Hessenberg path.)"""
    model = random_case(163)
    row = [[1, 1, 0, 0]]
    assert row[0] in np.asarray(achievable_structure(model)).tolist()
    gen = structured_bank(model, row)
    assert judge(gen, model, row, model.fault_names) == []


@pytest.mark.parametrize("seed, what", [
    (21, "discrete plant with eigenvalues within 5e-3 of z = 1 and a fault-only mode at z = 1: the stable "
         "factorisation of the internal form must move that mode alone"),
    (37, "discrete clustered plant with noise w: the approximate design on the pencil bases"),
])
def test_cheap_slow_seeds_in_the_default_run(seed, what):
    """Two of the slow set's seeds that cost about a second each, run by default: each was broken
    (refused as "too ill-conditioned") until the fix its label names."""
    _assert_case(seed, max_rows=6)


@pytest.mark.slow
@pytest.mark.parametrize("seed", _seeds(range(N_FAST, N_FAST + N_SLOW)))
def test_random_design_meets_the_judge_slow(seed):
    _assert_case(seed, max_rows=6)


if __name__ == "__main__":  # quick manual run: python tests/test_synthesis_random.py [N]
    t0 = time.perf_counter()
    for s in range(int(sys.argv[1]) if len(sys.argv) > 1 else 10):
        t = time.perf_counter()
        for r in check_case(s):
            print(s, f"{time.perf_counter() - t:5.1f}s", *r)
    print(f"{time.perf_counter() - t0:.1f} s")


def test_judge_grid_reaches_the_plant_beside_a_fast_filter_pole():
    """The judge's grid floor (no points below 1e-9 of the top, against an integrator computed at 1e-17) may not
    rise above the plant's dynamics: approximate matching's order-3 row of random seed 32 (filter pole 1.4e7,
    grid top 1.4e9) was judged without a point below 1.6 rad/s, and its u leak read 8e-8 where numpy reads 1.5e-7
    at 0.94 rad/s. Here, in closed form: y = u/(s + 1) + f, ``q_y = P/(s + P)`` (P = 1e7), ``q_u = −q_y/(s + 1) +
    ε s/(s² + 0.02 s + 0.01)``, so ``R_f = q_y`` (peak 1 at s = 0) and ``R_u = ε s/(s² + 0.02 s + 0.01)``, whose
    peak 50 ε = 5e-7 sits at 0.1 rad/s and which is below 1.1e-8 (= ε/(ω·|1 − 0.01/ω²|)) from 1 rad/s up: a grid
    floored at 1.4 rad/s would pass it (measured: 4.7e-7 read, refused)."""
    from fmu_fdi.design.toolkit.postconditions import check_generator
    from fmu_fdi.generator import ResidualGenerator
    from fmu_fdi.lti import LTI

    P, eps = 1e7, 1e-8
    model = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], faults=[sensor_fault("f", "y0")])
    qy = LTI([[-P]], [[P]], [[1.0]], [[0.0]])
    lag = LTI([[-1.0]], [[1.0]], [[1.0]], [[0.0]])
    res = LTI([[0.0, 1.0], [-0.01, -0.02]], [[0.0], [1.0]], [[0.0, eps]], [[0.0]])   # ε s/(s² + 0.02 s + 0.01)
    qu = res - qy @ lag
    A = sla.block_diag(qy.A, qu.A)
    Q = LTI(A, sla.block_diag(qy.B, qu.B), np.hstack([qy.C, qu.C]), np.hstack([qy.D, qu.D]))
    w = np.logspace(-3, 3, 2001)
    numpy_leak = float(np.max(np.abs(eps * 1j * w / ((1j * w) ** 2 + 0.02j * w + 0.01))))
    assert numpy_leak == pytest.approx(50 * eps, rel=1e-3)
    fig = check_generator(ResidualGenerator(Q, model, "test"), raise_error=False)
    assert fig["fault_gain"] == pytest.approx(1.0, rel=1e-6)
    # the judge's log grid (~10 % steps) against a resonance of half-power width 20 %: at least half the peak
    assert 0.5 * numpy_leak <= fig["decoupling"] <= 1.01 * numpy_leak, (fig["decoupling"], numpy_leak)
    assert any("leak" in f for f in fig["failures"]), fig.get("failures")
