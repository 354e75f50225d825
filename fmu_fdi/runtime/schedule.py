"""Scheduled diagnosers at run time: K member designs, one per operating point, and a rule
that picks the member whose outputs are shown (numpy and stdlib only; bundled in the FMU).

A scheduled design (format ``fmu-fdi-scheduled-design/1``, docs/design-file.md) holds K
ordinary designs (``fmu-fdi-design/1``) of the same residual structure, each with its own
operating point (u0_k, y0_k), evaluators and thresholds, plus the schedule:

* ``signals`` — S scheduling signals, names among the design's inputs u and outputs y;
* ``points`` — K × S: member k's operating value of each scheduling signal;
* ``scale`` — S positive numbers: the unit of distance along each signal (default: the
  smallest gap between distinct member values, i.e. the grid step);
* ``hysteresis`` η ≥ 0, in those units;
* ``warm`` (optional, LTI members): per member the steady-state gain ``M_k = (I − A_k)⁻¹ B_k``
  of its discrete filter. At the first valid sample after a reset each member's filter
  starts from ``x_k = M_k v_k`` (its steady state for that sample held) instead of 0: a
  member whose operating point is far from where the plant starts would otherwise carry
  a start-up transient of the size of that distance for the life of its slowest pole.

Per call (docs/semantics.md §12, the one written rule): every member runs the whole step of
docs/semantics.md on the same sample (each subtracts its own operating point), so a switch
is bumpless — the member switched to has been filtering, evaluating and deciding all along.
On a valid sample with scheduling values s, with

    d_k(s) = sqrt( Σ_j ((s_j − p_kj) / c_j)² )        (j = 1..S in order)

and b the smallest k with the least d_k (at the first valid sample after a reset, with
``warm``, every member's filter state is first set to ``M_k v_k``, v_k = [y − y0_k; u − u0_k]): if no member is active yet, b becomes active;
otherwise b replaces the active member a only if ``d_b + η < d_a``. The outputs are the
active member's (member 1's while none is active), with ``active_member`` (1-based, 0 before
the first valid sample) inserted before ``fault_detected``, and ``numeric_reset`` and
``input_invalid`` set when any member's sample overflowed (docs/semantics.md §8, §12).
"""
from __future__ import annotations

import math

from . import schema as S
from .design_check import FORMAT as MEMBER_FORMAT
from .design_check import DesignCheckError, check_design
from .engine import FAULT_DETECTED, INPUT_INVALID, NUMERIC_RESET, DiagnoserRuntime, StepSizeError, sample_signals

SCHEDULED_FORMAT = "fmu-fdi-scheduled-design/1"
#: most members a scheduled design may hold (each runs every sample)
MAX_MEMBERS = 256
RULES = ("nearest",)
ACTIVE_MEMBER = "active_member"
_TOP_REQUIRED = ("format", "name", "signals", "faults", "schedule", "members")
_TOP_ALLOWED = set(_TOP_REQUIRED) | {"units", "created_by", "description", "report", "model_set"}
_SCHEDULE_KEYS = ("rule", "signals", "points", "scale", "hysteresis")
#: relative tolerance of the check (I − A) M = B of a warm-start gain
WARM_RTOL = 1e-8


def is_scheduled(design) -> bool:
    return isinstance(design, dict) and design.get("format") == SCHEDULED_FORMAT


def default_scale(points) -> list[float]:
    """Per scheduling signal: the smallest positive gap between the members' values (the grid
    step), 1.0 when all members share one value."""
    out = []
    for j in range(len(points[0]) if points else 0):
        vals = sorted({float(p[j]) for p in points})
        gaps = [b - a for a, b in zip(vals, vals[1:]) if b > a]
        out.append(min(gaps) if gaps else 1.0)
    return out


