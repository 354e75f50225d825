"""One co-simulation FMU as the master sees it: variables by name, one running instance.

A thin layer over fmpy's low-level classes (:class:`fmpy.fmi2.FMU2Slave`,
:class:`fmpy.fmi3.FMU3Slave`) that hides the two things the FMI versions spell differently:
the typed get/set calls (``getReal`` vs ``getFloat64``) and the life cycle
(``setupExperiment`` exists only in FMI 2; FMI 3's ``doStep`` reports a termination request).
Everything else in the master speaks of variables by name and of four value kinds:
``"real"``, ``"integer"``, ``"boolean"`` and ``"string"``.
"""
from __future__ import annotations

import collections
import difflib
import itertools
import re
import shutil
import weakref
from ctypes import byref
from pathlib import Path

from ..fmu.exit_guard import guard_library
from .elements import Element, Packed, refused_array, variables_by_name
from .errors import CoSimulationError, SimulationFailed

# FMI 2 logging. fmpy's native proxy (fmpy/logging: it formats the printf arguments ctypes cannot
# pass) keeps ONE logger per process — the last one registered — so a Python logger per instance
# would route every FMU's messages to the newest instance, and call freed memory once that
# instance is gone while an older one (a campaign's pooled instance) still logs. Every instance
# therefore registers the same logger, made once and never freed, and is found again by its
# componentEnvironment (an id of its own, FMI 2.0 sec. 2.1.5).
_BY_ENVIRONMENT: "weakref.WeakValueDictionary[int, FMUInstance]" = weakref.WeakValueDictionary()
_ENVIRONMENT_IDS = itertools.count(1)
_LOGGER2 = []  # [the CFUNCTYPE logger], made on first use (fmpy is imported lazily)


def _logger2():
    if not _LOGGER2:
        from fmpy.fmi2 import fmi2CallbackLoggerTYPE

        def dispatch(env, instance, status, category, message):
            fmu = _BY_ENVIRONMENT.get(env or 0)
            if fmu is not None:
                fmu._log2(env, instance, status, category, message)

        _LOGGER2.append(fmi2CallbackLoggerTYPE(dispatch))
    return _LOGGER2[0]

# FMI type name -> the master's value kind. Enumerations travel as integers in both versions.
_KIND = {
    "Real": "real", "Float64": "real", "Float32": "real",
    "Integer": "integer", "Enumeration": "integer",
    "Int8": "integer", "UInt8": "integer", "Int16": "integer", "UInt16": "integer",
    "Int32": "integer", "UInt32": "integer", "Int64": "integer", "UInt64": "integer",
    "Boolean": "boolean", "String": "string",
}
# FMI 2 groups all integer-like types under one call; FMI 3 has a call per type.
_FMI2_CALL = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
              "String": "String"}
_CAST = {"real": float, "integer": int, "boolean": bool, "string": str}
_INSTANCE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_RESERVED = {"time", "fault"}  # would clash with the Result's own columns
_LOG_LINES = 20
_DATED = re.compile(r"^t\s*=\s*\S+:")  # an FMU message that names its own time, 't=12: ...'
_WARNINGS_KEPT = 20  # distinct warning texts kept per FMU (all are counted)


def check_instance_name(name) -> str:
    """Return ``name`` if it can name an FMU instance (an identifier, not ``time``/``fault``)."""
    if not isinstance(name, str) or not _INSTANCE_NAME.match(name) or name in _RESERVED:
        raise CoSimulationError(
            f"FMU instance name {name!r} is not valid: use letters, digits and '_' (no dots, since "
            f"'name.variable' addresses a variable), and not one of {sorted(_RESERVED)}")
    return name


