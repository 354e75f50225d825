"""The master's step loop: every value on two buses, every FMI call prepared before the first step.

:class:`~fmu_fdi.cosim.master.CoSimulation` describes *what* is exchanged (its module docstring
states the semantics); this module does it at the cost of the FMI calls and little more. After
the FMUs are initialised everything a step needs is laid out once:

- the **float bus** ``bf`` (float64) holds every Real/Float output of every FMU, then the
  external signals that feed real inputs (their values at the current point ``t_k``), then the
  fixed sources (the values a faulted input or tunable parameter holds after initialisation);
  the **integer bus** ``bi`` (int64) the Integer/Enumeration/Boolean outputs and the signals
  that feed such inputs (converted as the FMU receives them: truncated, or ``!= 0``);
- each FMU's output port writes its float64 outputs straight into its slice of ``bf`` (the FMI
  ``get`` call's value array *is* that slice); other types are copied in with one numpy call;
- each FMU's inputs are gathered from a bus with one ``numpy.take`` into the value array of its
  ``set`` call; faults are then applied in place at their positions, each evaluated at the
  time of the value it corrupts (``lag``: 1 for an output of an FMU already stepped in a
  Gauss–Seidel step, else 0);
- each row recorded is a copy of the buses into a chunk of rows; the :class:`Result` columns
  (outputs, recorded inputs with their faults, fault signals) are computed from the chunk with
  array operations when it is full, with the same formulas as the step
  (:meth:`~fmu_fdi.cosim.faults.FaultChannel.values`).

String connections (rare) keep a per-step path through the instance's :class:`Accessor`.
"""
from __future__ import annotations

import numpy as np

from .faults import FaultChannel
from .port import Port, Step, fmi_call

_REAL = np.float64


class Lane:
    """What one FMU's part of a step needs, prepared: input copies, faults, set/get calls."""

    def __init__(self, name, fmu):
        self.name, self.fmu = name, fmu
        self.moves_in = []    # (destination slice, source slice): bus -> the set calls' values
        self.moves_set = []   # (a set call's own values, slice of them) for calls of another type than the bus
        self.faulted = []     # (position in fbuf, lag, [FaultChannel], bus slot of the nominal value)
        self.fbuf = None      # the float values the faults act on (the Real set calls read them)
        self.sets = []        # Group
        self.step = None      # Step
        self.gets = []        # Group
        self.moves_out = []   # (bus slice, a get call's own values) for calls of another type than the bus
        self.string_out = None   # Accessor of the String outputs a String connection reads
        self.string_in = []      # (Accessor of one String input, (source fmu, var))


