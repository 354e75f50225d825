"""Parity space residual generation (Chow and Willsky 1984; Frank, section 4).

Over a window of s+1 samples the discrete plant satisfies

    Y_s(k) = O_s x(k-s) + H_{u,s} U_s(k) + H_{d,s} D_s(k) + H_{f,s} F_s(k)

with the stacked samples ``Y_s(k) = [y(k-s); ...; y(k)]``, the observability matrix
``O_s = [C; CA; ...; CA^s]`` and lower block-triangular Toeplitz matrices of Markov
parameters. A *parity vector* v with ``v [O_s H_{d,s}] = 0`` gives the finite-memory
residual

    r(k) = v (Y_s(k) - H_{u,s} U_s(k)) = v H_{f,s} F_s(k),

exactly decoupled from the state, the known inputs and the unknown inputs. All rows
of ``null([O_s H_{d,s}]^T)`` form the Chow–Willsky parity relations of order s.

When no parity vector of order s exists or none sees every fault, the optimal robust
parity vector (Lou, Willsky and Verghese 1986; Ding 2008, sec. 6.3) still removes the
state, ``v O_s = 0``, and minimises the ratio of disturbance to fault energy

    J(v) = ||v H_{d,s}||^2 / ||v H_{f,s}||^2,

a generalised symmetric eigenvalue problem (noise inputs w count as disturbances
here). The filter is the FIR realisation ``Q(z) = N(z) / z^s`` (all poles at 0).

When fewer residuals than parity relations are asked for and the model has noise inputs w,
the exact design keeps the rdim combinations of largest steady-state fault-to-noise ratio

    R(v) = ||v H_{f,s} (1 ⊗ I)||^2 / ||v H_{w,s}||^2      (v in the parity space),

the same generalised eigenvalue problem with the noise as the disturbance and constant faults
(their response over the window summed). Its eigenvectors do not depend on which basis of the
parity space the rank decisions produced, nor on its operator scaling ρ (up to the choice
among directions of equal ratio), and give every residual unit noise variance per sample
(unit-variance w). Before, the combination maximised the fault sensitivity condition from that
basis as it came: on the wind-turbine pitch model (order 4, 6 of 24 relations) changing ρ
from 2 to 1 moved the steady-state fault-to-threshold ratios of the three sensor faults from
0.53, 0.48, 0.75 to 0.43, 0.58, 0.26; this choice gives 1.38 for each (ρ = 1).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import left_null, rank_tol, single_blas_thread
from ...model import FDIModel
from ..toolkit._basis import NullspaceBasis, ParityData, _block_toeplitz, realize_rows
from .nullspace import _exact, detectability_by_rows, undetectable_error
from ..toolkit.postconditions import check_generator
from ..toolkit.notes import keeps_notes


@keeps_notes
@single_blas_thread
def parity_space(model: FDIModel, order: int | None = None, *, Ts: float | None = None, rdim: int | None = None,
                 robust: str | bool = "auto", FDtol: float = 1e-4, tol: float | None = None,
                 seed: int = 0, atol: float = 0.0) -> ResidualGenerator:
    """Finite-memory parity-space residual generator of order ``order``.

    Parameters
    ----------
    model : FDIModel
        A discrete model, or a continuous one together with ``Ts`` (it is then
        discretised exactly with a zero-order hold of every input).
    order : int, optional
        The parity order s (window of s+1 samples), ``0 <= s``. Default: the smallest order
        with an exact parity relation that sees every fault (the robust design at order n
        when there is none).
    Ts : float, optional
        Sample time for a continuous model.
    rdim : int, optional
        Number of residuals. Exact design: default all parity relations of order s (the
        Chow–Willsky residual vector); a smaller number selects the combinations of largest
        steady-state fault-to-noise ratio when the model has noise inputs w (module docstring;
        ``info['fault_to_noise']``), else those with the best fault sensitivity condition.
        Robust design: default 1 (the optimal vector).
    robust : {'auto', True, False}
        'auto' uses exact decoupling when a parity vector of order s sees every fault and
        the optimal robust vector otherwise; True forces the robust design; False raises
        a DesignError when exact decoupling is impossible at this order.
    FDtol, tol, seed
        Detectability threshold, rank tolerance, seed of the combination search.
    atol : float
        Absolute rank tolerance (Varga's ``atol``): singular values at or below
        ``max(tol·σ_max, atol)`` of the column-normalised ``[O_s H_d,s]`` (exact design) and of
        ``O_s`` and ``Z H_f,s`` (robust design) count as zero.

    Returns
    -------
    ResidualGenerator
        Discrete, poles at 0. ``info['parity_matrix']`` holds the parity vectors (in the
        scaled operator of ``info['rho']``) and ``info['mode']`` is 'exact' or 'robust'
        (with ``info['robustness_ratio'] = sqrt(J)``).
    """
    if order is not None and (not isinstance(order, (int, np.integer)) or order < 0):
        raise DesignError(f"parity order must be a non-negative integer, got {order!r}")
    if robust not in ("auto", True, False):
        raise DesignError(f"robust must be 'auto', True or False, got {robust!r}")
    if rdim is not None and (not isinstance(rdim, (int, np.integer)) or rdim < 1):
        raise DesignError(f"rdim must be a positive integer, got {rdim!r}")
    if not (np.isfinite(atol) and atol >= 0):
        raise DesignError(f"atol must be a finite non-negative number, got {atol!r}")
    if not model.is_discrete:
        if Ts is None:
            raise DesignError("parity_space is a finite-memory (discrete-time) design: pass Ts=... to sample "
                              "the continuous model, or use nullspace_design for a continuous filter")
        model = model.discretize(Ts)
    elif Ts is not None and abs(Ts - model.dt) > 1e-12 * model.dt:
        raise DesignError(f"Ts={Ts} differs from the discrete model's sample time {model.dt}")
    if order is None:
        for s in range(model.n + 2):
            try:
                return parity_space(model, s, rdim=rdim, robust=False, FDtol=FDtol, tol=tol, seed=seed, atol=atol)
            except DesignError:
                continue
        if robust is False:
            raise DesignError(f"no exact parity relation of any order up to n+1 = {model.n + 1} sees every fault")
        order = max(model.n, 1)
    s = int(order)
    data = ParityData(model, reduce=False)  # annihilate the whole state: no initial-state transient
    if robust is not True:
        N = data.parity_vectors(s, tol, atol)
        rows = [data.row(v, s) for v in N]
        if rows:
            basis = NullspaceBasis(rows, data.rho, model.dt, model.ny, model.nu, 0)
            seen = detectability_by_rows(model, basis, FDtol) >= FDtol
            if not model.faults or np.all(seen.max(axis=0)):
                k = len(rows) if rdim is None else int(rdim)
                if k > len(rows):
                    raise DesignError(f"rdim = {k} but there are only {len(rows)} parity relations of order {s}")
                noisy = model.nw and model.faults and k < len(rows)
                gen = _fault_to_noise(model, data, N, s, k, FDtol) if noisy else None
                if gen is None:
                    gen = _exact(model, basis, seen, k if k < len(rows) else "all",
                                 lambda c: np.zeros(c, complex), None, 0.01, seed)
                    gen.method = "parity"
                check_generator(gen, decouple=("u", "d"), block=True, FDtol=FDtol, normalize=False)  # parity scaling
                if "parity_matrix" not in gen.info:  # the full basis, when the generator has none of its own
                    gen.info["parity_matrix"] = np.array([r.coef[:, : model.ny].ravel() for r in rows]).tolist()
                gen.info.update({"mode": "exact", "parity_order": s})
                return gen
        if robust is False:
            if not rows:
                raise DesignError(f"no parity relation of order {s} decouples the state and d: "
                                  f"[O_s H_d,s] has full row rank; increase the order or allow robust=True")
            raise undetectable_error(model, seen, what=f"d is decoupled by parity relations of order {s}")
    return _robust(model, data, s, 1 if rdim is None else int(rdim), tol, atol)


def _fault_to_noise(model: FDIModel, data: ParityData, N: np.ndarray, s: int, rdim: int,
                    FDtol: float) -> ResidualGenerator | None:
    """The ``rdim`` parity relations of largest steady-state fault-to-noise ratio (module
    docstring), or None when some fault is invisible in them (the caller then combines for
    the fault sensitivity condition instead)."""
    G = model.lti()
    sl = model.group_slices()
    nf = model.nf
    Hf = _block_toeplitz(data.markov(G.B[:, sl["f"]], G.D[:, sl["f"]], s), s)
    Hw = _block_toeplitz(data.markov(G.B[:, sl["w"]], G.D[:, sl["w"]], s), s)
    F = N @ sum(Hf[:, i * nf:(i + 1) * nf] for i in range(s + 1))  # constant faults over the window
    W = N @ Hw
    Bn = W @ W.T
    # noise-free relations (noise reaching no output they read) rank first: a ratio ~1e12
    Bn += 1e-12 * max(float(np.trace(Bn)), np.finfo(float).tiny) * np.eye(len(Bn))
    lam, X = sla.eigh(F @ F.T, Bn)
    X = X[:, ::-1][:, :rdim]
    rows = [data.row(v, s) for v in X.T @ N]
    basis = NullspaceBasis(rows, data.rho, model.dt, model.ny, model.nu, 0)
    if not np.all(detectability_by_rows(model, basis, FDtol).max(axis=0) >= FDtol):
        return None
    gen = _fir_generator(model, data, rows, s)
    Q = gen.Q
    gen.info.update({"order": int(Q.n), "rdim": len(rows), "combination": X.T.tolist(), "rho": data.rho,
                     "poles": [0.0] * int(Q.n), "basis_degrees": [s] * len(rows),
                     "selection": "steady-state fault-to-noise ratio",
                     "fault_to_noise": np.sqrt(np.maximum(lam[::-1][:rdim], 0.0)).tolist(),
                     "parity_matrix": np.array([r.coef[:, : model.ny].ravel() for r in rows]).tolist()})
    return gen


def _fir_generator(model: FDIModel, data: ParityData, rows, s: int) -> ResidualGenerator:
    """The parity relations ``rows`` of order ``s`` realised as one generator (all poles at 0,
    in the scaled operator of ``data.rho``); the caller records its own info."""
    Q = realize_rows([r.coef for r in rows], [np.zeros(s)] * len(rows), data.rho, model.dt)
    return ResidualGenerator(Q, model, "parity")


def _robust(model: FDIModel, data: ParityData, s: int, rdim: int, tol, atol: float = 0.0) -> ResidualGenerator:
    if not model.faults:
        raise DesignError("the robust parity vector maximises fault sensitivity: the model has no faults")
    sl = model.group_slices()
    G = model.lti()
    dw = np.r_[np.arange(G.m)[sl["d"]], np.arange(G.m)[sl["w"]]].astype(int)
    Hdw = (_block_toeplitz(data.markov(G.B[:, dw], G.D[:, dw], s), s) if dw.size
           else np.zeros(((s + 1) * model.ny, 0)))
    Hf = _block_toeplitz(data.markov(G.B[:, sl["f"]], G.D[:, sl["f"]], s), s)
    Z = left_null(data.O(s), tol, atol) if data.n else np.eye((s + 1) * model.ny)
    if Z.shape[0] == 0:
        raise DesignError(f"no parity vector of order {s} removes the state (O_s has full row rank): increase "
                          f"the order above {s}")
    Wf = Z @ Hf
    U, sv, _ = sla.svd(Wf, full_matrices=False)
    r = int(np.sum(sv > rank_tol(sv, Wf.shape, None, atol)))
    if r == 0:
        raise DesignError(f"no fault reaches the parity space of order {s}: Z H_f,s = 0 (increase the order)")
    T = U[:, :r] / sv[:r]  # c = x T^T makes ||c Z H_f||^2 = ||x||^2
    Wd = Z @ Hdw
    M = T.T @ Wd @ Wd.T @ T
    lam, X = sla.eigh((M + M.T) / 2)
    rdim = min(rdim, r)
    V = (X[:, :rdim].T @ T.T) @ Z  # parity vectors, rows
    ratio = float(np.sqrt(max(lam[0], 0.0)))
    rows = [data.row(v, s) for v in V]
    gen = _fir_generator(model, data, rows, s)
    check_generator(gen, decouple=("u",), block=True, FDtol=0.0, normalize=False)  # robust: d minimised; unit noise
    gen.info.update({"mode": "robust", "parity_order": s, "robustness_ratio": ratio,
                     "parity_matrix": V.tolist(), "rho": data.rho, "poles": [0.0] * (s * len(rows))})
    return gen
