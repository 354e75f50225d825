"""The door from a plant FMU to an FDIModel: linearise (model exchange) or identify (co-simulation).

Used by :meth:`fmu_fdi.FDIModel.from_fmu` and ``fmu-fdi model``. The model describes
deviations from the operating point ``(u0, y0)`` it carries; the disturbances' operating
values are absorbed in it (d is a deviation too). Its ``provenance`` records where it came
from: FMU name, GUID, method, and for identification the order, sample time, excitation and
the validation fit per output.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import IdentificationError
from .noise import check_noise_option

METHODS = ("auto", "linearise", "identify")


def _fault_list(spec, names, kind):
    from ..faults import actuator_fault, sensor_fault

    if spec is None or spec == [] or spec == ():
        return []
    chosen = list(names) if spec == "all" or spec == ["all"] else ([spec] if isinstance(spec, str) else list(spec))
    bad = [n for n in chosen if n not in names]
    if bad:
        raise IdentificationError(f"{kind} faults asked for {bad}, which are not model "
                                  f"{'outputs' if kind == 'sensor' else 'inputs'} {list(names)}")
    make = sensor_fault if kind == "sensor" else actuator_fault
    return [make(f"{kind}_{n}", n, description=f"additive {kind} fault on {n}") for n in chosen]


def model_from_fmu(path, inputs=None, outputs=None, disturbances=(), *, at=None, method: str = "auto",
                   trim: bool = True, sensor_faults=None, actuator_faults=None, ts: float | None = None,
                   excite=None, excitation=None, parameters=None, order: int | None = None,
                   max_order: int = 10, min_fit: float = 50.0, validation_png=None, name: str | None = None,
                   record=None, noise: str | None = None):
    """An :class:`~fmu_fdi.model.FDIModel` of a plant FMU (see the module docstring).

    Parameters
    ----------
    path : str or Path
        FMI 2.0 or 3.0 FMU.
    inputs, outputs, disturbances : list of str
        Model inputs u, outputs y and unknown inputs d, by FMU variable name. For
        linearisation inputs default to the FMU's Real inputs (not in d) and outputs to its
        Real outputs; identification needs inputs and outputs named.
    at : dict, optional
        Operating point: input values, parameter values, and (model exchange) state values
        (the trim's starting guess, or the point itself with ``trim=False``).
    method : {'auto', 'linearise', 'identify'}
        'auto': linearise when the FMU has a model-exchange interface, else identify.
    trim : bool
        Model exchange: find the steady state from the inputs.
    sensor_faults, actuator_faults : 'all', list of str or None
        Additive faults to add, named ``sensor_<y>`` / ``actuator_<u>``.
    ts : float, optional
        Identification: sample time of the experiment (default the FMU's default step).
        Linearisation: not used.
    excite, excitation, order, max_order
        Identification: FMU inputs to excite, an :class:`~fmu_fdi.identify.experiment.Excitation`
        (its seed drives the identification run, seed + 1 the validation run), the model
        order (default from the singular values) and the largest order considered.
    min_fit : float
        Identification: refuse a model whose validation fit (NRMSE %) on any output is below
        this; measurement noise alone caps the fit at 100 (1 − σ_noise / σ_y), so a low fit
        means too little excitation for the noise, or a plant far from linear at this amplitude.
    parameters : dict, optional
        FMU parameter values (also accepted in ``at``).
    validation_png : path, optional
        Identification: write the measured-vs-model plot of the validation run here.
    name : str, optional
        Model name (default the FMU's model name).
    record : path, optional
        Identification: write the identification run (time, u, d and y columns) as CSV here,
        a fault-free log for ``design --method data``.
    noise : {None, 'innovation', 'measurement'}
        Identification: add noise inputs ``w_<output>`` (unit white) learned from the data
        (:mod:`fmu_fdi.identify.noise`): 'innovation', the steady-state Kalman innovation form
        estimated on the estimation run (``Bw = K Lₑ``, ``Dw = Lₑ``, ``Lₑ Lₑᵀ = Re``);
        'measurement', output noise only (``Bw = 0``, ``Dw`` the Cholesky factor of the
        output-error covariance on the validation run). Default None: no noise inputs.
        The identified noise model is discrete (sample time ts); the continuous model's Bw is
        the exact inverse of its zero-order hold, like B, so ``model.discretize(ts)`` (and a
        design at ``--ts`` = ts) has exactly the identified noise model, w a unit white
        sequence held over each sample.

    Returns
    -------
    FDIModel
        Continuous-time, with ``operating_point`` and ``provenance``.
    """
    from .linearise import read_description

    path = Path(path)
    if not path.is_file():
        raise IdentificationError(f"no such FMU file: {path}")
    if method not in METHODS:
        raise IdentificationError(f"method must be one of {METHODS}, got {method!r}")
    check_noise_option(noise)
    md = read_description(path)
    if method == "auto":
        method = "linearise" if md.modelExchange is not None else "identify"
    if noise is not None and method != "identify":
        raise IdentificationError(f"{path}: noise={noise!r} needs identification from data (method='identify'); "
                                  f"a linearisation has no noise to learn from")
    at = dict(at or {})
    params = dict(parameters or {})
    by_name = {v.name: v for v in md.modelVariables}
    for k in list(at):
        v = by_name.get(k)
        if v is not None and v.causality in ("parameter", "calculatedParameter", "structuralParameter"):
            params[k] = at.pop(k)
    guid = getattr(md, "instantiationToken", None) or md.guid
    prov = {"fmu": path.name, "model_name": md.modelName, "guid": str(guid or ""), "fmi_version": md.fmiVersion}
    if params:
        prov["parameters"] = [f"{k}={v}" for k, v in params.items()]
    if method == "linearise":
        from .linearise import linearise

        lin = linearise(path, inputs, outputs, disturbances, at=at, trim=trim, parameters=params)
        nu = len(lin.input_names) - len(list(disturbances))
        u_names, d_names, y_names = lin.input_names[:nu], lin.input_names[nu:], lin.output_names
        A, B, C, D = lin.A, lin.B, lin.C, lin.D
        u0, y0 = lin.v0[:nu], lin.y0
        prov.update({"method": f"linearisation ({lin.method})", "trimmed": lin.trimmed,
                     "states": list(lin.state_names), "state_values": lin.x0.tolist(),
                     "derivative_residual": lin.derivative_residual})
        if len(d_names):
            prov["disturbance_values"] = lin.v0[nu:].tolist()
    else:
        from dataclasses import replace

        from .experiment import Excitation, run_experiment
        from .noise import innovation_noise, measurement_noise
        from .subspace import moesp
        from .validation import validate

        if md.coSimulation is None:
            raise IdentificationError(f"{path} has no co-simulation interface to run an experiment on")
        if not inputs or not outputs:
            raise IdentificationError(f"{path}: identification needs the model's inputs and outputs named "
                                      f"(inputs=..., outputs=... / --inputs, --outputs)")
        u_names, d_names, y_names = list(inputs), list(disturbances), list(outputs)
        if ts is None:
            ts = md.defaultExperiment.stepSize if md.defaultExperiment and md.defaultExperiment.stepSize else None
            if ts is None:
                raise IdentificationError(f"{path} declares no default step: give the sample time ts")
            ts = float(ts)
        exc = excitation or Excitation()
        sig = u_names + d_names
        runs = []
        for k in range(2):
            e = Excitation(**{**exc.__dict__, "seed": exc.seed + k})
            runs.append(run_experiment(path, sig, y_names, excite=excite, at=at, parameters=params, step=ts,
                                       excitation=e))
        ident, check = runs
        du, dy = ident.u - ident.u0, ident.y - ident.y0      # deviations from the operating point
        du_val, dy_val = check.u - check.u0, check.y - check.y0
        sub = moesp(du, dy, ts, order, max_order=max_order, feedthrough=False)
        A, B, C, D = sub.to_continuous()
        rep = validate(sub, du_val, dy_val, check.t, np.linalg.eigvals(A), y_names)
        nm = None
        if noise == "measurement":
            nm = measurement_noise(sub, rep.y, rep.y_hat, rep.kind)
        elif noise == "innovation":
            nm = innovation_noise(sub, du, dy, du_val, dy_val)
        if nm is not None:  # Bw: the inverse zero-order hold of the discrete K Lₑ, as for B
            Bw = replace(sub, B=np.hstack([sub.B, nm.Bw])).to_continuous()[1][:, sub.B.shape[1]:]
        if validation_png is not None:
            rep.plot(validation_png)
        if np.min(rep.fit) < min_fit:
            worst = int(np.argmin(rep.fit))
            raise IdentificationError(
                f"{path}: the identified model (order {sub.order}) fits the validation run poorly: "
                f"{', '.join(f'{n} {f:.1f} %' for n, f in zip(y_names, rep.fit))} (worst {y_names[worst]}, "
                f"minimum {min_fit:g} %); excite more strongly or more slowly (amplitude, signal='prbs' with a "
                f"longer period, more samples), switch measurement noise off if the FMU allows, or give the order")
        if record is not None:
            _write_record(record, ident, sig, y_names)
        nu = len(u_names)
        u0, y0 = ident.u0[:nu], ident.y0
        prov.update({"method": "subspace identification (PO-MOESP)", "order": sub.order, "sample_time": ts,
                     "block_rows": sub.block_rows, "samples": int(exc.samples),
                     "singular_values": sub.singular_values.tolist(),
                     "excitation": f"{exc.signal}, seed {exc.seed}, amplitudes "
                                   + ", ".join(f"{k}={v:g}" for k, v in ident.excited.items()),
                     "fit_percent": rep.fit.tolist(), "fit_kind": rep.kind,
                     "poles": [f"{p.real:.6g}{p.imag:+.6g}j" for p in rep.poles_continuous]})
        if nm is not None:
            prov.update(nm.provenance(y_names))
        if d_names:
            prov["disturbance_values"] = ident.u0[nu:].tolist()
    from ..model import FDIModel

    noise_kw = {} if noise is None else {"Bw": Bw, "Dw": nm.Dw, "w_names": list(prov["noise_inputs"])}
    nu = len(u_names)
    faults = _fault_list(sensor_faults, y_names, "sensor") + _fault_list(actuator_faults, u_names, "actuator")
    return FDIModel(A, B[:, :nu], C, D[:, :nu], Bd=B[:, nu:], Dd=D[:, nu:], faults=faults,
                    u_names=u_names, y_names=y_names, d_names=d_names,
                    name=_model_name(name or md.modelName), operating_point={"u": u0, "y": y0},
                    description=f"{prov['method']} of {path.name} at its operating point",
                    provenance=prov, **noise_kw)


def parse_values(items, option: str) -> dict:
    """``["Q1=21.4", "noise_enable=false"]`` → ``{"Q1": 21.4, "noise_enable": False}`` (numbers and Booleans)."""
    out = {}
    for item in items or []:
        key, sep, val = item.partition("=")
        low = val.strip().lower()
        try:
            out[key.strip()] = low == "true" if low in ("true", "false") else float(val)
        except ValueError:
            sep = ""
        if not sep or not key.strip():
            raise IdentificationError(f"{option} takes NAME=VALUE with a number or true/false, got {item!r}")
    return out


def summary(model) -> str:
    """One line: method, order, signals and the validation fit of a model made here."""
    prov = model.provenance
    fit = (", fit " + ", ".join(f"{n} {f:.1f} %" for n, f in zip(model.y_names, prov["fit_percent"]))
           if "fit_percent" in prov else "")
    return f"{prov.get('method', '?')}, n = {model.n}, u = {model.u_names}, y = {model.y_names}{fit}"


def _model_name(text):
    from ..model import _sanitize

    return _sanitize(text)


def _write_record(path, rec, sig, y_names):
    from ..cosim import Result

    names = ["time"] + list(sig) + list(y_names)
    res = Result.empty(names, ["real"] * len(names), len(rec.t))
    res["time"] = rec.t
    for j, nm in enumerate(sig):
        res[nm] = rec.u[:, j]
    for j, nm in enumerate(y_names):
        res[nm] = rec.y[:, j]
    res.to_csv(path)
