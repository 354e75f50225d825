"""The door from a plant FMU to an FDIModel: linearise (model exchange) or identify (co-simulation).

Used by :func:`fmu_fdi.identify.model_from_fmu` and ``fmu-fdi model``. The model describes
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
    from ..faults import actuator_fault, identifier_of, sensor_fault

    if spec is None or spec == [] or spec == ():
        return []
    chosen = list(names) if spec == "all" or spec == ["all"] else ([spec] if isinstance(spec, str) else list(spec))
    bad = [n for n in chosen if n not in names]
    if bad:
        raise IdentificationError(f"{kind} faults asked for {bad}, which are not model "
                                  f"{'outputs' if kind == 'sensor' else 'inputs'} {list(names)}")
    make = sensor_fault if kind == "sensor" else actuator_fault
    return [make(f"{kind}_{identifier_of(n)}", n, description=f"additive {kind} fault on {n}") for n in chosen]


def model_from_fmu(path, inputs=None, outputs=None, disturbances=(), *, at=None, method: str = "auto",
                   trim: bool = True, sensor_faults=None, actuator_faults=None, ts: float | None = None,
                   excite=None, excitation=None, parameters=None, order: int | None = None,
                   max_order: int = 10, min_fit: float = 50.0, validation_png=None, name: str | None = None,
                   record=None, noise: str | None = "auto", design: bool = True, log=None):
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
        Identification: sample time of the experiment (default chosen by the experiment design,
        the FMU's default step or a multiple of it). Linearisation: not used.
    excite, excitation, order, max_order
        Identification: FMU inputs to excite, an :class:`~fmu_fdi.identify.experiment.Excitation`
        (its seed drives the identification run, seed + 1 the validation run and its repeat;
        fields left at None are chosen by the experiment design), the model order (default
        from the singular values) and the largest order considered.
    design : bool
        Identification: choose what ``excitation`` and ``ts`` leave open from a pre-test
        (:mod:`fmu_fdi.identify.design`, default); False uses fixed fallbacks.
    log : callable, optional
        Receives the chosen experiment and the validation verdict as text (the CLI prints them).
    min_fit : float
        Identification: refuse a model whose fit to the noise-free response
        (:class:`~fmu_fdi.identify.validation.NoiseFloor`: the validation run repeated with
        another noise realisation gives the noise-only mismatch) is below this % on any output.
    parameters : dict, optional
        FMU parameter values (also accepted in ``at``).
    validation_png : path, optional
        Identification: write the measured-vs-model plot of the validation run here.
    name : str, optional
        Model name (default the FMU's model name).
    record : path, optional
        Identification: write the identification run (time, u, d and y columns) as CSV here,
        a fault-free log for ``design --method data``.
    noise : {'auto', None, 'innovation', 'measurement'}
        Identification: add noise inputs ``w_<output>`` (unit white) learned from the data
        (:mod:`fmu_fdi.identify.noise`): 'innovation', the steady-state Kalman innovation form
        estimated on the estimation run (``Bw = K Lₑ``, ``Dw = Lₑ``, ``Lₑ Lₑᵀ = Re``);
        'measurement', output noise only (``Bw = 0``, ``Dw`` the Cholesky factor of the
        output-error covariance on the validation run); None: no noise inputs. Default 'auto':
        'innovation' when the runs have noise (the noise floor's repeat run differs, or the
        settle phase shows it); else none, with a note to ``log`` (the misfit of a noise-free
        run is model error, not noise).
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
    if noise != "auto":
        check_noise_option(noise)
    md = read_description(path)
    if method == "auto":
        method = "linearise" if md.modelExchange is not None else "identify"
    if noise == "auto" and method != "identify":
        noise = None
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
    _start_values(md, at, params, path, method)
    guid = getattr(md, "instantiationToken", None) or md.guid
    prov = {"fmu": path.name, "model_name": md.modelName, "guid": str(guid or ""), "fmi_version": md.fmiVersion}
    if params:
        prov["parameters"] = [f"{k}={v}" for k, v in params.items()]
    if method == "linearise":
        u_names, d_names, y_names, A, B, C, D, u0, y0 = _linearised(path, inputs, outputs, disturbances, at, trim,
                                                                    params, prov, log)
    else:
        u_names, d_names, y_names, A, B, C, D, u0, y0, nm, Bw = _identified(
            path, md, inputs, outputs, disturbances, at=at, params=params, prov=prov, ts=ts, excite=excite,
            excitation=excitation, order=order, max_order=max_order, min_fit=min_fit,
            validation_png=validation_png, record=record, noise=noise, design=design, log=log)
        noise = nm.kind if nm is not None else None
    from ..model import FDIModel

    noise_kw = {} if noise is None else {"Bw": Bw, "Dw": nm.Dw, "w_names": list(prov["noise_inputs"])}
    nu = len(u_names)
    faults = _fault_list(sensor_faults, y_names, "sensor") + _fault_list(actuator_faults, u_names, "actuator")
    units, types = _signal_types(md, u_names + y_names + d_names)
    type_defs = _type_attributes(md, set(types.values()))
    return FDIModel(A, B[:, :nu], C, D[:, :nu], Bd=B[:, nu:], Dd=D[:, nu:], faults=faults,
                    u_names=u_names, y_names=y_names, d_names=d_names, units=units, declared_types=types,
                    type_definitions=type_defs,
                    name=_model_name(name or md.modelName), operating_point={"u": u0, "y": y0},
                    description=f"{prov['method']} of {path.name} at its operating point",
                    provenance=prov, **noise_kw)


def _start_values(md, at, params, path, method) -> None:
    """``at`` entries that are neither inputs (the operating point) nor, for a linearisation, states
    (the trim's guess) are start values set before initialisation (e.g. an output with
    ``initial="exact"``): moved to ``params`` when FMI lets a master set them
    (:func:`fmu_fdi.cosim.startvalues.refusal`, the one rule), else a one-line error."""
    from ..cosim.elements import ELEMENT, variables_by_name
    from ..cosim.startvalues import refusal

    by_name = variables_by_name(md)  # FMI 3 array elements 'x[1]' too
    states = set()
    if method == "linearise":
        states = {u.variable.derivative.name for u in (md.derivatives or [])
                  if getattr(u.variable, "derivative", None) is not None}
        states |= {k for k in at if ELEMENT.match(k) and ELEMENT.match(k).group("array") in states}
    for k in list(at):
        v = by_name.get(k)
        if v is None:
            raise IdentificationError(f"{path}: --at {k}: the FMU has no variable {k!r}")
        if v.causality == "input" or k in states:
            continue
        why = refusal(v)
        if why is not None:
            raise IdentificationError(f"{path}: --at {k}: cannot be set before initialisation: {k} {why}")
        params[k] = at.pop(k)


def _signal_types(md, names) -> tuple[dict, dict]:
    """The unit and declaredType of each signal, as the model description gives them (a variable's
    own ``unit``, else its type definition's)."""
    from ..cosim.elements import variables_by_name

    by_name = variables_by_name(md)  # an array element has its array's unit and type
    units, types = {}, {}
    for nm in names:
        v = by_name.get(nm)
        declared = getattr(v, "declaredType", None)
        unit = getattr(v, "unit", None) or getattr(declared, "unit", None)
        if unit:
            units[nm] = str(unit)
        if declared is not None and getattr(declared, "name", None):
            types[nm] = str(declared.name)
    return units, types


def _type_attributes(md, names: set) -> dict:
    """The ``quantity``, ``unit`` and ``displayUnit`` of each named type definition of the model
    description (the model file's ``[type_definitions]``)."""
    from ..model import TYPE_ATTRIBUTES

    out = {}
    for t in getattr(md, "typeDefinitions", None) or []:
        if getattr(t, "name", None) in names:
            out[str(t.name)] = {k: str(getattr(t, k)) for k in TYPE_ATTRIBUTES if getattr(t, k, None)}
    return out


def _linearised(path, inputs, outputs, disturbances, at, trim, params, prov, log):
    """Stage of :func:`model_from_fmu`: the model-exchange FMU linearised at ``at`` (``prov`` gets
    the method, trim and state values)."""
    from .linearise import linearise

    lin = linearise(path, inputs, outputs, disturbances, at=at, trim=trim, parameters=params)
    nu = len(lin.input_names) - len(list(disturbances))
    u_names, d_names, y_names = lin.input_names[:nu], lin.input_names[nu:], lin.output_names
    A, B, C, D = lin.A, lin.B, lin.C, lin.D
    u0, y0 = lin.v0[:nu], lin.y0
    if lin.warning:
        prov["warning"] = lin.warning
        if log is not None:
            log(f"warning: {lin.warning}")
    prov.update({"method": f"linearisation ({lin.method})", "trimmed": lin.trimmed,
                 "states": list(lin.state_names), "state_values": lin.x0.tolist(),
                 "derivative_residual": lin.derivative_residual})
    if len(d_names):
        prov["disturbance_values"] = lin.v0[nu:].tolist()
    return u_names, d_names, y_names, A, B, C, D, u0, y0


def _identified(path, md, inputs, outputs, disturbances, *, at, params, prov, ts, excite, excitation, order,
                max_order, min_fit, validation_png, record, noise, design, log):
    """Stage of :func:`model_from_fmu`: the co-simulation FMU identified from experiments (PO-MOESP,
    refined by output error on a stiff plant, validated on an independent run, with its noise
    model ``nm`` and continuous ``Bw`` when one is learned; ``prov`` gets the experiment and the
    validation figures)."""
    if md.coSimulation is None:
        raise IdentificationError(f"{path} has no co-simulation interface to run an experiment on")
    if not inputs or not outputs:
        raise IdentificationError(f"{path}: identification needs the model's inputs and outputs named "
                                  f"(inputs=..., outputs=... / --inputs, --outputs)")
    u_names, d_names, y_names = list(inputs), list(disturbances), list(outputs)
    sig = u_names + d_names
    ident, check, repeat, exc, plan, ts = _experiments(path, md, sig, y_names, at=at, params=params, ts=ts,
                                                       excite=excite, excitation=excitation, max_order=max_order,
                                                       design=design, log=log)
    sub, rep, joint = _estimated(ident, check, sig, y_names, ts, order, max_order)
    refined = None
    if joint is None:
        sub, rep, refined = _refined(sub, rep, ident, check, y_names, max_order)
    nm, Bw, floor, tests, why_none = _noise_and_tests(path, sub, rep, ident, check, repeat, joint, noise, max_order,
                                                      refined is not None)
    if validation_png is not None:
        rep.plot(validation_png)
    verdict = _verdict(y_names, rep, floor, tests, sub.order, exc, plan)
    if log is not None:
        log(verdict)
    _refuse_if_wrong(path, rep, floor, tests, sub, verdict, min_fit, exc, plan, y_names,
                     own_loop=set(ident.excited) != set(sig))
    if noise == "auto" and nm is None and log is not None:
        log(f"no noise model: {why_none}")
    if record is not None:
        _write_record(record, ident, sig, y_names)
    nu = len(u_names)
    u0, y0 = ident.u0[:nu], ident.y0 + (refined["offset"] if refined is not None else 0.0)
    A, B, C, D = sub.to_continuous()
    _identification_provenance(prov, sub, rep, floor, tests, exc, ident, ts, joint, refined)
    if nm is not None:
        prov.update(nm.provenance(y_names))
    if d_names:
        prov["disturbance_values"] = ident.u0[nu:].tolist()
    return u_names, d_names, y_names, A, B, C, D, u0, y0, nm, Bw


def _estimated(ident, check, sig, y_names, ts, order, max_order):
    """Stage of :func:`_identified`: the subspace model and its validation report ``(sub, rep, joint)``
    — joint input-output for a plant in its own loop (``joint`` its joint model, else None), else
    PO-MOESP with the order given or chosen by cross-validation."""
    from .subspace import moesp, static_model
    from .validation import validate

    du, dy = ident.u - ident.u0, ident.y - ident.y0      # deviations from the operating point
    du_val, dy_val = check.u - check.u0, check.y - check.y0
    excited = list(ident.excited)
    # a plant in its own loop (model inputs that are FMU outputs): the references as instruments
    own = [excited.index(n) if n in excited else None for n in sig] if set(excited) != set(sig) else None
    joint = None
    if own is not None and len(excited) == len(sig):
        from .closed_loop import identify_closed_loop, joint_outputs

        sub, joint = identify_closed_loop(ident.r, du, dy, check.r, du_val, dy_val, ts, own, order,
                                          max_order=max_order)
        A = sub.to_continuous()[0]
        # validated as what it is identified as: the closed loop from the references, simulated
        rep = validate(joint_outputs(joint, own), check.r, dy_val, check.t, np.linalg.eigvals(A), y_names,
                       kind="closed-loop simulation")
    elif order is None:
        sub, rep = _order_by_cross_validation(
            moesp(du, dy, ts, None, max_order=max_order, feedthrough=False, candidates=True)
            + [static_model(du, dy, ts)], du_val, dy_val, check.t, y_names)
    elif order == 0:
        sub = static_model(du, dy, ts)
        rep = validate(sub, du_val, dy_val, check.t, np.zeros(0), y_names)
    else:
        sub = moesp(du, dy, ts, order, max_order=max_order, feedthrough=False)
        rep = validate(sub, du_val, dy_val, check.t, np.linalg.eigvals(sub.to_continuous()[0]), y_names)
    return sub, rep, joint


def _refined(sub, rep, ident, check, y_names, max_order):
    """Stage of :func:`_identified`: on a stiff plant (the identified model's slowest time scale over
    its fastest above :data:`~fmu_fdi.identify.design.STIFF_RATIO`), the subspace model refined by
    the output-error criterion over the whole estimation run
    (:func:`~fmu_fdi.identify.output_error.refine_output_error`: PO-MOESP's window of s samples
    cannot resolve both ends), each output weighted by its noise in the settle phase. Kept when
    its simulation error on the validation run (mean over outputs of ||e_j||²/||y_j − ȳ_j||²) is
    smaller. Returns ``(sub, rep, info or None)``; ``info['offset']`` corrects the operating
    point's outputs (estimated over the whole run instead of the settle phase)."""
    from .design import STIFF_RATIO
    from .output_error import refine_output_error
    from .validation import settle_noise_std, validate

    if sub.order < 1 or sub.info.get("static") is not None or rep.kind != "simulation":
        return sub, rep, None
    lam = np.abs(rep.poles_continuous)  # the simulation report of sub carries its continuous poles
    if lam.min() <= 0 or lam.max() / lam.min() <= STIFF_RATIO:
        return sub, rep, None
    du, dy = ident.u - ident.u0, ident.y - ident.y0
    half = ident.settle_y[len(ident.settle_y) // 2:] if ident.settle_y is not None else np.zeros((0, dy.shape[1]))
    sigma = settle_noise_std(half, max_order) if len(half) > 1 else np.zeros(dy.shape[1])
    try:
        new, info = refine_output_error(sub, du, dy, sigma)
        A = new.to_continuous()[0]
    except IdentificationError:
        return sub, rep, None
    new_rep = validate(new, check.u - check.u0, check.y - check.y0, check.t, np.linalg.eigvals(A), y_names)
    if new_rep.kind != "simulation" or not _simulation_error(new_rep) < _simulation_error(rep):
        return sub, rep, None
    info.update(validation_error_before=_simulation_error(rep), validation_error_after=_simulation_error(new_rep))
    return new, new_rep, info


def _noise_and_tests(path, sub, rep, ident, check, repeat, joint, noise, max_order, refined=False):
    """Stage of :func:`_identified`: the noise floor, the noise model and Ljung's residual tests.
    A model ``refined`` by output error has a second innovation form, its own (K = 0,
    :func:`~fmu_fdi.identify.noise.output_error_noise`): the one whose predictor's innovations on the
    validation run are whiter (Ljung's test, worst output) is kept. Returns ``(nm, Bw, floor, tests,
    why_none)``."""
    from dataclasses import replace

    from .noise import innovation_noise, measurement_noise, output_error_noise, predictor_innovations
    from .validation import noise_floor, residual_tests, settle_noise_std, whiteness

    du, dy = ident.u - ident.u0, ident.y - ident.y0
    du_val, dy_val = check.u - check.u0, check.y - check.y0
    # the settle phase's noise about a settling transient (a noise-free plant still settling has none)
    half = check.settle_y[len(check.settle_y) // 2:]
    sigma = settle_noise_std(half, max_order) if len(check.settle_y) > 1 else None
    floor = noise_floor(dy_val, rep.y_hat, repeat.y - check.y0, sigma)
    # the innovation form is estimated whatever noise model is asked for: its innovations are what
    # the whiteness test judges
    nm, inn, why_none = None, None, None
    try:
        inn = innovation_noise(sub, du, dy, du_val, dy_val)
    except (IdentificationError, np.linalg.LinAlgError) as exc_:
        why_none = f"the innovation form cannot be estimated ({exc_}): is the run noise-free?"
        if noise == "innovation":
            raise IdentificationError(f"{path}: {why_none}") from None
    # noise: above round-off (1e-9 of the outputs' level)
    noisy = np.any(floor.noise_rms > 1e-9 * np.sqrt(np.mean(check.y ** 2, axis=0)))
    if noise == "measurement":
        nm = measurement_noise(sub, rep.y, rep.y_hat, rep.kind)
    elif noise == "innovation" or (noise == "auto" and noisy):
        nm = inn
    elif noise == "auto":  # what the innovation form would hold is model error (e.g. a nonlinearity), no noise
        why_none = ("the runs are noise-free (the validation run repeated with another noise seed came out "
                    "identical, and the outputs are constant at the operating point)")
    eps = None
    if inn is not None:
        drop = 2 * sub.block_rows * max(sub.order, 1)
        eps = predictor_innovations(sub, inn.K, du_val, dy_val, drop=drop)
        if refined:
            oe = output_error_noise(sub, du, dy, du_val, dy_val)
            eps_oe = predictor_innovations(sub, oe.K, du_val, dy_val, drop=drop)
            if np.max(whiteness(eps_oe)) < np.max(whiteness(eps)):
                inn, eps = oe, eps_oe
                if nm is not None and nm.kind == "innovation":
                    nm = oe
    # the output error of a plant in its own loop follows the measured u through the loop: judged against r
    tests = residual_tests(eps, dy_val - rep.y_hat, du_val if joint is None else check.r)
    Bw = None
    if nm is not None:  # Bw: the inverse zero-order hold of the discrete K Lₑ, as for B
        Bw = replace(sub, B=np.hstack([sub.B, nm.Bw])).to_continuous()[1][:, sub.B.shape[1]:]
    return nm, Bw, floor, tests, why_none


def _refuse_if_wrong(path, rep, floor, tests, sub, verdict, min_fit, exc, plan, y_names, own_loop):
    """Stage of :func:`_identified`: a one-line refusal of a model the validation shows wrong (an
    unstable model whose predictor validation flatters it while its residual tests fail; a fit to
    the noise-free response below ``min_fit`` on some output), naming the next thing to change."""
    if rep.kind == "one-step predictor" and not tests.independent and np.max(tests.whiteness) > 10:
        raise IdentificationError(
            f"{path}: the identified model (order {sub.order}) is unstable, so it is validated by its one-step "
            f"predictor, whose fit flatters it; its output error is correlated with past inputs and its own "
            f"innovations are far from white (over 10× the bound), so it is wrong: {verdict}; next: "
            + ("a plant in its own loop identified with noise is biased (its inputs follow the noise): excite "
               "more strongly (--amplitude) so the noise matters less, give --order, or switch the noise off "
               "if the FMU allows" if own_loop else
               _next_step(floor, tests, exc, plan, int(np.argmin(floor.floor)), y_names)))
    clean = np.nan_to_num(floor.fit_noise_free, nan=-np.inf)
    if np.min(clean) < min_fit:
        worst = int(np.argmin(clean))
        raise IdentificationError(
            f"{path}: the identified model (order {sub.order}) fits the validation run poorly: {verdict} "
            f"(worst {y_names[worst]}, minimum {min_fit:g} % of the noise-free response); next: "
            f"{_next_step(floor, tests, exc, plan, worst, y_names)}")


def _identification_provenance(prov, sub, rep, floor, tests, exc, ident, ts, joint, refined) -> None:
    """Stage of :func:`_identified`: the method, experiment and validation figures into ``prov``."""
    prov.update({"method": "subspace identification (PO-MOESP)", "order": sub.order, "sample_time": ts,
                 "block_rows": sub.block_rows, "samples": int(exc.samples),
                 "singular_values": sub.singular_values.tolist(),
                 "excitation": f"{exc.signal}" + (f" clock {exc.period}" if exc.signal == "prbs" else "")
                               + (f", slow clock {exc.slow_period}" if exc.slow_period is not None else "")
                               + f", seed {exc.seed}, settle {exc.settle if exc.settle is not None else 200 * ts:g} s, amplitudes "
                               + ", ".join(f"{k}={v:g}" for k, v in ident.excited.items()),
                 "fit_percent": rep.fit.tolist(), "fit_kind": rep.kind,
                 "floor_percent": floor.floor.tolist(), "fit_corrected_percent": floor.fit_noise_free.tolist(),
                 "floor_source": floor.source, "floor_rms": floor.noise_rms.tolist(),
                 "whiteness": tests.whiteness.tolist(), "independence": tests.independence.tolist(),
                 "residual_lags": tests.lags,
                 "poles": [f"{p.real:.6g}{p.imag:+.6g}j" for p in rep.poles_continuous]})
    if sub.info.get("static") is not None:
        prov["method"] = "static gain (least squares; order 0: no state)"
    if refined is not None:
        prov["method"] = ("subspace identification (PO-MOESP) refined by output-error prediction-error "
                          "minimisation (stiff plant)")
        prov.update({f"refinement_{k}": (np.asarray(v, float).tolist() if isinstance(v, np.ndarray) else
                                         float(v) if isinstance(v, (int, float)) else str(v))
                     for k, v in refined.items()})
    if joint is not None:
        prov.update({"method": "closed-loop subspace identification (joint input-output PO-MOESP, references "
                               "as instruments)", "joint_order": joint.order, "delays": sub.info["delays"]})


def _experiments(path, md, sig, y_names, *, at, params, ts, excite, excitation, max_order, design, log):
    """Stage of :func:`_identified`: the experiment (designed by a pre-test unless fully given) run
    three times: estimation, validation and the validation input with another noise realisation.
    Returns ``(estimation, validation, repeat, excitation, plan or None, ts)``."""
    from .experiment import Excitation, run_experiment

    user_ts = ts
    if ts is None:
        ts = md.defaultExperiment.stepSize if md.defaultExperiment and md.defaultExperiment.stepSize else None
        if ts is None:
            raise IdentificationError(f"{path} declares no default step: give the sample time ts")
        ts = float(ts)
    exc = excitation or Excitation()
    exc.check()
    if design and not _fully_given(exc, excite, sig, user_ts, md):
        from .design import plan_experiment

        plan = plan_experiment(path, sig, y_names, excite=excite, at=at, parameters=params, ts=user_ts,
                               step=ts, excitation=exc, max_order=max_order)
        exc, ts = plan.excitation, plan.ts
        if log is not None:
            log(plan.describe())
    else:
        exc, plan = exc.resolved(), None
    seed_param = _noise_seed_parameter(md, params)
    base = int(params.get(seed_param, 0) or 0) if seed_param else 0
    runs = []
    # estimation (excitation seed s), validation (s + 1) and the validation input repeated with
    # another noise realisation (the plant's noise seed + 2, when it has one) for the noise floor
    # (the estimation run of a designed experiment is checked for signal/noise instead of settling:
    # too weak a response, it is repeated stronger; the two later runs check the settling)
    for k, (es, ns) in enumerate(((0, 0), (1, 1), (1, 2))):
        p_k = dict(params, **({seed_param: base + ns} if seed_param else {}))
        adapt = k == 0 and plan is not None and bool(plan.limits)
        for _ in range(2 if adapt else 1):
            e = Excitation(**{**exc.__dict__, "seed": exc.seed + es})
            rec = run_experiment(path, sig, y_names, excite=excite, at=at, parameters=p_k, step=ts,
                                 excitation=e, noise_std=None if plan is None else
                                 [plan.noise_std[n] for n in y_names], check_settle=not adapt)
            stronger = plan.adapted(rec) if adapt else None
            if stronger is None:
                break
            exc = stronger
            if log is not None:
                log(f"  note: {plan.notes[-1]}")
        runs.append(rec)
    return (*runs, exc, plan, ts)


def _simulation_error(rep) -> float:
    """The mean over outputs of the normalised squared simulation error ``||e_j||² / ||y_j − ȳ_j||²`` of a
    validation report (the criterion of the order choice and of the output-error refinement)."""
    y, yh = rep.y, rep.y_hat
    return float(np.mean(np.sum((y - yh) ** 2, axis=0) / np.maximum(np.sum((y - y.mean(0)) ** 2, axis=0),
                                                                    np.finfo(float).tiny)))


def _order_by_cross_validation(cands, du_val, dy_val, t, y_names):
    """The order from the singular values, or a lower-error one on the validation run (Ljung 1999,
    sec. 16.4, cross-validation): among the stable candidates within 3 of it (and the static gain,
    order 0, :func:`~fmu_fdi.identify.subspace.static_model`) that have a continuous model, the
    smallest order whose mean normalised squared simulation error Σ_j ||e_j||²/||y_j − ȳ_j||² / p
    is within 2 % of the best plus 1e-4 (a 1 % NRMSE: on noise-free data a higher order only fits
    a nonlinearity a little better). The gap order stands when it is unstable (a plant in its own
    loop, judged by its one-step predictor instead)."""
    from .subspace import least_order_near_best
    from .validation import validate

    def judged(sub):
        return sub, validate(sub, du_val, dy_val, t, np.linalg.eigvals(sub.to_continuous()[0]), y_names)

    gap = cands[0]
    if np.any(np.abs(np.linalg.eigvals(gap.A)) >= 1.0):
        return judged(gap)
    scored = []
    for sub in cands[1:]:
        if (abs(sub.order - gap.order) > 3 and sub.order) or np.any(np.abs(np.linalg.eigvals(sub.A)) >= 1.0):
            continue
        try:
            res = judged(sub)
        except IdentificationError:
            continue
        scored.append((_simulation_error(res[1]), sub.order, res))
    if not scored:
        return judged(gap)
    return least_order_near_best(scored)


def _fully_given(exc, excite, sig, ts, md) -> bool:
    """Every choice of the experiment given (signal, samples, PRBS period, an amplitude for each
    excited input): nothing to design, no pre-test."""
    names = excite if excite is not None else [v.name for v in md.modelVariables
                                               if v.name in sig and v.causality == "input"]
    amp = exc.amplitude
    amps = amp is not None and (not isinstance(amp, dict) or all(n in amp for n in names))
    return (exc.signal is not None and exc.samples is not None and amps
            and (exc.signal != "prbs" or exc.period is not None))


def _noise_seed_parameter(md, params):
    """The FMU's Integer parameter that seeds its noise (named ``seed`` or ending in ``seed``,
    case-insensitive), or None; a seed the user fixed in ``at`` is still varied per run."""
    for v in md.modelVariables:
        if v.causality == "parameter" and v.type == "Integer" and v.name.lower().endswith("seed"):
            return v.name
    return None


def _verdict(y_names, rep, floor, tests, order, exc, plan) -> str:
    """One line: fit per output against the noise floor, and the residual tests."""
    per = ", ".join(f"{n} {f:.1f} % (floor {fl:.1f} %, noise-free "
                    + (f"{fn:.1f} %)" if np.isfinite(fn) else "n/a: no response beyond the noise)")
                    for n, f, fl, fn in zip(y_names, rep.fit, floor.floor, floor.fit_noise_free))
    white = ("innovations white" if tests.white else
             f"innovations not white (worst {y_names[int(np.argmax(tests.whiteness))]}: "
             f"{np.max(tests.whiteness):.2g}× the 99 % bound)") if np.any(tests.whiteness) else "no innovation test"
    indep = ("independent of the inputs" if tests.independent else
             f"output error correlated with past inputs (worst {y_names[int(np.argmax(tests.independence))]}: "
             f"{np.max(tests.independence):.2g}× the 99 % bound)")
    return f"validation fit (order {order}): {per}; residuals: {white}, {indep} (lags 0..{tests.lags})"


def _next_step(floor, tests, exc, plan, worst, y_names) -> str:
    """What to change first, from which figure failed (Ljung 1999, sec. 16.6)."""
    if not floor.floor[worst] >= 50:
        return (f"the noise hides the response on {y_names[worst]} (floor {floor.floor[worst]:.1f} % < 50 %): "
                f"excite more strongly (--amplitude) or record longer (--samples)")
    if not tests.independent:
        return ("the output error still follows the inputs (dynamics missing): give a higher --order or a "
                "longer record (--samples)")
    return ("the model error is larger than the noise but not linear in the inputs (a nonlinear plant at "
            "this amplitude?): lower --amplitude and record longer (--samples), or move the operating point")


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
    return (f"{prov.get('method', '?')}, n = {model.n}, u = {', '.join(model.labels(model.u_names))}; "
            f"y = {', '.join(model.labels(model.y_names))}{fit}")


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
