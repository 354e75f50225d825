"""Linearisation of a model-exchange FMU (FMI 2 or FMI 3) at an operating point.

The FMU's continuous states x, the chosen inputs v = [u; d] and outputs y obey

    x' = f(x, v),    y = g(x, v).

At an operating point (x0, v0) the linear model of the deviations is

    dx' = A dx + B dv,   dy = C dx + D dv,   A = ∂f/∂x, B = ∂f/∂v, C = ∂g/∂x, D = ∂g/∂v,

and it describes the plant around a *steady state* only when f(x0, v0) = 0. With ``trim``
the states are found from the given inputs by solving f(x, v0) = 0 (Powell's hybrid method,
scipy.optimize.root, started from the FMU's initial states or the states given in ``at``).

Jacobians
---------
- When the FMU declares ``providesDirectionalDerivative(s)``, column j of [A B; C D] is the
  directional derivative along the unit seed e_j (exact up to the FMU's own arithmetic).
- Otherwise central differences, column j = (F(z + h_j e_j) − F(z − h_j e_j)) / (2 h_j) with
  ``h_j = eps^(1/3) · max(|z_j|, nominal_j)`` (nominal: the FMU's state nominals, the
  variable's ``nominal`` attribute for inputs, 1 by default). This step balances the
  truncation error h²/6 |F'''| against the rounding error eps |F| / h: both are of order
  eps^(2/3) ≈ 4e-11 relative to the scale of F, far below any modelling error.
  ``h_j`` is rounded so that z_j ± h_j are exact machine numbers.

Trim tolerance: the steady state is accepted when
``max|f(x, v0)| <= trim_tol · (|A||x| + |B||v0| + 1)`` (∞-norms) — the derivative is small
next to the terms that cancel in it; default ``trim_tol = 1e-9``.
"""
from __future__ import annotations

import contextlib
import ctypes
import shutil
import tempfile
from dataclasses import dataclass, field

import numpy as np

from ..cosim.elements import Element, Packed, element_names, refused_array, shape, variables_by_name
from .errors import IdentificationError

_EPS_STEP = np.finfo(float).eps ** (1.0 / 3.0)


