"""The FDI synthesis model (Frank, eqs. 4-6).

    x' = A x + Bu u + Bd d + Bw w + Bf f
    y  = C x + Du u + Dd d + Dw w + Df f

continuous (``dt = 0``) or discrete (``dt > 0``), with a name for every known input u,
measured output y, unknown input d (decoupled exactly), noise input w (decoupled
approximately) and fault. A linearised plant may carry its operating point
``(u0, y0)``: the matrices then describe deviations ``u - u0``, ``y - y0``, and a
diagnoser fed with absolute signals subtracts the point first. The fault columns ``Bf``, ``Df`` are assembled from the named
:class:`~fmu_fdi.faults.FaultSpec` entries; a fault may occupy several columns.
"""
from __future__ import annotations

import copy
import json
import re
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from . import _schema as S
from . import sidecar
from .outpath import write_atomically
from ._schema import check_format, check_keys, parse, read_text
from .faults import FaultSpec, ModelError, _matrix, check_name, check_signal_name, component_fault
from .lti import LTI
from .progress import log, set_stage

FORMAT = "fmu-fdi-model/1"
#: the format of a model file whose matrices are in a binary sidecar (:mod:`fmu_fdi.sidecar`);
#: files without one are still written as ``FORMAT`` and both are read
FORMAT_SIDECAR = "fmu-fdi-model/2"
GROUPS = ("u", "d", "w", "f")
_TOP_KEYS = {"format", "name", "dt", "signals", "units", "matrices", "faults", "description", "operating_point",
             "provenance", "minimal", "minreal_tol", "arrays", "declared_types", "type_definitions"}
#: the attributes of a declared type (an FMI type definition) a model file carries
TYPE_ATTRIBUTES = ("quantity", "unit", "displayUnit")
_MATRIX_KEYS = {"A", "Bu", "C", "Du", "Bd", "Dd", "Bw", "Dw"}


