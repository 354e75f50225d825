"""Is the plant's model one a diagnoser may be built on? The operating point must not drift:
a model with a pole outside the stability region is refused unless the point is an equilibrium
(trimmed), the plant closes its own loop, or the user says so (``--allow-unstable``);
docs/plant-fmu.md. Used by ``fmu-fdi model`` for one point and for every member of a model set."""
from __future__ import annotations

import numpy as np

from ..errors import ModelError

#: relative margin beyond the stability boundary that counts as unstable: eigenvalues of a
#: backward-stable eigensolver are exact for A + E with ||E|| ~ n eps ||A||; a pole
#: on the boundary (an integrator) may land up to that far outside it (1e-6 leaves room for
#: identification noise on an integrator well above eps)
UNSTABLE_MARGIN = 1e-6

#: an identified pole counts as unstable when its mode grows by more than e^0.0953 = 1.1 over the
#: recorded run: a slower growth is within what the data tells from an integrator (Re λ = 0)
GROWTH_OVER_RECORD = float(np.log(1.1))


def check_stable(model, allow_unstable: bool = False, closed_loop: bool = False) -> None:
    """Refuse ``model`` if a pole lies outside the stability region, unless the operating point
    is an equilibrium (provenance ``trimmed``), the plant closes its own loop (``closed_loop``:
    model inputs that are FMU outputs; the loop settles though the open-loop model is unstable,
    docs/plant-fmu.md) or ``allow_unstable``. The error names the pole."""
    if allow_unstable or closed_loop or model.provenance.get("trimmed") is True or model.A.size == 0:
        return
    lam = np.linalg.eigvals(model.A)
    scale = max(1.0, float(np.max(np.abs(lam))))
    if model.dt:  # discrete: |λ| > 1
        excess = np.abs(lam) - 1.0
        region = "outside the unit circle (|λ| > 1)"
    else:
        excess = lam.real
        region = "in the right half-plane (Re λ > 0)"
    k = int(np.argmax(excess))
    margin = UNSTABLE_MARGIN * scale
    prov = model.provenance
    if "identification" in str(prov.get("method", "")) and prov.get("samples") and prov.get("sample_time"):
        # identified: a growth rate the record cannot tell from an integrator's is no evidence of
        # drift; a mode growing by e^(Re λ T) < 1.1 over the record length T (10 %) is within it
        margin = max(margin, GROWTH_OVER_RECORD / (float(prov["samples"]) * float(prov["sample_time"])))
        if model.dt:
            margin = max(margin, GROWTH_OVER_RECORD / float(prov["samples"]))
    if excess[k] <= margin:
        return
    p = lam[k]
    how = ("identified from an experiment: the plant drifts away from the operating point, which is not an "
           "equilibrium it settles at" if "identification" in str(model.provenance.get("method", ""))
           else "linearised at a point that is not trimmed to an equilibrium")
    raise ModelError(f"the model of {model.provenance.get('fmu', model.name)} has the pole {p.real:.6g}{p.imag:+.6g}j "
                     f"{region}, {how}; a drifting operating point is refused (docs/plant-fmu.md): choose an "
                     f"equilibrium, trim it (--trim), or give --allow-unstable if the plant is unstable and the "
                     f"point is an equilibrium")


def check_plant_models(plant, models, allow_unstable: bool = False) -> None:
    """:func:`check_stable` on each model of the plant FMU ``plant``, closed loop when a model
    input is an FMU output."""
    from fmpy import read_model_description

    md = read_model_description(str(plant), validate=False)
    fmu_outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    for model in models:
        check_stable(model, allow_unstable, closed_loop=bool(set(model.u_names) & fmu_outputs))