@dataclass
class Linearisation:
    """Continuous-time A, B, C, D of a model-exchange FMU at an operating point.

    Attributes
    ----------
    A, B, C, D : ndarray
        Jacobians; B and D have one column per name in ``input_names`` (u then d).
    state_names, input_names, output_names : list of str
        The FMU's variable names.
    x0, v0, y0 : ndarray
        The operating point: states, inputs, outputs.
    derivative_residual : float
        max |f(x0, v0)| at the point (0 at an exact steady state).
    method : str
        ``"directional derivatives"`` or ``"central differences"``.
    trimmed : bool
        Whether the states were found by trimming.
    info : dict
        FMU name, GUID/instantiation token, FMI version.
    warning : str
        Without trim: the point is not a steady state (the largest derivative named), else "".
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: list
    input_names: list
    output_names: list
    x0: np.ndarray
    v0: np.ndarray
    y0: np.ndarray
    derivative_residual: float
    method: str
    trimmed: bool
    info: dict = field(default_factory=dict)
    warning: str = ""


class _MEInstance:
    """A model-exchange instance in continuous-time mode: f and g evaluated at any (x, v)."""

    def __init__(self, path, md, unzipdir, parameters):
        from fmpy.fmi2 import FMU2Model
        from fmpy.fmi3 import FMU3Model

        self.md = md
        self.v3 = md.fmiVersion.startswith("3")
        cls = FMU3Model if self.v3 else FMU2Model
        guid = md.instantiationToken if self.v3 else md.guid
        self.fmu = cls(guid=guid, unzipDirectory=unzipdir, modelIdentifier=md.modelExchange.modelIdentifier,
                       instanceName="linearise")
        self.vars = variables_by_name(md)  # FMI 3 array elements 'u[1]' too (cosim/elements.py)
        self.fmu.instantiate()
        if not self.v3:
            self.fmu.setupExperiment(startTime=0.0)
        self.set(parameters)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        for _ in range(100):  # event iteration to a consistent point
            more = (self.fmu.updateDiscreteStates() if self.v3 else self.fmu.newDiscreteStates())[0]
            if not more:
                break
        self.fmu.enterContinuousTimeMode()
        ders = md.derivatives  # the continuous-state order is the order of the derivatives
        self.der_vrs = [u.variable.valueReference for u in ders]
        self.state_names = []
        # an FMI 3 array derivative holds one state per element (FMI 3.0 sec. 2.4.7.1.2), named x[i]
        sizes = [array_size(md, u.variable) for u in ders]
        self.arrays = any(u.variable.dimensions for u in ders)
        for u, size in zip(ders, sizes):
            state = u.variable.derivative
            name = state.name if state is not None else f"x{len(self.state_names)}"
            self.state_names += [name] if not u.variable.dimensions else [f"{name}[{i + 1}]" for i in range(size)]
        self.nx = len(self.state_names)
        self._x = (ctypes.c_double * max(self.nx, 1))()
        self._dx = (ctypes.c_double * max(self.nx, 1))()

    def vr(self, name):
        return self.vars[name].valueReference

    def set(self, values: dict):
        for name, val in values.items():
            vr = [self.vr(name)]
            v = self.vars[name]
            if isinstance(v, Element):  # an array is set whole, the other elements at their start values
                Packed([v], held=values).set(self.fmu.setFloat64, [float(val)])
            elif v.type in ("Real", "Float64", "Float32"):
                (self.fmu.setFloat64 if self.v3 else self.fmu.setReal)(vr, [float(val)])
            elif v.type == "Boolean":
                self.fmu.setBoolean(vr, [bool(val)])
            else:
                (self.fmu.setInt32 if self.v3 else self.fmu.setInteger)(vr, [int(val)])

    def get(self, vrs) -> np.ndarray:
        return np.array((self.fmu.getFloat64 if self.v3 else self.fmu.getReal)(list(vrs)), float)

    def states(self) -> np.ndarray:
        if self.nx == 0:
            return np.zeros(0)
        self.fmu.getContinuousStates(self._x, self.nx)
        return np.array(self._x[: self.nx])

    def nominals(self) -> np.ndarray:
        if self.nx == 0:
            return np.zeros(0)
        self.fmu.getNominalsOfContinuousStates(self._x, self.nx)
        return np.abs(np.array(self._x[: self.nx]))

    def evaluate(self, x, v, in_vrs, out_vrs):
        """(f(x, v), g(x, v)); ``in_vrs``/``out_vrs`` value references, or :class:`Packed` when
        FMI 3 array elements are among them."""
        if isinstance(in_vrs, Packed):
            in_vrs.set(self.fmu.setFloat64, v)
        elif len(in_vrs):
            (self.fmu.setFloat64 if self.v3 else self.fmu.setReal)(list(in_vrs), [float(a) for a in v])
        if self.nx:
            self._x[: self.nx] = [float(a) for a in x]
            self.fmu.setContinuousStates(self._x, self.nx)
            if self.v3:
                self.fmu.getContinuousStateDerivatives(self._dx, self.nx)
            else:
                self.fmu.getDerivatives(self._dx, self.nx)
        f = np.array(self._dx[: self.nx], float)
        if isinstance(out_vrs, Packed):
            return f, np.array(out_vrs.get(lambda r, n: self.fmu.getFloat64(r, nValues=n)), float)
        return f, self.get(out_vrs) if len(out_vrs) else np.zeros(0)

    def directional(self, unknowns, knowns, seed) -> np.ndarray:
        return np.array(self.fmu.getDirectionalDerivative(list(unknowns), list(knowns), list(seed)), float)

    def close(self):
        with contextlib.suppress(Exception):
            self.fmu.terminate()
        with contextlib.suppress(Exception):
            self.fmu.freeInstance()


def array_size(md, v) -> int:
    """Number of elements of an FMI 3 array variable (1 for a scalar): the product of its
    dimensions, each a fixed ``start`` or the start value of the fixed structural parameter it
    names (:func:`fmu_fdi.cosim.elements.shape`; a variable dimension is an IdentificationError)."""
    try:
        return int(np.prod(shape(md, v), dtype=int)) if v.dimensions else 1
    except ValueError as exc:
        raise IdentificationError(str(exc)) from None


def read_description(path):
    """fmpy's model description of ``path`` or an IdentificationError naming the file."""
    from fmpy import read_model_description

    try:
        return read_model_description(str(path), validate=False)
    except Exception as exc:  # fmpy raises bare Exceptions for broken archives and XML
        raise IdentificationError(f"{path}: cannot read modelDescription.xml: {exc}") from None


