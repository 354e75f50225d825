"""The fixed-step co-simulation master: plant FMU(s) and a diagnostic FMU on one time grid.

Communication points are ``t_k = start + k·h``, ``k = 0 … N`` with ``N = (stop − start)/h``
(a whole number). Over each step every FMU input is held at the value set at the step's start
(zero-order hold). Two orders:

- ``"gauss-seidel"`` (default): the FMUs are stepped one after the other in the order of the
  ``fmus`` mapping — list the plant(s) first — and each one's inputs are set just before its
  step, from outputs that earlier FMUs have already advanced to ``t_{k+1}``. The diagnoser thus
  reads ``y(t_{k+1})`` while computing its step to ``t_{k+1}``: no delay.
- ``"jacobi"``: all inputs are set from the outputs at ``t_k``, then all FMUs step (as if in
  parallel). Every connection carries a delay of one step: the diagnoser's step to ``t_{k+1}``
  reads ``y(t_k)``.

External signals and fixed sources are sampled at the step's start ``t_k`` in both orders.
A fault on a connection is evaluated at the time of the value it corrupts.

Initialisation: parameters, start values and the external signals at ``t_0`` are set before
each FMU initialises; connected inputs keep their start values through initialisation and get
the source outputs (as they are after every FMU initialised) for the first step. Row 0 of the
result holds the outputs after initialisation.
"""
from __future__ import annotations

import contextlib
import math

from ..progress import note
from .errors import CoSimulationError, SimulationFailed
from .faults import Fault
from .instance import FMUInstance
from .loop import Loop
from .result import CsvWriter, Result
from .signals import InputSignals
from .wiring import wire

ORDERS = ("gauss-seidel", "jacobi")