class FDIModel:
    """Linear plant with named known inputs, outputs, disturbances, noise and faults.

    Build it with :meth:`from_matrices`, :meth:`from_control` or :meth:`from_file`.
    The object is immutable in practice: the transformations (:meth:`discretize`,
    :meth:`with_disturbances`) return new models.
    """

    def __init__(self, A, Bu, C, Du=None, *, Bd=None, Dd=None, Bw=None, Dw=None,
                 faults: Iterable[FaultSpec | dict] = (), dt: float = 0.0,
                 u_names: Sequence[str] | None = None, y_names: Sequence[str] | None = None,
                 d_names: Sequence[str] | None = None, w_names: Sequence[str] | None = None,
                 units: dict | None = None, name: str = "plant", description: str = "",
                 operating_point: dict | None = None, provenance: dict | None = None,
                 minimal: bool | None = None, minreal_tol: float | None = None,
                 declared_types: dict | None = None, type_definitions: dict | None = None):
        tol = minreal_option(minimal, minreal_tol)
        # a static plant (n = 0) has an empty A; its outputs are the rows of C (p x 0) or of the
        # feedthroughs, its inputs the columns of Du
        A = _matrix(A, "A") if np.size(A) else np.zeros((0, 0))
        n = A.shape[0]
        if A.shape != (n, n):
            raise ModelError(f"A must be square, got shape {A.shape}")
        if np.size(C):
            C = _matrix(C, "C", cols=n)
        else:
            rows = [np.shape(X)[0] for X in (C, Du, Dd, Dw) if X is not None and np.ndim(X) == 2]
            C = np.zeros((max(rows, default=0), n))
        p = C.shape[0]
        if p == 0:
            raise ModelError("the model has no measured outputs (C has no rows)")
        Bu = _opt(Bu, "Bu", n, len(u_names) if u_names is not None else None)
        m = Bu.shape[1]
        if n == 0 and m == 0 and Du is not None and np.size(Du):
            Du = _matrix(Du, "Du", rows=p)  # static plant: the known inputs are the columns of Du
            m = Du.shape[1]
            Bu = np.zeros((0, m))
        Du = _opt(Du, "Du", p, m)
        if Du.shape[1] != m:
            raise ModelError(f"Du must be {p}x{m} to match Bu, got shape {Du.shape}")
        Bd = _opt(Bd, "Bd", n, len(d_names) if d_names is not None else None)
        Dd = _opt(Dd, "Dd", p, Bd.shape[1])
        Bw = _opt(Bw, "Bw", n, len(w_names) if w_names is not None else None)
        Dw = _opt(Dw, "Dw", p, Bw.shape[1])
        if Dd.shape[1] != Bd.shape[1] and not np.any(Bd):
            Bd = np.zeros((n, Dd.shape[1]))
        if Dw.shape[1] != Bw.shape[1] and not np.any(Bw):
            Bw = np.zeros((n, Dw.shape[1]))
        for key, B, D in (("d", Bd, Dd), ("w", Bw, Dw)):
            if B.shape[1] != D.shape[1]:
                raise ModelError(f"B{key} has {B.shape[1]} columns but D{key} has {D.shape[1]}")
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise ModelError(f"dt must be a number (0 for continuous time), got {dt!r}") from None
        if not np.isfinite(dt) or dt < 0:
            raise ModelError(f"dt must be 0 (continuous) or a positive sample time, got {dt!r}")

        self.name = check_name(name, "model")
        self.description = description
        self.dt = dt
        self.A, self.Bu, self.C, self.Du = A, Bu, C, Du
        self.Bd, self.Dd, self.Bw, self.Dw = Bd, Dd, Bw, Dw
        self.u_names = _names(u_names, m, "u", "u")
        self.y_names = _names(y_names, p, "y", "y")
        self.d_names = _names(d_names, Bd.shape[1], "d", "d")
        self.w_names = _names(w_names, Bw.shape[1], "w", "w")
        seen: dict[str, str] = {}
        for group, names in (("u", self.u_names), ("y", self.y_names), ("d", self.d_names),
                             ("w", self.w_names)):
            for nm in names:
                if nm in seen:
                    raise ModelError(f"signal name '{nm}' is used twice (in {seen[nm]} and {group})")
                seen[nm] = group
        self.units = _per_signal(units, seen, "units", "unit")
        #: the FMI declaredType (type definition) of each signal that has one, e.g. ``"Modelica.Units.SI.Angle"``
        self.declared_types = _per_signal(declared_types, seen, "declared_types", "declared type")
        #: per declared type, the attributes of its FMI type definition (``quantity``, ``unit``,
        #: ``displayUnit``), e.g. ``{"Modelica.Units.SI.Force": {"quantity": "Force", "unit": "N"}}``
        self.type_definitions = _type_definitions(type_definitions)

        op = dict(operating_point or {})
        bad = set(op) - {"u", "y"}
        if bad:
            raise ModelError(f"operating_point has unknown keys {sorted(bad)}; use 'u' and 'y'")
        self.u0 = _matrix(op["u"], "operating_point.u", rows=m).ravel() if "u" in op and m else np.zeros(m)
        self.y0 = _matrix(op["y"], "operating_point.y", rows=p).ravel() if "y" in op else np.zeros(p)

        self.provenance = _provenance(provenance)

        self.faults: list[FaultSpec] = []
        cols_B, cols_D = [], []
        start = 0
        for spec in faults:
            spec = FaultSpec.from_dict(spec) if isinstance(spec, dict) else copy.deepcopy(spec)
            if not isinstance(spec, FaultSpec):
                raise ModelError(f"faults must be FaultSpec objects or dicts, got {type(spec).__name__}")
            if spec.name in seen:
                raise ModelError(f"fault name '{spec.name}' is already used by {seen[spec.name]}")
            seen[spec.name] = "faults"
            Bf, Df = spec.additive_columns(A, Bu, C, Du, self.u_names, self.y_names)
            spec.columns = slice(start, start + Bf.shape[1])
            start += Bf.shape[1]
            cols_B.append(Bf)
            cols_D.append(Df)
            self.faults.append(spec)
        self.Bf = np.hstack(cols_B) if cols_B else np.zeros((n, 0))
        self.Df = np.hstack(cols_D) if cols_D else np.zeros((p, 0))
        #: ``(n, n_min, tol)`` when this construction reduced the realisation, else None
        self.reduction: tuple[int, int, float] | None = None
        if tol is not None:
            self._reduce(tol)

    def _reduce(self, tol: float) -> None:
        """Replace the realisation by a minimal one (see :func:`minimal_realisation`); the
        removed order and the tolerance go into :attr:`provenance` and the ``fmu_fdi`` log."""
        param = [f.name for f in self.faults if f.kind == "parametric"]
        if param:
            raise ModelError(f"cannot reduce the model to a minimal realisation: the parametric fault(s) {param} "
                             f"act on the full state x (dA, dB, dC); give them as component faults or build the "
                             f"model without minimal/minreal_tol")
        n = self.n
        B = np.hstack([self.Bu, self.Bd, self.Bw, self.Bf])
        A, B, C, used = minimal_realisation(self.A, B, self.C, tol)
        nr = A.shape[0]
        cuts = np.cumsum([self.nu, self.nd, self.nw])
        self.A, self.C = A, C
        self.Bu, self.Bd, self.Bw, self.Bf = np.split(B, cuts, axis=1)
        for spec in self.faults:
            if spec.kind == "component":
                spec.Bf = self.Bf[:, spec.columns]
        self.provenance.update({"minreal_tol_used": float(used), "minreal_order": [n, nr]})
        self.reduction = (n, nr, float(used))
        log.info("model '%s': minimal realisation (relative tolerance %.3g) removed %d of %d states",
                 self.name, used, n - nr, n)

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_matrices(cls, A, Bu, C, Du=None, **kwargs) -> "FDIModel":
        """Build a model from matrices; keywords as in the class signature.

        ``minimal=True`` (or a ``minreal_tol``) replaces the realisation by a minimal one of
        the map from ``[u; d; w; f]`` to y (:func:`minimal_realisation`); the removed
        order is recorded in ``provenance`` (``minreal_order = [n, n_min]``, ``minreal_tol_used``)
        and logged on the ``fmu_fdi`` logger.

        Examples
        --------
        >>> import numpy as np
        >>> from fmu_fdi import FDIModel, sensor_fault
        >>> m = FDIModel.from_matrices(-np.eye(1), [[1.0]], [[1.0]], faults=[sensor_fault("s", "y0")])
        >>> m.fault_names
        ['s']
        """
        return cls(A, Bu, C, Du, **kwargs)

    @classmethod
    def from_control(cls, sys, *, u=None, d=None, w=None, f=None, ignore=None,
                     faults: Iterable[FaultSpec | dict] = (), y_names=None, name: str = "plant",
                     units: dict | None = None, minimal: bool | None = None,
                     minreal_tol: float | None = None) -> "FDIModel":
        """Build a model from a python-control ``StateSpace``/``TransferFunction`` (or :class:`LTI`).

        The input groups ``u``, ``d``, ``w``, ``f`` are lists of input indices or input
        names. Inputs in ``f`` become component faults named after the inputs. Inputs
        not assigned are known inputs ``u`` when ``u`` is not given; otherwise they must
        be listed in ``ignore`` (so a forgotten input is an error, not a silent drop).
        Extra ``faults`` (actuator/sensor specs) are appended. ``minimal``/``minreal_tol``
        reduce the realisation as in :meth:`from_matrices`.
        """
        import control

        labels_in = labels_out = None
        if isinstance(sys, LTI):
            lti = sys
        else:
            if isinstance(sys, control.TransferFunction):
                labels_in, labels_out = list(sys.input_labels), list(sys.output_labels)
            elif isinstance(sys, control.StateSpace):
                labels_in, labels_out = list(sys.input_labels), list(sys.output_labels)
            lti = LTI.from_control(sys)
        labels_in = [_sanitize(s) for s in labels_in] if labels_in else [f"u{i}" for i in range(lti.m)]
        labels_out = [_sanitize(s) for s in labels_out] if labels_out else [f"y{i}" for i in range(lti.p)]

        def resolve(group, key):
            if group is None:
                return []
            group = [group] if isinstance(group, (int, str, np.integer)) else list(group)
            out = []
            for g in group:
                if isinstance(g, (int, np.integer)):
                    if not 0 <= g < lti.m:
                        raise ModelError(f"input index {g} in group '{key}' is out of range 0..{lti.m - 1}")
                    out.append(int(g))
                elif g in labels_in:
                    out.append(labels_in.index(g))
                else:
                    raise ModelError(f"input '{g}' in group '{key}' is not an input of the system {labels_in}")
            return out

        groups = {k: resolve(v, k) for k, v in (("u", u), ("d", d), ("w", w), ("f", f), ("ignore", ignore))}
        used: dict[int, str] = {}
        for k, idx in groups.items():
            for i in idx:
                if i in used:
                    raise ModelError(f"input {labels_in[i]!r} is assigned to both '{used[i]}' and '{k}'")
                used[i] = k
        rest = [i for i in range(lti.m) if i not in used]
        if rest:
            if u is None:
                groups["u"] = sorted(groups["u"] + rest)
            else:
                raise ModelError(
                    f"inputs {[labels_in[i] for i in rest]} are in no group: assign them to u, d, w or f, "
                    f"or list them in ignore"
                )
        fault_specs = [
            FaultSpec(name=labels_in[i], kind="component", Bf=lti.B[:, [i]], Df=lti.D[:, [i]])
            for i in groups["f"]
        ]
        return cls(
            lti.A, lti.B[:, groups["u"]], lti.C, lti.D[:, groups["u"]],
            Bd=lti.B[:, groups["d"]], Dd=lti.D[:, groups["d"]],
            Bw=lti.B[:, groups["w"]], Dw=lti.D[:, groups["w"]],
            faults=fault_specs + list(faults), dt=lti.dt,
            u_names=[labels_in[i] for i in groups["u"]],
            y_names=list(y_names) if y_names is not None else labels_out,
            d_names=[labels_in[i] for i in groups["d"]],
            w_names=[labels_in[i] for i in groups["w"]],
            units=units, name=name, minimal=minimal, minreal_tol=minreal_tol,
        )

    def labels(self, names: Sequence[str]) -> list[str]:
        """Signal names as listed to a user: ``h1 [cm]``, ``beta [rad: Angle]`` (unit, then the
        declaredType the plant FMU gave it), the bare name when it has neither."""
        out = []
        for nm in names:
            unit, typ = self.units.get(nm, ""), self.declared_types.get(nm, "")
            tag = unit + (": " if unit and typ else "") + typ
            out.append(f"{nm} [{tag}]" if tag else nm)
        return out

    # ------------------------------------------------------------------ sizes
    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def nu(self) -> int:
        return self.Bu.shape[1]

    @property
    def ny(self) -> int:
        return self.C.shape[0]

    @property
    def nd(self) -> int:
        return self.Bd.shape[1]

    @property
    def nw(self) -> int:
        return self.Bw.shape[1]

    @property
    def nf(self) -> int:
        """Number of additive fault columns (a fault may have several)."""
        return self.Bf.shape[1]

    @property
    def fault_names(self) -> list[str]:
        return [f.name for f in self.faults]

    @property
    def is_discrete(self) -> bool:
        return self.dt > 0

    def fault(self, name: str) -> FaultSpec:
        for f in self.faults:
            if f.name == name:
                return f
        raise KeyError(f"no fault named {name!r}; faults are {self.fault_names}")

    def fault_index(self, name: str) -> int:
        return self.fault_names.index(self.fault(name).name)

    def __repr__(self) -> str:
        kind = f"discrete, dt={self.dt:g}" if self.is_discrete else "continuous"
        return (f"FDIModel('{self.name}', n={self.n}, u={self.u_names}, y={self.y_names}, d={self.d_names}, "
                f"w={self.w_names}, faults={self.fault_names}, {kind})")

    # --------------------------------------------------------------- systems
    def matrices(self, group: str) -> tuple[np.ndarray, np.ndarray]:
        """``(B, D)`` of an input group: 'u', 'd', 'w' or 'f'."""
        try:
            return {"u": (self.Bu, self.Du), "d": (self.Bd, self.Dd), "w": (self.Bw, self.Dw),
                    "f": (self.Bf, self.Df)}[group]
        except KeyError:
            raise ValueError(f"unknown input group {group!r}; use one of {GROUPS}") from None

    def lti(self, *groups: str) -> LTI:
        """Transfer from the given input groups (default all, in order u, d, w, f) to y."""
        groups = groups or GROUPS
        Bs, Ds = zip(*(self.matrices(g) for g in groups))
        return LTI(self.A, np.hstack(Bs), self.C, np.hstack(Ds), self.dt)

    def augmented(self) -> LTI:
        """``Ge = [Gu Gd Gw Gf; I 0 0 0]``: from [u; d; w; f] to [y; u].

        A residual generator ``Q`` acting on ``[y; u]`` has internal form ``R = Q Ge``.
        """
        G = self.lti()
        m = self.nu
        tot = G.m
        Dlow = np.zeros((m, tot))
        Dlow[:, :m] = np.eye(m)
        return LTI(G.A, G.B, np.vstack([G.C, np.zeros((m, self.n))]), np.vstack([G.D, Dlow]), self.dt)

    def group_slices(self) -> dict[str, slice]:
        """Column ranges of u, d, w, f in :meth:`lti`/:meth:`augmented` inputs."""
        out, start = {}, 0
        for g, k in zip(GROUPS, (self.nu, self.nd, self.nw, self.nf)):
            out[g] = slice(start, start + k)
            start += k
        return out

    # -------------------------------------------------------- transformations
    def _replace(self, **changes) -> "FDIModel":
        kw = dict(A=self.A, Bu=self.Bu, C=self.C, Du=self.Du, Bd=self.Bd, Dd=self.Dd, Bw=self.Bw,
                  Dw=self.Dw, faults=self.faults, dt=self.dt, u_names=self.u_names, y_names=self.y_names,
                  d_names=self.d_names, w_names=self.w_names, units=self.units, name=self.name,
                  description=self.description, operating_point={"u": self.u0, "y": self.y0},
                  provenance=self.provenance, declared_types=self.declared_types,
                  type_definitions=self.type_definitions)
        kw.update(changes)
        return FDIModel(**kw)

    def discretize(self, Ts: float) -> "FDIModel":
        """Exact zero-order-hold discretisation of every input channel (u, d, w, f).

        Additive faults keep their kind (actuator and sensor faults resolve against the
        discretised Bu/Du); component and parametric faults become component faults with
        the discretised columns — exact for a piecewise-constant fault signal.
        """
        if self.is_discrete:
            raise ModelError("the model is already discrete")
        D = self.lti().to_discrete(Ts)
        sl = self.group_slices()
        faults = []
        for spec in self.faults:
            if spec.kind in ("actuator", "sensor"):
                faults.append(spec)
            else:
                faults.append(FaultSpec(name=spec.name, kind="component", Bf=D.B[:, sl["f"]][:, spec.columns],
                                        Df=self.Df[:, spec.columns], description=spec.description))
        return self._replace(A=D.A, Bu=D.B[:, sl["u"]], Bd=D.B[:, sl["d"]], Bw=D.B[:, sl["w"]],
                             faults=faults, dt=D.dt)

    def with_disturbances(self, faults: Sequence[str] = (), noise: bool = False) -> "FDIModel":
        """A model where the named faults (and, with ``noise=True``, the noise inputs) are
        unknown inputs to decouple exactly. Used for fault isolation and exact designs."""
        faults = list(faults)
        for nm in faults:
            self.fault(nm)
        moved = [f for f in self.faults if f.name in faults]
        Bd = [self.Bd] + [self.Bf[:, f.columns] for f in moved]
        Dd = [self.Dd] + [self.Df[:, f.columns] for f in moved]
        d_names = list(self.d_names) + [f"{f.name}_{k}" if f.columns.stop - f.columns.start > 1 else f.name
                                        for f in moved for k in range(f.columns.stop - f.columns.start)]
        w_names = self.w_names
        if noise:
            Bd.append(self.Bw)
            Dd.append(self.Dw)
            d_names += list(self.w_names)
            w_names = []
        faults_left = [f for f in self.faults if f.name not in faults]
        return self._replace(
            Bd=np.hstack(Bd), Dd=np.hstack(Dd), d_names=d_names,
            Bw=np.zeros((self.n, 0)) if noise else self.Bw, Dw=np.zeros((self.ny, 0)) if noise else self.Dw,
            w_names=w_names, faults=faults_left,
            units={k: v for k, v in self.units.items() if k in set(self.u_names) | set(self.y_names)
                   | set(self.d_names) | set(self.w_names)},
            declared_types={k: v for k, v in self.declared_types.items() if k in set(self.u_names)
                            | set(self.y_names) | set(self.d_names) | set(self.w_names)},
        )

    def minreal(self, tol: float | None = None) -> "FDIModel":
        """This model in a minimal realisation (relative tolerance ``tol``, default ``n²·eps``);
        see :func:`minimal_realisation`."""
        return self._replace(minimal=True, minreal_tol=tol)

    def series(self, pre, **kw) -> "FDIModel":
        """This model driven through ``pre`` (e.g. actuators): see :func:`series`."""
        return series(self, pre, **kw)

    def feedback(self, K, **kw) -> "FDIModel":
        """The loop ``u = r - K y`` closed: see :func:`feedback`."""
        return feedback(self, K, **kw)

    # ------------------------------------------------------------------ files
    def to_dict(self, arrays: dict | None = None) -> dict:
        """The model as the dict of a model file. With a dict ``arrays``, every matrix goes
        into it (to be written to a sidecar, :mod:`fmu_fdi.sidecar`) and the returned dict
        holds references ``{array, shape}`` in its place."""
        mats = {"A": self.A, "Bu": self.Bu, "C": self.C}
        for key in ("Du", "Bd", "Dd", "Bw", "Dw"):
            val = getattr(self, key)
            if val.size and np.any(val):
                mats[key] = val
        d = {
            "format": FORMAT,
            "name": self.name,
            "dt": self.dt,
            "signals": {"u": list(self.u_names), "y": list(self.y_names), "d": list(self.d_names),
                        "w": list(self.w_names)},
            "matrices": {k: np.asarray(v, float).tolist() for k, v in mats.items()},
            "faults": [f.to_dict() for f in self.faults],
        }
        if arrays is not None:
            d = sidecar.externalise(d, arrays)
        if self.description:
            d["description"] = self.description
        if self.units:
            d["units"] = dict(self.units)
        if self.declared_types:
            d["declared_types"] = dict(self.declared_types)
        used = {k: dict(v) for k, v in self.type_definitions.items() if k in set(self.declared_types.values())}
        if used:
            d["type_definitions"] = used
        if np.any(self.u0) or np.any(self.y0):
            d["operating_point"] = {"u": self.u0.tolist(), "y": self.y0.tolist()}
        if self.provenance:
            d["provenance"] = dict(self.provenance)
        return d

    @classmethod
    def from_dict(cls, d: dict, source: str = "model", *, minimal: bool | None = None,
                  minreal_tol: float | None = None, base=None) -> "FDIModel":
        """Build a model from the dict of a model file, checking every value's type first.

        ``minimal``/``minreal_tol`` given here override the file's keys of the same names.
        ``base`` is the folder of the model file, where its sidecar (if any) lies.
        """
        _check_format(d, source)
        d = sidecar.resolve(d, base, source, ModelError)
        _check_model_dict(d, source)
        if minimal is None and minreal_tol is None:
            minimal, minreal_tol = d.get("minimal"), d.get("minreal_tol")
        sig, mats = d["signals"], d["matrices"]
        u = sig.get("u", [])
        try:
            n = len(mats["A"])
            p = len(sig["y"])

            def get(key, rows, cols):
                if key not in mats:
                    return np.zeros((rows, cols))
                val = mats[key]
                if isinstance(val, list) and len(val) == 0:
                    return np.zeros((rows, cols))
                return _matrix(val, f"{source}: matrix {key}", rows=rows, cols=cols)

            # a static plant (n = 0): A is [] and C is [] or p empty rows
            A = _matrix(mats["A"], f"{source}: matrix A", rows=n, cols=n) if n else np.zeros((0, 0))
            C = _matrix(mats["C"], f"{source}: matrix C", rows=p, cols=n) if n or np.size(mats["C"]) else \
                np.zeros((p, 0))
            nd, nw = len(sig.get("d", [])), len(sig.get("w", []))
            return cls(
                A, get("Bu", n, len(u)), C, get("Du", p, len(u)),
                Bd=get("Bd", n, nd), Dd=get("Dd", p, nd), Bw=get("Bw", n, nw), Dw=get("Dw", p, nw),
                faults=d.get("faults", []), dt=d.get("dt", 0.0),
                u_names=u, y_names=sig["y"], d_names=sig.get("d", []), w_names=sig.get("w", []),
                units=d.get("units"), declared_types=d.get("declared_types"), name=d.get("name", "plant"),
                type_definitions=d.get("type_definitions"),
                description=d.get("description", ""),
                operating_point=d.get("operating_point"), provenance=d.get("provenance"),
                minimal=minimal, minreal_tol=minreal_tol,
            )
        except ModelError as exc:
            msg = str(exc)
            raise ModelError(msg if msg.startswith(source) else f"{source}: {msg}") from None

    @classmethod
    def from_file(cls, path, *, minimal: bool | None = None, minreal_tol: float | None = None) -> "FDIModel":
        """Read a model file (``.json`` or ``.toml``, UTF-8; format ``fmu-fdi-model/1``, or
        ``fmu-fdi-model/2`` with its matrices in a binary sidecar checked by shape and SHA-256).

        An FMU, a binary or UTF-16 file, a syntax error, too deep nesting or a value of the
        wrong type is a one-line :class:`ModelError` naming the file and the key.
        ``minimal``/``minreal_tol`` (as in :meth:`from_matrices`) override the file's keys.
        """
        path = Path(path)
        set_stage(f"reading the model file {path}")
        text = read_text(path, "model file", ModelError)
        suffix = path.suffix.lower()
        if suffix not in (".json", ".toml"):
            raise ModelError(f"{path}: model files end in .json or .toml, got '{suffix}'")
        return cls.from_dict(parse(text, suffix[1:], str(path), ModelError), source=str(path), minimal=minimal,
                             minreal_tol=minreal_tol, base=path.parent)

    def to_file(self, path, sidecar: bool | None = None) -> Path:
        """Write the model as JSON or TOML (by extension); floats round-trip exactly.

        ``sidecar=True`` writes the matrices to ``<name>.npz`` (``plant.toml.npz``) beside the file (format
        ``fmu-fdi-model/2``, :mod:`fmu_fdi.sidecar`), ``False`` keeps them in the text;
        None (default) uses the sidecar when the matrices hold more than
        :data:`fmu_fdi.sidecar.SIDECAR_MIN_ENTRIES` numbers in all. The file is written under a
        temporary name and renamed (the sidecar first); a file written without a sidecar removes
        the one an earlier save left under its name.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (".json", ".toml"):
            raise ModelError(f"{path}: model files end in .json or .toml, got '{suffix}'")
        if sidecar is None:
            entries = sum(X.size for X in (self.A, self.Bu, self.C, self.Du, self.Bd, self.Dd, self.Bw, self.Dw,
                                           self.Bf, self.Df))
            sidecar = entries > _sidecar.SIDECAR_MIN_ENTRIES
        arrays: dict | None = {} if sidecar else None
        d = self.to_dict(arrays)
        table = _sidecar.store(path, arrays)
        if table is not None:
            d["format"] = FORMAT_SIDECAR
            d["arrays"] = table
        if suffix == ".json":
            text = json.dumps(d, indent=2)
        elif suffix == ".toml":
            text = _toml_dumps(d)
        else:
            raise ModelError(f"{path}: model files end in .json or .toml, got '{suffix}'")
        return write_atomically(path, lambda part: part.write_text(text, encoding="utf-8"))  # never half a file


_sidecar = sidecar  # to_file's argument of the same name hides the module


# ---------------------------------------------------------------- the model's own algebra
# Interconnections (state-space, no inverses beyond the algebraic loop ``I + D_K D_u``):
# :func:`series` (a pre-system between command and plant input), :func:`feedback` (the loop
# ``u = r - K y`` closed) and :func:`parallel` (two models, same inputs, outputs stacked).
# Faults are carried over as component faults with their columns in the new model.


def _as_lti(K, dt: float, shape: tuple[int, int], what: str) -> LTI:
    if isinstance(K, LTI):
        sys = K
    elif hasattr(K, "A") and hasattr(K, "B"):
        sys = LTI.from_control(K)
    else:
        sys = LTI.static(np.atleast_2d(np.asarray(K, float)), dt)
    if sys.n and abs(sys.dt - dt) > 1e-12 * max(1.0, dt):
        raise ModelError(f"{what} has sample time {sys.dt} but the model has {dt}")
    if (sys.p, sys.m) != shape:
        raise ModelError(f"{what} must be {shape[0]}x{shape[1]} (outputs x inputs), got {sys.p}x{sys.m}")
    return LTI(sys.A, sys.B, sys.C, sys.D, dt)


def _carried_faults(model: FDIModel, Bf: np.ndarray, Df: np.ndarray) -> list[FaultSpec]:
    out = []
    for f in model.faults:
        desc = f"{f.kind} fault carried over from model '{model.name}'" + (f": {f.description}" if f.description else "")
        out.append(component_fault(f.name, Bf[:, f.columns], Df[:, f.columns], description=desc))
    return out


def series(model: FDIModel, pre, *, name: str | None = None, minimal: bool | None = None,
           minreal_tol: float | None = None) -> FDIModel:
    """The model driven through ``pre``: ``u_plant = P(λ) u`` (P square, m×m).

    States ``[x_P; x]``: ``A = [A_P 0; Bu C_P  A]``, ``Bu' = [B_P; Bu D_P]``,
    ``C' = [Du C_P  C]``, ``Du' = Du D_P``; d, w and faults enter ``[0; B]``.
    """
    m = model.nu
    P = _as_lti(pre, model.dt, (m, m), "pre-system")
    nP, n = P.n, model.n
    A = np.block([[P.A, np.zeros((nP, n))], [model.Bu @ P.C, model.A]])
    Bu = np.vstack([P.B, model.Bu @ P.D])
    C = np.hstack([model.Du @ P.C, model.C])
    Du = model.Du @ P.D
    z = lambda B: np.vstack([np.zeros((nP, B.shape[1])), B])  # noqa: E731
    return FDIModel(A, Bu, C, Du, Bd=z(model.Bd), Dd=model.Dd, Bw=z(model.Bw), Dw=model.Dw,
                    faults=_carried_faults(model, z(model.Bf), model.Df), dt=model.dt, u_names=model.u_names,
                    y_names=model.y_names, d_names=model.d_names, w_names=model.w_names, units=model.units,
                    declared_types=model.declared_types, type_definitions=model.type_definitions,
                    name=name or f"{model.name}_series", description=f"{model.name} with a {nP}-state pre-system "
                    f"in series", minimal=minimal, minreal_tol=minreal_tol)


def feedback(model: FDIModel, K, *, name: str | None = None, r_names: Sequence[str] | None = None,
             minimal: bool | None = None, minreal_tol: float | None = None) -> FDIModel:
    """The closed loop ``u = r − K(λ) y`` (K static m×p gain or LTI controller).

    With ``E = (I + D_K Du)^{-1}`` (the algebraic loop must be well posed) and the other
    inputs ``v = [d; w; f]``: ``u = E (r − C_K x_K − D_K C x − D_K D_v v)``, then the plant
    and controller state equations. New known inputs: r (default names ``r_<u>``).
    """
    m, p = model.nu, model.ny
    Kc = _as_lti(K, model.dt, (m, p), "controller")
    M = np.eye(m) + Kc.D @ model.Du
    if np.linalg.cond(M) > 1e12:
        raise ModelError(f"the feedback loop is not well posed: I + D_K Du is singular (condition "
                         f"{np.linalg.cond(M):.3g})")
    E = np.linalg.solve(M, np.eye(m))
    nk = Kc.n
    Bv = np.hstack([model.Bd, model.Bw, model.Bf])
    Dv = np.hstack([model.Dd, model.Dw, model.Df])
    # u = Ur r + Ux x + Uk xk + Uv v
    Ur, Ux, Uk, Uv = E, -E @ Kc.D @ model.C, -E @ Kc.C, -E @ Kc.D @ Dv
    # y = C x + Du u + Dv v
    Yr, Yx, Yk, Yv = model.Du @ Ur, model.C + model.Du @ Ux, model.Du @ Uk, Dv + model.Du @ Uv
    A = np.block([[model.A + model.Bu @ Ux, model.Bu @ Uk], [Kc.B @ Yx, Kc.A + Kc.B @ Yk]])
    Br = np.vstack([model.Bu @ Ur, Kc.B @ Yr])
    Bvc = np.vstack([Bv + model.Bu @ Uv, Kc.B @ Yv])
    C = np.hstack([Yx, Yk])
    nd, nw = model.nd, model.nw
    sl_d, sl_w, sl_f = slice(0, nd), slice(nd, nd + nw), slice(nd + nw, None)
    r_names = list(r_names or [f"r_{u}" for u in model.u_names])
    return FDIModel(A, Br, C, Yr, Bd=Bvc[:, sl_d], Dd=Yv[:, sl_d], Bw=Bvc[:, sl_w], Dw=Yv[:, sl_w],
                    faults=_carried_faults(model, Bvc[:, sl_f], Yv[:, sl_f]), dt=model.dt, u_names=r_names,
                    y_names=model.y_names, d_names=model.d_names, w_names=model.w_names,
                    units={k: v for k, v in model.units.items() if k in set(model.y_names) | set(model.d_names)
                           | set(model.w_names)},
                    declared_types={k: v for k, v in model.declared_types.items()
                                    if k in set(model.y_names) | set(model.d_names) | set(model.w_names)},
                    type_definitions=model.type_definitions,
                    name=name or f"{model.name}_loop", description=f"{model.name} in closed loop with a "
                    f"{nk}-state controller (u = r - K y)", minimal=minimal, minreal_tol=minreal_tol)


def parallel(first: FDIModel, second: FDIModel, *, name: str | None = None, minimal: bool | None = None,
             minreal_tol: float | None = None) -> FDIModel:
    """Two models driven by the same known inputs, outputs stacked ``[y1; y2]``;
    their d, w and faults are kept apart (names must differ)."""
    if first.nu != second.nu or abs(first.dt - second.dt) > 1e-12:
        raise ModelError("parallel models need the same known inputs and sample time")
    n1, n2 = first.n, second.n
    A = np.block([[first.A, np.zeros((n1, n2))], [np.zeros((n2, n1)), second.A]])
    Bu = np.vstack([first.Bu, second.Bu])
    C = np.block([[first.C, np.zeros((first.ny, n2))], [np.zeros((second.ny, n1)), second.C]])
    Du = np.vstack([first.Du, second.Du])

    def diag(B1, B2):
        return np.block([[B1, np.zeros((B1.shape[0], B2.shape[1]))], [np.zeros((B2.shape[0], B1.shape[1])), B2]])

    Bf, Df = diag(first.Bf, second.Bf), diag(first.Df, second.Df)
    faults = (_carried_faults(first, Bf[:, :first.nf], Df[:, :first.nf])
              + _carried_faults(second, Bf[:, first.nf:], Df[:, first.nf:]))
    return FDIModel(A, Bu, C, Du, Bd=diag(first.Bd, second.Bd), Dd=diag(first.Dd, second.Dd),
                    Bw=diag(first.Bw, second.Bw), Dw=diag(first.Dw, second.Dw), faults=faults, dt=first.dt,
                    u_names=first.u_names, y_names=list(first.y_names) + list(second.y_names),
                    d_names=list(first.d_names) + list(second.d_names),
                    w_names=list(first.w_names) + list(second.w_names),
                    name=name or f"{first.name}_{second.name}", minimal=minimal, minreal_tol=minreal_tol)


def _per_signal(table, seen: dict, what: str, one: str) -> dict:
    """A per-signal table of text (``units``, ``declared_types``): keys are signals of the model."""
    out = dict(table or {})
    for key, value in out.items():
        if key not in seen:
            raise ModelError(f"{what} given for unknown signal '{key}'; signals are {sorted(seen)}")
        if not isinstance(value, str):
            raise ModelError(f"{one} of '{key}' must be a string, got {value!r}")
    return out


def _type_definitions(table) -> dict:
    """Declared type name → its attributes (a subset of ``TYPE_ATTRIBUTES``, strings)."""
    out = {}
    for name, attrs in dict(table or {}).items():
        if not isinstance(attrs, dict):
            raise ModelError(f"type definition '{name}' must be a table of {', '.join(TYPE_ATTRIBUTES)}, got {attrs!r}")
        bad = set(attrs) - set(TYPE_ATTRIBUTES)
        if bad:
            raise ModelError(f"type definition '{name}': unknown attributes {sorted(map(str, bad))}; use "
                             f"{', '.join(TYPE_ATTRIBUTES)}")
        for key, value in attrs.items():
            if not isinstance(value, str):
                raise ModelError(f"type definition '{name}': {key} must be a string, got {value!r}")
        out[str(name)] = {k: attrs[k] for k in TYPE_ATTRIBUTES if attrs.get(k)}
    return out


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, dict):  # a sidecar reference {array, shape}: an inline table
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list) and v and isinstance(v[0], list):
        # A matrix: one row per line, so the file reads like the matrix it holds.
        return "[\n    " + ",\n    ".join(_toml_value(row) for row in v) + ",\n]"
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_key(k: str) -> str:
    """A TOML key: bare when it is one (letters, digits, '_', '-'), else quoted (``"y[2]"``)."""
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _toml_dumps(d: dict) -> str:
    """TOML writer for the model schema: scalars, then tables, matrices row by row."""
    lines = []
    for key, val in d.items():
        if not isinstance(val, (dict, list)):
            lines.append(f"{key} = {_toml_value(val)}")
    for key in ("arrays", "signals", "units", "declared_types", "type_definitions", "operating_point", "provenance",
                "matrices"):
        if key in d:
            lines.append(f"\n[{key}]")
            lines.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in d[key].items())
    for fault in d.get("faults", []):
        lines.append("\n[[faults]]")
        lines.extend(f"{k} = {_toml_value(v)}" for k, v in fault.items())
    return "\n".join(lines) + "\n"


def _provenance(prov) -> dict:
    """Where a model came from (e.g. ``fmu-fdi model``): a flat table of strings, numbers,
    Booleans and lists of them, kept as written and never read by any computation."""
    if prov is None:
        return {}
    if not isinstance(prov, dict):
        raise ModelError(f"provenance must be a table of key = value, got {type(prov).__name__}")
    out = {}
    for key, val in prov.items():
        vals = val if isinstance(val, list) else [val]
        if not all(isinstance(v, (str, int, float, bool)) for v in vals):
            raise ModelError(f"provenance.{key} must be a string, number, Boolean or a list of them, got {val!r}")
        out[str(key)] = list(val) if isinstance(val, list) else val
    return out


def minreal_option(minimal, minreal_tol, where: str = "") -> float | None:
    """The relative tolerance of the minimal realisation asked for, or None for none.

    ``minimal`` is None/True/False; ``minreal_tol`` a number in [0, 1) (0: the default
    ``n²·eps``) and implies ``minimal``. One check for every entry point (constructors,
    model files, CLI): anything else is a one-line :class:`ModelError`.
    """
    if minimal is not None and not isinstance(minimal, (bool, np.bool_)):
        raise ModelError(f"{where}minimal must be true or false, got {S.type_name(minimal)}")
    if minreal_tol is None:
        return 0.0 if minimal else None
    tol = S.real(minreal_tol, f"{where}minreal_tol", ModelError, lo=0.0, hi=1.0, hi_open=True)
    if minimal is not None and not minimal:
        raise ModelError(f"{where}minreal_tol = {tol:g} is given but minimal is false; drop one of them")
    return tol


def minimal_realisation(A, B, C, tol: float = 0.0):
    """A minimal realisation ``(Ar, Br, Cr, tol_used)`` of ``C (λI - A)^{-1} B``.

    Orthogonal controllability then observability staircases (SLICOT TB01PD, no diagonal
    balancing, so the decisions are those of the coordinates given) on the data scaled
    block-wise to unit norm, ``(A/||A||, B/||B||, C/||C||)``: a mode whose coupling to the
    inputs (outputs) is at most ``tol`` relative to the norms of the data is removed (Varga
    2017, sec. 10.3.1, the relative tolerance of ``gminreal``). Controllability and
    observability are invariant under these scalings, so the reduced realisation is the
    scaled-back one. ``tol = 0`` uses SLICOT's default ``n²·eps``.
    """
    A, B, C = (np.asarray(X, float) for X in (A, B, C))
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    used = float(tol) if tol > 0 else n * n * np.finfo(float).eps
    if n == 0:
        return A, B, C, used
    if m == 0 or p == 0 or not np.any(B) or not np.any(C):
        return np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0)), used
    sa, sb, sc = (float(np.linalg.norm(X)) or 1.0 for X in (A, B, C))
    r = LTI(A / sa, B / sb, C / sc, np.zeros((p, m))).minreal(used, job="M", equil="N")
    return sa * r.A, sb * r.B, sc * r.C, used


def _opt(X, name: str, rows: int, cols: int | None) -> np.ndarray:
    if X is None or (np.size(X) == 0):
        if cols is None and np.ndim(X) == 2 and np.shape(X)[0] == rows:
            cols = np.shape(X)[1]  # an empty (0 x m) input matrix of a static plant keeps its m columns
        return np.zeros((rows, cols or 0))
    return _matrix(X, name, rows=rows, cols=cols)


def _names(names, count: int, group: str, prefix: str) -> list[str]:
    if names is None:
        return [f"{prefix}{i}" for i in range(count)]
    names = list(names)
    if len(names) != count:
        raise ModelError(f"{len(names)} names given for {group} but the matrices have {count} {group} channels")
    for nm in names:
        check_signal_name(nm, f"signal ({group})")
    return names


def _sanitize(label: str) -> str:
    out = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in str(label)).strip("_")
    if not out or out[0].isdigit():
        out = "s_" + out
    return out


_FAULT_KEYS = {"name", "kind", "description", "input", "output", "Bf", "Df", "dA", "dB", "dC"}


def _check_format(d, source: str) -> None:
    """``format`` is one this version reads; ``arrays`` (a sidecar) only with ``fmu-fdi-model/2``."""
    if isinstance(d, dict) and d.get("format") == FORMAT_SIDECAR:
        return
    if isinstance(d, dict) and d.get("format") not in (None, FORMAT):
        raise ModelError(f"{source}: unsupported format {d['format']!r}; this version reads {FORMAT!r} and "
                         f"{FORMAT_SIDECAR!r} (matrices in a sidecar)")
    check_format(d, FORMAT, source, ModelError)
    if "arrays" in d:
        raise ModelError(f"{source}: a sidecar ([arrays]) needs format = {FORMAT_SIDECAR!r}, got {FORMAT!r}")


def _checked_array(value: np.ndarray, where: str) -> None:
    """A matrix given as an array (read from a sidecar, or a design held in memory): real numbers,
    finite and within the range of a file's numbers, checked at numpy speed."""
    if value.dtype.kind not in "fiu" or value.ndim not in (1, 2):
        raise ModelError(f"{where} must be an array of real numbers (a matrix or one column), got {value.dtype} "
                         f"of shape {value.shape}")
    sidecar.finite(value, where, ModelError)