def check_names(md, path, names, what, causalities) -> list:
    """Every name is a Real variable of one of ``causalities``; the message lists what exists."""
    import difflib

    refused = {}
    by_name = variables_by_name(md, refused)
    out = []
    for nm in names:
        v = by_name.get(nm)
        why = refused_array(nm, refused) or (refused.get(nm) if v is not None and v.dimensions else None)
        if why is not None:
            raise IdentificationError(f"{path}: {what} {nm!r}: {why}")
        if v is not None and v.dimensions:
            els = element_names(nm, shape(md, v))
            raise IdentificationError(f"{path}: {what} {nm!r} is an FMI 3 array variable ({len(els)} elements): "
                                      f"a model signal is one element, name them: {' '.join(els)}")
        if v is None or v.causality not in causalities or v.type not in ("Real", "Float64"):
            pool = [w.name for w in md.modelVariables if w.causality in causalities
                    and w.type in ("Real", "Float64")]
            near = difflib.get_close_matches(nm, pool, n=3)
            hint = f" (did you mean {', '.join(near)}?)" if near else ""
            found = "no such variable" if v is None else f"it is a {v.type} {v.causality}"
            raise IdentificationError(f"{path}: {what} {nm!r} is not a Real {'/'.join(causalities)} of the FMU "
                                      f"({found}){hint}; it has {pool}")
        out.append(nm)
    return out


def _signals(path, md, inputs, outputs, disturbances, at, parameters):
    """Stage of :func:`linearise`: the inputs, disturbances and outputs named (or the FMU's Real
    ones), and ``at`` split into parameters, held (event-only) inputs and the operating point.
    Returns ``(u_names, d_names, y_names, v_names, by_name, at, parameters, held)``."""
    # continuous Real inputs can be perturbed; discrete-variability, Integer and Boolean inputs change only
    # at events (FMI 2.0.4 sec. 3.2.3, FMI 3.0 sec. 3.2.3): they are held at their values (``at`` or start)
    # an FMI 3 array is the vector of its elements y[1], y[2], ... (fmu_fdi/cosim/elements.py)
    refused = {}
    scalars = [v for v in variables_by_name(md, refused).values() if not v.dimensions]
    real_in = [v.name for v in scalars if v.causality == "input" and v.type in ("Real", "Float64")
               and v.variability in (None, "continuous")]
    real_out = [v.name for v in scalars if v.causality == "output" and v.type in ("Real", "Float64")]
    io = {v.name for v in md.modelVariables if v.causality in ("input", "output")}
    arrays = [f"{k}: {why}" for k, why in refused.items() if k in io]
    d_names = check_names(md, path, list(disturbances), "disturbance", ("input",))
    u_names = (check_names(md, path, list(inputs), "input", ("input",)) if inputs is not None
               else [n for n in real_in if n not in d_names])
    y_names = check_names(md, path, list(outputs), "output", ("output",)) if outputs is not None else real_out
    if not y_names:
        raise IdentificationError(f"{path}: no outputs to linearise (the FMU has no Real outputs"
                                  + (f"; arrays of variable dimension are refused: {arrays})" if arrays else ")"))
    at = dict(at or {})
    by_name = variables_by_name(md)
    unknown = [k for k in at if k.split("[")[0] not in by_name]  # x[i]: an element of an array state
    if unknown:
        raise IdentificationError(f"{path}: operating-point values for unknown variables {unknown}")
    parameters = dict(parameters or {})
    for k in [k for k in at if k in by_name and by_name[k].causality in ("parameter", "calculatedParameter",
                                                                        "structuralParameter")]:
        parameters[k] = at.pop(k)
    v_names = u_names + d_names
    held_only = [n for n in v_names if n not in real_in]
    if held_only:
        kinds = ", ".join(f"{n} ({by_name[n].type}, {by_name[n].variability or 'continuous'})" for n in held_only)
        raise IdentificationError(f"{path}: inputs {kinds} change only at events, so a linearisation cannot "
                                  f"perturb them; they are held at their values: give them with at=... "
                                  f"(--at NAME=VALUE) and leave them out of the inputs")
    held = {k: at.pop(k) for k in [k for k in at if k in by_name and by_name[k].causality == "input"
                                   and k not in v_names]}
    return u_names, d_names, y_names, v_names, by_name, at, parameters, held


