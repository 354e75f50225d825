"""``fmu-fdi simulate``: plant FMU(s) + diagnostic FMU, faults, CSV out — a veneer over
:class:`~fmu_fdi.cosim.master.CoSimulation`.

Exit status: 0 on success (warnings the FMUs logged are printed to stderr); 1 if an FMU failed
during the run (the rows completed so far are in ``-o``, whose last line ``# incomplete: ...``
says why it stops early); 2 for a set-up error (bad file, name, type, step, fault SPEC or an
output path that cannot be written), reported before any FMU runs.
"""
from __future__ import annotations

import sys

from .errors import CoSimulationError, SimulationFailed
from .master import ORDERS, CoSimulation
from .signals import INTERPOLATIONS, InputSignals
from .spec import __doc__ as _SPEC_DOC
from .spec import parse_fault


_DESCRIPTION = """\
Co-simulate plant FMU(s) and a diagnostic FMU (FMI 2 or 3 co-simulation) on a fixed
communication step. Outputs are connected to the same-named inputs of the other FMUs unless
--connect is given; --input signals feed every unconnected input of their name. The result CSV
holds every output and every fed input of every FMU ("fmu.var": the plant inputs and what the
diagnoser read) and each fault's true signal ("fault.NAME", "fault.NAME.active"), streamed as
they are computed; it is a log 'fmu-fdi diagnose' and 'fmu-fdi design --calibrate' read as it
is. Every input of the diagnoser must be connected or fed by --input (else it would diagnose
its start values): an error unless --allow-unconnected. FMU warnings are printed to stderr.
Exit status: 0 done; 1 an FMU failed (the rows so far are written, and a last line
'# incomplete: ...' says why); 2 a set-up error (nothing is run)."""


def _plain(rst: str) -> str:
    """Help text from reStructuredText: roles (:mod:`~a.b`) become their last name, no ``
    and no literal-block ``::``."""
    import re

    text = re.sub(r":\w+:`~?([^`]*?)`", lambda m: m.group(1).rsplit(".", 1)[-1], rst)
    text = re.sub(r"::[ \t]*$", ":", text, flags=re.M)  # literal-block markers
    return text.replace("``", "")