def _check_model_dict(d, source: str) -> None:
    """Types of every value of a model file, before anything is converted (nothing is
    coerced: ``dt = "0.5"``, ``dt = true`` or ``"1e-3"`` in a matrix are errors). Matrices
    read from a sidecar arrive as float64 arrays already checked entry by entry."""
    _check_format(d, source)
    S.check_depth(d, source, ModelError)
    check_keys(d, (), _TOP_KEYS, source, ModelError)
    minreal_option(d.get("minimal"), d.get("minreal_tol"), f"{source}: ")
    for key in ("name", "description"):
        if key in d:
            S.text(d[key], f"{source}: {key}", ModelError, empty=key == "description")
    if "dt" in d:
        dt = S.real(d["dt"], f"{source}: dt", ModelError)
        if dt < 0:
            raise ModelError(f"{source}: dt must be 0 (continuous) or a positive sample time, got {dt!r}")
    sig = d.get("signals")
    if not isinstance(sig, dict) or "y" not in sig:
        raise ModelError(f"{source}: [signals] with at least 'y' is required")
    bad = set(sig) - {"u", "y", "d", "w"}
    if bad:
        raise ModelError(f"{source}: unknown signal groups {sorted(map(str, bad))}; use u, y, d, w")
    for key, names in sig.items():
        S.names(names, f"{source}: signals.{key}", ModelError)
    for table in ("units", "declared_types"):
        if table in d:
            for key, unit in S.table(d[table], f"{source}: {table}", ModelError).items():
                S.text(unit, f"{source}: {table}.{key}", ModelError, empty=True)
    if "type_definitions" in d:
        for key, attrs in S.table(d["type_definitions"], f"{source}: type_definitions", ModelError).items():
            for att, value in S.table(attrs, f"{source}: type_definitions.{key}", ModelError).items():
                S.text(value, f"{source}: type_definitions.{key}.{att}", ModelError, empty=True)
    if "operating_point" in d:
        op = S.table(d["operating_point"], f"{source}: operating_point", ModelError)
        for key in ("u", "y"):
            if key in op:
                S.vector(op[key], f"{source}: operating_point.{key}", ModelError)
    mats = d.get("matrices")
    if not isinstance(mats, dict):
        raise ModelError(f"{source}: [matrices] is required, got {S.type_name(mats)}")
    bad = set(mats) - _MATRIX_KEYS
    if bad:
        raise ModelError(f"{source}: unknown matrices {sorted(map(str, bad))}; allowed: {sorted(_MATRIX_KEYS)}")
    for key in ("A", "C"):
        if key not in mats:
            raise ModelError(f"{source}: matrix {key} is required")
    if sig.get("u") and "Bu" not in mats:
        raise ModelError(f"{source}: matrix Bu is required when there are inputs u")
    A = mats["A"]
    n = len(A) if isinstance(A, np.ndarray) else len(S.array(A, f"{source}: matrix A", ModelError))
    p, m = len(sig["y"]), len(sig.get("u", []))
    nd, nw = len(sig.get("d", [])), len(sig.get("w", []))
    shapes = {"A": (n, n), "Bu": (n, m), "C": (p, n), "Du": (p, m), "Bd": (n, nd), "Dd": (p, nd),
              "Bw": (n, nw), "Dw": (p, nw)}
    for key, value in mats.items():
        rows, cols = shapes[key]
        if isinstance(value, np.ndarray):
            _checked_array(value, f"{source}: matrix {key}")
            if value.shape != (rows, cols):
                raise ModelError(f"{source}: matrix {key} must be {rows}x{cols}, got shape {value.shape}")
            continue
        S.matrix(value, f"{source}: matrix {key}", ModelError, cols=cols)
        if len(value) != rows and not (not value and cols == 0):
            raise ModelError(f"{source}: matrix {key} must be {rows}x{cols}, got {len(value)} rows")
    faults = S.array(d.get("faults", []), f"{source}: faults", ModelError)
    for i, f in enumerate(faults):
        where = f"{source}: faults[{i}]"
        S.table(f, where, ModelError)
        for key in ("name", "kind"):
            if key not in f:
                raise ModelError(f"{where} needs '{key}'")
        name = S.text(f["name"], f"{where}.name", ModelError)
        where = f"{source}: fault '{name}'"
        S.text(f["kind"], f"{where}: kind", ModelError)
        for key in ("input", "output", "description"):
            if key in f:
                S.text(f[key], f"{where}: {key}", ModelError, empty=key == "description")
        for key in ("Bf", "Df", "dA", "dB", "dC"):
            if key in f:
                value = f[key]
                if isinstance(value, np.ndarray):
                    _checked_array(value, f"{where}: {key}")  # the fault checks its shape
                    continue
                if isinstance(value, list) and value and not isinstance(value[0], list):
                    S.vector(value, f"{where}: {key}", ModelError)  # one column written as a list
                else:
                    S.matrix(value, f"{where}: {key}", ModelError)
