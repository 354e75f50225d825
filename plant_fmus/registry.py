"""What a plant FMU is made of: the slave source, the bundled modules, its model files and
the fault inputs it offers. Each plant sub-package defines one :class:`Plant`."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

SUPPORT = Path(__file__).with_name("_support.py")
#: pythonfmu 0.7's exit-time use-after-free guard, shared with the diagnostic FMU
EXIT_GUARD = Path(__file__).resolve().parent.parent / "fmu_fdi" / "fmu" / "exit_guard.py"


@dataclass(frozen=True)
class FaultInput:
    """One fault-injection variable of a plant FMU.

    ``variable`` is the FMU variable (a Real input), ``model_fault`` the fault of the model
    file it realises (to first order at the operating point), ``kind`` that fault's kind,
    ``detection_target`` a documented detection-time target in seconds (plants.md, marked
    unverified there) or None when none is published.
    """

    variable: str
    model_fault: str | None
    kind: str
    unit: str
    description: str
    detection_target: float | None = None


@dataclass(frozen=True)
class Plant:
    """Metadata of one benchmark plant FMU.

    Attributes
    ----------
    name : registry key and FMU file stem.
    prefix : module-name prefix, unique per plant: the slave is ``<prefix>_plant.py``, the
        bundled helpers ``<prefix>_*.py`` (pythonfmu issue 228: same-named modules clash).
    slave : path of the pythonfmu slave script.
    helpers : numpy-only modules bundled next to the slave (already plant-prefixed).
    model_files : TOML model files (format fmu-fdi-model/1) shipped with the FMU.
    step : default communication step (s), also the DefaultExperiment step.
    faults : the ``f_*`` fault inputs. Every sensor ``y`` also has ``gain_y``, ``stuck_y``
        and ``stuck_value_y`` inputs and a ``std_y`` noise parameter; every actuator ``u``
        has ``gain_u``, ``stuck_u`` and ``stuck_value_u``.
    sensors, actuators : names of the measured outputs and of the actuators.
    noise : default std of every noise parameter (``std_*``), in the signal's unit.
    uncertain : uncertain-parameter FMU parameters and their documented default bounds.
    linear_models : computes the model files' contents from the plant parameters.
    """

    name: str
    prefix: str
    slave: Path
    helpers: tuple[Path, ...]
    model_files: tuple[Path, ...]
    step: float
    faults: tuple[FaultInput, ...]
    sensors: tuple[str, ...]
    actuators: tuple[str, ...]
    noise: dict = field(default_factory=dict)
    uncertain: dict = field(default_factory=dict)
    linear_models: Callable[[], list] | None = None
    description: str = ""

    def __post_init__(self):
        for path in (self.slave, *self.helpers):
            if not path.stem.startswith(self.prefix + "_"):
                raise ValueError(f"plant '{self.name}': bundled module {path.name} must start with "
                                 f"'{self.prefix}_' so that it cannot clash with another FMU's module")

    @classmethod
    def in_folder(cls, folder: Path, model_files, **kwargs) -> "Plant":
        """A plant whose slave is ``folder/<prefix>_plant.py`` and whose one helper is
        ``folder/<prefix>_physics.py``; ``model_files`` are file names in ``folder``."""
        prefix = kwargs["prefix"]
        return cls(slave=folder / f"{prefix}_plant.py", helpers=(folder / f"{prefix}_physics.py",),
                   model_files=tuple(folder / f for f in model_files), **kwargs)

    def bundle(self) -> list[tuple[Path, str]]:
        """``(source, bundled file name)`` of every module the FMU carries besides the slave."""
        return ([(SUPPORT, f"{self.prefix}_support.py"), (EXIT_GUARD, f"{self.prefix}_exit_guard.py")]
                + [(p, p.name) for p in self.helpers])

    def fault(self, variable: str) -> FaultInput:
        """The fault input named ``variable``."""
        for f in self.faults:
            if f.variable == variable:
                return f
        raise KeyError(f"plant '{self.name}' has no fault input {variable!r}; "
                       f"it has {[f.variable for f in self.faults]}")


def additive_inputs(kind: str, channels, in_model: bool = True) -> list[FaultInput]:
    """``f_<fault>`` inputs of additive sensor or actuator faults; ``channels`` are
    ``(fault name, signal, unit)`` triples; ``in_model``: the model file has the fault."""
    where = "the measured" if kind == "sensor" else "the applied"
    return [FaultInput(f"f_{fault}", fault if in_model else None, kind, unit, f"additive fault on {where} {signal}")
            for fault, signal, unit in channels]
