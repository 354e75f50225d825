"""Who feeds what: connections, external signals, faults and parameters resolved to a plan.

The plan is a list of :class:`Feed` entries, one per FMU variable the master sets during the
run. A feed takes a *source* (another FMU's output, an external signal, or a fixed value: the
variable's own start or parameter value) and passes it through a *chain* of faults, in this
order: faults targeting the source output (they corrupt the signal on every connection from
it), then faults targeting the variable itself, each in the order given. Everything is checked
here, before any FMU is instantiated, so a bad name fails in milliseconds with a message that
names it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .errors import CoSimulationError
from .startvalues import refusal

_SETTABLE = ("parameter", "input")


@dataclass
class Feed:
    """One variable the master sets: ``fmu.var = chain(source)``.

    ``source`` is ``("output", fmu, var)``, ``("signal", name)`` or ``("fixed", None)`` (the
    value the variable holds after initialisation). ``runtime`` is False for a fault on a fixed
    parameter, applied once before initialisation and kept here only for recording.
    """

    fmu: str
    var: str
    source: tuple
    faults: list = field(default_factory=list)
    runtime: bool = True


@dataclass
class Wiring:
    """The resolved plan (see the module docstring)."""

    connections: list      # [(src_fmu, src_var, dst_fmu, dst_var)]
    signal_targets: dict   # signal name -> [(fmu, var)]
    feeds: list            # [Feed]
    initial: dict          # fmu -> {var: value} set before initialisation
    fault_feed: dict       # fault name -> (Feed, position in its chain)


def split_target(text, fmus, what: str):
    """``"fmu.var"`` -> ``(fmu, var)``, checking both exist."""
    if not isinstance(text, str) or "." not in text:
        raise CoSimulationError(f"{what} {text!r} must read 'fmu.variable'")
    name, var = text.split(".", 1)
    if name not in fmus:
        raise CoSimulationError(f"{what} {text!r}: no FMU named {name!r} (FMUs: {', '.join(fmus)})")
    fmus[name].variable(var)
    return name, var


def resolve_connections(spec, fmus) -> list:
    """Connections as ``(src_fmu, src_var, dst_fmu, dst_var)``.

    ``spec`` is ``"auto"`` (every input takes the same-named output of another FMU, if exactly
    one has it), None (no connections) or a list of ``("a.out", "b.in")`` pairs.
    """
    if spec is None:
        return []
    if isinstance(spec, str):
        if spec != "auto":
            raise CoSimulationError(f"connections must be 'auto', None or a list of pairs, got {spec!r}")
        pairs = []
        for dst, dfmu in fmus.items():
            for var in dfmu.names("input"):
                srcs = [s for s, sfmu in fmus.items() if s != dst and var in sfmu.names("output")]
                if len(srcs) > 1:
                    raise CoSimulationError(
                        f"auto connection of {dst}.{var} is ambiguous: outputs "
                        f"{', '.join(s + '.' + var for s in srcs)} all match; pass connections explicitly")
                if srcs:
                    pairs.append((f"{srcs[0]}.{var}", f"{dst}.{var}"))
    else:
        pairs = list(spec)
    out, seen = [], {}
    for pair in pairs:
        if isinstance(pair, str) or len(pair) != 2:
            raise CoSimulationError(f"connection {pair!r} must be a pair ('fmu.output', 'fmu.input')")
        (sf, sv), (df, dv) = (split_target(pair[0], fmus, "connection source"),
                              split_target(pair[1], fmus, "connection destination"))
        src, dst = fmus[sf].variable(sv), fmus[df].variable(dv)
        if src.causality != "output":
            raise CoSimulationError(f"connection {pair[0]} -> {pair[1]}: {pair[0]} is not an output "
                                    f"(causality {src.causality})")
        if dst.causality != "input":
            raise CoSimulationError(f"connection {pair[0]} -> {pair[1]}: {pair[1]} is not an input "
                                    f"(causality {dst.causality})")
        ks, kd = fmus[sf].kind(sv), fmus[df].kind(dv)
        if ks is None or ks != kd:
            raise CoSimulationError(f"connection {pair[0]} -> {pair[1]}: types differ "
                                    f"({src.type} -> {dst.type})")
        if (df, dv) in seen:
            raise CoSimulationError(f"{pair[1]} is connected twice (from {seen[(df, dv)]} and {pair[0]})")
        seen[(df, dv)] = pair[0]
        out.append((sf, sv, df, dv))
    return out


def route_signals(names, fmus, connected) -> dict:
    """Signal name -> the inputs it feeds; a bare name feeds every unconnected input of that name."""
    routes, fed = {}, {}
    for name in names:
        first = name.split(".", 1)[0]
        if "." in name and first in fmus:
            targets = [split_target(name, fmus, "input signal")]
            if fmus[first].variable(targets[0][1]).causality != "input":
                raise CoSimulationError(f"input signal {name!r}: {name} is not an input")
            if targets[0] in connected:
                raise CoSimulationError(f"input signal {name!r}: {name} is already connected to an output")
        else:
            targets = [(f, name) for f, fmu in fmus.items()
                       if name in fmu.names("input") and (f, name) not in connected]
            if not targets:
                raise CoSimulationError(f"input signal {name!r} matches no unconnected input of "
                                        f"{', '.join(fmus)}")
        for t in targets:
            if fmus[t[0]].kind(t[1]) == "string":
                raise CoSimulationError(f"input signal {name!r}: {t[0]}.{t[1]} is a String input")
            if t in fed:
                raise CoSimulationError(f"{t[0]}.{t[1]} is fed by two input signals, {fed[t]!r} and {name!r}")
            fed[t] = name
        routes[name] = targets
    return routes


def wire(fmus, connections, signal_names, faults, parameters, start: float) -> Wiring:
    """Resolve everything into a :class:`Wiring` (see the module docstring)."""
    conns = resolve_connections(connections, fmus)
    connected = {(df, dv): (sf, sv) for sf, sv, df, dv in conns}
    routes = route_signals(signal_names, fmus, connected)
    initial = {name: {} for name in fmus}
    for key, value in (parameters or {}).items():
        f, v = split_target(key, fmus, "parameter")
        var = fmus[f].variable(v)
        why = refusal(var)  # the one rule of what a master may set before initialisation
        if why is not None:
            raise CoSimulationError(f"parameter {key}: cannot be set before initialisation: {key} {why}")
        kind = fmus[f].kind(v)
        if kind is None:
            raise CoSimulationError(f"parameter {key}: type {var.type} is not supported")
        initial[f][v] = checked_value(key, var.type, kind, value)

    feeds = {}
    for (df, dv), (sf, sv) in connected.items():
        feeds[(df, dv)] = Feed(df, dv, ("output", sf, sv))
    for name, targets in routes.items():
        for f, v in targets:
            feeds[(f, v)] = Feed(f, v, ("signal", name))

    fault_feed, names = {}, set()
    output_faults = {}
    for fault in faults:
        if fault.name in names:
            raise CoSimulationError(f"two faults are named {fault.name!r}; give them distinct names")
        names.add(fault.name)
        f, v = split_target(fault.target, fmus, f"fault {fault.name!r} target")
        var = fmus[f].variable(v)
        if fmus[f].kind(v) != "real":
            raise CoSimulationError(f"fault {fault.name!r}: target {fault.target} is {var.type}; "
                                    f"faults act on Real (Float) variables")
        if var.causality == "output":
            if not any((sf, sv) == (f, v) for sf, sv, _, _ in conns):
                raise CoSimulationError(f"fault {fault.name!r}: output {fault.target} feeds no input, so "
                                        f"the fault would change nothing; connect it or target an input")
            output_faults.setdefault((f, v), []).append(fault)
        elif var.causality in _SETTABLE:
            feed = feeds.setdefault((f, v), Feed(f, v, ("fixed", None)))
            if var.causality == "parameter" and var.variability != "tunable":
                _fixed_parameter_fault(fault, fmus[f], v, start, initial[f], feed)
            feed.faults.append(fault)
        else:
            raise CoSimulationError(f"fault {fault.name!r}: target {fault.target} has causality "
                                    f"{var.causality}; target an output, input or parameter")
    for feed in feeds.values():
        if feed.source[0] == "output":
            feed.faults[:0] = output_faults.get(feed.source[1:], [])
        for pos, fault in enumerate(feed.faults):
            fault_feed.setdefault(fault.name, (feed, pos))
    return Wiring(conns, routes, list(feeds.values()), initial, fault_feed)


def _fixed_parameter_fault(fault, fmu, var, start, initial, feed):
    """A fixed parameter can only change before initialisation: apply the fault once, there."""
    if not fault.constant_from(start):
        raise CoSimulationError(
            f"fault {fault.name!r}: parameter {fault.target} is fixed, so it can only change before "
            f"initialisation; use a permanent abrupt/gain/stuck/parameter fault with onset <= start "
            f"time {start:g}, or a tunable parameter")
    if feed.runtime:  # the first fault on it: remember the nominal value for recording
        nominal = initial.get(var, fmu.start_value(var))
        if nominal is None:
            raise CoSimulationError(f"fault {fault.name!r}: parameter {fault.target} has no start value "
                                    f"to apply the fault to; give one in parameters")
        feed.source = ("fixed", float(nominal))
        feed.runtime = False
        initial[var] = float(nominal)
    initial[var] = fault.apply(start, float(initial[var]))


# value ranges of the FMI integer types (FMI 2 Integer and Enumeration: 32-bit)
_INT_RANGE = {"Integer": 32, "Enumeration": 32, "Int8": 8, "Int16": 16, "Int32": 32, "Int64": 64,
              "UInt8": -8, "UInt16": -16, "UInt32": -32, "UInt64": -64}


def checked_value(key: str, fmi_type: str, kind: str, value):
    """``value`` for a variable of ``fmi_type`` set before initialisation, exactly as given or
    refused: a Real takes a finite or infinite number (not a Boolean); an integer type takes a
    whole number inside its range (no wrap-around: 4294967303 is not a 32-bit 7); a Boolean
    takes ``true``/``false`` only (not 1, ``"no"`` or ``"maybe"``); a String takes text."""
    import math

    if kind == "boolean":
        if isinstance(value, bool):
            return value
        raise CoSimulationError(f"parameter {key}: {value!r} is not a Boolean; write true or false")
    if kind == "string":
        if isinstance(value, str):
            return value
        raise CoSimulationError(f"parameter {key}: {value!r} is not text ({fmi_type})")
    if isinstance(value, bool) or isinstance(value, str):
        raise CoSimulationError(f"parameter {key}: {value!r} is not a number ({fmi_type})")
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise CoSimulationError(f"parameter {key}: {value!r} is not a number ({fmi_type})") from None
    if kind == "real":
        if math.isnan(number):
            raise CoSimulationError(f"parameter {key}: NaN is not a value ({fmi_type})")
        return number
    whole = int(value) if isinstance(value, int) else (int(number) if math.isfinite(number) and
                                                       number == int(number) else None)
    if whole is None:
        raise CoSimulationError(f"parameter {key}: {value!r} is not a whole number ({fmi_type})")
    bits = _INT_RANGE.get(fmi_type, 32)
    lo, hi = (0, 2 ** -bits - 1) if bits < 0 else (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    if not lo <= whole <= hi:
        raise CoSimulationError(f"parameter {key}: {whole} is outside the range of {fmi_type} "
                                f"[{lo}, {hi}]; it would be stored as another number")
    return whole
