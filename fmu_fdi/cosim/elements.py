"""FMI 3 array variables as vectors of scalar signals named ``name[i]``.

An FMI 3 array variable (a ``<Dimension>`` child, FMI 3.0 sec. 2.4.7.6) has ONE value
reference and ``N`` values: ``fmi3GetFloat64(vr, 1, v, N)`` returns its elements in
row-major order (FMI 3.0 sec. 2.2.6.1, "serialization of arrays"). fmu-fdi's models, design
files and diagnostic FMUs have scalar signals only, so an array is seen as the vector of its
elements, named by FMI's *structured naming convention* (FMI 2.0 sec. 2.2.9, FMI 3.0
sec. 2.4.7.5): ``y[1]``, ``y[2]`` for a vector, ``A[1,2]`` for a matrix, indices from 1.

Why this spelling and no mangling (``y_1``): it is the name FMI itself gives an array element,
so the same string names the plant's element, the model file's signal (TOML and JSON keep it
in quoted keys), the design file's signal and the diagnostic FMU's scalar input — in FMI 2,
which has no arrays and spells a flattened array exactly so, and in FMI 3 alike (a scalar
named ``y[2]`` is legal under ``variableNamingConvention="structured"``). ``simulate`` then
connects plant ``y[2]`` to diagnoser ``y[2]`` by name, as it connects scalars. (The diagnostic
FMU keeps scalar inputs in FMI 3 too: a design may use some elements of an array only.)

Dimensions: a fixed ``start`` or a structural parameter (``<Dimension valueReference=...>``)
of variability ``fixed`` — this master never enters Configuration Mode, so its start value is
the size. A ``tunable`` structural parameter (the size may change in Reconfiguration Mode) or
one without a start is a *variable* dimension: such an array is not expanded, and naming one
of its elements is refused in one line (:func:`refused_array`).
"""
from __future__ import annotations

import itertools
import re

import numpy as np

#: ``name[i]`` / ``name[i,j]``: the element of an array variable, indices from 1
ELEMENT = re.compile(r"^(?P<array>.+)\[(?P<idx>[1-9][0-9]*(?:,[1-9][0-9]*)*)\]$")


class Element:
    """One element of an FMI 3 array variable, looking like a scalar fmpy model variable: every
    attribute not set here (causality, variability, type, valueReference, unit, declaredType,
    nominal, ...) is the array's; ``name`` and ``start`` are the element's own."""

    def __init__(self, array, name: str, offset: int, size: int, start):
        self.array = array        # the fmpy ModelVariable of the whole array
        self.name = name          # 'y[2]'
        self.offset = offset      # position in the array's row-major serialisation, from 0
        self.size = size          # number of elements of the array
        self.start = start        # this element's start (a string, as fmpy gives scalars), or None
        self.dimensions = []      # a scalar
        self.shape = None         # the array's dimensions (set by :func:`elements`)

    def __getattr__(self, attr):  # everything else is the array's (not the special names: copy, pickle)
        array = self.__dict__.get("array")
        if array is None or attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(array, attr)

    def __repr__(self):
        return f"Element({self.name!r} of {self.array.name!r}, offset {self.offset})"


def shape(md, var) -> tuple[int, ...]:
    """The dimensions of array variable ``var`` of model description ``md``.

    Raises
    ------
    ValueError
        A variable dimension (a tunable structural parameter, or one without a start), in one
        line naming the variable and the parameter.
    """
    by_vr = None
    out = []
    for dim in var.dimensions:
        if dim.start is not None:
            out.append(int(dim.start))
            continue
        if by_vr is None:
            by_vr = {w.valueReference: w for w in md.modelVariables}
        par = by_vr.get(dim.valueReference)
        what = f"structural parameter {par.name!r}" if par is not None else f"value reference {dim.valueReference}"
        if par is None or par.start is None or getattr(par, "variability", "fixed") != "fixed":
            why = ("has no start value" if par is not None and par.start is None else "is tunable"
                   if par is not None else "names no variable")
            raise ValueError(f"array variable {var.name!r} has a variable dimension: its {what} {why}; only "
                             f"fixed dimensions (a start, or a fixed structural parameter) are supported")
        out.append(int(float(par.start)))
    return tuple(out)


