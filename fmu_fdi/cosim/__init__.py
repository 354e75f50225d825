"""Co-simulation of plant FMU(s) with a diagnostic FMU, fault scenarios and SSP export.

- :class:`CoSimulation` — the fixed-step master (Gauss–Seidel or Jacobi) on fmpy's low-level
  FMI 2 / FMI 3 co-simulation API; ``.run()`` returns a :class:`Result`.
- :class:`Fault`, :func:`parse_fault` — fault scenarios and their SPEC mini-language.
- :class:`InputSignals` — external signals from arrays or CSV (zero-order hold or linear).
- :func:`export_ssp`, :func:`ssp_parameter_set` — the connected system as an SSP file.
"""
from .errors import CoSimulationError, SimulationFailed
from .faults import Fault
from .master import CoSimulation
from .result import Result
from .signals import InputSignals
from .spec import format_fault, parse_fault
from .ssp import export_ssp, ssp_parameter_set

__all__ = ["CoSimulation", "Result", "Fault", "parse_fault", "format_fault", "InputSignals",
           "export_ssp", "ssp_parameter_set", "CoSimulationError", "SimulationFailed"]
