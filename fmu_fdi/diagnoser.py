"""The Diagnoser: residual generator + evaluation + thresholds + decision logic.

A ``Diagnoser`` is configuration (what to compute) around one numpy-only runtime
(:class:`~fmu_fdi.runtime.engine.DiagnoserRuntime`) that does the computing; the same
runtime runs inside the diagnostic FMU, so ``Diagnoser.step``/``run`` and the FMU give
the same numbers.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .analysis import structure_matrix
from .designfile import FORMAT, checked_design, read_design, save_design, validate_design
from .errors import DesignError
from .evaluation.selector import ThresholdDesign
from .generator import ResidualGenerator
from .lti import LTI
from .model import FDIModel
from .outpath import copied
from .runtime.engine import DiagnoserRuntime, output_type

DEFAULT_EVALUATION = {"kind": "rms", "window": 10}


def _lti_dict(Q: LTI) -> dict:
    return {"A": Q.A.tolist(), "B": Q.B.tolist(), "C": Q.C.tolist(), "D": Q.D.tolist()}


def _threshold_spec(t) -> dict:
    if isinstance(t, ThresholdDesign):
        return dict(t.spec)
    if isinstance(t, (int, float, np.floating, np.integer)):
        return {"kind": "fixed", "value": float(t)}
    if isinstance(t, dict):
        return dict(t)
    if hasattr(t, "value"):  # a statistical threshold estimate
        return {"kind": "fixed", "value": float(t.value)}
    raise DesignError(f"a threshold must be a number, a spec dict or a ThresholdDesign, got {type(t).__name__}")


class Diagnoser:
    """Residual generator, evaluation functions, thresholds and isolation logic.

    Parameters
    ----------
    generator : ResidualGenerator, ResidualBank or RLSEstimator
        A continuous generator needs ``Ts`` (it is discretised exactly with a zero-order
        hold and kept for re-discretisation at other step sizes).
    Ts : float, optional
        Sample time of the diagnosis (defaults to the generator's).
    evaluation : dict or list of dict
        Evaluator spec(s), one for all groups or one per residual group
        (default ``{"kind": "rms", "window": 10}``).
    thresholds : number, dict, ThresholdDesign, or a list of these (one per group)
        Required: fixed values, runtime specs, or results of the threshold designers.
    decision : dict, optional
        ``persistence`` ([k, n]), ``latch`` (bool), ``isolation`` ('auto', 'structure',
        'direction', 'none'), ``structure`` (groups × faults; default: the generator's weak
        structure matrix), ``min_margin`` for directional isolation (radians).
    groups : 'each' or list of list of int, optional
        Regroup the residuals for evaluation (default: the generator's groups, e.g. one
        group per bank member); 'each' evaluates every residual on its own.
    name : str, optional
    valid_range : dict, optional
        ``{signal name: (lo, hi)}`` in the signal's units (None for an unbounded side): a
        sample outside is rejected like a NaN (``input_invalid``), so that a sensor glitch
        (e.g. an overflowing 1e300) never reaches the generator (docs/semantics.md §3).

    Examples
    --------
    >>> import numpy as np
    >>> from fmu_fdi import FDIModel, sensor_fault, nullspace_design, Diagnoser
    >>> m = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0], [1.0]], faults=[sensor_fault("s", "y0")])
    >>> dg = Diagnoser(nullspace_design(m, poles=[-2.0]), Ts=0.1, thresholds=0.1)
    >>> out = dg.run(np.arange(5) * 0.1, np.ones((5, 1)), np.zeros((5, 2)))
    >>> out.dtype.names[:2]
    ('time', 'residual_1')
    """

    def __init__(self, generator, *, Ts: float | None = None, evaluation=None, thresholds=None,
                 decision: dict | None = None, groups=None, name: str | None = None,
                 valid_range: dict | None = None):
        if thresholds is None:
            raise DesignError("thresholds are required: give a number per residual group, a spec, or a threshold "
                              "design (threshold_selector, analytic_threshold, data_driven_threshold)")
        gen = generator if groups is None else _regrouped(generator, groups)
        cont = None
        if getattr(gen, "dt", 0.0) == 0.0:
            if Ts is None:
                raise DesignError("the generator is continuous: give the diagnosis sample time Ts")
            cont = gen
            gen = gen.to_discrete(Ts)
        else:
            if Ts is not None and abs(Ts - gen.dt) > 1e-12 * gen.dt:
                raise DesignError(f"Ts={Ts} differs from the discrete generator's sample time {gen.dt}")
            cont = getattr(gen, "continuous", None)
        self.generator = gen
        self.continuous = cont
        self.Ts = gen.dt
        model: FDIModel = gen.model
        groups = gen.groups
        ng = len(groups)
        evals = evaluation if isinstance(evaluation, list) else [evaluation or DEFAULT_EVALUATION] * ng
        evals = [_whitened(e, gen, grp) for e, grp in zip(evals, groups)]
        thrs = thresholds if isinstance(thresholds, list) else [thresholds] * ng
        if len(evals) != ng or len(thrs) != ng:
            raise DesignError(f"the generator has {ng} residual groups: give one evaluation and threshold each "
                              f"(got {len(evals)} and {len(thrs)})")
        self.design = self._build_design(gen, cont, model, [dict(e) for e in evals],
                                         [_threshold_spec(t) for t in thrs], dict(decision or {}), name)
        if valid_range:
            self.design["signals"]["valid_range"] = {k: _jsonable_range(v) for k, v in valid_range.items()}
        validate_design(self.design, "diagnoser")
        self.runtime = DiagnoserRuntime(self.design, checked=True)  # validated just above

    # ----------------------------------------------------------------- design
    def _build_design(self, gen, cont, model: FDIModel, evals, thrs, decision, name) -> dict:
        isolation = decision.pop("isolation", "auto")
        info = dict(getattr(gen, "info", {}))
        nf = len(model.faults)
        if isolation == "auto":
            if not isinstance(gen, ResidualGenerator):
                isolation = "none"  # no LTI internal form to read a structure from (e.g. RLS)
            elif "fault_directions" in info and nf:
                isolation = "direction"
            elif len(gen.groups) > 1 and nf:
                isolation = "structure"
            else:
                isolation = "none"
        dec = {"persistence": list(decision.pop("persistence", [1, 1])), "latch": bool(decision.pop("latch", False)),
               "isolation": isolation}
        if isolation == "structure":
            S = decision.pop("structure", None)
            if S is None:
                S = structure_matrix(gen)
            dec["structure"] = np.asarray(S, int).tolist()
        elif isolation == "direction":
            dirs = decision.pop("directions", info.get("fault_directions"))
            if dirs is None:
                raise DesignError("directional isolation needs fault directions (a fault detection filter design)")
            if isinstance(dirs, dict):  # {fault name: direction}; faults without one get a zero column
                cols = [np.asarray(dirs.get(f.name, np.zeros(gen.Q.p)), float) for f in model.faults]
                dirs = np.column_stack(cols)
            dec["directions"] = np.asarray(dirs, float).tolist()
            dec["min_margin"] = float(decision.pop("min_margin", 0.1))
        if decision:
            raise DesignError(f"unknown decision options {sorted(decision)}")
        units = {k: v for k, v in model.units.items()}
        return {
            "format": FORMAT,
            "name": name or f"{model.name}_{gen.method}",
            "created_by": f"fmu-fdi {_version()}",
            "signals": {"u": list(model.u_names), "y": list(model.y_names)},
            "units": units,
            "operating_point": {"u": model.u0.tolist(), "y": model.y0.tolist()},
            "faults": [{"name": f.name, "kind": f.kind, "description": f.description} for f in model.faults],
            "generator": {
                "method": gen.method, "dt": gen.dt, "discrete": gen.runtime_spec(),
                "continuous": _lti_dict(cont.Q) if isinstance(cont, ResidualGenerator) else None,
                "residual_names": list(gen.residual_names), "groups": [list(g) for g in gen.groups],
                "info": _jsonable_info(info),
            },
            "evaluation": [{"evaluator": e, "threshold": t} for e, t in zip(evals, thrs)],
            "decision": dec,
            "model": model.to_dict(),
        }

    # ------------------------------------------------------------------- run
    @property
    def output_names(self) -> list[str]:
        return list(self.runtime.names)

    @property
    def fault_names(self) -> list[str]:
        return [f["name"] for f in self.design["faults"]]

    def fault_name(self, index: int) -> str:
        """Name of an ``isolated_fault`` value: '' for 0, 'unknown' for -1."""
        if index == 0:
            return ""
        if index < 0:
            return "unknown"
        return self.fault_names[index - 1]

    def reset(self) -> None:
        self.runtime.reset()

    def _dtype(self) -> np.dtype:
        code = {"Boolean": "?", "Integer": "i4", "Real": "f8"}
        return np.dtype([("time", "f8")] + [(nm, code[output_type(nm)]) for nm in self.runtime.names])

    def step(self, u, y) -> dict:
        """Process one sample (docs/semantics.md); returns the FMU outputs by name, plus ``isolated_name``,
        ``isolation_status`` ('none', 'isolated', 'unknown', 'several') and
        ``isolation_margin`` (radians, directional isolation only)."""
        vals = self.runtime.advance(u, y)
        conv = {"Boolean": bool, "Integer": int, "Real": float}
        out = {nm: conv[output_type(nm)](v) for nm, v in zip(self.runtime.names, vals)}
        out["isolated_name"] = self.fault_name(out["isolated_fault"])
        out["isolation_status"] = self.runtime.decision.status
        out["isolation_margin"] = self.runtime.decision.margin
        return out

    def run(self, t, u, y, reset: bool = True) -> np.ndarray:
        """Process a record: ``t`` (N,), ``u`` (N × inputs), ``y`` (N × outputs).

        Returns a structured array with ``time`` and the FMU output names. The sample
        spacing must be uniform; a spacing other than Ts is served like an FMU
        communication step (sub-steps or exact re-discretisation). Identical to calling
        :meth:`step` on each row after :meth:`reset`.
        """
        t = np.asarray(t, float).ravel()
        N = t.size
        u = np.asarray(u, float).reshape(N, -1) if self.runtime.nu else np.zeros((N, 0))
        y = np.asarray(y, float).reshape(N, -1)
        if u.shape[1] != self.runtime.nu or y.shape[1] != self.runtime.ny:
            raise ValueError(f"u must be N x {self.runtime.nu} and y N x {self.runtime.ny}; got {u.shape}, {y.shape}")
        if reset:
            self.runtime.reset()
        h = None
        if N > 1:
            dt = np.diff(t)
            h = float(np.median(dt))
            if not np.all(np.abs(dt - h) <= 1e-9 * max(h, 1e-300)):
                raise ValueError("the sample times t must be uniformly spaced")
        out = np.zeros(N, dtype=self._dtype())
        out["time"] = t
        names = self.runtime.names
        rows = np.empty((N, len(names)))
        for k in range(N):
            rows[k] = self.runtime.advance(u[k], y[k], h)
        for j, nm in enumerate(names):
            out[nm] = rows[:, j]
        return out

    # ------------------------------------------------------------------ files
    def save(self, path) -> Path:
        """Write the versioned JSON design file (schema: docs/design-file.md)."""
        return save_design(self.design, path)

    @classmethod
    def load(cls, path) -> "Diagnoser":
        """Read a design file. The returned diagnoser runs exactly as the saved one;
        its ``generator`` is rebuilt from the embedded model when the design is LTI."""
        return cls._from_checked(*read_design(path))

    @classmethod
    def from_design(cls, design: dict) -> "Diagnoser":
        """A diagnoser of a design dict (validated here; a copy is kept, so the caller's dict may change)."""
        design = copied(design)
        return cls._from_checked(design, checked_design(design, "design"))

    @classmethod
    def _from_checked(cls, design: dict, model: FDIModel | None) -> "Diagnoser":
        """A diagnoser of a design validated by :func:`~fmu_fdi.designfile.checked_design`, which
        returned ``model`` (the embedded one); the diagnoser keeps ``design`` itself."""
        self = cls.__new__(cls)
        self.design = design
        self.runtime = DiagnoserRuntime(self.design, checked=True)  # validated by the caller
        self.Ts = float(design["generator"]["dt"])
        self.generator = self.continuous = None
        g = design["generator"]
        if model is not None and g["discrete"].get("kind") == "lti":
            Qd = LTI(g["discrete"]["A"], g["discrete"]["B"], g["discrete"]["C"], g["discrete"]["D"], self.Ts)
            md = model if model.is_discrete else model.discretize(self.Ts)
            self.generator = ResidualGenerator(Qd, md, g["method"], g["residual_names"], g["groups"], g.get("info"))
            if g.get("continuous") is not None and not model.is_discrete:
                c = g["continuous"]
                self.continuous = ResidualGenerator(LTI(c["A"], c["B"], c["C"], c["D"]), model, g["method"],
                                                    g["residual_names"], g["groups"], g.get("info"))
        return self


def _regrouped(gen, groups):
    if not isinstance(gen, ResidualGenerator):
        raise DesignError(f"residual groups can only be changed for LTI generators, not {type(gen).__name__}")
    groups = [[k] for k in range(gen.n_residuals)] if groups == "each" else [list(g) for g in groups]
    cont = gen.continuous
    if cont is not None:
        cont = ResidualGenerator(cont.Q, cont.model, cont.method, cont.residual_names, groups, cont.info)
    return ResidualGenerator(gen.Q, gen.model, gen.method, gen.residual_names, groups, gen.info, continuous=cont)


def _whitened(evaluation: dict, gen, group) -> dict:
    """Statistical tests on a discrete Kalman innovation use its whitening Σ^{-1/2} by default."""
    evaluation = dict(evaluation)
    info = getattr(gen, "info", {})
    if (evaluation.get("kind") in ("chi2", "cusum", "glr") and "W" not in evaluation and "sigma" not in evaluation
            and info.get("innovation_kind") == "covariance" and "whitening" in info):
        W = np.asarray(info["whitening"], float)
        evaluation["W"] = W[np.ix_(group, group)].tolist()
    return evaluation


def _jsonable_range(pair):
    """(lo, hi) with numpy numbers as floats and -inf / +inf as null (unbounded); anything else
    (NaN, strings, a wrong length) is left for the runtime to refuse with its message."""
    if not isinstance(pair, (list, tuple, np.ndarray)):
        return pair
    out = [float(b) if isinstance(b, (np.integer, np.floating)) else b for b in list(pair)]
    if len(out) == 2:
        out = [None if out[0] == -np.inf else out[0], None if out[1] == np.inf else out[1]]
    return out


def _version() -> str:
    from . import __version__

    return __version__


def _jsonable_info(info: dict) -> dict:
    from .designfile import _clean

    return _clean({k: v for k, v in info.items() if isinstance(v, (int, float, str, list, dict, bool, np.ndarray,
                                                                    np.floating, np.integer, type(None)))})