def add_parser(subparsers):
    """Add the ``simulate`` command to an ``argparse`` sub-parser set; returns the parser."""
    import argparse

    p = subparsers.add_parser(
        "simulate", help="co-simulate plant FMU(s) with a diagnostic FMU and fault scenarios",
        description=_DESCRIPTION, epilog="fault SPEC:" + _plain(_SPEC_DOC.split("::", 1)[1]),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plant", action="append", required=True, metavar="[NAME=]P.fmu",
                   help="plant FMU (repeatable; default instance names 'plant', 'plant2', ... unless NAME= given)")
    p.add_argument("--diagnoser", metavar="[NAME=]FDI.fmu",
                   help="diagnostic FMU (default instance name 'diagnoser' unless NAME= given); stepped after the "
                        "plants (default: none)")
    p.add_argument("--stop", type=float, required=True, help="stop time (s)")
    p.add_argument("--step", type=float, required=True, help="communication step (s)")
    p.add_argument("--start", type=float, default=0.0, help="start time (s) (default: 0)")
    p.add_argument("--input", metavar="CSV", help="external input signals: a 'time' column and one "
                   "column per signal, fed to every unconnected input of that name (default: none)")
    p.add_argument("--interpolation", choices=INTERPOLATIONS, default="zoh",
                   help="how --input is read between its samples (default: zoh)")
    p.add_argument("--fault", action="append", default=[], metavar="SPEC",
                   help="fault scenario KIND:TARGET:ONSET[:END]:MAGNITUDE[,opt=val...] (repeatable; default: none)")
    p.add_argument("--connect", action="append", metavar="SRC=DST",
                   help="explicit connection, e.g. plant.y=diagnoser.y (repeatable; replaces the "
                        "default: connect outputs to same-named inputs)")
    p.add_argument("--param", action="append", default=[], metavar="FMU.VAR=VALUE",
                   help="parameter or start value set before initialisation (repeatable; default: "
                        "the FMU's start values)")
    p.add_argument("--order", choices=ORDERS, default="gauss-seidel",
                   help="stepping order (default: gauss-seidel; jacobi: the diagnoser reads each (u, y) of one "
                        "sample)")
    p.add_argument("--allow-unconnected", action="store_true",
                   help="run although some diagnoser inputs are neither connected nor fed by --input "
                        "(they keep their start values; default: refuse)")
    p.add_argument("--ssp", metavar="OUT.ssp",
                   help="also export the connected system (without the faults) as SSP (default: none)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv", help="result CSV")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Execute ``fmu-fdi simulate`` with parsed ``args``; returns the exit status.

    The rows are streamed to ``-o`` as they are computed (bounded memory for any stop time);
    the output path is checked before the first FMU starts, so an unwritable path fails at once.
    Warnings the FMUs logged (e.g. a parameter value they ignored) are printed to stderr.
    """
    from ..errors import InputFileError, OutputError
    from ..inputfiles import check_input_file
    from ..outpath import check_output_path

    try:
        reads = [args.input] + [t.partition("=")[2] or t for t in args.plant + [args.diagnoser or ""] if t]
        check_output_path(args.output, (".csv",), "result CSV", inputs=reads)
        if args.ssp:
            check_output_path(args.ssp, (".ssp",), "SSP file")
        if args.input:
            check_input_file(args.input, "input CSV")
        sim = _build(args)
        if args.ssp:
            sim.export_ssp(args.ssp, drop_faults=True)
            if sim.faults:
                print(f"fmu-fdi simulate: note: {args.ssp} describes the fault-free system "
                      f"(SSP cannot express the fault scenarios)", file=sys.stderr)
        with _stop_between_steps(sim):
            result = sim.run(csv=args.output)
    except (CoSimulationError, FileNotFoundError, InputFileError, OutputError) as exc:
        print(f"fmu-fdi simulate: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"fmu-fdi simulate: interrupted (Ctrl-C); the rows so far are in {args.output}, marked incomplete",
              file=sys.stderr)
        return 130
    except SimulationFailed as exc:
        _warn([w for w in exc.warnings if w.split(": ", 1)[-1] not in str(exc)])  # not the failure twice
        print(f"fmu-fdi simulate: {exc} ({exc.rows_written} rows written to {args.output}, marked incomplete)",
              file=sys.stderr)
        return 1
    _warn(result.warnings)
    print(f"{sim.n_steps + 1} rows x {len(result.names)} columns written to {args.output}")
    return 0


class _stop_between_steps:
    """Ctrl-C asks the master to stop between two steps (a second Ctrl-C interrupts at once):
    an FMU that runs Python (pythonfmu) never sees the interruption inside its step."""

    def __init__(self, sim):
        self.sim = sim
        self._old = None

    def __enter__(self):
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame):
        if self.sim.interrupt_requested:
            raise KeyboardInterrupt
        self.sim.interrupt_requested = True

    def __exit__(self, *exc):
        import signal

        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        return False


def _warn(lines):
    for line in lines:
        print(f"fmu-fdi simulate: warning: {line}", file=sys.stderr)


def _build(args) -> CoSimulation:
    fmus = {}
    for i, text in enumerate(args.plant):
        _named(fmus, text, "plant" if i == 0 else f"plant{i + 1}")
    if args.diagnoser:
        _named(fmus, args.diagnoser, "diagnoser")
    connections = "auto"
    if args.connect:
        connections = [_pair(c, "--connect", "SRC=DST") for c in args.connect]
    params = {}
    for text in args.param:
        key, value = _pair(text, "--param", "FMU.VAR=VALUE")
        params[key] = _literal(value)
    inputs = InputSignals.from_csv(args.input, args.interpolation) if args.input else None
    _check_swapped(fmus)
    return CoSimulation(fmus, connections, inputs, step=args.step, stop=args.stop, start=args.start,
                        order=args.order, faults=[parse_fault(s) for s in args.fault], parameters=params,
                        record_inputs=True, allow_unconnected=args.allow_unconnected)


def _check_swapped(fmus: dict) -> None:
    """A --diagnoser FMU without diagnostic outputs next to a --plant FMU with them: swapped."""
    from .instance import FMUInstance

    if "diagnoser" not in fmus or len(fmus) < 2:
        return
    diagnostic = {"fault_detected", "isolated_fault"}
    insts = {n: FMUInstance(n, p) for n, p in fmus.items()}
    if diagnostic <= set(insts["diagnoser"].names("output")):
        return
    plants = [n for n, f in insts.items() if n != "diagnoser" and diagnostic <= set(f.names("output"))]
    if plants:
        raise CoSimulationError(f"--diagnoser {fmus['diagnoser']} has no fault_detected/isolated_fault outputs but "
                                f"--plant {fmus[plants[0]]} has: are --plant and --diagnoser swapped?")


def _named(fmus, text, default):
    name, sep, path = text.partition("=")
    if not sep or name.endswith((".fmu", "/")) or not name.isidentifier():
        name, path = default, text
    if name in fmus:
        raise CoSimulationError(f"two FMUs are named {name!r}")
    fmus[name] = path


def _pair(text, option, form):
    a, sep, b = text.partition("=")
    if not sep or not a.strip() or not b.strip():
        raise CoSimulationError(f"{option} {text!r} must read {form}")
    return a.strip(), b.strip()


def _literal(text):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text
