"""Batched FMI get/set on ctypes arrays prepared once: the master loop's calls into one FMU.

A :class:`Port` holds, for a fixed list of scalar variables of one running instance, one group
per FMI value call (``fmi2GetReal``, ``fmi3GetInt32``, ...): the value-reference array, the value
array the FMU reads from or writes into, a numpy view of that array, and the C function bound to
them. A call then costs one foreign call and no Python object: no list of value references,
no ctypes array and no list of values is built per step (fmpy's ``FMU2Slave.getReal`` builds
all three). The C functions are taken from the FMU's shared library with argument types of our
own (pointers as ``void *``), so a value array may also be a slice of a numpy array: a Real
output group can write straight into the master's value bus (:mod:`fmu_fdi.cosim.loop`).

Status handling is fmpy's: Warning passes (its message reaches the instance's log), Discard and
worse raise ``fmpy``'s ``FMICallException`` naming the function and status, which the master turns
into :class:`~fmu_fdi.cosim.errors.SimulationFailed`.
"""
from __future__ import annotations

import ctypes
from ctypes import c_bool, c_double, c_float, c_int, c_size_t, c_uint, c_void_p

import numpy as np

from .elements import Element, Packed
from .errors import CoSimulationError

# value ctype of each FMI call; FMI 2 passes Integer and Boolean as int
CTYPE2 = {"Real": c_double, "Integer": c_int, "Boolean": c_int}
CTYPE3 = {"Float64": c_double, "Float32": c_float, "Int8": ctypes.c_int8, "UInt8": ctypes.c_uint8,
          "Int16": ctypes.c_int16, "UInt16": ctypes.c_uint16, "Int32": ctypes.c_int32, "UInt32": ctypes.c_uint32,
          "Int64": ctypes.c_int64, "UInt64": ctypes.c_uint64, "Boolean": c_bool}


def fmi_call(fmu, var: str) -> str:
    """The FMI call suffix of ``var`` (``"Real"``, ``"Float64"``, ``"Int32"``, ...)."""
    from .instance import _FMI2_CALL

    v = fmu.variable(var)
    if fmu.fmi_version == 2:
        return _FMI2_CALL[v.type]
    return "Int64" if v.type == "Enumeration" else v.type


def c_function(fmu, name: str):
    """The C function ``name`` of ``fmu``'s loaded library, called without argument conversion
    (a fresh function object, fmpy's is left as it is): every argument is passed as a ctypes
    object prepared once, which halves the cost of a call against declared argument types."""
    f = fmu._slave.dll[name]
    f.argtypes = None
    f.restype = c_int
    return f


def component(fmu) -> int:
    """The address of ``fmu``'s running instance (``fmi2Component`` / ``fmi3Instance``)."""
    return fmu._slave.component.value if isinstance(fmu._slave.component, c_void_p) else fmu._slave.component