class FMUInstance:
    """An FMI 2 or FMI 3 co-simulation FMU under an instance name.

    Construction reads ``modelDescription.xml`` only; :meth:`start` extracts, instantiates and
    initialises; :meth:`close` terminates and frees. Between the two, :meth:`accessor` gives
    batched typed access to a list of variables and :meth:`do_step` advances time.

    Parameters
    ----------
    name : str
        Instance name, used in column names (``name.variable``) and messages.
    path : str or Path
        The ``.fmu`` file.
    """

    def __init__(self, name: str, path):
        from fmpy import read_model_description

        self.name = check_instance_name(name)
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"FMU '{name}': no such file {str(self.path)!r}")
        try:
            md = read_model_description(str(self.path), validate=False)
        except Exception as exc:  # fmpy raises bare Exceptions for broken archives and XML
            raise CoSimulationError(f"FMU '{name}' ({self.path}): cannot read its modelDescription.xml: "
                                    f"{exc}") from exc
        if md.fmiVersion not in ("2.0", "3.0"):
            raise CoSimulationError(f"FMU '{name}' ({self.path}) is FMI {md.fmiVersion}; "
                                    f"only FMI 2.0 and 3.0 are supported")
        if md.coSimulation is None:
            raise CoSimulationError(f"FMU '{name}' ({self.path}) has no co-simulation interface "
                                    f"(model exchange only)")
        self.model_description = md
        self.fmi_version = int(md.fmiVersion[0])
        # FMI 3 arrays also as their elements 'y[1]', 'y[2]' (scalar variables to the master, fmu_fdi/cosim/elements.py)
        self._unsized = {}  # array name -> why its dimension is variable (not expanded)
        self.variables = variables_by_name(md, self._unsized)
        self._array_values = {}  # array value reference -> the values last set (elements.Packed)
        self._kinds = {}   # var -> kind, and causality -> names: the description never changes
        self._names = {}
        self.log = collections.deque(maxlen=_LOG_LINES)
        #: warning (and worse) messages of the running instance: text -> [count, first time]
        self.warnings: dict = {}
        self.n_warnings = 0
        self.now = None  # the communication point being processed, to date messages
        self._slave = None
        self._unzipdir = None
        self._status = 0  # worst FMI status returned so far (0 OK ... 4 Fatal)

    # -- variables -------------------------------------------------------------------------------

    def variable(self, var: str):
        """The model variable ``var``; raises :class:`CoSimulationError` naming close matches."""
        try:
            return self.variables[var]
        except KeyError:
            why = refused_array(var, self._unsized)
            if why is not None:
                raise CoSimulationError(f"FMU '{self.name}': {var!r} cannot be a signal: {why}") from None
            near = difflib.get_close_matches(var, list(self.variables), n=3)
            hint = f" (did you mean {', '.join(repr(n) for n in near)}?)" if near else ""
            raise CoSimulationError(f"FMU '{self.name}' has no variable {var!r}{hint}") from None

    def kind(self, var: str):
        """Value kind of ``var`` (``"real"``, ...), or None for whole arrays (their elements
        ``var[i]`` have kinds), binaries and clocks."""
        try:
            return self._kinds[var]
        except KeyError:
            v = self.variable(var)
            kind = self._kinds[var] = None if v.dimensions else _KIND.get(v.type)
            return kind

    def names(self, causality: str) -> list:
        """Scalar variables of a causality (``"output"``, ``"input"``, ``"parameter"``) in file order."""
        names = self._names.get(causality)
        if names is None:
            names = self._names[causality] = [v.name for v in self.variables.values()
                                              if v.causality == causality and self.kind(v.name) is not None]
        return list(names)

    def start_value(self, var: str):
        """The ``start`` attribute of ``var`` converted to its kind, or None if it has none."""
        v = self.variable(var)
        if v.start is None:
            return None
        kind = self.kind(var)
        if kind == "boolean":
            return str(v.start).strip().lower() in ("true", "1")
        return _CAST[kind](float(v.start)) if kind == "integer" else _CAST[kind](v.start)

    # -- life cycle ------------------------------------------------------------------------------

    def start(self, start_time: float, stop_time: float, values: dict):
        """Extract, instantiate, apply ``values`` (parameters and start values), initialise.

        Raises
        ------
        SimulationFailed
            If the FMU refuses any call of the sequence.
        """
        import fmpy

        self._status = 0
        self._array_values.clear()  # arrays start from their start values again
        self.log.clear()
        self.warnings, self.n_warnings, self.now = {}, 0, start_time
        md = self.model_description
        kwargs = dict(guid=md.guid, unzipDirectory=None, instanceName=self.name,
                      modelIdentifier=md.coSimulation.modelIdentifier)
        try:
            self._unzipdir = fmpy.extract(str(self.path))
            kwargs["unzipDirectory"] = self._unzipdir
            if self.fmi_version == 2:
                self._start2(kwargs, start_time, stop_time, values)
            else:
                self._start3(kwargs, start_time, stop_time, values)
        except SimulationFailed:
            raise
        except Exception as exc:
            self._status = max(self._status, getattr(exc, "status", 3))
            raise self._failure(f"failed to initialise at t={start_time:g}: {exc}", start_time) from exc

    def _start2(self, kwargs, start_time, stop_time, values):
        from fmpy import calloc, free
        from fmpy.fmi2 import FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions

        # FMI 2 log messages are printf formats; fmpy's native proxy formats them for Python.
        self._callbacks = fmi2CallbackFunctions()
        self._environment = next(_ENVIRONMENT_IDS)
        _BY_ENVIRONMENT[self._environment] = self
        self._callbacks.logger = _logger2()
        self._callbacks.componentEnvironment = self._environment
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(byref(self._callbacks))
        except Exception:  # no proxy for this platform: messages arrive unformatted, still useful
            pass
        self._slave = FMU2Slave(**kwargs)
        # logging on: the messages only go to the bounded buffer, and they are what explains a failure
        self._slave.instantiate(callbacks=self._callbacks, loggingOn=True)
        # a pythonfmu FMU (ours guard themselves; others do not) would corrupt this process's
        # heap when it exits: pythonfmu 0.7's use-after-free, see fmu_fdi/fmu/exit_guard.py
        guard_library(self._slave.dll._name)
        try:  # every category (nCategories = 0): some FMUs send even errors only when asked to
            self._slave.setDebugLogging(True, [])
        except Exception:  # optional for an FMU; a refusal is no reason to stop
            pass
        self._slave.setupExperiment(startTime=start_time, stopTime=stop_time)
        self._write(values, start_time)
        self._slave.enterInitializationMode()
        self._slave.exitInitializationMode()

    def _start3(self, kwargs, start_time, stop_time, values):
        from fmpy.fmi3 import FMU3Slave

        self._slave = FMU3Slave(**kwargs)
        self._slave.instantiate(loggingOn=True, logMessage=self._log3)
        self._write(values, start_time)
        self._slave.enterInitializationMode(startTime=start_time, stopTime=stop_time)
        self._slave.exitInitializationMode()

    def _write(self, values: dict, time: float):
        if values:
            self.accessor(list(values)).write(list(values.values()), time)

    def do_step(self, time: float, step: float):
        """Advance from ``time`` by ``step``; raise :class:`SimulationFailed` if the FMU refuses."""
        self.now = time
        try:
            if self.fmi_version == 2:
                self._slave.doStep(currentCommunicationPoint=time, communicationStepSize=step)
                return
            _, terminate, early, last = self._slave.doStep(currentCommunicationPoint=time,
                                                           communicationStepSize=step)
        except Exception as exc:
            self._status = max(self._status, getattr(exc, "status", 3))
            raise self._failure(f"doStep from t={time:g} (step {step:g}) failed: {exc}", time) from exc
        if terminate:
            raise self._failure(f"asked to terminate the simulation in doStep from t={time:g}", time)
        if early:
            raise self._failure(f"returned early from doStep at t={last:g} (step from t={time:g})", time)

    def close(self):
        """End the instance as the FMI state machine allows, then delete the extraction.

        OK, Warning or Discard: terminate and free. Error: free only (terminate is not allowed).
        Fatal: no call at all. After Error or Fatal the shared library also stays loaded: objects
        the FMU created may outlive it (an in-process Python FMU leaves its exception's
        traceback in the interpreter), and unloading their code would crash the host later.
        """
        slave, self._slave = self._slave, None
        if slave is not None and slave.component:
            if self._status < 3:
                try:
                    slave.terminate()
                except Exception:  # a refusal to terminate is no reason to keep the instance
                    pass
                slave.freeInstance()
            elif self._status == 3:
                getattr(slave, f"fmi{self.fmi_version}FreeInstance")(slave.component)
        elif slave is not None:
            slave.freeLibrary()
        if self._unzipdir is not None:
            shutil.rmtree(self._unzipdir, ignore_errors=True)
            self._unzipdir = None

    # -- values ----------------------------------------------------------------------------------

    def accessor(self, names) -> "Accessor":
        """Batched typed get/set of ``names`` (one FMI call per type, not per variable)."""
        return Accessor(self, list(names))

    def _failure(self, what: str, time: float) -> SimulationFailed:
        log = list(self.log)
        tail = (" Last FMU messages: " + " | ".join(log[-3:])) if log else " The FMU logged no message."
        return SimulationFailed(f"FMU '{self.name}' {what.rstrip('.')}.{tail}", fmu=self.name, time=time,
                                log=log)

    def _log2(self, env, instance, status, category, message):
        self._record(status, message)

    def _log3(self, env, status, category, message):
        self._record(status, message)

    def _record(self, status, message):
        labels = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")
        label = labels[status] if 0 <= status < len(labels) else str(status)
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        text = " ".join(text.split())  # one line (a Python FMU logs tracebacks over several)
        self.log.append(f"[{label}] {text}")
        if status >= 1:  # Warning and worse: kept for the user (see warning_summary)
            self.n_warnings += 1
            seen = self.warnings.get(text)
            if seen is not None:
                seen[0] += 1
            elif len(self.warnings) < _WARNINGS_KEPT:
                self.warnings[text] = [1, self.now]

    def warning_summary(self) -> list:
        """One line per distinct warning message: ``FMU 'name' at t=...: text (N times)``."""
        lines = [f"FMU '{self.name}'" + (f" at t={t:g}" if t is not None and not _DATED.match(text) else "")
                 + f": {text}" + (f" ({count} times)" if count > 1 else "")
                 for text, (count, t) in self.warnings.items()]  # a message that dates itself is not dated twice
        kept = sum(c for c, _ in self.warnings.values())
        if self.n_warnings > kept:
            lines.append(f"FMU '{self.name}': {self.n_warnings - kept} more warnings with other texts")
        return lines