def _equations(inst, state_vars, in_vrs, out_vrs, nominal_x, nominal_v, use_dd):
    """Stage of :func:`linearise`: ``F(x, v) = [ẋ; y]`` of the instance and its Jacobian
    ``[∂F/∂x ∂F/∂v]`` (directional derivatives, or central differences scaled by the nominals)."""
    def F(x, v):
        f, g = inst.evaluate(x, v, in_vrs, out_vrs)
        return np.concatenate([f, g])

    def jac(x, v):
        if use_dd:
            knowns = [sv.valueReference for sv in state_vars] + in_vrs
            unknowns = inst.der_vrs + out_vrs
            inst.evaluate(x, v, in_vrs, out_vrs)  # the point the derivatives are taken at
            cols = []
            for j in range(len(knowns)):
                seed = np.zeros(len(knowns))
                seed[j] = 1.0
                cols.append(inst.directional(unknowns, knowns, seed))
            return np.column_stack(cols) if cols else np.zeros((len(unknowns), 0))
        z = np.concatenate([x, v])
        scale = np.concatenate([nominal_x, nominal_v])
        cols = []
        for j in range(z.size):
            h = _EPS_STEP * max(abs(z[j]), scale[j] if scale[j] > 0 else 1.0)
            zp, zm = z.copy(), z.copy()
            zp[j] += h
            zm[j] -= h
            h2 = zp[j] - zm[j]  # the step actually taken, exactly representable
            nx = x.size
            cols.append((F(zp[:nx], zp[nx:]) - F(zm[:nx], zm[nx:])) / h2)
        return np.column_stack(cols) if cols else np.zeros((inst.nx + len(out_vrs), 0))

    return F, jac