class Loop:
    """One run of a :class:`CoSimulation`: :meth:`start`, then :meth:`advance` ``N`` times,
    recording rows into :attr:`rec_f`/:attr:`rec_i` (``chunk`` rows, :meth:`record`) and turning
    them into :class:`Result` rows with :meth:`convert`."""

    def __init__(self, sim, chunk: int):
        self.sim = sim
        self.chunk = chunk
        self.channels = {f.name: FaultChannel(f, sim.start, sim.step, sim.n_steps) for f in sim.faults}
        self.lanes = []
        self.string_values = {}
        self._sig_base, self._sig_rows_f, self._sig_rows_i = 0, np.zeros((0, 0)), np.zeros((0, 0), np.int64)
        self._sig_const, self._sig_len = False, 0

    # -- set-up ------------------------------------------------------------------------------------

    def start(self, stack):
        """Initialise every FMU (parameters, start values, signals at ``t_0``) and lay out the loop."""
        sim, w = self.sim, self.sim._wiring
        t0 = sim.start
        for name, fmu in sim.fmus.items():
            initial = dict(w.initial[name])
            # external signals are known before initialisation: let the FMU initialise with them
            for feed in w.feeds:
                if feed.fmu == name and feed.source[0] == "signal":
                    value = sim.inputs.value(feed.source[1], t0)
                    for fault in feed.faults:
                        value = self.channels[fault.name].at(0, t0, value)
                    initial[feed.var] = value
            stack.callback(fmu.close)
            fmu.start(t0, sim.stop, initial)
        self._layout()
        self.advance = self._compile()
        for lane in self.lanes:
            self._get(lane, t0)
        self._signals_at(0)
        # every faulted value at t_0, as the first row records it: fixes what a stuck fault freezes
        for lane in self.lanes:
            for _, _, chain, slot in lane.faulted:
                v = float(self.bf[slot])
                for ch in chain:
                    v = ch.at(0, t0, v)

    def _layout(self):
        sim, w = self.sim, self.sim._wiring
        fmus = sim.fmus
        kind = {n: {v: f.kind(v) for v in f.variables} for n, f in fmus.items()}
        runtime = {n: {fd.var: fd for fd in w.feeds if fd.fmu == n and fd.runtime} for n in fmus}

        def by_call(name, names, slot=None):
            """One block per FMI call (so each call's values are contiguous), within a block in
            the order of the sources' bus slots (so runs of sources copy as one slice)."""
            order = {}
            for v in names:
                order.setdefault(fmi_call(fmus[name], v), []).append(v)
            return [v for vs in order.values() for v in (sorted(vs, key=slot) if slot else vs)]

        # the integer bus is int32 (FMI 2 Integer and Boolean, FMI 3 Int32 land in it directly)
        # unless a 64-bit or unsigned 32-bit integer passes
        wide = any(fmi_call(f, v) in ("Int64", "UInt64", "UInt32") for n, f in fmus.items()
                   for v in f.variables if kind[n][v] in ("integer", "boolean")
                   and (f.variable(v).causality == "output" or v in runtime[n]))
        int_type = np.int64 if wide else np.int32

        # the buses' slots
        f_slot, i_slot = {}, {}
        out_f, out_i = {}, {}
        for name, fmu in fmus.items():
            outs = fmu.names("output")
            out_f[name] = by_call(name, [v for v in outs if kind[name][v] == "real"])
            out_i[name] = by_call(name, [v for v in outs if kind[name][v] in ("integer", "boolean")])
            for v in out_f[name]:
                f_slot[("output", name, v)] = len(f_slot)
            for v in out_i[name]:
                i_slot[("output", name, v)] = len(i_slot)
        self.sig_f, self.sig_i = [], []  # (slot, signal) / (slot, signal, kind): contiguous runs of slots
        for name in fmus:
            for fd in runtime[name].values():
                k = kind[name][fd.var]
                key = self._source_key(fd, k)
                if fd.source[0] != "signal" or k == "string":
                    continue
                if k == "real" and key not in f_slot:
                    f_slot[key] = len(f_slot)
                    self.sig_f.append((f_slot[key], fd.source[1]))
                elif k != "real" and key not in i_slot:
                    i_slot[key] = len(i_slot)
                    self.sig_i.append((i_slot[key], fd.source[1], k))
        for name in fmus:
            for fd in runtime[name].values():
                if fd.source[0] == "fixed":
                    f_slot[self._source_key(fd, "real")] = len(f_slot)
        self.bf = np.zeros(len(f_slot), np.float64)
        self.bi = np.zeros(len(i_slot), int_type)
        self.f_slot, self.i_slot = f_slot, i_slot
        self._sf = slice(self.sig_f[0][0], self.sig_f[-1][0] + 1) if self.sig_f else slice(0, 0)
        self._si = slice(self.sig_i[0][0], self.sig_i[-1][0] + 1) if self.sig_i else slice(0, 0)

        order = list(fmus)
        string_sources = {fd.source[1:] for n in fmus for fd in runtime[n].values()
                          if kind[n][fd.var] == "string" and fd.source[0] == "output"}
        for name, fmu in fmus.items():
            lane = Lane(name, fmu)
            # outputs: those of the buses' types land in the bus itself, the others are copied in
            for names, bus, slots in ((out_f[name], self.bf, f_slot), (out_i[name], self.bi, i_slot)):
                if names:
                    lo = slots[("output", name, names[0])]
                    for g in Port(fmu, names, "get", bus[lo:lo + len(names)]).groups:
                        lane.gets.append(g)
                        if not g.direct:
                            lane.moves_out.append((bus[lo + g.positions[0]:lo + g.positions[-1] + 1], g.view))
            strings = [v for v in fmu.names("output") if (name, v) in string_sources]
            if strings:
                lane.string_out = fmu.accessor(strings)
            # inputs: copied from a bus in runs of slots, faults in place, set
            feeds = runtime[name]
            for which, bus, slots, dtype in (("real", self.bf, f_slot, np.float64), ("int", self.bi, i_slot, int_type)):
                vs = [v for v in feeds if (kind[name][v] == "real") == (which == "real") and kind[name][v] != "string"]
                if not vs:
                    continue

                def slot(v, slots=slots):
                    return slots[self._source_key(feeds[v], kind[name][v])]

                vs = by_call(name, vs, slot)
                buf = np.zeros(len(vs), dtype)
                src = [slot(v) for v in vs]
                lane.moves_in += _runs(buf, bus, src)
                for g in Port(fmu, vs, "set", buf).groups:
                    lane.sets.append(g)
                    if not g.direct:
                        lane.moves_set.append((g.view, buf[g.positions[0]:g.positions[-1] + 1]))
                if which == "real":
                    lane.fbuf = buf
                    for pos, v in enumerate(vs):
                        fd = feeds[v]
                        if fd.faults:
                            # evaluated at the time of the value it corrupts: an output of an FMU
                            # stepped before this one in a Gauss-Seidel step is already at t_{k+1}
                            lag = int(fd.source[0] == "output" and sim.order == "gauss-seidel"
                                      and order.index(fd.source[1]) < order.index(name))
                            lane.faulted.append((pos, lag, [self.channels[f.name] for f in fd.faults], src[pos]))
            lane.string_in = [(fmu.accessor([v]), feeds[v].source[1:]) for v in feeds if kind[name][v] == "string"]
            lane.step = Step(fmu, sim.step)
            self.lanes.append(lane)
        for feed in w.feeds:  # a fixed source is the value the variable has after initialisation
            if feed.runtime and feed.source == ("fixed", None):
                value = fmus[feed.fmu].accessor([feed.var]).read(sim.start)[0]
                self.bf[f_slot[("fixed", feed.fmu, feed.var)]] = value
        self.rec_f = np.zeros((self.chunk, len(self.bf)), np.float64)
        self.rec_i = np.zeros((self.chunk, len(self.bi)), int_type)
        self._columns()

    @staticmethod
    def _source_key(feed, kind):
        src = feed.source
        if src[0] == "output":
            return ("output", src[1], src[2])
        if src[0] == "signal":
            return ("signal", src[1], kind)
        return ("fixed", feed.fmu, feed.var)

    # -- the step ----------------------------------------------------------------------------------

    def _set(self, lane, k, t, t_next):
        for dst, src in lane.moves_in:
            dst[...] = src
        if lane.faulted:
            buf = lane.fbuf
            for pos, lag, chain, _ in lane.faulted:
                v = buf.item(pos)
                j, tj = (k + 1, t_next) if lag else (k, t)
                for ch in chain:
                    v = ch.at(j, tj, v)
                buf[pos] = v
        for dst, src in lane.moves_set:
            dst[...] = src
        for g in lane.sets:
            st = g.bound()
            if st > 1:
                self._call_failed(lane, g, st, t)
        for acc, source in lane.string_in:
            acc.write([self.string_values[source]], t)

    def _step(self, lane, t):
        lane.fmu.now = t
        s = lane.step
        s.time.value = t
        self._stepped(lane, s.call(), t)

    def _stepped(self, lane, st, t):
        """Check a doStep's status (and FMI 3's flags)."""
        s = lane.step
        if st > 1:
            self._call_failed(lane, s, st, t, step=s.size.value)
        if s.flags:
            if s.terminate.value:
                raise lane.fmu._failure(f"asked to terminate the simulation in doStep from t={t:g}", t)
            if s.early.value:
                raise lane.fmu._failure(f"returned early from doStep at t={s.last.value:g} (step from t={t:g})", t)

    def _get(self, lane, t):
        for g in lane.gets:
            st = g.bound()
            if st > 1:
                self._call_failed(lane, g, st, t)
        for dst, src in lane.moves_out:
            dst[...] = src
        if lane.string_out is not None:
            for v, value in zip(lane.string_out.names, lane.string_out.read(t)):
                self.string_values[(lane.name, v)] = value

    def advance(self, k: int):
        """One communication step from ``t_k`` to ``t_{k+1}`` (see the master's module docstring);
        :meth:`start` replaces it by its compiled form (:meth:`_compile`)."""
        self._compile()(k)

    def _compile(self):
        """:meth:`advance` with everything it touches bound to locals: a lane without faults or
        String connections sets, steps and gets in a few lines, the others go through
        :meth:`_set` / :meth:`_get`."""
        start, h, jacobi = self.sim.start, self.sim.step, self.sim.order == "jacobi"
        fail, stepped, set_, get_ = self._call_failed, self._stepped, self._set, self._get
        lanes = tuple((lane, bool(lane.faulted or lane.moves_set or lane.string_in), tuple(lane.moves_in),
                       tuple((g.bound, g) for g in lane.sets), lane.fmu, lane.step.time, lane.step.call,
                       lane.step.flags, lane.string_out is not None, tuple((g.bound, g) for g in lane.gets),
                       tuple(lane.moves_out)) for lane in self.lanes)

        def put(lane, special, moves, sets, k, t, t_next):
            if special:
                set_(lane, k, t, t_next)
                return
            for dst, src in moves:
                dst[...] = src
            for call, g in sets:
                st = call()
                if st > 1:
                    fail(lane, g, st, t)

        def take(lane, strings, gets, moves, t):
            if strings:
                get_(lane, t)
                return
            for call, g in gets:
                st = call()
                if st > 1:
                    fail(lane, g, st, t)
            for dst, src in moves:
                dst[...] = src

        def advance(k):
            t, t_next = start + k * h, start + (k + 1) * h
            if jacobi:
                for lane, special, moves, sets, fmu, tc, do, flags, strings, gets, moves_out in lanes:
                    put(lane, special, moves, sets, k, t, t_next)
                for lane, special, moves, sets, fmu, tc, do, flags, strings, gets, moves_out in lanes:
                    fmu.now = t
                    tc.value = t
                    st = do()
                    if st > 1 or flags:
                        stepped(lane, st, t)
                for lane, special, moves, sets, fmu, tc, do, flags, strings, gets, moves_out in lanes:
                    take(lane, strings, gets, moves_out, t_next)
            else:
                for lane, special, moves, sets, fmu, tc, do, flags, strings, gets, moves_out in lanes:
                    put(lane, special, moves, sets, k, t, t_next)
                    fmu.now = t
                    tc.value = t
                    st = do()
                    if st > 1 or flags:
                        stepped(lane, st, t)
                    take(lane, strings, gets, moves_out, t_next)

        return advance

    def _call_failed(self, lane, call, status, t, step=None):
        from fmpy.fmi1 import FMICallException

        fmu = lane.fmu
        fmu._status = max(fmu._status, status)
        exc = FMICallException(function=call.name, status=status)
        if step is not None:
            raise fmu._failure(f"doStep from t={t:g} (step {step:g}) failed: {exc}", t) from exc
        raise fmu._failure(f"{call.direction}{call.call}({', '.join(call.names)}) at t={t:g} failed: {exc}",
                           t) from exc

    # -- signals -----------------------------------------------------------------------------------

    def _signals_at(self, k: int):
        """Put the signals' values at ``t_k`` on the buses (sampled a chunk at a time; a chunk
        over which no signal changes is put once)."""
        i = k - self._sig_base
        if 0 <= i < self._sig_len:
            if not self._sig_const:
                self.bf[self._sf] = self._sig_rows_f[i]
                self.bi[self._si] = self._sig_rows_i[i]
            return
        if not (self.sig_f or self.sig_i):
            self._sig_base, self._sig_len, self._sig_const = 0, self.sim.n_steps + 1, True
            return
        self._sample(k)
        self.bf[self._sf] = self._sig_rows_f[0]
        self.bi[self._si] = self._sig_rows_i[0]

    def _sample(self, k0: int):
        sim = self.sim
        rows = np.arange(k0, min(k0 + self.chunk, sim.n_steps + 1))
        t = sim.start + rows * sim.step
        self._sig_base, self._sig_len = k0, len(rows)
        self._sig_rows_f = np.column_stack([sim.inputs.sample(s, t) for _, s in self.sig_f] or
                                           [np.zeros((len(rows), 0))])
        cols = []
        for _, s, k in self.sig_i:
            v = sim.inputs.sample(s, t)
            cols.append((v != 0) if k == "boolean" else np.trunc(v))
        self._sig_rows_i = np.column_stack(cols or [np.zeros((len(rows), 0))]).astype(self.bi.dtype)
        self._sig_const = bool((self._sig_rows_f == self._sig_rows_f[0]).all()
                               and (self._sig_rows_i == self._sig_rows_i[0]).all())

    # -- recording ---------------------------------------------------------------------------------

    def record(self, i: int, k: int):
        """Row ``i`` of the chunk: the buses at ``t_k`` (signals set to ``t_k`` first)."""
        if not (self._sig_const and 0 <= k - self._sig_base < self._sig_len):
            self._signals_at(k)
        self.rec_f[i] = self.bf
        if self.bi.size:
            self.rec_i[i] = self.bi

    def _columns(self):
        """How each Result column comes from the recorded chunk (see :meth:`convert`)."""
        sim, w = self.sim, self.sim._wiring
        self.col_src = []
        for name, fmu in sim.fmus.items():
            for v in fmu.names("output"):
                k = fmu.kind(v)
                if k == "real":
                    self.col_src.append((f"{name}.{v}", ("f", self.f_slot[("output", name, v)])))
                elif k != "string":
                    self.col_src.append((f"{name}.{v}", ("i", self.i_slot[("output", name, v)])))
            for var in sim._fed_inputs(name):
                fd = next(fd for fd in w.feeds if fd.fmu == name and fd.var == var)
                self.col_src.append((f"{name}.{var}", ("chain", fd)))
        self.fault_cols = [(f, w.fault_feed[f.name]) for f in sim.faults]

    def _source(self, fd, m):
        """The nominal source values of feed ``fd`` at the chunk's first ``m`` rows."""
        k = self.sim.fmus[fd.fmu].kind(fd.var)
        if fd.source[0] == "fixed" and fd.source[1] is not None:
            return np.full(m, float(fd.source[1]))
        key = self._source_key(fd, k)
        return self.rec_f[:m, self.f_slot[key]] if k == "real" else self.rec_i[:m, self.i_slot[key]]

    def _chain(self, fd, upto, rows) -> list:
        """Values along a feed's chain at ``rows``: the nominal source value, then after each fault."""
        vals = [self._source(fd, len(rows))]
        for fault in fd.faults[:upto]:
            vals.append(self.channels[fault.name].values(rows, vals[-1]))
        return vals

    def convert(self, out, m: int, k0: int):
        """Fill ``out`` (``m`` Result rows) from the chunk's first ``m`` rows, grid points ``k0 …``."""
        sim = self.sim
        rows = np.arange(k0, k0 + m)
        out["time"] = sim.start + rows * sim.step
        for col, how in self.col_src:
            if how[0] == "f":
                out[col] = self.rec_f[:m, how[1]]
            elif how[0] == "i":
                out[col] = self.rec_i[:m, how[1]]
            else:
                out[col] = self._chain(how[1], len(how[1].faults), rows)[-1]
        for fault, (fd, pos) in self.fault_cols:
            vals = self._chain(fd, pos + 1, rows)
            out[f"fault.{fault.name}"] = vals[pos + 1] - vals[pos]
            out[f"fault.{fault.name}.active"] = self.channels[fault.name].active_rows(rows)


def _runs(dst, bus, slots) -> list:
    """``(dst[a:b], bus[c:d])`` pairs that copy ``bus[slots[i]]`` to ``dst[i]``, one per run of
    consecutive slots."""
    out, i = [], 0
    while i < len(slots):
        j = i + 1
        while j < len(slots) and slots[j] == slots[j - 1] + 1:
            j += 1
        out.append((dst[i:j], bus[slots[i]:slots[i] + j - i]))
        i = j
    return out
