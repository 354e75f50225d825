"""Design notes: what a user should know about a returned filter, kept with the filter.

A design either returns a filter that meets every requirement or raises a ``DesignError``
(FaultDetectionTools.jl returns its remarks in ``info`` too): a remark that does not stop the
design — a requested pole the filter's order leaves unused, a row that decouples only to the
post-condition tolerance — belongs in the filter's ``info['notes']`` (a list of one-line
strings), not in a ``UserWarning`` printed beside it. The toolkit calls :func:`note` where it
notices; every public design function runs under :func:`keeps_notes`, which collects the notes
of the call (nested designs included) and attaches them to the returned object. Outside any
design (a toolkit function called on its own) :func:`note` still warns, so nothing is lost.
"""
from __future__ import annotations

import functools
import warnings
from contextlib import contextmanager
from contextvars import ContextVar

#: the notes of the design in progress (None: no design in progress); nesting is by re-noting on return
_COLLECTOR: ContextVar[list[str] | None] = ContextVar("fmu_fdi_design_notes", default=None)


def note(message: str) -> None:
    """Record ``message`` for the design in progress (an enclosing design gets it when that one returns,
    :func:`keeps_notes`); a ``UserWarning`` when no design is in progress."""
    notes = _COLLECTOR.get()
    if notes is None:
        warnings.warn(message, UserWarning, stacklevel=3)
    elif message not in notes:
        notes.append(message)


def keeps_notes(design):
    """Decorator of a public design function: the notes of the call go into ``info['notes']`` of
    the returned ResidualGenerator/ResidualBank (and of a bank's members that made them); the notes of
    a call that raises are dropped with it (a bank's row tried and refused says nothing)."""

    @functools.wraps(design)
    def wrapper(*args, **kwargs):
        notes: list[str] = []
        token = _COLLECTOR.set(notes)  # this call's own: a call that fails leaves no notes behind
        try:
            out = design(*args, **kwargs)
        finally:
            _COLLECTOR.reset(token)
        attach(out, notes)
        if _COLLECTOR.get() is not None:  # an enclosing design (a bank of rows) keeps them too
            for text in notes:
                note(text)
        return out

    return wrapper


def attach(out, notes: list[str]) -> None:
    """Append ``notes`` to ``out.info['notes']`` (no duplicates); no-op for objects without ``info``."""
    info = getattr(out, "info", None)
    if not isinstance(info, dict) or not notes:
        return
    have = info.setdefault("notes", [])
    have.extend(n for n in notes if n not in have)


@contextmanager
def silenced():
    """Within: :func:`note` records and warns nothing (a remark that is no news to the caller, e.g. the pole
    choice for an internal denominator)."""
    token = _COLLECTOR.set([])
    try:
        yield
    finally:
        _COLLECTOR.reset(token)


@contextmanager
def tentative():
    """Within: an attempt the design may abandon. Its notes reach the design in progress only if the
    block completes; an attempt that raises (a refused set of rows, a basis the design does without)
    says nothing — the notes of a filter are about the filter returned."""
    notes: list[str] = []
    token = _COLLECTOR.set(notes)
    try:
        yield
    finally:
        _COLLECTOR.reset(token)
    for text in notes:
        note(text)