class Accessor:
    """Reads and writes a fixed list of scalar variables of one running :class:`FMUInstance`.

    FMI 3 array elements (``y[2]``) are read with their whole array (one value reference, N
    values) and written by setting the whole array, the other elements keeping the values last
    set (:class:`fmu_fdi.cosim.elements.Packed`)."""

    def __init__(self, fmu: FMUInstance, names: list):
        self.fmu = fmu
        self.names = names
        groups: dict = {}
        self.kinds = []
        for pos, name in enumerate(names):
            kind = fmu.kind(name)
            v = fmu.variables[name]
            if kind is None or (isinstance(v, Element) and kind == "string"):
                raise CoSimulationError(f"FMU '{fmu.name}': variable {name!r} is not a scalar of a "
                                        f"supported type (Real/Float, Integer, Boolean, String)")
            self.kinds.append(kind)
            call = _FMI2_CALL[v.type] if fmu.fmi_version == 2 else (
                "Int64" if v.type == "Enumeration" else v.type)
            group = groups.setdefault(call, ([], [], kind))
            group[0].append(v.valueReference)
            group[1].append(pos)
        # a group with array elements reads and writes whole arrays (Packed); others one value per reference
        self._groups = [(call, vrs, pos, _CAST[kind], self._packed(fmu, [names[p] for p in pos]))
                        for call, (vrs, pos, kind) in groups.items()]

    @staticmethod
    def _packed(fmu, names):
        vs = [fmu.variables[n] for n in names]
        return Packed(vs, store=fmu._array_values) if any(isinstance(v, Element) for v in vs) else None

    def read(self, time: float | None = None) -> list:
        """Current values, in the order of ``names``; ``time`` only labels a failure."""
        out = [None] * len(self.names)
        slave = self.fmu._slave
        for call, vrs, positions, cast, packed in self._groups:
            try:
                get = getattr(slave, "get" + call)
                values = get(vrs) if packed is None else packed.get(lambda r, n: get(r, nValues=n))
            except Exception as exc:
                raise self._failed("get" + call, positions, time, exc) from exc
            for p, value in zip(positions, values):
                out[p] = cast(value.decode() if isinstance(value, bytes) else value)
        return out

    def write(self, values, time: float | None = None):
        """Set the variables to ``values`` (same order as ``names``), converted to their kinds."""
        slave = self.fmu._slave
        for call, vrs, positions, cast, packed in self._groups:
            try:
                if packed is None:
                    getattr(slave, "set" + call)(vrs, [cast(values[p]) for p in positions])
                else:
                    packed.set(getattr(slave, "set" + call), [values[p] for p in positions], cast)
            except Exception as exc:
                raise self._failed("set" + call, positions, time, exc) from exc

    def _failed(self, call, positions, time, exc):
        self.fmu._status = max(self.fmu._status, getattr(exc, "status", 3))
        names = ", ".join(self.names[p] for p in positions)
        at = "" if time is None else f" at t={time:g}"
        return self.fmu._failure(f"{call}({names}){at} failed: {exc}", time)