def element_names(name: str, dims) -> list[str]:
    """``y[1] ... y[N]`` (or ``A[1,1], A[1,2], ...``): row-major, as FMI serialises arrays."""
    return [f"{name}[{','.join(str(i) for i in idx)}]"
            for idx in itertools.product(*(range(1, n + 1) for n in dims))]


def elements(md, var) -> list[Element]:
    """The elements of array variable ``var`` (raises ValueError for a variable dimension)."""
    dims = shape(md, var)
    names = element_names(var.name, dims)
    starts = str(var.start).split() if var.start is not None else []
    if len(starts) == 1 and len(names) > 1:  # one start for all elements
        starts = starts * len(names)
    out = [Element(var, nm, k, len(names), starts[k] if k < len(starts) else None) for k, nm in enumerate(names)]
    for el in out:
        el.shape = dims
    return out



def variables_by_name(md, refused: dict | None = None) -> dict:
    """Every variable of ``md`` by name, in file order, each array followed by its elements.
    Arrays of variable dimension stay unexpanded; ``refused`` (if given) gets their reason."""
    out = {}
    for v in md.modelVariables:
        out[v.name] = v
        if v.dimensions:
            try:
                for el in elements(md, v):
                    out[el.name] = el
            except ValueError as exc:
                if refused is not None:
                    refused[v.name] = str(exc)
    return out


def refused_array(name: str, refused: dict) -> str | None:
    """Why ``name`` (an element ``y[2]``) cannot be a signal: its array's variable dimension; else None."""
    m = ELEMENT.match(name)
    return refused.get(m.group("array")) if m else None


class Packed:
    """Scalars and array elements read and written with one get/set call of whole variables.

    An array is set whole (FMI 3 sets all its values at once): the elements not written keep
    their values in ``store`` (value reference → values; started from the start values, and
    ``held`` overrides them), so a write of ``u[1]`` alone leaves ``u[2]`` where it was set
    last. Accessors of one instance share its store.

    ``get(fn)`` calls ``fn(vrs, n_values)``; ``set(fn, values)`` calls ``fn(vrs, all_values)``.
    """

    def __init__(self, variables, held: dict | None = None, store: dict | None = None):
        self.store = {} if store is None else store
        self.vrs, self.sizes, where, flat = [], [], {}, {}
        for v in variables:
            arr = v.array if isinstance(v, Element) else v
            if arr.valueReference in where:
                continue
            size = v.size if isinstance(v, Element) else 1
            where[arr.valueReference] = sum(self.sizes)
            self.vrs.append(arr.valueReference)
            self.sizes.append(size)
            if arr.valueReference not in self.store:
                self.store[arr.valueReference] = np.array(elements_start(arr, size), dtype=float)
            if isinstance(v, Element):
                flat.update({nm: (arr.valueReference, k) for k, nm in enumerate(element_names(arr.name, v.shape))})
        self.index = np.array([where[v.valueReference] + (v.offset if isinstance(v, Element) else 0)
                               for v in variables], dtype=int)
        self.n_values = int(sum(self.sizes))
        for name, value in (held or {}).items():  # other elements of the arrays, held at their values
            if name in flat:
                vr, k = flat[name]
                self.store[vr][k] = float(value)

    def get(self, fn) -> list:
        values = list(fn(self.vrs, self.n_values))
        return [values[k] for k in self.index]

    def set(self, fn, values, cast=float) -> None:
        buffer = np.concatenate([self.store[vr] for vr in self.vrs])
        buffer[self.index] = [float(a) for a in values]
        at = 0
        for vr, size in zip(self.vrs, self.sizes):
            self.store[vr][:] = buffer[at:at + size]
            at += size
        fn(self.vrs, [cast(a) for a in buffer])


def elements_start(var, size: int) -> list[float]:
    """Start values of a variable's ``size`` values (0 where none is declared)."""
    text = str(var.start).split() if getattr(var, "start", None) is not None else []
    if len(text) == 1 and size > 1:
        text = text * size
    out = []
    for k in range(size):
        try:
            out.append(float(text[k]) if k < len(text) else 0.0)
        except ValueError:  # a Boolean 'true'
            out.append(1.0 if text[k].lower() == "true" else 0.0)
    return out