class CoSimulation:
    """Plant FMU(s) and a diagnostic FMU connected and stepped together, with fault scenarios.

    The constructor reads the model descriptions and checks the whole set-up (names, types,
    step, faults) without instantiating anything; :meth:`run` does the work.

    Parameters
    ----------
    fmus : mapping of str to path or FMUInstance
        Instance name -> ``.fmu`` file (FMI 2.0 or 3.0 co-simulation), or an
        :class:`~fmu_fdi.cosim.instance.FMUInstance` of that name (a campaign worker passes the
        instances it keeps alive between runs). The mapping's order is the Gauss–Seidel
        stepping order: plants first, diagnoser last.
    connections : "auto", None or list of (str, str)
        ``"auto"``: every input takes the output of the same name of another FMU (an error if
        several FMUs have it). None: no connections. A list: ``("plant.y", "diagnoser.y")``
        pairs, output first.
    inputs : InputSignals, path, structured array or None
        External signals (see :mod:`fmu_fdi.cosim.signals`; a path is a CSV read with
        zero-order hold). A column ``Q1`` feeds every unconnected input named ``Q1``; a column
        ``plant.Q1`` feeds that input only.
    step : float
        Communication step ``h > 0``.
    stop : float
        Stop time; ``stop − start`` must be a whole number of steps.
    start : float
        Start time.
    order : {"gauss-seidel", "jacobi"}
        See the module docstring.
    faults : sequence of Fault
        Scenarios (see :class:`~fmu_fdi.cosim.faults.Fault`). A fault on an *output* is applied
        by the master to the value it passes along every connection from that output, so any
        third-party plant FMU can be given sensor faults; the output column keeps the true
        value. A fault on an *input* changes the value that FMU receives (connected, external
        or its own start value); on a *tunable parameter* the master sets the faulty value
        before each step; a *fixed parameter* only accepts a fault that is constant from the
        start, applied before initialisation. Several faults on one target act in list order,
        those on a source output before those on the receiving input.
    parameters : mapping of str to value, optional
        ``{"plant.a": 2.0}``: parameter and input start values set before initialisation.
    record_inputs : bool
        Also record every input the master sets (``fmu.var``: the plant inputs from external
        signals and faults, what the diagnoser read), so the result is a complete log for
        offline diagnosis. ``fmu-fdi simulate`` does. Default False.
    allow_unconnected : bool
        Every input of a diagnostic FMU (one with ``fault_detected`` and ``isolated_fault``
        outputs) must be connected or fed by an external signal, else it would diagnose its
        start values: a :class:`CoSimulationError` unless this is True (then each loose input
        is listed in :attr:`warnings`). Default False, as ``fmu-fdi simulate``.

    Attributes
    ----------
    fmus : dict of str to FMUInstance
    connections : list of (str, str)
        The resolved connections, e.g. ``[("plant.y", "diagnoser.y")]``.
    times : list of float
        The communication points ``start + k·step``.

    Examples
    --------
    >>> sim = CoSimulation({"plant": "P.fmu", "diagnoser": "FDI.fmu"}, step=0.1, stop=100,
    ...                    faults=[Fault.stuck("plant.h1", onset=50)])   # doctest: +SKIP
    >>> result = sim.run()                                                # doctest: +SKIP
    >>> result.to_csv("out.csv")                                          # doctest: +SKIP
    """

    def __init__(self, fmus, connections="auto", inputs=None, *, step, stop, start=0.0,
                 order="gauss-seidel", faults=(), parameters=None, record_inputs: bool = False,
                 allow_unconnected: bool = False):
        if order not in ORDERS:
            raise CoSimulationError(f"order {order!r} is not one of {ORDERS}")
        self.start, self.stop, self.step = _grid(start, stop, step)
        self.order = order
        if not fmus:
            raise CoSimulationError("no FMUs given")
        self.fmus = {name: path if isinstance(path, FMUInstance) and path.name == name else FMUInstance(name, path)
                     for name, path in dict(fmus).items()}
        self.inputs = _signals(inputs)
        self.faults = tuple(faults)
        for f in self.faults:
            if not isinstance(f, Fault):
                raise CoSimulationError(f"faults must be Fault objects (see parse_fault), got {f!r}")
        self.parameters = dict(parameters or {})
        self.record_inputs = bool(record_inputs)
        self._wiring = wire(self.fmus, connections, self.inputs.names if self.inputs else (),
                            self.faults, self.parameters, self.start)
        self.connections = [(f"{a}.{b}", f"{c}.{d}") for a, b, c, d in self._wiring.connections]
        #: number of communication steps N (the grid has N + 1 points)
        self.n_steps = round((self.stop - self.start) / self.step)
        for f in self.faults:
            slack = 1e-9 * max(1.0, abs(self.start), abs(self.stop))
            if f.onset < self.start - slack:
                raise CoSimulationError(f"fault {f.name}: onset {f.onset:g} is before the start time {self.start:g}")
            if f.onset > self.stop + slack:
                raise CoSimulationError(f"fault {f.name}: onset {f.onset:g} is after the stop time {self.stop:g}, "
                                        f"so it would never act")
        #: warnings (and worse) the FMUs logged in the last run, one line per distinct message
        self.warnings: list[str] = []
        #: diagnoser inputs neither connected nor fed (allowed by ``allow_unconnected``)
        self.unconnected = self._diagnoser_inputs_fed(allow_unconnected)
        #: set (e.g. by a SIGINT handler) to stop :meth:`run` between two steps with KeyboardInterrupt,
        #: never inside an FMU's step (a Python FMU would turn the interruption into a fatal error)
        self.interrupt_requested = False

    def _diagnoser_inputs_fed(self, allow: bool) -> list:
        """Loose diagnoser inputs as ``fmu.var``; an error unless ``allow`` (see the class docstring)."""
        diagnostic = {"fault_detected", "isolated_fault"}
        fed = {(fd.fmu, fd.var) for fd in self._wiring.feeds if fd.source[0] in ("output", "signal")}
        loose = []
        for name, fmu in self.fmus.items():
            if diagnostic <= set(fmu.names("output")):
                loose += [f"{name}.{v}" for v in fmu.names("input") if (name, v) not in fed]
        if loose and not allow:
            where = sorted({v.split(".", 1)[0] for v in loose})
            names = [v.split(".", 1)[1] for v in loose] if len(where) == 1 else loose
            raise CoSimulationError(
                f"diagnoser inputs {', '.join(names)} are neither connected nor fed by an input signal (instance "
                f"{', '.join(where)}), so the diagnoser would read their start values; give them a source "
                f"(--input CSV with columns {', '.join(names)}, or --connect; inputs=, connections=) or pass "
                f"--allow-unconnected (allow_unconnected=True)")
        return loose

    @property
    def times(self) -> list:
        """The communication points ``start + k·step``, k = 0 … N (built on request)."""
        return [self.time(k) for k in range(self.n_steps + 1)]

    def time(self, k: int) -> float:
        """Communication point k."""
        return self.start + k * self.step

    # -- running ---------------------------------------------------------------------------------

    def columns(self) -> list:
        """``(name, kind)`` of every column of the :class:`Result`, in order."""
        cols = [("time", "real")]
        for name, fmu in self.fmus.items():
            cols += [(f"{name}.{v}", fmu.kind(v)) for v in fmu.names("output") if fmu.kind(v) != "string"]
            cols += [(f"{name}.{v}", fmu.kind(v)) for v in self._fed_inputs(name)]
        for f in self.faults:
            cols += [(f"fault.{f.name}", "real"), (f"fault.{f.name}.active", "boolean")]
        return cols

    def _fed_inputs(self, name) -> list:
        """Inputs of FMU ``name`` the master sets during the run, recorded as ``name.var``
        when ``record_inputs``."""
        if not self.record_inputs:
            return []
        return [fd.var for fd in self._wiring.feeds
                if fd.fmu == name and fd.runtime and self.fmus[name].variable(fd.var).causality == "input"]

    def run(self, csv=None, *, chunk_rows: int = 4096, max_memory: float = 2**30):
        """Instantiate, initialise and step all FMUs from start to stop; record every row.

        Parameters
        ----------
        csv : path, optional
            Stream the rows to this CSV (format of :meth:`Result.to_csv`) in chunks of
            ``chunk_rows``, so a run of any length needs bounded memory. The file is created
            before any FMU starts (an unwritable path is a :class:`CoSimulationError`); if
            the run stops early its last line is ``# incomplete: <why>``.
        max_memory : float
            Without ``csv``, the result is kept in memory; a run whose result would need
            more bytes than this is refused before it starts (use ``csv``).

        Returns
        -------
        Result
            Without ``csv``: one row per communication point (columns in
            :mod:`fmu_fdi.cosim.result`). With ``csv``: the last rows written (at most
            ``chunk_rows``). Either way ``result.warnings`` (also :attr:`warnings`) lists the
            warnings the FMUs logged.

        Raises
        ------
        SimulationFailed
            If an FMU fails to initialise or its ``doStep`` returns Discard/Error/Fatal (or, in
            FMI 3, asks to terminate). The message names the FMU and the time and ends with the
            FMU's last messages; the rows completed so far are in the exception's ``result``
            (without ``csv``) or in the CSV, marked incomplete. The FMUs are always freed.
        """
        cols = self.columns()
        names, kinds = [c for c, _ in cols], [k for _, k in cols]
        rows = self.n_steps + 1
        chunk = min(rows, max(1, int(chunk_rows)))
        writer = None
        if csv is not None:
            try:
                writer = CsvWriter(csv, names)
            except OSError as exc:
                raise CoSimulationError(f"cannot write the result to {csv}: {exc.strerror or exc}") from None
            buf = Result.empty(names, kinds, chunk)
        else:
            need = rows * Result.empty(names, kinds, 0).itemsize
            if need > max_memory:
                raise CoSimulationError(f"the result of {rows} rows x {len(names)} columns would need "
                                        f"{need / 2**30:.3g} GiB in memory; stream it to a file instead "
                                        f"(run(csv=...), or fmu-fdi simulate -o OUT.csv)")
            buf = Result.empty(names, kinds, rows)
        loop = Loop(self, chunk)
        state = {"done": 0, "base": 0, "flushed": 0}  # rows in the chunk, grid point of its row 0, rows in the CSV
        self.warnings = []

        def flush():
            """Turn the chunk's rows into Result rows (and write them to the CSV)."""
            m, k0 = state["done"], state["base"]
            if m:
                if writer is not None:
                    loop.convert(buf[:m], m, k0)
                    writer.write(buf[:m])
                    state["flushed"] += m
                else:
                    loop.convert(buf[k0:k0 + m], m, k0)
            state["done"], state["base"] = 0, k0 + m

        completed = False
        try:
            with contextlib.ExitStack() as stack:
                try:
                    loop.start(stack)
                    advance, record = loop.advance, loop.record
                    for k in range(rows):
                        if self.interrupt_requested:
                            raise KeyboardInterrupt
                        if k:
                            advance(k - 1)
                        i = state["done"]
                        if i == chunk or not k & 1023:
                            note(f"co-simulation at t = {self.time(k):g} s of {self.stop:g} s (row {k} of {rows})")
                            if i == chunk:
                                flush()
                                i = 0
                        record(i, k)
                        state["done"] = i + 1
                    completed = True
                finally:
                    self.warnings = [line for fmu in self.fmus.values() for line in fmu.warning_summary()]
                    self.warnings += [f"{v} is not connected: the diagnoser read its start value"
                                      for v in self.unconnected]
                    if hasattr(loop, "rec_f"):  # the rows recorded so far, also when a step failed
                        tail = state["done"]
                        flush()
        except SimulationFailed as exc:
            exc.warnings = self.warnings
            if writer is not None:
                writer.close(f"the run stopped after {state['flushed']} of {rows} rows: {exc}")
                exc.result = None
                exc.rows_written = state["flushed"]
            else:
                exc.result = buf[:state["base"]]
            raise
        finally:
            if writer is not None:
                if completed:
                    writer.close()
                else:  # an interruption other than SimulationFailed (already closed above)
                    writer.close(f"the run stopped after {state['flushed']} of {rows} rows (interrupted)")
        result = buf[:tail] if writer is not None else buf
        result.warnings = self.warnings
        return result

    def export_ssp(self, path, *, drop_faults: bool = False):
        """Write the connected system as an SSP file; see :func:`fmu_fdi.cosim.ssp.export_ssp`."""
        from .ssp import export_ssp

        return export_ssp(self, path, drop_faults=drop_faults)


