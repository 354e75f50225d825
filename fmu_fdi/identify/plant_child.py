"""``fmu-fdi model``'s plant work in a child process, and the stability check of its result.

A plant FMU is foreign code: it can crash (a segmentation fault), end the process (``_exit``),
never return from a step, or compute NaN. :func:`run_model_child` runs the linearisation or
identification (:func:`fmu_fdi.identify.envelope.model_from_fmu`) in a process started with the
``spawn`` context, under a wall-clock limit, and turns each of those into one
:class:`~fmu_fdi.errors.ModelError` line. The request goes in and the model comes back as JSON
text (the model file's dict, :meth:`FDIModel.to_dict <fmu_fdi.model.FDIModel.to_dict>`): nothing
the user sees is pickled.

:func:`~fmu_fdi.identify.plant_stability.check_stable` refuses a model with a pole outside the stability region (Re λ > 0, or
|λ| > 1 for a discrete model) unless its operating point is an equilibrium: a trimmed
linearisation, or the user's word (``--allow-unstable``). An identified model of an unstable
plant (one that does not close its own loop) describes a plant that never settled at the point.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import multiprocessing
import os
import signal
import sys
import time


from ..errors import ModelError
from .plant_stability import check_plant_models

#: default wall-clock limit of ``fmu-fdi model`` (--timeout), in seconds
DEFAULT_TIMEOUT = 600.0

def run_model_child(args: argparse.Namespace, timeout: float = DEFAULT_TIMEOUT) -> dict | None:
    """Run :func:`model_work` on ``args`` in a spawned child within ``timeout`` seconds.

    Returns the model's dict (one operating point), or None (--at-grid: the child wrote the model
    set). A crash, an exit without a result, a hang past the limit or an error in the child is
    raised as one :class:`ModelError` line."""
    ctx = multiprocessing.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    request = json.dumps({k: v for k, v in vars(args).items() if k != "func"})
    proc = ctx.Process(target=_child_main, args=(request, send), daemon=True, name="fmu-fdi-model-plant")
    with _one_blas_thread():
        proc.start()
    send.close()  # the child holds the only write end: its death is an end of file here
    deadline = time.monotonic() + timeout
    try:
        while True:  # lines the child prints, then its reply
            if not receive.poll(max(deadline - time.monotonic(), 0.0)):
                raise ModelError(f"{args.plant}: the plant did not finish within {timeout:g} s (--timeout); it was "
                                 f"stopped: a step that never returns, or an experiment longer than the limit "
                                 f"(raise --timeout)")
            try:
                reply = json.loads(receive.recv_bytes().decode())
            except EOFError:
                raise ModelError(_ended(args.plant, proc)) from None
            if "out" not in reply:
                break
            sys.stdout.write(reply["out"])
            sys.stdout.flush()
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(5.0)
        receive.close()
    if "error" in reply:
        raise ModelError(reply["error"])
    return reply["model"]


#: the thread-count variables of the BLAS libraries numpy and scipy load (OpenBLAS, OpenMP, MKL)
_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _one_blas_thread():
    """The spawned child's BLAS on one thread, unless the user set a thread count. Identification's
    linear algebra is tall and narrow (records of ≤ 20 000 samples × ≤ a few hundred Hankel rows),
    where threads gain little, and on a shared machine a threaded BLAS spins against the other
    processes: a 1000 × 154 QR took 1.8 s with OpenBLAS's threads at load 7 on 2 cores, 0.011 s on
    one (the drive train's ``fmu-fdi model``: 40 s → see benchmarks/identify_plants.py). The library
    reads the variable when it loads, so it is set around the child's start only."""
    if any(k in os.environ for k in _BLAS_THREADS):
        yield
        return
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        yield
    finally:
        os.environ.pop("OPENBLAS_NUM_THREADS", None)


def _ended(plant, proc) -> str:
    """The one line for a child that ended without a reply: killed by a signal, or exited."""
    proc.join(5.0)
    code = proc.exitcode
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"{plant}: the plant FMU crashed ({name}) while it was modelled; no model was written"
    return f"{plant}: the plant FMU ended the process (exit code {code}) before a model was made; no model was written"


class _PipeOut:
    """The child's stdout: each write goes to the parent, which prints it (in order, live)."""

    def __init__(self, send):
        self.send = send

    def write(self, text: str) -> int:
        if text:
            self.send.send_bytes(json.dumps({"out": text}).encode())
        return len(text)

    def flush(self) -> None:
        pass


def model_work(args: argparse.Namespace) -> dict | None:
    """The plant work of ``fmu-fdi model`` (in the child): the model's dict, or None after
    writing a model set (--at-grid)."""
    from ..progress import report_minreal
    from . import Excitation, model_from_fmu
    from .fmu_model import parse_values

    exc = Excitation(signal=args.signal, amplitude=parse_values(args.amplitude, "--amplitude") or None,
                     samples=args.samples, settle=args.settle, period=args.period, seed=args.seed)
    if args.at_grid:  # several operating points: a model set (fmu_fdi/identify/envelope.py)
        from .envelope import envelope_cli

        envelope_cli(args, exc, parse_values(args.at, "--at"))
        return None
    model = model_from_fmu(args.plant, args.inputs, args.outputs, args.disturbances or (),
                           at=parse_values(args.at, "--at"), method=args.method, trim=args.trim,
                           sensor_faults=args.sensor_faults, actuator_faults=args.actuator_faults, ts=args.ts,
                           excite=args.excite, excitation=exc, order=args.order, min_fit=args.min_fit,
                           validation_png=args.plot, record=args.record,
                           noise=None if args.noise == "none" else args.noise,
                           minimal=args.minimal, minreal_tol=args.minreal_tol, log=print)
    check_plant_models(args.plant, [model], args.allow_unstable)
    report_minreal(model)
    return model.to_dict()


def _child_main(request: str, send) -> None:
    """Entry of the child: every error becomes a one-line reply; a plant that kills the process
    leaves no reply (the parent reads the exit status)."""
    from ..cosim.errors import CoSimulationError
    from ..errors import BuildError, DesignError, InputFileError, OutputError, one_line

    sys.stdout = _PipeOut(send)
    try:
        reply = {"model": model_work(argparse.Namespace(**json.loads(request)))}
    except KeyboardInterrupt:
        return
    except (ModelError, DesignError, BuildError, OutputError, InputFileError, CoSimulationError) as exc:
        reply = {"error": one_line(exc)}  # what the CLI reports of each in one line
    except OSError as exc:  # the file system said no (writing --record, --plot)
        reply = {"error": one_line(exc.strerror or exc) + (f": {exc.filename}" if exc.filename else "")}
    except Exception as exc:  # the plant or a library under it failed in a way no check named
        reply = {"error": f"the plant could not be modelled: {type(exc).__name__}: {one_line(exc)}"}
    send.send_bytes(json.dumps(reply).encode())
    send.close()
