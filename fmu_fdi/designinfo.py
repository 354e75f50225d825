"""What a design file says about itself, for descriptions, plots and tables.

- :func:`group_faults`: the faults each residual group's alarm responds to — row i of the
  structure matrix S (groups × faults) the decision logic isolates with, or, for a design
  that isolates nothing, the weak structure matrix of its generator (a nonzero fault-to-
  residual transfer, :func:`fmu_fdi.analysis.structure_matrix`) computed from the model and
  generator the design file carries.
- :func:`isolable_faults`: the faults structure-matrix isolation can name: fault j is
  isolated when exactly the groups of column j alarm, so its column must be nonzero and
  differ from every other column (Frank, section 7; Varga 2017, section 3.5). With
  directional isolation every fault with a nonzero direction can be named.
- :func:`residual_unit`: the residuals' unit when the outputs share one (see
  :mod:`fmu_fdi.fmu.builder`).
"""
from __future__ import annotations

#: largest generator order for which the structure is computed at build/plot time: an H∞
#: norm per fault block costs O(n³) per iteration, seconds beyond this on large plants
MAX_ORDER_FOR_STRUCTURE = 200

#: evaluation kinds whose value has the residual's unit
UNIT_KEEPING = ("norm", "rms", "ewrms", "peak", "narendra")


def _structure(design: dict):
    faults = [f["name"] for f in design["faults"]]
    S = design["decision"].get("structure")
    if S is not None:
        return S, faults
    info = design["generator"].get("info") or {}
    if info.get("structure") is not None:
        return info["structure"], list(info.get("faults") or faults)
    return _computed_structure(design), faults


def _computed_structure(design: dict):
    """Weak structure matrix (groups × faults) of the design's LTI generator, or None."""
    disc = design["generator"]["discrete"]
    if "model" not in design or disc.get("kind") != "lti" or len(disc["A"]) > MAX_ORDER_FOR_STRUCTURE:
        return None
    from .analysis import structure_matrix
    from .diagnoser import Diagnoser

    gen = Diagnoser.from_design(design).generator
    return None if gen is None else structure_matrix(gen).tolist()


def group_faults(design: dict) -> list[list[str]] | None:
    """Per residual group, the names of the faults its alarm responds to; None when the
    design records no structure and none can be computed (e.g. an RLS estimator)."""
    S, names = _structure(design)
    if S is None:
        return None
    return [[names[j] for j, v in enumerate(row) if v] for row in S]


def isolable_faults(design: dict) -> list[str]:
    """Names of the faults the decision logic can isolate (see the module docstring)."""
    mode = design["decision"].get("isolation", "none")
    if mode == "direction":
        return [f["name"] for f in design["faults"]]
    S, names = _structure(design)
    if mode != "structure" or S is None:
        return []
    cols = [tuple(row[j] for row in S) for j in range(len(names))]
    return [n for j, n in enumerate(names) if any(cols[j]) and cols.count(cols[j]) == 1]


def residual_unit(design: dict) -> str | None:
    """The unit of the residuals when every measured output has the same one, else None
    (also None for RLS residuals, which are in standard deviations)."""
    units = design.get("units") or {}
    ys = [units.get(n) for n in design["signals"]["y"]]
    if design["generator"]["method"] == "rls" or not ys or None in ys or len(set(ys)) != 1:
        return None
    return ys[0]


def evaluation_unit(design: dict, group: int) -> str | None:
    """The unit of evaluation ``group`` (0-based) and its threshold, or None."""
    unit = residual_unit(design)
    kind = design["evaluation"][group]["evaluator"]["kind"]
    return unit if kind in UNIT_KEEPING else None


def indistinguishable(design: dict, fault: str) -> list[str]:
    """The other faults whose structure-matrix column equals ``fault``'s: faults the alarms
    cannot tell apart from it (empty when it is isolable or the structure is unknown)."""
    S, names = _structure(design)
    if S is None or fault not in names:
        return []
    col = [row[names.index(fault)] for row in S]
    return [n for j, n in enumerate(names) if n != fault and [row[j] for row in S] == col]