def check_scheduled_design(d, source: str = "scheduled design") -> dict:
    """The one validation of a scheduled design (module docstring); raises DesignCheckError."""
    err = DesignCheckError
    S.check_format(d, SCHEDULED_FORMAT, source, err)
    S.check_depth(d, source, err)
    S.check_keys(d, _TOP_REQUIRED, _TOP_ALLOWED, source, err)
    S.text(d["name"], f"{source}: name", err)
    members = S.array(d["members"], f"{source}: members", err)
    if not 1 <= len(members) <= MAX_MEMBERS:
        raise err(f"{source}: members must hold 1 to {MAX_MEMBERS} designs, got {len(members)}")
    first = None
    for k, m in enumerate(members, 1):
        where = f"{source}: members[{k}]"
        if not isinstance(m, dict) or m.get("format") != MEMBER_FORMAT:
            raise err(f"{where} must be a design of format {MEMBER_FORMAT!r}")
        check_design(m, where)
        shape = {"signals": m["signals"], "faults": [f["name"] for f in m["faults"]],
                 "residual_names": m["generator"]["residual_names"], "groups": m["generator"]["groups"],
                 "dt": m["generator"]["dt"], "isolation": m["decision"].get("isolation", "none"),
                 "continuous": m["generator"].get("continuous") is not None,
                 "kind": m["generator"]["discrete"].get("kind"),
                 # the same kinds accept the same step sizes (docs/semantics.md §9, §12)
                 "evaluator kinds": [e["evaluator"]["kind"] for e in m["evaluation"]],
                 "threshold kinds": [e["threshold"]["kind"] for e in m["evaluation"]]}
        if first is None:
            first = shape
            continue
        for key, val in shape.items():
            if val != first[key]:
                raise err(f"{where}: {key} {val!r} differs from members[1]'s {first[key]!r}; every member needs the "
                          f"same signals, faults and residual structure (residual i means the same everywhere)")
    sig = S.table(d["signals"], f"{source}: signals", err)
    if sig != first["signals"]:
        raise err(f"{source}: signals {sig!r} differ from the members' {first['signals']!r}")
    u, y = list(sig["u"]), list(sig["y"])  # none named active_member: design_check.RESERVED
    faults = S.array(d["faults"], f"{source}: faults", err)
    if [f.get("name") if isinstance(f, dict) else f for f in faults] != first["faults"]:
        raise err(f"{source}: faults differ from the members' {first['faults']}")
    sch = S.table(d["schedule"], f"{source}: schedule", err)
    S.check_keys(sch, _SCHEDULE_KEYS, _SCHEDULE_KEYS + ("warm",), f"{source}: schedule", err)
    if sch["rule"] not in RULES:
        raise err(f"{source}: schedule.rule must be one of {list(RULES)}, got {S.type_name(sch['rule'])}")
    names = S.names(sch["signals"], f"{source}: schedule.signals", err)
    bad = [n for n in names if n not in u and n not in y]
    if not names or bad:
        raise err(f"{source}: schedule.signals {bad or names} must be one or more of the inputs {u} or outputs {y}")
    K, ns = len(members), len(names)
    pts = S.matrix(sch["points"], f"{source}: schedule.points", err, rows=K, cols=ns)
    for i in range(K):
        for j in range(i):
            if list(pts[i]) == list(pts[j]):
                raise err(f"{source}: members {j + 1} and {i + 1} sit at the same scheduling point {list(pts[i])}")
    S.vector(sch["scale"], f"{source}: schedule.scale", err, size=ns, lo=0.0, lo_open=True)
    S.real(sch["hysteresis"], f"{source}: schedule.hysteresis", err, lo=0.0)
    if "warm" in sch:
        _check_warm(S.array(sch["warm"], f"{source}: schedule.warm", err), members, source)
    return d


def _check_warm(warm: list, members: list, source: str) -> None:
    """Each M_k is n_k × (ny + nu) with (I − A_k) M_k = B_k (relative to ‖B_k‖ + ‖M_k‖(1 + ‖A_k‖))."""
    import numpy as np

    err = DesignCheckError
    if len(warm) != len(members):
        raise err(f"{source}: schedule.warm holds {len(warm)} gains for {len(members)} members")
    for k, (M, m) in enumerate(zip(warm, members), 1):
        where = f"{source}: schedule.warm[{k}]"
        g = m["generator"]["discrete"]
        if g.get("kind") != "lti":
            raise err(f"{where}: a warm start needs an LTI generator, member {k} is {g.get('kind')!r}")
        n, nin = len(g["A"]), len(g["B"][0]) if g["B"] else len(g["D"][0])
        S.matrix(M, where, err, rows=n, cols=nin)
        if n == 0:
            continue
        A, B, Mk = (np.asarray(x, float).reshape(n, -1) for x in (g["A"], g["B"], M))
        res = np.abs((np.eye(n) - A) @ Mk - B).max()
        size = np.abs(B).max() + np.abs(Mk).max() * (1.0 + np.abs(A).sum(axis=1).max())
        if not res <= WARM_RTOL * size:
            raise err(f"{where} is not the steady-state gain (I - A)^-1 B of member {k}'s filter: "
                      f"max|(I - A) M - B| = {res:.3g} > {WARM_RTOL:g} * {size:.3g}")


