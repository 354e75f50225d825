"""Signs of life for long computations: the current stage, reported while it runs.

Analysis and design of large models (n = 500-2000 states) take minutes: their cost is a
few dozen dense eigenvalue problems and complex solves of size n, each O(n³)
(docs/large-models.md has the measured figures). Library code names its stage with
:func:`set_stage` (one line, no indentation change) or :func:`stage` (a context manager);
both log the stage on the ``fmu_fdi`` logger at level INFO. A :class:`Heartbeat` (the CLI
runs every command under one) prints the current stage to stderr when a command has run
longer than ``first`` seconds and then every ``every`` seconds, so fast commands stay
quiet and slow ones show what they are doing::

    fmu-fdi: still working after 30 s: isolability analysis (n = 500 states, 5 faults)

The stage is per process (the CLI runs one command at a time); the heartbeat thread is a
daemon that only reads it and stops when the command returns.
"""
from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time

log = logging.getLogger("fmu_fdi")
_current = {"stage": "", "since": time.monotonic()}


def set_stage(what: str) -> None:
    """Name the stage that starts now (logged at INFO on the ``fmu_fdi`` logger)."""
    _current["stage"], _current["since"] = what, time.monotonic()
    log.info("%s", what)


def note(what: str) -> None:
    """Update the current stage's description without logging (for frequent updates, e.g.
    the co-simulation's time)."""
    _current["stage"] = what


def current_stage() -> str:
    return _current["stage"]


def own_display(on: bool) -> None:
    """A command that draws its own progress line on a terminal (a campaign's bar) turns the
    heartbeat off while it does, so the two never splice into one line."""
    _current["own_display"] = bool(on)


@contextlib.contextmanager
def stage(what: str):
    """Run a block as the named stage; the previous stage is current again afterwards."""
    before = _current["stage"]
    set_stage(what)
    t0 = time.monotonic()
    try:
        yield
    finally:
        log.debug("%s: %.3g s", what, time.monotonic() - t0)
        _current["stage"] = before


class Heartbeat:
    """Print the current stage to ``stream`` while a long command runs.

    Parameters
    ----------
    first : float
        Seconds of silence before the first report.
    every : float
        Seconds between later reports.
    stream : file, optional
        Default ``sys.stderr``.
    """

    def __init__(self, first: float = 10.0, every: float = 30.0, stream=None):
        self.first, self.every = first, every
        self.stream = stream
        self._stop = threading.Event()
        self._thread = None
        self.reports = 0

    def __enter__(self):
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="fmu-fdi heartbeat", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        return False

    def _run(self):
        wait = self.first
        while not self._stop.wait(wait):
            if _current.get("own_display"):
                continue
            what = _current["stage"] or "working"
            stream = self.stream or sys.stderr
            print(f"fmu-fdi: still working after {time.monotonic() - self._t0:.0f} s: {what}", file=stream,
                  flush=True)
            self.reports += 1
            wait = self.every


def report_minreal(model) -> None:
    """Say what a minimal realisation removed from ``model`` (nothing when it was not reduced)."""
    if model.reduction is not None:
        n, nr, tol = model.reduction
        print(f"model '{model.name}': minimal realisation removed {n - nr} of {n} states (relative tolerance "
              f"{tol:.3g})")