def linearise(path, inputs=None, outputs=None, disturbances=(), *, at=None, trim: bool = True,
              parameters=None, directional: str | bool = "auto", trim_tol: float = 1e-9) -> Linearisation:
    """Linearise a model-exchange FMU at an operating point (see the module docstring).

    Parameters
    ----------
    path : str or Path
        An FMI 2.0 or 3.0 FMU with a model-exchange interface.
    inputs, outputs : list of str, optional
        Real inputs u and outputs y (default: all Real inputs not in ``disturbances``; all
        Real outputs).
    disturbances : list of str
        Real inputs d (unknown inputs of the FDI model); their columns follow u's in B, D.
    at : dict, optional
        Values of inputs (default their start values), of states (default the FMU's
        initial states, the trim's starting guess) and of parameters.
    trim : bool
        Find the steady state f(x, v0) = 0 from the given inputs; states named in ``at``
        are then only the starting guess. Without trim, the FMU is linearised at the given
        (or initial) states as they are.
    parameters : dict, optional
        Parameter values set before initialisation.
    directional : 'auto', True or False
        Use the FMU's directional derivatives ('auto': when it provides them).
    trim_tol : float
        Relative steady-state tolerance (module docstring).

    Raises
    ------
    IdentificationError
        No model-exchange interface, unknown names, directional derivatives required but not
        provided, or no steady state found (with the residual and what to change).
    """
    from fmpy import extract

    md = read_description(path)
    if md.fmiVersion not in ("2.0", "3.0"):
        raise IdentificationError(f"{path} is FMI {md.fmiVersion}; linearisation reads FMI 2.0 and 3.0")
    if md.modelExchange is None:
        raise IdentificationError(f"{path} has no model-exchange interface: identify it from an experiment "
                                  f"instead (method='identify')")
    u_names, d_names, y_names, v_names, by_name, at, parameters, held = _signals(path, md, inputs, outputs,
                                                                                 disturbances, at, parameters)
    provides = _provides_directional(path, md)
    if directional is True and not provides:
        raise IdentificationError(f"{path} does not provide directional derivatives; use directional='auto'")
    use_dd = provides and directional is not False
    unzipdir = extract(str(path), tempfile.mkdtemp(prefix="fmu_fdi_lin_"))
    inst = None
    try:
        try:
            inst = _MEInstance(path, md, unzipdir, {**parameters, **held})
        except Exception as exc:
            raise IdentificationError(f"{path}: the FMU failed to instantiate/initialise for linearisation: "
                                      f"{exc}") from None
        elements = any(isinstance(by_name[n], Element) for n in v_names + y_names)
        if (inst.arrays or elements) and use_dd:  # arrays are seeded per variable, not per element: differences
            if directional is True:
                raise IdentificationError(f"{path}: its states or signals are FMI 3 arrays; directional derivatives are "
                                          f"seeded per element only with central differences (directional='auto')")
            use_dd = False
        state_vars = [by_name.get(n) for n in inst.state_names]
        x0 = inst.states()
        for i, nm in enumerate(inst.state_names):
            if nm in at:
                x0[i] = float(at[nm])
        v0 = np.array([float(at[n]) if n in at else float(by_name[n].start or 0.0) for n in v_names])
        in_vrs = [by_name[n].valueReference for n in v_names]
        out_vrs = [by_name[n].valueReference for n in y_names]
        if elements:  # whole arrays set and read, the held elements at their values (cosim/elements.py)
            in_vrs, out_vrs = Packed([by_name[n] for n in v_names], held=held), Packed([by_name[n] for n in y_names])
        nominal_x = np.maximum(inst.nominals(), 1e-300) if inst.nx else np.zeros(0)
        nominal_v = np.array([abs(float(getattr(by_name[n], "nominal", None) or 1.0)) for n in v_names])

        F, jac = _equations(inst, state_vars, in_vrs, out_vrs, nominal_x, nominal_v, use_dd)
        if use_dd and any(sv is None for sv in state_vars):
            raise IdentificationError(f"{path}: a state derivative does not name its state (derivative "
                                      f"attribute); cannot seed directional derivatives")
        trimmed = False
        if trim and inst.nx:
            x0 = _trim(inst, F, jac, x0, v0, trim_tol, path, v_names)
            trimmed = True
        try:
            J = jac(x0, v0)
            f0, y0 = inst.evaluate(x0, v0, in_vrs, out_vrs)
        except Exception as exc:  # fmpy raises FMICallException (a bare Exception subclass) on a failed call
            raise IdentificationError(f"{path}: the FMU failed while being linearised at the operating point: "
                                      f"{exc}") from None
        nx = inst.nx
        A, B, C, D = J[:nx, :nx], J[:nx, nx:], J[nx:, :nx], J[nx:, nx:]
        if not np.all(np.isfinite(J)):
            raise IdentificationError(f"{path}: the Jacobian at the operating point is not finite (the FMU "
                                      f"returned NaN/inf): choose another point with at=...")
        info = {"fmu": md.modelName, "guid": (md.instantiationToken if inst.v3 else md.guid),
                "fmi_version": md.fmiVersion}
        warning = "" if trimmed else _not_steady(f0[:nx], A, B, x0, v0, trim_tol, inst.state_names)
        return Linearisation(A, B, C, D, list(inst.state_names), v_names, y_names, np.asarray(x0, float), v0,
                             y0, float(np.max(np.abs(f0), initial=0.0)),
                             "directional derivatives" if use_dd else "central differences", trimmed, info, warning)
    finally:
        if inst is not None:
            inst.close()
        shutil.rmtree(unzipdir, ignore_errors=True)


