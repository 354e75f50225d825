"""The mixed H−/H∞ optimal residual generator: Ding's unified solution.

With a left coprime factorisation ``[Gu Gw Gf] = M̂⁻¹ [N̂u N̂w N̂f]``, every residual generator
that decouples u is ``Q = R [M̂  −N̂u]`` (R stable), with ``Rw = R N̂w`` and ``Rf = R N̂f``.
If ``N̂w`` has full row rank on the boundary (measurement noise on every output: ``Dw`` of
full row rank), factor ``N̂w = N̂wo N̂wi`` (co-outer, co-inner) and take ``R = N̂wo⁻¹``:

    Q_opt = N̂wo⁻¹ [M̂  −N̂u],    Rw = N̂wi (co-inner, ||Rw||∞ = 1),    Rf = N̂wo⁻¹ N̂f.

It is optimal for every ratio of fault sensitivity to noise at once (S. X. Ding, *Model-based
Fault Diagnosis Techniques*, 2nd ed., Springer 2013, sec. 7.5, Theorem 7.14): for any
u-decoupling Q scaled to ``||Q Gw||∞ ≤ 1``, ``Rf~(jω) Rf(jω) ≤ Rf_opt~(jω) Rf_opt(jω)`` at
every ω — in particular every fault's gain is at most the unified solution's, frequency by
frequency — so the optimised designs can be compared with it.
"""
from __future__ import annotations

import numpy as np

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import single_blas_thread
from ...model import FDIModel
from ..toolkit.approximate import coouter_inverse
from .coprime import factorized
from ..toolkit.postconditions import check_generator
from ..toolkit.notes import keeps_notes


@keeps_notes
@single_blas_thread
def unified_observer(model: FDIModel, poles=None, *, atol: float = 0.0) -> ResidualGenerator:
    """Ding's unified H−/H∞ (and H∞/H∞, H2/H2) optimal residual generator.

    Parameters
    ----------
    model : FDIModel
        With noise inputs w and no unknown inputs d (decouple d first, e.g. by designing on
        a model with d, or use :func:`~fmu_fdi.design.problems.nullspace.nullspace_design`).
    poles : array_like, optional
        Poles of the coprime factorisation (as in :func:`~fmu_fdi.design.problems.coprime.factorized`);
        the optimum does not depend on them.
    atol : float
        Absolute rank tolerance (Varga's ``atol``) of the minimal realisations of the noise
        response and of the filter (SLICOT's default relative tolerance when 0).

    Returns
    -------
    ResidualGenerator
        ``info``: ``noise_hinf`` (``||Rw||∞``, 1 up to rounding) and ``postconditions``.

    Raises
    ------
    DesignError
        No noise inputs, unknown inputs present, or the noise response lacks full row rank /
        has zeros on the stability boundary (the co-outer factor is then not invertible).
    """
    if not (np.isfinite(atol) and atol >= 0):
        raise DesignError(f"atol must be a finite non-negative number, got {atol!r}")
    if not model.nw:
        raise DesignError("the unified solution trades fault sensitivity against noise: the model has no noise "
                          "inputs w")
    if model.nd:
        raise DesignError(f"the unified solution attenuates w but cannot decouple d {model.d_names}: design on a "
                          f"model without d (or treat d as noise with with_disturbances)")
    Q0 = factorized(model, poles).Q
    sl = model.group_slices()
    Rw0 = (Q0 @ model.augmented())[:, sl["w"]].minreal(atol)
    fac = coouter_inverse(Rw0)
    if fac is None:
        raise DesignError("the noise response M̂⁻¹-factor N̂w has no invertible co-outer factor: its feedthrough "
                          "must have full row rank (measurement noise on every output, Dw of full row rank) and "
                          "no zeros on the stability boundary")
    Q = (fac[0] @ Q0).minreal(atol)
    gen = ResidualGenerator(Q, model, "unified")
    check_generator(gen, decouple=("u",), faults=[], block=True)
    Rw = gen.Rw
    gen.info["noise_hinf"] = float(Rw.hinfnorm()[0]) if Rw.n else float(np.linalg.norm(Rw.D, 2))
    return gen