def nearest(points, scale, s, active: int, hysteresis: float) -> int:
    """The member (0-based) active after a valid sample with scheduling values ``s``; ``active``
    is the one before (-1: none yet). The rule and its distance: module docstring."""
    best, best_d, d_active = -1, math.inf, math.inf
    for k, p in enumerate(points):
        acc = 0.0
        for sj, pj, cj in zip(s, p, scale):
            q = (sj - pj) / cj
            acc += q * q
        dk = math.sqrt(acc)
        if dk < best_d:
            best, best_d = k, dk
        if k == active:
            d_active = dk
    if active < 0 or best_d + hysteresis < d_active:
        return best
    return active


def output_names(member_names: list) -> list:
    """The member's outputs with ``active_member`` before the four trailing flags."""
    return list(member_names[:FAULT_DETECTED]) + [ACTIVE_MEMBER] + list(member_names[FAULT_DETECTED:])


class ScheduledRuntime:
    """Per-sample scheduled diagnosis from a scheduled design dict (module docstring)."""

    def __init__(self, design: dict, *, checked: bool = False):
        if not checked:
            check_scheduled_design(design)
        self.members = [DiagnoserRuntime(m, checked=True) for m in design["members"]]
        first = self.members[0]
        self.u_names, self.y_names, self.nu, self.ny = first.u_names, first.y_names, first.nu, first.ny
        self.u0, self.y0, self.Ts = first.u0, first.y0, first.Ts
        self.faults = first.faults
        sch = design["schedule"]
        self.schedule = list(sch["signals"])
        self._where = [(0, self.u_names.index(n)) if n in self.u_names else (1, self.y_names.index(n))
                       for n in self.schedule]
        self.points = [[float(x) for x in row] for row in sch["points"]]
        self.scale = [float(c) for c in sch["scale"]]
        self.hysteresis = float(sch["hysteresis"])
        self.warm = [[[float(x) for x in row] for row in M] for M in sch["warm"]] if "warm" in sch else None
        self._ops = [(m.u0.tolist(), m.y0.tolist()) for m in self.members]
        self.names = output_names(first.names)
        self.n_residuals, self.n_groups = first.n_residuals, first.n_groups
        self.reset()

    # the runtime interface the FMU slave and Diagnoser use
    @property
    def h(self) -> float:
        return self.members[0].h

    @property
    def sample_ratio(self) -> float:
        return self.members[0].sample_ratio

    @property
    def decision(self):
        """The active member's decision (member 1's while none is active)."""
        return self.members[max(self.active, 0)].decision

    @property
    def threshold_scale(self) -> float:
        return self.members[0].threshold_scale

    @threshold_scale.setter
    def threshold_scale(self, value: float) -> None:
        for m in self.members:
            m.threshold_scale = value

    def set_threshold_scale(self, value) -> None:
        """Every member's ``threshold_scale`` (docs/semantics.md §6): a finite number >= 0, else
        ValueError (member 1's reason) and every scale kept."""
        self.members[0].set_threshold_scale(value)
        self.threshold_scale = self.members[0].threshold_scale

    def reset(self) -> None:
        for m in self.members:
            m.reset()
        self.active = -1
        self.outputs = self._compose([m.outputs for m in self.members])

    def set_step(self, h: float) -> None:
        """Every member to step h, or none (StepSizeError, all as before)."""
        before = [m.get_state() for m in self.members]
        try:
            for m in self.members:
                m.set_step(h)
        except StepSizeError:
            for m, s in zip(self.members, before):
                m.set_state(s)
            raise

    def get_state(self) -> dict:
        return {"active": self.active, "outputs": list(self.outputs),
                "members": [m.get_state() for m in self.members]}

    def set_state(self, s: dict) -> None:
        """Restore :meth:`get_state`. Accepted only if a run of this design can produce it
        (docs/semantics.md §10, §12): every member's state valid for that member (§10), the
        active member -1..K-1 (-1: none yet, the warm start armed; >= 0 only after a valid
        sample), the members at one step h,
        one ``threshold_scale`` and one count of valid samples (they run on the same calls), and
        the outputs those the members and the active index compose. Else ValueError and
        nothing changed."""
        before = self.get_state()
        try:
            active = s["active"]
            if type(active) is not int or not -1 <= active < len(self.members):
                raise ValueError(f"active member {active!r} is not an integer -1..{len(self.members) - 1}")
            states = s["members"]
            if type(states) is not list or len(states) != len(self.members):
                raise ValueError(f"member states must be a list of {len(self.members)}")
            outputs = s["outputs"]
            if type(outputs) is not list or len(outputs) != len(self.names):
                raise ValueError(f"outputs must be {len(self.names)} numbers")
            outputs = [float(x) for x in outputs]
            for k, (m, ms) in enumerate(zip(self.members, states), 1):
                try:
                    m.set_state(ms)
                except ValueError as exc:
                    raise ValueError(f"member {k}: {exc}") from None
            first = self.members[0]
            for k, m in enumerate(self.members[1:], 2):
                if (m.h, m.threshold_scale, m.n_samples) != (first.h, first.threshold_scale, first.n_samples):
                    raise ValueError(f"member {k} is at step {m.h!r}, threshold_scale {m.threshold_scale!r} after "
                                     f"{m.n_samples} samples, member 1 at {first.h!r}, {first.threshold_scale!r}, "
                                     f"{first.n_samples} (members run on the same calls)")
            if active >= 0 and first.n_samples == 0:
                raise ValueError(f"active member {active + 1} before any valid sample (a member becomes active on one)")
            composed = self._compose([m.outputs for m in self.members], active)
            if outputs != composed:
                raise ValueError("the outputs are not those of the active member and the members' flags")
        except (ValueError, TypeError, KeyError, IndexError, AttributeError) as exc:
            for m, ms in zip(self.members, before["members"]):
                m.set_state(ms)
            raise ValueError(f"scheduled runtime state does not fit this design: {exc}") from None
        self.active, self.outputs = active, outputs

    def _compose(self, outs: list, active: int | None = None) -> list:
        """The scheduled outputs (docs/semantics.md §12 step 5): the active member's (member 1's
        while none is active) with ``numeric_reset`` = any member's, ``input_invalid`` = the
        active member's or ``numeric_reset`` (an overflow in any member, §8), and
        ``active_member`` inserted before ``fault_detected``."""
        active = self.active if active is None else active
        out = list(outs[max(active, 0)])
        if any(o[NUMERIC_RESET] for o in outs):
            out[NUMERIC_RESET] = out[INPUT_INVALID] = 1.0
        out.insert(len(out) + FAULT_DETECTED, float(active + 1))
        return out

    def advance(self, u, y, h: float | None = None) -> list:
        """Diagnose the sample (u, y) with every member; outputs in the order of :attr:`names`."""
        u, y = sample_signals(u, y, self.nu, self.ny)
        if h is not None and h != self.h:
            self.set_step(h)
        valid = self.members[0]._valid(u, y)  # §3: members share signals and valid ranges, one verdict
        if self.active < 0 and self.warm is not None and valid:
            self._warm_start(u, y)
        outs = [m.advance(u, y, None) for m in self.members]
        if valid:  # an overflow inside a member (§8) does not hold the schedule: s is a valid sample
            s = [(u, y)[side][i] for side, i in self._where]
            self.active = nearest(self.points, self.scale, s, self.active, self.hysteresis)
        self.outputs = self._compose(outs)
        return list(self.outputs)

    def step(self, u, y) -> list:
        return self.advance(u, y, None)

    def _warm_start(self, u: list, y: list) -> None:
        """Every member's filter at its steady state for this sample: x_k = M_k v_k (sums in
        index order); a member whose v_k or x_k is not finite keeps x = 0 (its step then resets)."""
        for m, M, (u0, y0) in zip(self.members, self.warm, self._ops):
            v = [a - b for a, b in zip(y, y0)] + [a - b for a, b in zip(u, u0)]
            x = []
            for row in M:
                acc = 0.0
                for mij, vj in zip(row, v):
                    acc += mij * vj
                x.append(acc)
            if all(map(math.isfinite, x)):
                m.generator.set_state({"x": x})


def runtime_for(design: dict, *, checked: bool = False):
    """The runtime of a design dict of either format (plain or scheduled)."""
    if is_scheduled(design):
        return ScheduledRuntime(design, checked=checked)
    return DiagnoserRuntime(design, checked=checked)
