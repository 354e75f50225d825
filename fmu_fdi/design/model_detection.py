"""Exact model detection (EMDP) for multiplicative faults: one filter per model of a set.

A multiple-model set ``{(Gu_j, Gd_j)}`` (e.g. the plant with each loss-of-effectiveness
pattern) is monitored by a bank: filter i decouples model i exactly and responds to every
other model,

    Q_i [Gu_i Gd_i; I 0] = 0,      R_ij = Q_i [Gu_j; I] ≠ 0  (j ≠ i),

so the residual of the true model's filter is the one that stays at zero (Varga 2017,
sec. 6.2, Procedure EMD; FaultDetectionTools.jl ``emdsyn``). Filter i is the least-order
detector of :func:`~fmu_fdi.design.nullspace.nullspace_design` on model i with one fault
channel per other model, ``f_j ↦ (Gu_j − Gu_i) f_j`` (the u-response filter i sees when
model j is true), appended as extra states. The distance-mapping performance is the
matrix ``MDperf[i, j] = ||R_ij||∞`` (zero diagonal), each row scaled to a largest entry 1.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import DesignError
from ..faults import component_fault
from ..generator import ResidualBank, ResidualGenerator
from ..linalg import single_blas_thread
from ..lti import LTI
from ..model import FDIModel
from .nullspace import nullspace_design


def _with_model_faults(models: Sequence[FDIModel], i: int) -> FDIModel:
    base = models[i]
    n0 = base.n
    blocks_A, blocks_B, blocks_C, faults = [base.A], [], [base.C], []
    k = n0
    for j, mj in enumerate(models):
        if j == i:
            continue
        diff = LTI(np.block([[base.A, np.zeros((n0, mj.n))], [np.zeros((mj.n, n0)), mj.A]]),
                   np.vstack([-base.Bu, mj.Bu]), np.hstack([base.C, mj.C]), mj.Du - base.Du, base.dt).minreal()
        blocks_A.append(diff.A)
        blocks_C.append(diff.C)
        blocks_B.append((k, diff))
        k += diff.n
    import scipy.linalg as sla

    A = sla.block_diag(*blocks_A)
    C = np.hstack(blocks_C)
    j_names = [mj.name for j, mj in enumerate(models) if j != i]
    for (start, diff), nm in zip(blocks_B, j_names):
        Bf = np.zeros((k, base.nu))
        Bf[start:start + diff.n] = diff.B
        faults.append(component_fault(f"model_{nm}", Bf, diff.D))
    pad = lambda B: np.vstack([B, np.zeros((k - n0, B.shape[1]))])  # noqa: E731
    return FDIModel(A, pad(base.Bu), C, base.Du, Bd=pad(base.Bd), Dd=base.Dd, faults=faults, dt=base.dt,
                    u_names=base.u_names, y_names=base.y_names, d_names=base.d_names, name=f"{base.name}_md")


@single_blas_thread
def model_detection_bank(models: Sequence[FDIModel], *, poles=None, sdeg=None, FDtol: float = 1e-4,
                         **kwargs) -> ResidualBank:
    """A bank of least-order filters, filter i exact for model i and sensitive to all others.

    Parameters
    ----------
    models : sequence of FDIModel
        The model set: same outputs, known inputs and sample time; unknown inputs d of each
        model are decoupled by its own filter; faults and noise of the models are ignored.
    poles, sdeg, FDtol, **kwargs
        Passed to :func:`~fmu_fdi.design.nullspace.nullspace_design` for each filter.

    Returns
    -------
    ResidualBank
        Designed against ``models[0]``; ``info['MDperf']`` the distance-mapping matrix
        (rows scaled to max 1), ``info['MDperf_abs']`` unscaled, ``info['models']`` the names.
    """
    models = list(models)
    if len(models) < 2:
        raise DesignError("model detection needs at least two models")
    m0 = models[0]
    for mj in models[1:]:
        if (mj.ny, mj.nu, abs(mj.dt - m0.dt) < 1e-12) != (m0.ny, m0.nu, True):
            raise DesignError(f"model '{mj.name}' has other outputs/inputs/sample time than '{m0.name}'")
    bare = [mj._replace(faults=[], Bw=np.zeros((mj.n, 0)), Dw=np.zeros((mj.ny, 0)), w_names=[]) for mj in models]
    members = []
    for i in range(len(bare)):
        mi = _with_model_faults(bare, i)
        try:
            g = nullspace_design(mi, rdim=1, poles=poles, sdeg=sdeg, FDtol=FDtol, **kwargs)
        except DesignError as exc:
            raise DesignError(f"filter {i + 1} (model '{models[i].name}'): {exc}") from None
        members.append(ResidualGenerator(g.Q, bare[0], "model_detection", info=g.info))
    perf = np.zeros((len(bare), len(bare)))
    for i, g in enumerate(members):
        for j, mj in enumerate(bare):
            Gj = mj.augmented()[:, np.arange(mj.nu)]
            perf[i, j] = (g.Q @ Gj).minreal().hinfnorm()[0]
    scaled = perf / np.maximum(perf.max(axis=1, keepdims=True), np.finfo(float).tiny)
    return ResidualBank(members, "model_detection", info={"MDperf": scaled.tolist(), "MDperf_abs": perf.tolist(),
                                                            "models": [mj.name for mj in models]})


def nu_gap_siso(G1: LTI, G2: LTI, omega) -> float:
    """Chordal distance ``sup_ω |G1 − G2| / sqrt((1 + |G1|²)(1 + |G2|²))`` on a grid: the ν-gap of
    two SISO systems when Vinnicombe's winding-number condition holds (e.g. both stable and
    minimum phase), the model distance ``mddist`` of FaultDetectionTools.jl."""
    a, b = G1.freqresp(omega)[:, 0, 0], G2.freqresp(omega)[:, 0, 0]
    return float(np.max(np.abs(a - b) / np.sqrt((1 + np.abs(a) ** 2) * (1 + np.abs(b) ** 2))))