def _provides_directional(path, md) -> bool:
    """The model-exchange flag: FMI 2 ``providesDirectionalDerivative``, FMI 3 ``...Derivatives``
    (read from the XML: fmpy maps only the FMI 2 spelling)."""
    import zipfile
    import xml.etree.ElementTree as ET

    if md.modelExchange.providesDirectionalDerivative:
        return True
    try:
        with zipfile.ZipFile(path) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return False
    me = root.find("ModelExchange")
    flag = me.get("providesDirectionalDerivatives", me.get("providesDirectionalDerivative", "false")) if me is not None else "false"
    return flag.strip().lower() in ("true", "1")


def _not_steady(f0, A, B, x0, v0, tol, state_names) -> str:
    """A warning when the untrimmed point is not a steady state by the trim's own test
    (``max|f| > tol · (|A||x| + |B||v| + 1)``), naming the largest derivative; else ""."""
    f0 = np.asarray(f0, float)
    if not f0.size:
        return ""
    scale = (np.linalg.norm(A, np.inf) * np.linalg.norm(x0, np.inf)
             + (np.linalg.norm(B, np.inf) * np.linalg.norm(v0, np.inf) if B.size else 0.0) + 1.0)
    worst = float(np.max(np.abs(f0)))
    if worst <= tol * scale:
        return ""
    i = int(np.argmax(np.abs(f0)))
    return (f"not at a steady state (trim off): der({state_names[i]}) = {f0[i]:.4g} is the largest derivative "
            f"(> {tol:g}·{scale:.3g}); the model describes deviations around a moving point — trim, or give "
            f"states that are an equilibrium")


def _trim(inst, F, jac, x0, v0, tol, path, v_names):
    """Steady state f(x, v0) = 0 by Powell's hybrid method with the Jacobian ∂f/∂x."""
    from scipy.optimize import root

    nx = inst.nx

    def fun(x):
        return F(x, v0)[:nx]

    def fjac(x):
        return jac(x, v0)[:nx, :nx]

    try:
        sol = root(fun, x0, jac=fjac, method="hybr", options={"xtol": 1e-13, "maxfev": 200 * (nx + 1)})
        x = sol.x
    except Exception as exc:  # the FMU failing at a trial point
        raise IdentificationError(f"{path}: trimming failed while evaluating the FMU: {exc}") from None
    J = jac(x, v0)
    res = fun(x)
    scale = (np.linalg.norm(J[:nx, :nx], np.inf) * np.linalg.norm(x, np.inf)
             + np.linalg.norm(J[:nx, nx:], np.inf) * np.linalg.norm(v0, np.inf) + 1.0)
    worst = float(np.max(np.abs(res))) if res.size else 0.0
    if not np.all(np.isfinite(res)) or worst > tol * scale:
        i = int(np.nanargmax(np.abs(res)))
        raise IdentificationError(
            f"{path}: no steady state found for inputs "
            f"{dict(zip(v_names, np.round(v0, 6).tolist()))}: after {sol.nfev} evaluations "
            f"max|dx/dt| = {worst:.3g} (in der({inst.state_names[i]})) > {tol:g}·{scale:.3g}; "
            f"give other inputs or a starting guess for the states with at=..., or linearise "
            f"without trim at given states")
    return x
