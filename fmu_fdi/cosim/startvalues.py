"""Which variables a master may set before an FMU initialises: the one rule, FMI 2 and FMI 3.

Between instantiation and ``enterInitializationMode`` (the *Instantiated* state) FMI lets a
master set every variable whose variability is not ``constant`` and whose ``initial`` is
``exact`` or ``approx`` (FMI 2.0 sec. 2.2.7 and the state machine of sec. 4.2.4; FMI 3.0
sec. 2.4.7 and its Instantiated state). With the default ``initial`` of each
causality × variability pair (FMI 2.0 sec. 2.2.7's table, FMI 3.0's the same) that reads:

- ``parameter`` (fixed or tunable): always (``initial`` is ``exact``);
- ``input``: always (its start value; inputs may also be set in initialisation mode);
- ``output`` and ``local``: only when the model description declares ``initial="exact"``
  (a start value the FMU uses, e.g. a state's initial value) or ``initial="approx"`` (an
  iteration start the FMU may change); with the default ``initial="calculated"`` the FMU
  computes the value during initialisation and a set is an error;
- never: ``calculatedParameter`` (computed from other parameters), ``independent`` (time,
  the master's step sets it), ``constant`` variability, and FMI 3 ``structuralParameter``
  (settable only in Configuration Mode, which this master does not enter).

:func:`refusal` is the rule; ``fmu-fdi simulate --param``, campaigns and ``fmu-fdi model --at``
all ask it (through :func:`fmu_fdi.cosim.wiring.wire` or directly), so they accept and refuse
the same variables with the same words.
"""
from __future__ import annotations

# the default ``initial`` of FMI 2.0 sec. 2.2.7 / FMI 3.0 sec. 2.4.7, by variability then causality
_DEFAULT_INITIAL = {
    "constant": {"output": "exact", "local": "exact"},
    "fixed": {"parameter": "exact", "structuralParameter": "exact", "calculatedParameter": "calculated",
              "local": "calculated"},
    "tunable": {"parameter": "exact", "structuralParameter": "exact", "calculatedParameter": "calculated",
                "local": "calculated"},
    "discrete": {"input": "exact", "output": "calculated", "local": "calculated"},
    "continuous": {"input": "exact", "output": "calculated", "local": "calculated"},
}


def initial_of(var) -> str | None:
    """``var``'s ``initial``: as declared, else the FMI default for its causality and variability."""
    declared = getattr(var, "initial", None)
    if declared:
        return declared
    variability = getattr(var, "variability", None) or "continuous"
    return _DEFAULT_INITIAL.get(variability, {}).get(getattr(var, "causality", None) or "local")


def refusal(var) -> str | None:
    """Why a master may not set ``var`` (an fmpy model variable) before initialisation, or None
    when it may (module docstring). The reason is a phrase that follows the variable's name."""
    causality = getattr(var, "causality", None) or "local"
    variability = getattr(var, "variability", None) or "continuous"
    if causality == "independent":
        return "is the independent variable (time): the master's step sets it"
    if variability == "constant":
        return "is a constant"
    if causality == "calculatedParameter":
        return "is a calculatedParameter: the FMU computes it from other parameters"
    if causality == "structuralParameter":
        return ("is a structuralParameter: FMI 3 lets a master set it only in Configuration Mode, "
                "which fmu-fdi does not enter")
    if causality in ("parameter", "input"):
        return None
    initial = initial_of(var)
    if initial in ("exact", "approx"):
        return None
    return (f"has causality {causality}, variability {variability} and initial=\"{initial}\": the FMU "
            f"computes it during initialisation; FMI lets a master set before initialisation only "
            f"parameters and inputs, and variables declared initial=\"exact\" or \"approx\" (start values)")