def _grid(start, stop, step):
    try:
        start, stop, step = float(start), float(stop), float(step)
    except (TypeError, ValueError):
        raise CoSimulationError(f"start, stop and step must be numbers, got {start!r}, {stop!r}, {step!r}") from None
    if not all(map(math.isfinite, (start, stop, step))):
        raise CoSimulationError("start, stop and step must be finite")
    if not step > 0:
        raise CoSimulationError(f"step must be positive, got {step:g}")
    if not stop > start:
        raise CoSimulationError(f"stop ({stop:g}) must be after start ({start:g})")
    n = (stop - start) / step
    if not math.isfinite(n) or n > MAX_STEPS:
        raise CoSimulationError(f"(stop − start) / step = {n:.3g} steps is more than the {MAX_STEPS:.0e} a "
                                f"co-simulation may take; shorten the run or lengthen the step")
    if round(n) < 1:
        raise CoSimulationError(f"step {step:g} s is longer than the run (stop − start = {stop - start:g} s): "
                                f"there would be no step at all")
    if abs(n - round(n)) > 1e-9 * max(1.0, n):
        raise CoSimulationError(f"stop − start = {stop - start:g} is not a whole number of steps "
                                f"{step:g} ({n:.6g}); choose stop = start + N·step")
    return start, stop, step


#: most communication steps of one co-simulation: 1e10 steps are days of stepping (streamed to a CSV
#: in bounded memory); beyond it a run would not end in a working lifetime (``--stop 1e308``)
MAX_STEPS = 10 ** 10


def _signals(inputs):
    if inputs is None or isinstance(inputs, InputSignals):
        return inputs
    if isinstance(inputs, (str, bytes)) or hasattr(inputs, "__fspath__"):
        return InputSignals.from_csv(inputs)
    if getattr(getattr(inputs, "dtype", None), "names", None):
        return InputSignals.from_array(inputs)
    raise CoSimulationError(f"inputs must be InputSignals, a CSV path or a structured array, "
                            f"got {type(inputs).__name__}")
