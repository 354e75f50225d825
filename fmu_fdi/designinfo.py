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
- :func:`variable_units`, :func:`variable_types`, :func:`type_definitions`,
  :func:`variable_descriptions`: the one description of the FMU's variables that both builders (:mod:`fmu_fdi.fmu.builder`, :mod:`fmu_fdi.native.build`) write.
"""
from __future__ import annotations

#: largest order of the internal form (generator and plant states together) for which the
#: structure is computed at build/plot time: an H∞ norm per fault block costs O(n³) per
#: iteration, seconds beyond this on large plants
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
    if "model" not in design or disc.get("kind") != "lti":
        return None
    plant = design["model"].get("matrices", {}).get("A", []) if isinstance(design["model"], dict) else []
    n = plant["shape"][0] if isinstance(plant, dict) else len(plant)  # a sidecar reference or the rows
    if len(disc["A"]) + n > MAX_ORDER_FOR_STRUCTURE:  # R = Q·Ge holds both
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


def variable_units(design: dict) -> dict[str, str]:
    """Variable name -> unit: the plant signals' units from the design and the residuals',
    evaluations' and thresholds' where they share one (both targets)."""
    signals = set(design["signals"]["u"]) | set(design["signals"]["y"])
    units = {k: v for k, v in (design.get("units") or {}).items() if k in signals}
    units.update(_output_units(design))
    return units


def variable_types(design: dict) -> dict[str, str]:
    """Variable name -> ``declaredType`` of the plant signals, from the model the design carries
    (the model file's ``[declared_types]``, e.g. the plant FMU's own types); both targets."""
    view = design["members"][0] if "members" in design else design
    signals = set(view["signals"]["u"]) | set(view["signals"]["y"])
    types = (view.get("model") or {}).get("declared_types") or {}
    return {k: v for k, v in types.items() if k in signals and isinstance(v, str) and v}


def variable_type_attributes(design: dict) -> dict[str, dict[str, str]]:
    """``declaredType`` name -> the attributes of its type definition (``quantity``, ``unit``,
    ``displayUnit``) from the model the design carries (the model file's ``[type_definitions]``)."""
    view = design["members"][0] if "members" in design else design
    defs = (view.get("model") or {}).get("type_definitions") or {}
    return {k: dict(v) for k, v in defs.items() if isinstance(v, dict)}


def type_definitions(types: dict, units: dict, attributes: dict | None = None) -> dict[str, dict[str, str]]:
    """``declaredType`` name -> the attributes written on its type definition: ``unit``, the one unit
    every variable of that type has (none when they differ: the units then stay on the variables
    alone, which FMI lets override the type's), and ``quantity`` from ``attributes`` (the plant
    FMU's type definition, :func:`variable_type_attributes`). The type's ``displayUnit`` is not
    written: FMI resolves it through a ``<DisplayUnit>`` conversion the model file does not hold."""
    out: dict = {}
    for name, typ in types.items():
        out.setdefault(typ, set()).add(units.get(name))
    attributes = attributes or {}
    defs = {}
    for typ, us in sorted(out.items()):
        quantity = (attributes.get(typ) or {}).get("quantity")
        unit = next(iter(us)) if len(us) == 1 else None
        defs[typ] = {k: v for k, v in (("quantity", quantity), ("unit", unit)) if v}
    return defs


def variable_descriptions(design: dict) -> dict[str, str]:
    """Variable name -> description of every FMU variable of the design (both targets): the
    plant signals, ``threshold_scale``, and per residual group what its alarm responds to
    (:func:`group_faults`)."""
    sig, g = design["signals"], design["generator"]
    faults = [f["name"] for f in design["faults"]]
    seen = group_faults(design)
    out = {n: f"plant input {n}" for n in sig["u"]}
    out.update({n: f"plant output (measurement) {n}" for n in sig["y"]})
    out["threshold_scale"] = "tunable factor on every threshold (>= 0; default 1)"
    group_of = {k: i for i, grp in enumerate(g["groups"]) for k in grp}

    def sees(i):
        if seen is None:
            return "fault sensitivity not recorded in the design"
        return f"sensitive to {', '.join(seen[i])}" if seen[i] else "sensitive to no modelled fault"

    for k, name in enumerate(g["residual_names"]):
        out[f"residual_{k + 1}"] = f"residual {name} (group {group_of[k] + 1}: {sees(group_of[k])})"
    for i, grp in enumerate(g["groups"]):
        ev = design["evaluation"][i]
        members = ", ".join(g["residual_names"][j] for j in grp)
        out[f"evaluation_{i + 1}"] = f"{ev['evaluator']['kind']} evaluation of residual group {i + 1} ({members}); {sees(i)}"
        out[f"threshold_{i + 1}"] = f"{ev['threshold']['kind']} threshold of group {i + 1} (times threshold_scale)"
        out[f"alarm_{i + 1}"] = f"evaluation_{i + 1} >= threshold_{i + 1} (with persistence/latching); {sees(i)}"
    out["fault_detected"] = "any alarm"
    legend = ", ".join(f"{j + 1} = {nm}" for j, nm in enumerate(faults)) or "no faults modelled"
    out["isolated_fault"] = f"0 none, -1 unknown or several, else the fault: {legend}"
    out["input_invalid"] = ("the last input sample had NaN/Inf or was outside its valid range (diagnosis held), "
                            "or overflowed the evaluation (numeric_reset)")
    out["numeric_reset"] = ("the last sample overflowed the evaluation (a value became NaN/Inf): counted as fault "
                            "evidence for the groups it reached, sample discarded, generator and evaluation "
                            "restarted (docs/semantics.md)")
    return out


def _output_units(design: dict) -> dict[str, str]:
    unit = residual_unit(design)
    if unit is None:
        return {}
    g = design["generator"]
    out = {f"residual_{k + 1}": unit for k in range(len(g["residual_names"]))}
    for i in range(len(design["evaluation"])):
        if evaluation_unit(design, i):
            out[f"evaluation_{i + 1}"] = out[f"threshold_{i + 1}"] = unit
    return out