class Group:
    """One FMI value call on prepared arrays: ``vrs`` (value references), ``values`` (ctypes)
    and ``view`` (numpy, sharing ``values``' memory); ``positions`` index the port's names."""

    def __init__(self, fmu, call: str, names: list, positions: list, direction: str, memory=None):
        ctype = (CTYPE2 if fmu.fmi_version == 2 else CTYPE3).get(call)
        if ctype is None:
            raise CoSimulationError(f"FMU '{fmu.name}': FMI call {direction}{call} is not supported by the "
                                    f"master loop")
        self.fmu, self.call, self.direction, self.positions = fmu, call, direction, list(positions)
        self.names = list(names)
        variables = [fmu.variable(v) for v in self.names]
        if any(isinstance(v, Element) for v in variables):  # FMI 3 array elements: whole arrays per call
            self._packed(fmu, variables, ctype, memory)
            return
        vrs = [v.valueReference for v in variables]
        self.ctype, self.n = ctype, len(vrs)
        self.vrs = (c_uint * self.n)(*vrs)
        if memory is not None:  # a slice of the caller's array: values land there directly
            assert memory.dtype == np.dtype(ctype) and memory.size == self.n
            self.values = (ctype * self.n).from_buffer(memory)
            self.view = memory
            self._memory = True
        else:
            self.values = (ctype * self.n)()
            self._memory = False
            self.view = np.ctypeslib.as_array(self.values) if ctype is not c_bool else \
                np.frombuffer(self.values, dtype=np.bool_)
        name = f"fmi{fmu.fmi_version}{direction.capitalize()}{call}"
        self.name = name
        f = c_function(fmu, name)
        n = c_size_t(self.n)
        if fmu.fmi_version == 2:
            self.bound = _bind(f, c_void_p(component(fmu)), self.vrs, n, self.values)
        else:
            self.bound = _bind(f, c_void_p(component(fmu)), self.vrs, n, self.values, n)

    def _packed(self, fmu, variables, ctype, memory=None):
        """The group's call on whole arrays (:class:`~fmu_fdi.cosim.elements.Packed`: one value
        reference, N values each); ``view`` holds the group's own elements (the caller's ``memory`` when
        given, as for scalars), copied to or from the call's values by :attr:`bound`, the elements not set
        keeping their values in the instance's store (``fmu._array_values``, shared with
        :class:`~fmu_fdi.cosim.instance.Accessor`)."""
        packed = Packed(variables, store=fmu._array_values)
        self.ctype, self.n = ctype, len(variables)
        self.vrs = (c_uint * len(packed.vrs))(*packed.vrs)
        raw = (ctype * packed.n_values)()
        flat = np.ctypeslib.as_array(raw) if ctype is not c_bool else np.frombuffer(raw, dtype=np.bool_)
        self.values = raw
        if memory is not None:  # a slice of the caller's array: the elements land there directly
            assert memory.dtype == flat.dtype and memory.size == self.n
            self.view, self._memory = memory, True
        else:
            self.view, self._memory = np.zeros(self.n, flat.dtype), False
        self.name = f"fmi3{self.direction.capitalize()}{self.call}"
        call = _bind(c_function(fmu, self.name), c_void_p(component(fmu)), self.vrs, c_size_t(len(packed.vrs)), raw,
                     c_size_t(packed.n_values))
        index, view, store = packed.index, self.view, packed.store
        spans = [(vr, sum(packed.sizes[:k]), size) for k, (vr, size) in enumerate(zip(packed.vrs, packed.sizes))]

        if self.direction == "get":
            def bound():
                st = call()
                np.take(flat, index, out=view)
                return st
        else:
            def bound():
                for vr, at, size in spans:
                    flat[at:at + size] = store[vr]
                flat[index] = view
                for vr, at, size in spans:
                    store[vr][:] = flat[at:at + size]
                return call()
        self.bound = bound

    @property
    def direct(self) -> bool:
        """True if the value array is the caller's memory (no copy needed)."""
        return self._memory

def _bind(f, *args):
    """``f`` with its arguments fixed: a call is ``f(*args)`` without building anything."""
    import functools

    return functools.partial(f, *args)


class Step:
    """``doStep`` of one instance: set :attr:`time` (a ``c_double``) and call :attr:`call`; FMI 3's
    flags are read after each call (:attr:`flags` True)."""

    def __init__(self, fmu, step: float):
        self.fmu = fmu
        self.time, self.size = c_double(), c_double(step)
        comp = c_void_p(component(fmu))
        self.name = f"fmi{fmu.fmi_version}DoStep"
        f = c_function(fmu, self.name)
        if fmu.fmi_version == 2:
            self.call = _bind(f, comp, self.time, self.size, c_int(1))
            self.flags = False
        else:
            self.event, self.terminate, self.early = c_bool(), c_bool(), c_bool()
            self.last = c_double()
            refs = tuple(ctypes.byref(x) for x in (self.event, self.terminate, self.early, self.last))
            self.call = _bind(f, comp, self.time, self.size, c_bool(True), *refs)
            self.flags = True


class Port:
    """Prepared get (``direction="get"``) or set calls for ``names`` of one running FMU.

    ``memory``: optional array of ``len(names)`` entries; the variables whose call passes values
    of its dtype (float64: FMI 2 Real, FMI 3 Float64; int32: FMI 2 Integer and Boolean, FMI 3
    Int32) then use their entries of it as their value array, so a get writes there and a set
    reads from there without a copy.
    """

    def __init__(self, fmu, names, direction: str, memory=None):
        self.fmu, self.names = fmu, list(names)
        by_call: dict = {}
        for pos, var in enumerate(self.names):
            by_call.setdefault(fmi_call(fmu, var), []).append(pos)
        self.groups = []
        for call, positions in by_call.items():
            mem = None
            ctype = (CTYPE2 if fmu.fmi_version == 2 else CTYPE3).get(call)
            if memory is not None and memory.dtype == np.dtype(ctype):
                lo = positions[0]
                if positions == list(range(lo, lo + len(positions))):
                    mem = memory[lo:lo + len(positions)]
            self.groups.append(Group(fmu, call, [self.names[p] for p in positions], positions, direction, mem))
