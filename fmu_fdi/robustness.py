"""Robustness of one residual filter over a set of models (e.g. the plant at several operating
points, or with perturbed actuators): the judge's figures per model and the worst of them
(Varga 2017, sec. 5.4, the robustness of a design against model variations).
"""
from __future__ import annotations

from typing import Sequence

from .analysis import hinf_minus
from .design.toolkit.postconditions import check_generator
from .errors import ModelError
from .generator import ResidualGenerator
from .model import FDIModel


def robustness(gen, models: Sequence[FDIModel], *, structure=None, faults=None) -> dict:
    """Apply one filter to every model of a set; report per-model and worst figures.

    For each model (same signals as the design model): the relative decoupling of u and d
    and of the faults with ``S = 0``, and the smallest relative fault gain of the required
    faults (:func:`~fmu_fdi.design.toolkit.postconditions.check_generator` with ``raise_error=False``),
    plus the H∞− index ``min_j ||Rf_j||∞``.
    """
    S = structure if structure is not None else gen.info.get("structure")
    names = faults if faults is not None else gen.info.get("faults")
    rows = []
    for mdl in models:
        if (mdl.ny, mdl.nu, mdl.fault_names) != (gen.model.ny, gen.model.nu, gen.model.fault_names):
            raise ModelError(f"model '{mdl.name}' has other signals than the design model '{gen.model.name}'")
        g = ResidualGenerator(gen.Q, mdl, gen.method, gen.residual_names, gen.groups)
        fig = check_generator(g, structure=S, faults=names, raise_error=False)
        rows.append({"model": mdl.name, "decoupling": fig.get("decoupling", 0.0),
                     "structure_leak": fig.get("structure_leak", 0.0),
                     "fault_visibility": fig.get("fault_visibility", float("inf")),
                     "hinf_minus": hinf_minus(g) if mdl.faults else 0.0})
    return {"models": rows,
            "worst_decoupling": max(r["decoupling"] for r in rows),
            "worst_structure_leak": max(r["structure_leak"] for r in rows),
            "worst_fault_visibility": min(r["fault_visibility"] for r in rows),
            "worst_hinf_minus": min(r["hinf_minus"] for r in rows)}
