"""Beard–Jones fault detection filter: an output observer that gives each fault a fixed
output direction (Beard 1971; Jones 1973; White & Speyer 1987; Chen & Patton 1999, ch. 4).

For faults ``x' = A x + Bu u + Σ_i f_i ν_i`` with fixed directions ``f_i`` (columns of Bf:
actuator and component faults) the observer ``x̂' = A x̂ + Bu u + D (y − C x̂ − Du u)``
has the residual ``r = y − ŷ = C e``, ``e' = (A − D C) e + Σ_i f_i ν_i``. Let

- ``k_i``, the detectability index of fault i: the smallest k with ``C A^{k−1} f_i ≠ 0``;
- ``f_i* = A^{k_i−1} f_i``, its detector direction, and ``F* = [f_1*, ..., f_q*]``;
- ``p_i(λ)``, the monic polynomial of degree ``k_i`` whose roots are the poles requested
  for fault i.

A gain with

    D C F* = [p_1(A) f_1, ..., p_q(A) f_q]

makes the detection space ``W_i = span{f_i, A f_i, ..., A^{k_i−1} f_i}`` invariant under
``A − D C`` with characteristic polynomial ``p_i`` on it (for j < k_i − 1,
``(A − D C) A^j f_i = A^{j+1} f_i`` because ``C A^j f_i = 0``; and
``(A − D C) f_i* = A^{k_i} f_i − p_i(A) f_i`` lies in ``W_i``). Since ``C W_i = span{C f_i*}``,
fault i then moves r only along the fixed output direction ``C f_i*`` — directional
residuals, isolated by the direction of r. A solution exists when the faults are
*mutually detectable*, ``rank C F* = q`` (Beard 1971), which also makes the detection
spaces independent. All solutions are

    D = P (C F*)⁺ + D2 U⊥ᵀ,        U⊥ an orthonormal basis of range(C F*)^⊥,

and ``D2`` places the remaining eigenvalues through the projected output ``U⊥ᵀ C`` (the
part of y no fault direction uses). Modes unobservable from it beyond the detection
spaces — the invariant zeros of the fault channels (White & Speyer 1987) — cannot be
moved and must be stable.

Sensor faults (a nonzero Df column) are not given a direction: a sensor fault acts on y
directly and, written as a state fault, needs two directions (``h`` and ``A h`` with
``C h = e_j``, the second driven by the fault's derivative), so its response fills a plane.
They are rejected with an error that says so; leave them out with ``faults=``.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import default_rtol, rank, right_null
from ...model import FDIModel
from ._observer import (check_pole_set, default_poles, observable_order, observer_gain,
                        observer_generator, output_observer, residual_names)


def fault_detection_filter(model: FDIModel, poles=None, faults=None, *, atol: float = 0.0) -> ResidualGenerator:
    """Beard–Jones detection filter: fault i drives ``r = y − ŷ`` along ``C f_i*`` only.

    Parameters
    ----------
    model : FDIModel
        Continuous or discrete (designed directly in discrete time).
    poles : array_like, optional
        The filter eigenvalues, in this order: ``k_1`` roots of ``p_1`` (fault 1's detection
        space), ..., ``k_q`` roots of ``p_q``, then the assignable remainder. Each fault's
        block must be closed under conjugation. The count is ``Σ k_i`` plus the number of
        modes observable from the projected output; a wrong count raises an error that
        gives both. Default: distinct poles twice as fast as the plant's modes.
    faults : list of str, optional
        The faults to give directions to (default: all faults of the model). Other faults
        are not constrained: they move r in no particular direction.
    atol : float
        Absolute rank tolerance of the observability staircase (Varga's ``atol``): singular values at or
        below ``max(rtol·||[A; C]||, atol)`` count as zero (default 0: relative only).

    Returns
    -------
    ResidualGenerator
        One residual group, ``r = y − C x̂ − Du u``. ``info``: ``faults``,
        ``detection_orders`` {name: k_i}, ``fault_directions`` {name: unit vector C f_i*/‖C f_i*‖
        (sign: largest entry positive)}, ``detector_directions`` {name: f_i*}, ``gain`` D,
        ``poles`` (detection-space roots then the remainder), ``fixed_modes``,
        ``eigenvector_condition`` (of A − D C), ``detected_faults``.

    Notes
    -----
    Zero-order-hold sampling destroys the structural zeros ``C A^j f_i = 0``: a fault with
    index 2 in continuous time has index 1 on the sampled model, with a small ``C Γ f_i``,
    and the filter needs a large gain (large ``eigenvector_condition``). Prefer a
    discrete model that keeps the structure, or the continuous design (whose sampled
    version keeps the directions only approximately).

    Raises
    ------
    DesignError
        A named fault does not exist, is a sensor fault (Df ≠ 0) or has several columns; a
        fault is undetectable (``C A^k f_i = 0`` for all k); faults not mutually detectable
        (``rank C F* < q``; names the dependent faults); unstable modes that no gain can
        assign (named); poles invalid or of the wrong count.

    References
    ----------
    R. V. Beard, Failure accommodation in linear systems through self-reorganization, PhD thesis, MIT 1971.
    H. L. Jones, Failure detection in linear systems, PhD thesis, MIT 1973.
    J. E. White and J. L. Speyer, Detection filter design: spectral theory and algorithms, IEEE TAC 32(7), 1987.
    J. Chen and R. J. Patton, *Robust Model-Based Fault Diagnosis for Dynamic Systems*, 1999, ch. 4.
    """
    A, C = model.A, model.C
    n, p = model.n, model.ny
    names = _fault_names(model, faults)
    fvec = [_direction(model, nm) for nm in names]
    q = len(names)

    orders, fstar = _detection_orders(A, C, names, fvec)
    Fs = np.column_stack(fstar)
    G = C @ Fs  # output directions C f_i*
    _check_mutual(G, names, p)
    nk = int(sum(orders))

    # distinct over the whole filter (no accidental Jordan blocks) and real: a detection space of
    # order 1 cannot hold a conjugate pair of the plant-speed defaults
    defaults = _real_speeds(default_poles(n, model.dt, A), model.dt)
    given, blocks = _pole_blocks(poles, defaults, orders, names, model.dt)

    Pcols = [_poly_times(A, f, blk) for f, blk in zip(fvec, blocks)]
    U, _, _ = sla.svd(G, full_matrices=True)
    Uperp = U[:, q:]
    D1 = np.column_stack(Pcols) @ np.linalg.pinv(G)
    A0 = A - D1 @ C
    Cbar = Uperp.T @ C
    fixed_reason = ("they lie outside the detection spaces and the projected output (I − Π) y cannot see them: "
                    "they are invariant zeros of the fault channels (A, f_i, C) (White & Speyer 1987), which no "
                    "detection filter with these fault directions can move")
    # The detection spaces W are (A - D1 C)-invariant and invisible to the projected output by
    # construction (C W ⊂ range C F*), so the remaining modes live on the quotient: with
    # T = [W, W⊥] orthogonal, A0 is block upper triangular and only (W⊥ᵀ A0 W⊥, Cbar W⊥) is
    # left to place. Working there keeps a rank decision from calling detection-space modes
    # observable (it did with redundant sensors, where Cbar has a structurally zero row).
    Wdet = np.column_stack([np.linalg.matrix_power(A, j) @ f for f, k in zip(fvec, orders) for j in range(k)])
    Qw, _ = sla.qr(Wdet)
    Wperp = Qw[:, nk:]
    leak = np.linalg.norm(Wperp.T @ A0 @ Qw[:, :nk]) if nk and n > nk else 0.0
    if leak > 1e-6 * max(1.0, np.linalg.norm(A0, 2)):
        raise DesignError(f"the detection spaces are not invariant under A - D1 C (leak {leak:.3g}): the fault "
                          f"directions are too close to dependent for this placement")
    A_R, C_R = Wperp.T @ A0 @ Wperp, Cbar @ Wperp
    n_o = observable_order(A_R, C_R, model.dt, what="the Beard–Jones filter", fixed_reason=fixed_reason, atol=atol)
    rest = defaults[nk:nk + n_o]
    if given is not None:
        rest = given[nk:]
        if rest.size != n_o:
            raise DesignError(
                f"{given.size} poles given but the Beard–Jones filter assigns {nk + n_o}: {nk} for the detection "
                f"spaces (k = {dict(zip(names, orders))}) and {n_o} through the projected output"
                + (f"; the other {n - nk - n_o} modes are fixed" if n - nk - n_o else ""))
    gain = observer_gain(A_R, C_R, rest, model.dt, what="the Beard–Jones filter", fixed_reason=fixed_reason,
                         atol=atol)
    Dgain = D1 + Wperp @ gain.L @ Uperp.T
    Q = output_observer(model, Dgain)

    detection_roots = np.concatenate(blocks)
    info = {
        "faults": names,
        "detection_orders": dict(zip(names, orders)),
        "fault_directions": {nm: _unit(g).tolist() for nm, g in zip(names, G.T)},
        "detector_directions": {nm: v.tolist() for nm, v in zip(names, fstar)},
        "gain": Dgain.tolist(),
        "poles": np.concatenate([detection_roots, gain.poles]).tolist(),
        "fixed_modes": np.asarray(gain.fixed).tolist(),  # the quotient's unobservable modes only
        "placement": gain.method,
        # Large values (≳ 1e6) mean a fault direction is nearly invisible: the exact
        # directions then rest on a large gain, and rounding in r grows with it.
        "eigenvector_condition": float(np.linalg.cond(np.linalg.eig(Q.A)[1])) if n else 1.0,
    }
    return observer_generator(model, Q, "fault_detection_filter", info, residual_names(model))


def _detection_orders(A, C, names, fvec):
    """Stage of :func:`fault_detection_filter`: each fault's detectability index k_i and detector
    direction ``f_i* = A^(k_i - 1) f_i`` (an undetectable fault is refused)."""
    orders, fstar = [], []
    for nm, f in zip(names, fvec):
        k, v = _detectability_index(A, C, f)
        if k is None:
            raise DesignError(f"fault '{nm}' is undetectable: C A^k f = 0 for every k (its direction lies in the "
                              f"unobservable subspace of (A, C)), so no observer residual can see it")
        orders.append(k)
        fstar.append(v)
    return orders, fstar


def _pole_blocks(poles, defaults, orders, names, dt):
    """Stage of :func:`fault_detection_filter`: the poles of each fault's detection space (k_i
    each, from ``poles`` or the defaults); returns ``(poles given or None, blocks)``."""
    nk = int(sum(orders))
    if poles is None:
        given = None
        blocks = np.split(defaults[:nk], np.cumsum(orders)[:-1])
    else:
        given = check_pole_set(poles, dt)
        if given.size < nk:
            raise DesignError(f"{given.size} poles given, but the detection spaces alone need {nk}: "
                              f"k = {dict(zip(names, orders))} (one pole per dimension, fault by fault)")
        blocks = np.split(given[:nk], np.cumsum(orders)[:-1])
        for nm, blk in zip(names, blocks):
            check_pole_set(blk, dt, what=f"poles of the detection space of fault '{nm}'")
    return given, blocks


def _fault_names(model: FDIModel, faults) -> list[str]:
    names = list(model.fault_names if faults is None else ([faults] if isinstance(faults, str) else faults))
    if not names:
        raise DesignError("no faults to give directions to: the model has none, or faults=[] was passed")
    for nm in names:
        if nm not in model.fault_names:
            raise DesignError(f"unknown fault {nm!r}; the model's faults are {model.fault_names}")
    if len(set(names)) != len(names):
        raise DesignError(f"faults lists a fault twice: {names}")
    return names


def _direction(model: FDIModel, name: str) -> np.ndarray:
    """The single state direction f_i of a fault, or the reason it has none."""
    spec = model.fault(name)
    Bf, Df = model.Bf[:, spec.columns], model.Df[:, spec.columns]
    if np.any(Df):
        rest = [nm for nm in model.fault_names if nm != name]
        raise DesignError(
            f"fault '{name}' acts on the measurements directly (its Df column is nonzero, e.g. a sensor fault): "
            f"the Beard–Jones filter gives fixed output directions only to faults of the state equation; a "
            f"measurement fault is a state fault in two directions (h and A h with C h = Df, the second driven "
            f"by the fault's derivative) and fills a plane of residual space. Leave it out, e.g. "
            f"faults={rest}, or isolate it with dedicated_bank")
    if Bf.shape[1] != 1:
        raise DesignError(f"fault '{name}' has {Bf.shape[1]} columns: the Beard–Jones filter gives one fixed "
                          f"direction per fault; split it into single-column component faults")
    return Bf[:, 0]


def _detectability_index(A: np.ndarray, C: np.ndarray, f: np.ndarray) -> tuple[int | None, np.ndarray]:
    """``(k, A^{k−1} f)`` with k the smallest index such that ``C A^{k−1} f ≠ 0``.

    ``C v`` counts as zero below ``1e3 max(n, p) eps ||C|| ||v||`` (a rounding-level
    fraction of what C could make of v). Cayley–Hamilton: if k > n there is none.
    """
    n, p = A.shape[0], C.shape[0]
    normC = float(np.linalg.norm(C, 2))
    tol = default_rtol((n, p)) * normC
    v = f.astype(float)
    for k in range(1, n + 1):
        nv = float(np.linalg.norm(v))
        if nv == 0.0:
            break
        if np.linalg.norm(C @ v) > tol * nv:
            return k, v
        v = A @ v
    return None, v


def _check_mutual(G: np.ndarray, names: list[str], p: int) -> None:
    """``rank C F* = q`` with column-normalised C F* (the decision must not depend on scaling)."""
    q = G.shape[1]
    Gn = G / np.linalg.norm(G, axis=0)
    if rank(Gn) == q:
        return
    N = right_null(Gn)
    dependent = [nm for nm, row in zip(names, N) if np.max(np.abs(row)) > 1e-8]
    why = f" (there are {q} faults but only {p} outputs)" if q > p else ""
    raise DesignError(
        f"the faults {dependent} are not mutually detectable: their output directions C f* are linearly "
        f"dependent (rank C F* = {rank(Gn)} < {q} faults){why}, so the filter cannot give each of them its own "
        f"fixed direction. Give directions to fewer faults (faults=...) or add sensors")


def _real_speeds(poles: np.ndarray, dt: float) -> np.ndarray:
    """Real poles as fast as ``poles`` (``|z|`` in discrete, ``−|λ|`` in continuous time), made
    distinct by a few per cent where a conjugate pair collapses onto one value."""
    out: list[complex] = []
    for q in poles:
        r = abs(q) if dt else -abs(q)
        while any(abs(r - o) <= 1e-9 * max(1.0, abs(r)) for o in out):
            r = r * 0.95 if dt else r * 1.05
        out.append(complex(r))
    return np.array(out, complex)


def _poly_times(A: np.ndarray, f: np.ndarray, roots: np.ndarray) -> np.ndarray:
    """``p(A) f`` for the monic polynomial with the given roots (Horner; real coefficients)."""
    coef = np.real(np.poly(roots)) if roots.size else np.array([1.0])
    v = coef[0] * f
    for c in coef[1:]:
        v = A @ v + c * f
    return v


def _unit(g: np.ndarray) -> np.ndarray:
    """``g / ||g||`` with its largest-magnitude entry positive (a reproducible sign)."""
    u = g / np.linalg.norm(g)
    return u if u[np.argmax(np.abs(u))] > 0 else -u
