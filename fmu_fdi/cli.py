"""fmu-fdi command line: a thin layer over the library.

  fmu-fdi model PLANT.fmu [--inputs ...] [--outputs ...] -o MODEL.toml   linear model of a plant FMU
  fmu-fdi analyze MODEL                    detectability / isolability table
  fmu-fdi design MODEL --method M ... -o DESIGN.json
  fmu-fdi build DESIGN.json -o FDI.fmu [--target native [--fmi 3]]
  fmu-fdi plants build [--out DIR]
  fmu-fdi plot OUT.csv -o PLOT.png [--design DESIGN.json]
  fmu-fdi demo [--out DIR]
  fmu-fdi simulate --plant P.fmu --diagnoser FDI.fmu --stop T --step Ts [--fault SPEC ...] -o OUT.csv
  fmu-fdi campaign CAMPAIGN.toml -o DIR [--dry-run] [--resume] [--workers N] [--scheduler ADDR]
  fmu-fdi diagnose LOG.csv --design DESIGN.json -o OUT.csv

Every error a user can make is reported as one line ``fmu-fdi: error: ...`` with exit status 2;
output paths are checked before any work is done.
"""
from __future__ import annotations

import argparse
import difflib
import math
import re
import sys

import numpy as np

from .cosim.errors import CoSimulationError
from .errors import BuildError, DesignError, InputFileError, ModelError, OutputError
from .errors import one_line as _one_line
from .inputfiles import check_input_file
from .outpath import check_output_path
from .progress import Heartbeat, set_stage
from .progress import report_minreal as _report_minreal

METHODS = {
    # name: (design function, options it takes from the command line, one-line guide)
    "nullspace": ("nullspace_design", ("poles", "rdim"),
                  "least-order residual(s) decoupled from u and d (Varga's null-space synthesis; "
                  "approximate decoupling of noise w); the general default"),
    "parity": ("parity_space", ("order", "rdim", "ts_design"),
               "finite-memory parity relations over --order+1 samples; discrete time (--ts)"),
    "luenberger": ("luenberger", ("poles",),
                   "output error of a full-order observer; no decoupling of d"),
    "kalman": ("kalman", ("Qw", "Rv"),
               "innovation of the steady-state Kalman filter for the noise w (--Qw, --Rv)"),
    "uio": ("unknown_input_observer", ("poles",),
            "unknown-input observer: decouples d exactly (needs rank C Bd = rank Bd, Dd = 0)"),
    "fdf": ("fault_detection_filter", ("poles", "faults"),
            "Beard-Jones filter: each fault in --faults drives the residual along a fixed direction"),
    "factorized": ("factorized", ("poles",),
                   "left coprime factorisation r = M y - N u; stable for any plant"),
    "dos": ("dedicated_bank", ("kind", "poles"),
            "dedicated observer scheme: residual i sees only fault i of --kind (isolates single faults)"),
    "gos": ("generalized_bank", ("kind", "poles"),
            "generalised observer scheme: residual i sees every fault of --kind but fault i"),
    "structured": ("structured_bank", ("structure", "poles", "faults"),
                   "one least-order residual per row of --structure over --faults"),
    "rls": ("rls_estimator", ("order", "ts_design"),
            "recursive least-squares estimation of the model's coefficients; residuals in "
            "standard deviations (parametric faults)"),
    "data": ("data_driven", ("order", "kind", "record"),
             "no model matrices: parity relations / predictors identified from the fault-free log "
             "--calibrate (Ding's data-driven design); --kind sensor (a bank) or detection"),
}


def _method(text: str) -> str:
    """argparse type of --method: a known name, or an error suggesting the close match."""
    if text in METHODS:
        return text
    close = difflib.get_close_matches(text.lower(), METHODS, n=1, cutoff=0.5)
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise argparse.ArgumentTypeError(f"unknown method {text!r}; {hint}methods: {', '.join(sorted(METHODS))}")


def _positive_time(text: str) -> float:
    """argparse type of a sample or stop time: a positive finite number of seconds."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite time in seconds, got {text}")
    return value


def _persistence(text: str) -> list:
    """argparse type of --persistence: ``K/N`` with whole numbers ``1 <= K <= N``."""
    k, sep, n = text.partition("/")
    try:
        k, n = int(k), int(n)
    except ValueError:
        k = n = None
    if not sep or k is None or not 1 <= k <= n:
        raise argparse.ArgumentTypeError(f"{text!r} must read K/N with whole numbers 1 <= K <= N "
                                         f"(K alarms among the last N samples), e.g. 3/5")
    return [k, n]


def _valid_range(text: str) -> tuple:
    """argparse type of --valid-range: ``NAME:LO:HI`` (an empty LO or HI leaves that side open).
    The name and the order of the bounds are checked by the one design validator."""
    name, sep1, rest = text.partition(":")
    lo, sep2, hi = rest.partition(":")
    bounds = []
    for b in (lo, hi):
        try:
            bounds.append(float(b) if b.strip() else None)
        except ValueError:
            bounds = None
            break
    if not (sep1 and sep2) or not name or bounds is None:
        raise argparse.ArgumentTypeError(f"{text!r} must read NAME:LO:HI with numbers (empty for an open side), "
                                         f"e.g. h1:0:0.7 or q::1e-4")
    return name, bounds


def _valid_ranges(pairs, model) -> dict:
    """--valid-range arguments as a dict, refused before the design work if a name is not one of
    the model's inputs or outputs or comes twice (the bounds are the design validator's)."""
    names = list(model.u_names) + list(model.y_names)
    out = {}
    for name, bounds in pairs:
        if name not in names:
            raise DesignError(f"--valid-range {name}: not an input or output of the model ({', '.join(names)})")
        if name in out:
            raise DesignError(f"--valid-range {name} is given twice")
        out[name] = bounds
    return out


def _method_table() -> str:
    import textwrap

    width = max(map(len, METHODS)) + 4
    lines = []
    for name, (fn, _, guide) in METHODS.items():
        lines.append(f"  {name:<{width}}{fn}()")
        lines += textwrap.wrap(guide, 92, initial_indent=" " * (width + 4), subsequent_indent=" " * (width + 4))
    return "\n".join(lines)


DESIGN_HELP = """\
methods (--method NAME, then the Python function it calls; docs/methods.md says which when):
""" + _method_table() + """

Defaults (no options): the method's own defaults (null-space: one least-order residual,
poles at the plant's median eigenvalue magnitude; parity: the smallest exact order,
finite memory); evaluation
'rms:10' (RMS over 10 samples); threshold 'fault-size:1' (half the steady-state
evaluation of a unit step of the weakest fault each residual sees); sample time: the
model's for a discrete model, otherwise --ts is required.

--method data identifies its residual generators from the fault-free record given with
--calibrate (columns time and the model's u and y names); the model file gives the names,
faults and operating point (--kind sensor: one per sensor fault; detection: one group).

--evaluation  norm | rms:N | ewrms:LAMBDA | peak:N | narendra:ALPHA,BETA,GAMMA | chi2:N
--threshold   fault-size:F | fixed:V | sensor-gain:DELTA,J0 (adaptive, from ±DELTA level-
              sensor gain errors via the threshold selector) | analytic:ALPHA[,STD] (false-alarm
              probability ALPHA per sample for white noise inputs w of standard deviation STD,
              default 1) | data:RATE (false-alarm rate RATE, 95 % confidence, from the fault-free
              record given with --calibrate CSV: columns time and the model's u and y names) |
              sigma:ALPHA (residuals in standard deviations, e.g. RLS: sqrt of the chi-square
              quantile 1-ALPHA of the group size; the default for --method rls with 'norm')
"""


def _load_model(path, args=None):
    """A model file; a plant FMU is refused with the command that turns it into one.
    ``--minimal``/``--minreal-tol`` (if the command has them) reduce it to a minimal realisation."""
    from .model import FDIModel

    inside = _design_inside(path)
    if inside:
        raise InputFileError(f"{path} is a diagnostic FMU (built by 'fmu-fdi build'), not a model file; the model it "
                             f"was designed from is the 'model' of its design (unzip -p {path} {inside}); a model "
                             f"of a plant FMU comes from 'fmu-fdi model PLANT.fmu -o model.toml'")
    model = FDIModel.from_file(check_input_file(path, "model file"), minimal=getattr(args, "minimal", None),
                               minreal_tol=getattr(args, "minreal_tol", None))
    _report_minreal(model)
    return model


def _minreal_options(parser) -> None:
    """The model-building options of every command that reads or writes a model."""
    parser.add_argument("--minimal", action=argparse.BooleanOptionalAction, default=None,
                        help="reduce the model to a minimal realisation of [u d w f] -> y (default: as the "
                             "model file's 'minimal' key says, else off)")
    parser.add_argument("--minreal-tol", type=float, metavar="TOL",
                        help="relative tolerance of that reduction in [0, 1), implies --minimal (default: the "
                             "model file's 'minreal_tol', else n^2*eps; docs/model-file.md)")


def _check_model_options(args) -> None:
    """The experiment options of ``fmu-fdi model`` checked before the plant runs: every number in
    its range (a sample time, settle time and counts that fit in memory), every name one the FMU
    has (--at: any variable; --amplitude: an input)."""
    def bad(option, value, need):
        raise ModelError(f"{option} {value!r}: {need}")

    if args.ts is not None and not (math.isfinite(args.ts) and args.ts > 0):
        bad("--ts", args.ts, "the sample time must be a positive finite number of seconds")
    if args.settle is not None and not (math.isfinite(args.settle) and args.settle >= 0):
        bad("--settle", args.settle, "the settle time must be a finite number of seconds >= 0")
    if args.seed is not None and not 0 <= args.seed < 2 ** 63:
        bad("--seed", args.seed, "the seed must be a whole number in [0, 2^63)")
    if args.min_fit is not None and not (math.isfinite(args.min_fit) and args.min_fit <= 100):
        bad("--min-fit", args.min_fit, "the least validation fit must be a finite percentage <= 100")
    for option in ("samples", "period", "order"):
        value = getattr(args, option, None)
        low = 0 if option == "order" else 1  # order 0: a static plant (a pure feedthrough)
        if value is not None and not low <= value <= MAX_MODEL_SAMPLES:
            bad(f"--{option}", value, f"must be a whole number in [{low}, {MAX_MODEL_SAMPLES}]")
    md = _plant_description(args.plant)
    if md is None:
        return  # not an FMU: the model builder says so
    variables = {v.name: v for v in md.modelVariables}
    inputs = [n for n, v in variables.items() if v.causality == "input"]
    for option, items, known, what in (("--at", args.at, list(variables), "a variable"),
                                       ("--amplitude", args.amplitude, args.excite or inputs, "an excited input")):
        for item in items or []:
            name = item.partition("=")[0].strip()
            if name and name not in known:
                close = difflib.get_close_matches(name, known, n=3)
                hint = f"; did you mean {', '.join(close)}?" if close else f"; it has {', '.join(known[:12])}"
                raise ModelError(f"{option} {item}: {name!r} is not {what} of {args.plant}{hint}")
    ts = args.ts or getattr(md.defaultExperiment, "stepSize", None)
    try:
        ts = float(ts) if ts is not None else None
    except ValueError:
        ts = None
    if args.settle is not None and ts and args.settle / ts > MAX_MODEL_SAMPLES:
        bad("--settle", args.settle, f"{args.settle / ts:.3g} steps of {ts:g} s is more than {MAX_MODEL_SAMPLES}; "
                                     f"settle for less time")


#: most steps of one identification run (settling or recording): 1e7 samples are minutes of a plant FMU
MAX_MODEL_SAMPLES = 10 ** 7


def _plant_description(path):
    """The modelDescription of a plant FMU, or None if ``path`` is not a readable FMU."""
    try:
        from fmpy import read_model_description

        return read_model_description(str(path), validate=False)
    except Exception:  # not an FMU, not a zip, broken XML: model_from_fmu reports it in its words
        return None


def _model(args) -> int:
    _check_model_options(args)
    from .identify.fmu_model import parse_values, summary
    from .identify.plant_child import run_model_child
    from .model import FDIModel, minreal_option

    # only checked here, before the excitation options (model_from_fmu applies them)
    minreal_option(args.minimal, args.minreal_tol)
    parse_values(args.amplitude, "--amplitude"), parse_values(args.at, "--at")
    if not args.at_grid:
        check_output_path(args.output, (".toml", ".json"), "model file", error=ModelError)
    # the plant runs in a child under the wall-clock limit: its crash, exit or hang is one line here
    d = run_model_child(args, args.timeout)
    if d is None:  # --at-grid: the child wrote the model set
        return 0
    model = FDIModel.from_dict(d, str(args.plant))
    print(f"wrote {model.to_file(args.output)}: {summary(model)}")
    return 0


def _analyze(args) -> int:
    from .analysis import detectability, isolability

    model = _load_model(args.model, args)
    set_stage(f"detectability analysis (n = {model.n} states, {len(model.faults)} faults)")
    det = detectability(model)
    set_stage(f"isolability analysis (n = {model.n} states, {len(model.faults)} faults)")
    iso = isolability(model)
    print(f"model '{model.name}': n={model.n}, u={model.labels(model.u_names)}, y={model.labels(model.y_names)}, "
          f"d={model.labels(model.d_names)}, "
          f"w={model.w_names}, {'dt=' + format(model.dt, 'g') if model.dt else 'continuous'}")
    width = max([len("fault")] + [len(n) for n in model.fault_names])
    print(f"{'fault':<{width}}  kind        detectable  rank[Gd Gf]  rank Gd  isolable from")
    for j, spec in enumerate(model.faults):
        d = det[spec.name]
        others = [model.fault_names[k] for k in range(len(model.faults)) if k != j and iso["matrix"][j, k]]
        print(f"{spec.name:<{width}}  {spec.kind:<10}  {'yes' if d['detectable'] else 'NO':<10}  "
              f"{d['rank_Gd_Gf']:<11}  {d['rank_Gd']:<7}  {', '.join(others) or '-'}")
    print(f"fully isolable (structure I achievable): {'yes' if iso['fully_isolable'] else 'no'}")
    return 0


def parse_evaluation(text: str) -> dict:
    kind, _, arg = text.partition(":")
    try:
        if kind == "norm":
            return {"kind": "norm"}
        if kind in ("rms", "peak", "chi2"):
            return {"kind": kind, "window": int(arg)}
        if kind == "ewrms":
            return {"kind": "ewrms", "lambda": float(arg)}
        if kind == "narendra":
            a, b, g = (float(x) for x in arg.split(","))
            return {"kind": "narendra", "alpha": a, "beta": b, "gamma": g}
    except ValueError:
        pass
    raise DesignError(f"cannot read evaluation {text!r}: use norm, rms:N, ewrms:LAMBDA, peak:N, "
                      f"narendra:ALPHA,BETA,GAMMA or chi2:N")


_THRESHOLD_FORMS = ("use fault-size:F, fixed:V, sensor-gain:DELTA,J0, analytic:ALPHA[,STD], data:RATE or "
                    "sigma:ALPHA")
_THRESHOLD_ARGS = {"sigma": (1, 1), "analytic": (1, 2), "data": (1, 1), "fixed": (1, 1), "fault-size": (0, 1),
                   "sensor-gain": (2, 2)}


def _threshold_args(text: str) -> tuple[str, list]:
    """``KIND:a,b`` -> (kind, [a, b]) with the count of numbers each kind takes."""
    kind, _, arg = text.partition(":")
    lo, hi = _THRESHOLD_ARGS.get(kind, (-1, -1))
    try:
        nums = [float(x) for x in arg.split(",")] if arg else []
    except ValueError:
        nums = None
    if lo < 0 or nums is None or not lo <= len(nums) <= hi or not all(map(math.isfinite, nums)):
        raise DesignError(f"cannot read threshold {text!r}: {_THRESHOLD_FORMS}")
    return kind, nums


def _thresholds(text: str, gen, evaluation: dict, calibrate=None):
    kind, nums = _threshold_args(text)
    try:
        return _threshold_values(kind, nums, gen, evaluation, calibrate)
    except (DesignError, ModelError, InputFileError):
        raise
    except ValueError as exc:  # the library's reason, e.g. too few calibration samples
        raise DesignError(f"--threshold {text}: {exc}") from None


def _threshold_values(kind, nums, gen, evaluation, calibrate):
    from .evaluation import (analytic_threshold, fault_size_thresholds, sensor_gain_plants,
                             threshold_selector)

    if kind == "sigma":
        from scipy.stats import chi2

        return [float(np.sqrt(chi2.ppf(1 - nums[0], len(g)))) for g in gen.groups]
    if kind == "analytic":
        alpha, std = nums[0], (nums[1] if len(nums) > 1 else 1.0)
        cov = std * std * np.eye(gen.model.nw) if gen.model.nw else None
        return [analytic_threshold(gen, evaluation, alpha, noise_cov=cov, group=i) for i in range(len(gen.groups))]
    if kind == "data":
        if calibrate is None:
            raise DesignError("--threshold data:RATE needs a fault-free record: --calibrate CSV")
        from .diagnoser import Diagnoser

        t, u, y = _read_record(calibrate, gen.model)
        probe = Diagnoser(gen, evaluation=evaluation, thresholds=1e150)  # evaluations only (reachable: design_check)
        out = probe.run(t, u, y)
        return [_log_threshold(out, gen, evaluation, i, nums[0]) for i in range(len(gen.groups))]
    if kind == "fixed":
        return nums[0]
    if kind == "fault-size":
        return fault_size_thresholds(gen, evaluation, nums[0] if nums else 1.0)
    delta, J0 = nums  # sensor-gain
    plants = sensor_gain_plants(gen.model, delta)
    return [threshold_selector(gen, evaluation, J0=J0, plants=plants)] * len(gen.groups)


def _log_threshold(out, gen, evaluation, i, rate):
    """Group i's ``data:RATE`` threshold (fmu_fdi/evaluation/gaussfit.log_threshold); a Gaussian fit, used
    when the log is too short for the evaluation's tail, is said and recorded in the design's info."""
    from .evaluation import log_threshold

    r = np.column_stack([out[f"residual_{j + 1}"] for j in gen.groups[i]])
    est = log_threshold(out[f"evaluation_{i + 1}"], r, evaluation, rate)
    if est.method == "gaussian":
        note = (f"group {i + 1}: threshold {est.value:.4g} from a Gaussian fit of the residuals (rate {rate:g}, "
                f"bound at confidence {est.confidence:g} on the autocovariance estimated from {est.n_effective} "
                f"effective residual samples), "
                f"not from the evaluation's tail: {est.details['short_log']}")
        print(f"note: {note}")
        gen.info.setdefault("threshold_fits", []).append(note)
    return est


def _read_record(path, model):
    """A CSV record with a time column and the model's u and y columns (plain or
    instance-prefixed names, see :func:`fmu_fdi.recorded.read_log`)."""
    from .recorded import read_log

    log = read_log(path, model.u_names, model.y_names)
    print(f"{path}: {log.describe()}")
    return log.t, log.u, log.y


def _design(args) -> int:
    from . import design as design_pkg
    from .diagnoser import Diagnoser

    check_output_path(args.output, (".json",), "design file", inputs=(args.model, args.calibrate))
    from .modelset import is_model_set_file

    if is_model_set_file(args.model):  # one design per member, scheduled (fmu_fdi/schedule.py)
        from .schedule import design_cli

        return design_cli(args, _design)
    if args.calibrate:
        check_input_file(args.calibrate, "calibration record")

    model = _load_model(args.model, args)
    valid_range = _valid_ranges(args.valid_range or (), model)
    fname, takes, _ = METHODS[args.method]
    fn = getattr(design_pkg, fname, None)
    if fn is None:
        raise DesignError(f"method '{args.method}' is not available in this installation")
    kw = {}
    if "poles" in takes and args.poles is not None:
        kw["poles"] = args.poles
    if "rdim" in takes and args.rdim is not None:
        kw["rdim"] = args.rdim
    if "order" in takes and args.order is not None:
        kw["order"] = args.order
    if "kind" in takes:
        kw["kind"] = args.kind
    if "structure" in takes:
        if not args.structure:
            raise DesignError("--method structured needs --structure '1,0,1;0,1,1' (rows ; separated)")
        try:
            kw["S"] = np.array([[int(x) for x in row.split(",")] for row in args.structure.split(";")])
        except ValueError:
            raise DesignError(f"--structure {args.structure!r} must be rows of 0/1 separated by ';', entries by ','"
                              f" (e.g. '1,0,1;0,1,1') with equally long rows") from None
    if "faults" in takes and args.faults:
        kw["faults"] = args.faults
    if "Qw" in takes:
        # defaults: the model's noise inputs w are unit white noise (their size is in Bw,
        # Dw) and there is no measurement noise beyond them
        kw["Qw"] = np.diag(args.Qw) if args.Qw else np.eye(model.nw)
        kw["Rv"] = np.diag(args.Rv) if args.Rv else np.zeros((model.ny, model.ny))
    if "record" in takes:  # data-driven: the filter comes from the fault-free record
        if not args.calibrate:
            raise DesignError("--method data identifies its parity relations from a fault-free record: "
                              "give --calibrate LOG.csv (columns time and the model's u and y names)")
        kw.update(zip(("t", "u", "y"), _read_record(args.calibrate, model)))
    if "ts_design" in takes and not model.is_discrete:
        if args.ts is None:
            raise DesignError(f"--method {args.method} designs in discrete time: give --ts for a continuous model")
        kw["Ts"] = args.ts
    set_stage(f"designing the residual generator ({args.method}, n = {model.n} states)")
    gen = fn(model, **kw)
    for text in (getattr(gen, "info", None) or {}).get("notes", ()):  # design remarks (design/toolkit/notes.py)
        print(f"note: {text}")
    set_stage(f"discretising, thresholds and the design file ({args.method}, n = {model.n} states)")
    if gen.dt == 0.0:
        if args.ts is None:
            raise DesignError("the model is continuous: give the diagnosis sample time --ts")
        gen = gen.to_discrete(args.ts)
    if args.method == "data":  # relations scaled to unit RMS on the record; thresholds from it too
        evaluation = parse_evaluation(args.evaluation or "rms:10")
        thresholds = _thresholds(args.threshold or "data:0.001", gen, evaluation, args.calibrate)
    elif args.method == "rls":  # residuals are deviations in standard deviations
        evaluation = parse_evaluation(args.evaluation or "norm")
        thresholds = _thresholds(args.threshold or "sigma:1e-4", gen, evaluation, args.calibrate)
    else:
        evaluation = parse_evaluation(args.evaluation or "rms:10")
        if args.threshold:
            thresholds = _thresholds(args.threshold, gen, evaluation, args.calibrate)
        else:  # fault-size:1, raised to the noise model's analytic threshold (evaluation/defaults.py)
            from .evaluation import default_thresholds

            thresholds, why = default_thresholds(gen, evaluation)
            for i, text in enumerate(why):
                print(f"group {i + 1}: default threshold {thresholds[i]:.4g} from {text}")
    # plantfmu (issue 18): what the thresholds mean under the model's noise (evaluation/guidance.py)
    from .evaluation.guidance import describe, threshold_guidance

    try:
        guidance = threshold_guidance(gen, evaluation, thresholds)
    except (ValueError, TypeError, DesignError, np.linalg.LinAlgError, AttributeError) as exc:
        print(f"note: no threshold guidance for this design ({exc})")
    else:
        describe(gen, guidance, warn=lambda text: print(text, file=sys.stderr))
    decision = {"persistence": args.persistence, "latch": args.latch}
    dg = Diagnoser(gen, evaluation=evaluation, thresholds=thresholds, decision=decision, name=args.name,
                   valid_range=valid_range or None)
    path = dg.save(args.output)
    order = gen.Q.n if hasattr(gen, "Q") else "-"
    print(f"wrote {path}: method {gen.method}, {gen.n_residuals} residual(s) in {len(gen.groups)} group(s), "
          f"order {order}, Ts = {gen.dt:g} s, isolation "
          f"'{dg.design['decision']['isolation']}'")
    return 0


def _plot(args) -> int:
    from .recorded import diagnoser_prefix, read_result
    from .report import plot_diagnosis

    check_output_path(args.output, (".png", ".svg", ".pdf"), "plot", inputs=(args.result, args.design))
    res = read_result(check_input_file(args.result, "result CSV"))
    design = _design_for_labels(args.design)
    prefix = diagnoser_prefix(res, args.prefix, str(args.result))
    _isolation_column(res, prefix, args.result)
    if design:
        _check_design_matches_log(res, prefix, design, args.design, args.result)
    faults = [f["name"] for f in design["faults"]] if design else []
    path = plot_diagnosis(res, args.output, prefix=prefix, design=design, title=args.title)
    first, names = _verdict(res["time"], res[f"{prefix}fault_detected"], res[f"{prefix}isolated_fault"], faults)
    print(f"wrote {path}; {first}; isolated as: {names}")
    return 0


_DIAGNOSER_OUTPUT = re.compile(r"^(residual|evaluation|threshold|alarm)_\d+$|^(fault_detected|isolated_fault|"
                               r"input_invalid|numeric_reset|active_model|active_member|[a-z_]+_flag)$")


def _isolation_column(res, prefix, log_path) -> np.ndarray:
    """The log's isolated_fault column, refused unless it holds fault numbers (whole, >= -1)."""
    name = f"{prefix}isolated_fault"
    if name not in res.dtype.names:
        return np.zeros(0)
    iso = np.asarray(res[name], float)
    bad = ~(np.isfinite(iso) & (iso == np.round(iso)) & (iso >= -1) & (iso < 2 ** 31))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DesignError(f"{log_path}: column {name} holds {iso[k]:g} at row {k + 1}, not a fault number "
                          f"(-1, 0 or 1 ... the number of faults)")
    return iso


def _check_design_matches_log(res, prefix, design, design_path, log_path) -> None:
    """Refuse a design that is not the one whose diagnosis the log holds: its number of
    residuals and evaluation groups, the signals its diagnoser read (when the log records them)
    and the range of its isolation results must all fit."""
    names = [n[len(prefix):] for n in res.dtype.names if n.startswith(prefix) and n != "time"]
    gen = design["generator"]
    want = {"residual": len(gen.get("residual_names", [])), "evaluation": len(gen.get("groups", []))}
    problems = []
    for kind, n in want.items():
        have = sum(1 for x in names if re.fullmatch(rf"{kind}_\d+", x))
        if have and n and have != n:
            problems.append(f"{have} {kind} columns where the design has {n}")
    signals = list(design["signals"]["u"]) + list(design["signals"]["y"])
    read = [x for x in names if not _DIAGNOSER_OUTPUT.match(x)]
    missing = [x for x in signals if x not in names]
    if read and missing:
        problems.append(f"its diagnoser read {', '.join(read)}; the design reads {', '.join(signals)}")
    iso = _isolation_column(res, prefix, log_path)
    top = len(design["faults"])
    if len(iso) and np.nanmax(iso) > top:
        problems.append(f"isolated_fault reaches {np.nanmax(iso):g}, the design has {top} faults")
    if problems:
        raise DesignError(f"{design_path} is not the design of the diagnosis in {log_path}: {'; '.join(problems)}; "
                          f"give the design the diagnostic FMU was built from, or leave --design out")


def _verdict(t, detected, isolated, faults) -> tuple[str, str]:
    """('first alarm at t = <time> s' or 'no alarm', 'the names of every isolation result' or '-')."""
    det = np.asarray(detected).astype(bool)
    first = f"first alarm at t = {float(np.asarray(t)[det][0])!r} s" if det.any() else "no alarm"
    label = {-1: "unknown"}
    named = sorted({int(v) for v in isolated if v != 0})
    names = [label.get(v) or (faults[v - 1] if faults and 0 < v <= len(faults) else str(v)) for v in named]
    return first, ", ".join(names) or "-"


def _design_for_labels(path):
    from .designfile import load_design
    from .schedule import design_of

    if path and (scheduled := design_of(_design_file(path))) is not None:
        return scheduled["members"][0]  # the members share faults, residuals and groups
    return load_design(_design_file(path)) if path else None


def _design_inside(path) -> str | None:
    """The design.json member of a diagnostic FMU built by fmu-fdi, or None (not such an FMU)."""
    import zipfile

    from pathlib import Path

    p = Path(path)
    if not (p.is_file() and zipfile.is_zipfile(p)):
        return None
    try:
        with zipfile.ZipFile(p) as z:
            inside = [n for n in z.namelist() if n.startswith("resources/") and n.endswith("/design.json")]
    except (OSError, zipfile.BadZipFile):
        return None
    return inside[0] if inside else None


def _design_file(path):
    """``path`` checked as a design file, with the right advice for the files taken for one: a
    diagnostic FMU (built from a design: the design is inside it), a plant FMU (model it, then
    design), a model file (design from it)."""
    import zipfile

    from pathlib import Path

    p = Path(path)
    inside = _design_inside(p)
    if inside:
        with zipfile.ZipFile(p) as z:  # a large plant's model is in the sidecar beside it
            copy = (f"unzip -j {p} {inside} {inside}.npz" if f"{inside}.npz" in z.namelist()
                    else f"unzip -p {p} {inside} > design.json")
        raise InputFileError(f"{p} is a diagnostic FMU (built by 'fmu-fdi build'), not a design file; give the "
                             f"design file it was built from (the FMU carries a copy: {copy})")
    if p.is_file() and not zipfile.is_zipfile(p):
        head = p.read_bytes()[:4096].lstrip()
        model = b"fmu-fdi-model/" in head and b"fmu-fdi-design/" not in head  # the design embeds its model
        if model or (p.suffix.lower() == ".toml" and not head.startswith(b"{")):
            raise InputFileError(f"{p} is a model file, not a design file; design a diagnoser from it first: "
                                 f"fmu-fdi design {p} --method nullspace -o design.json (methods: fmu-fdi design -h)")
    return check_input_file(path, "design file")


def _diagnose(args) -> int:
    from .cosim import Result
    from .recorded import read_log

    check_output_path(args.output, (".csv",), "diagnosis CSV", inputs=(args.log, args.design))
    from .schedule import load_diagnoser  # a plain or a scheduled design

    dg = load_diagnoser(_design_file(args.design))
    sig = dg.design["signals"]
    log = read_log(check_input_file(args.log, "log CSV"), sig["u"], sig["y"], prefix=args.prefix)
    print(f"{args.log}: {log.describe()}")
    name = dg.design.get("name", "the design")
    set_stage(f"diagnose: running {name!r} on the {len(log.t)} samples of {args.log}")
    try:
        out = dg.run(log.t, log.u, log.y)
    except ValueError as exc:
        raise DesignError(f"{args.log}: {exc}") from None
    Result(out).to_csv(args.output)
    first, names = _verdict(out["time"], out["fault_detected"], out["isolated_fault"], dg.fault_names)
    print(f"wrote {args.output}: {len(out)} samples; {first}; isolated as: {names}")
    return 0


def _demo(args) -> int:
    from .demo import run_demo

    run_demo(args.out, target=args.target)
    return 0


def _plants_build(args) -> int:
    import plant_fmus

    for path in plant_fmus.build_all(args.out):
        print(path)
    return 0


def _build(args) -> int:
    from .fmu import build_fmu

    check_output_path(args.output, (".fmu",), "FMU", error=BuildError, inputs=(args.design,))
    path = build_fmu(_design_file(args.design), args.output, target=args.target,
                     fmi_version=args.fmi, stop_time=args.stop_time)
    print(f"wrote {path}")
    return 0


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("fmu-fdi")
    except metadata.PackageNotFoundError:
        from . import __version__

        return __version__


def build_parser() -> argparse.ArgumentParser:
    """The ``fmu-fdi`` argument parser: one sub-parser per command, each built by its own
    ``_<command>_parser(sub)`` below (cosim and campaign add theirs), in the order ``--help``
    lists them."""
    from .campaign import cli as campaign_cli
    from .cosim import cli as cosim_cli

    p = argparse.ArgumentParser(prog="fmu-fdi", description="Model-based fault detection and isolation as FMUs.")
    p.add_argument("--version", action="version", version=f"fmu-fdi {_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    for add_parser in (_analyze_parser, _plants_parser, _plot_parser, _demo_parser, cosim_cli.add_parser,
                       _diagnose_parser, campaign_cli.add_parser, _design_parser, _model_parser, _build_parser):
        add_parser(sub)
    return p


def _analyze_parser(sub) -> None:
    """``fmu-fdi analyze MODEL``."""
    a = sub.add_parser("analyze", help="detectability / isolability table of a model file")
    a.add_argument("model", help="model file (.toml or .json, docs/model-file.md)")
    _minreal_options(a)
    a.set_defaults(func=_analyze)


def _plants_parser(sub) -> None:
    """``fmu-fdi plants build [--out DIR]``."""
    pl = sub.add_parser("plants", help="benchmark plant FMUs (plant_fmus)")
    pl_sub = pl.add_subparsers(dest="plants_command", required=True)
    pb = pl_sub.add_parser("build", help="build every benchmark plant FMU")
    pb.add_argument("--out", default="out", help="output folder (default: out)")
    pb.set_defaults(func=_plants_build)


def _plot_parser(sub) -> None:
    """``fmu-fdi plot OUT.csv -o PLOT.png``."""
    pp = sub.add_parser("plot", help="PNG of residuals, thresholds, alarms and isolation from a result CSV")
    pp.add_argument("result", help="CSV from 'fmu-fdi simulate', 'fmu-fdi diagnose', fmpy or Result.to_csv")
    pp.add_argument("-o", "--output", required=True, help="image to write (.png, .svg or .pdf)")
    pp.add_argument("--prefix", help="column prefix of the diagnoser outputs, e.g. 'diagnoser.' "
                                     "(default: found from the fault_detected column)")
    pp.add_argument("--design", help="design file, to name the faults each panel watches and the isolated "
                                     "faults (default: none, panels by number)")
    pp.add_argument("--title", help="plot title (default: the diagnoser and what happened)")
    pp.set_defaults(func=_plot)


def _demo_parser(sub) -> None:
    """``fmu-fdi demo [--out DIR]``."""
    dm = sub.add_parser("demo", help="the three-tank demo: plant FMU, diagnoser design, diagnostic FMU, "
                                     "co-simulations, table and plot")
    dm.add_argument("--out", default="fmu-fdi-demo", help="output folder (default: fmu-fdi-demo)")
    dm.add_argument("--target", choices=("pythonfmu", "native"), default="pythonfmu",
                    help="diagnostic FMU target (default: pythonfmu; native: C, FMI 2.0, compiled with the system C compiler)")
    dm.set_defaults(func=_demo)


def _diagnose_parser(sub) -> None:
    """``fmu-fdi diagnose LOG.csv --design DESIGN.json -o OUT.csv``."""
    dg = sub.add_parser("diagnose", help="run a design file on a recorded log (no FMU) and write the diagnosis",
                        description="Run the diagnoser of a design file on a recorded CSV log: a 'time' column "
                                    "and one column per signal the design reads (the model's u and y names), "
                                    "plain ('h1') or behind an instance name ('plant.h1', as 'fmu-fdi "
                                    "simulate' writes). The columns used are printed.")
    dg.add_argument("log", help="CSV log with 'time' and the design's u and y signals")
    dg.add_argument("--design", required=True, help="design file (.json)")
    dg.add_argument("-o", "--output", required=True, help="diagnosis CSV to write (time and the FMU's outputs)")
    dg.add_argument("--prefix", help="read the signals from columns PREFIX<name>, e.g. 'diagnoser.' "
                                     "(default: plain names, else the one instance that has them, preferring "
                                     "the diagnoser's recorded inputs)")
    dg.set_defaults(func=_diagnose)


def _design_parser(sub) -> None:
    """``fmu-fdi design MODEL --method M ... -o DESIGN.json``."""
    d = sub.add_parser("design", help="design a diagnoser and write its design file",
                       formatter_class=argparse.RawDescriptionHelpFormatter, epilog=DESIGN_HELP)
    d.add_argument("model", help="model file (.toml or .json, docs/model-file.md)")
    d.add_argument("--method", required=True, type=_method, metavar="{" + ",".join(sorted(METHODS)) + "}",
                   help="residual generator design method (the list below)")
    d.add_argument("-o", "--output", required=True, help="design file to write (.json)")
    d.add_argument("--ts", type=_positive_time, help="diagnosis sample time in s (required for a continuous "
                                                     "model; default: the model's dt for a discrete one)")
    d.add_argument("--poles", type=float, nargs="+", help="filter poles (real; default: the method's own)")
    d.add_argument("--rdim", type=int, help="number of residuals (default: the method's least number)")
    d.add_argument("--order", type=int, help="parity order / ARX order (default: the smallest that works)")
    d.add_argument("--kind", default="sensor", choices=("sensor", "actuator", "detection"),
                   help="faults of a dos/gos bank; data: 'sensor' (a bank) or 'detection' (one relation) "
                        "(default: sensor)")
    d.add_argument("--structure", help="structure matrix for --method structured, rows separated by ';' "
                                       "(no default)")
    d.add_argument("--Qw", type=float, nargs="+", help="kalman: noise variances, diagonal of Qw "
                                                       "(default: 1 for every noise input w)")
    d.add_argument("--Rv", type=float, nargs="+", help="kalman: measurement noise variances, diagonal of Rv "
                                                       "(default: 0)")
    d.add_argument("--evaluation", help="evaluation function (default: rms:10; norm for rls)")
    d.add_argument("--threshold", help="threshold (default: fault-size:1; sigma:1e-4 for rls)")
    d.add_argument("--faults", nargs="+", help="fdf: the faults to give fixed directions (default: the "
                                               "state-entering ones); structured: the faults the columns of "
                                               "--structure refer to (default: all)")
    d.add_argument("--calibrate", help="fault-free record (CSV) for --threshold data:RATE and --method data (no default)")
    d.add_argument("--persistence", type=_persistence, default=[1, 1], metavar="K/N",
                   help="alarm when the threshold is crossed in K of the last N samples (default: 1/1)")
    d.add_argument("--latch", action="store_true", help="latch alarms until reset (default: off)")
    d.add_argument("--name", help="diagnoser name (default: MODEL_METHOD)")
    d.add_argument("--valid-range", type=_valid_range, action="append", metavar="NAME:LO:HI",
                   help="a sample of input or output NAME outside [LO, HI] is refused like a NaN (input_invalid), "
                        "e.g. a glitching sensor's 1e300; empty LO or HI: open; repeat per signal "
                        "(default: none, docs/semantics.md S2)")
    d.add_argument("--hysteresis", type=float, default=0.2, metavar="ETA",
                   help="model set: switch to the nearest member only when it is nearer than the active one by "
                        "ETA grid steps (default: 0.2; docs/semantics.md, scheduled designs)")
    d.add_argument("--warm-start", action=argparse.BooleanOptionalAction, default=True,
                   help="model set: start each member's filter at its steady state for the first sample "
                        "(default: on)")
    _minreal_options(d)
    d.set_defaults(func=_design)


def _model_parser(sub) -> None:
    """``fmu-fdi model PLANT.fmu ... -o MODEL.toml``."""
    mo = sub.add_parser("model", help="linear model file of a plant FMU: linearised (model exchange) or "
                                      "identified from an experiment (co-simulation)")
    mo.add_argument("plant", help="plant FMU (FMI 2.0 or 3.0)")
    mo.add_argument("-o", "--output", required=True, help="model file to write (.toml or .json)")
    mo.add_argument("--inputs", nargs="+", help="known inputs u (FMU variables; default: the FMU's Real inputs not in --disturbances, linearisation only)")
    mo.add_argument("--outputs", nargs="+", help="measured outputs y (FMU outputs; default: the FMU's Real outputs, linearisation only)")
    mo.add_argument("--disturbances", nargs="+", help="unknown inputs d (FMU inputs; default: none)")
    mo.add_argument("--at", nargs="+", metavar="NAME=VALUE", help="operating point: inputs, parameters, states (default: the FMU's start values)")
    mo.add_argument("--trim", action=argparse.BooleanOptionalAction, default=True,
                    help="model exchange: find the steady state from the inputs (default on)")
    mo.add_argument("--method", default="auto", choices=("auto", "linearise", "identify"))
    mo.add_argument("--sensor-faults", nargs="+", help="'all' or output names: additive sensor faults (default: none)")
    mo.add_argument("--actuator-faults", nargs="+", help="'all' or input names: additive actuator faults (default: none)")
    mo.add_argument("--ts", type=float, help="identification sample time (default: the FMU's default step)")
    mo.add_argument("--excite", nargs="+", help="FMU inputs to excite (default: the model inputs that are FMU inputs)")
    # plantfmu (issue 18): the experiment options default to the automatic design (identify/design.py)
    mo.add_argument("--signal", choices=("multisine", "prbs"), help="excitation signal (default: chosen, PRBS)")
    mo.add_argument("--amplitude", nargs="+", metavar="NAME=A",
                    help="peak excitation per input (default: chosen from a pre-test for signal/noise 10)")
    mo.add_argument("--samples", type=int, help="recorded steps per run (default: chosen, 6 slowest time scales)")
    mo.add_argument("--settle", type=float, help="seconds at the operating point first (default: designed, until the "
                    "outputs are steady; 200 steps when the whole experiment is given)")
    mo.add_argument("--period", type=int, help="PRBS clock period in steps (default: chosen, fastest time scale)")
    mo.add_argument("--seed", type=int, default=0, help="excitation seed (default: 0; validation run: seed + 1)")
    mo.add_argument("--order", type=int, help="model order (default: by cross-validation near the singular "
                                              "values' largest gap)")
    mo.add_argument("--min-fit", type=float, default=50.0,
                    help="refuse a fit to the noise-free response below this (%%, default 50)")
    mo.add_argument("--plot", help="PNG of measured vs model outputs on the validation run (default: none)")
    mo.add_argument("--record", help="CSV of the identification run, a fault-free log for --method data (default: none)")
    # identify.noise.NOISE_MODELS, written out: importing it would load the identification
    # package on every CLI call; test_identify_noise checks the two lists agree
    mo.add_argument("--noise", choices=("innovation", "measurement", "none"), default="auto",
                    help="identification: unit white noise inputs w_<output> learned from the data: the Kalman "
                         "innovation form, or output noise from the validation error (default: innovation when "
                         "the data has noise; docs/plant-fmu.md)")
    mo.add_argument("--at-grid", nargs="+", metavar="NAME=LO:HI:K",
                    help="operating envelope: model the plant at K values of each NAME from LO to HI and write a "
                         "model set (.json) for a scheduled design (default: one point, --at)")
    mo.add_argument("--grid-mode", choices=("product", "path"), default="product",
                    help="--at-grid points: every combination (product, default) or the axes walked together (path)")
    mo.add_argument("--schedule-on", nargs="+", metavar="NAME",
                    help="measured scheduling signal(s), model inputs or outputs (default: the grid's variables)")
    mo.add_argument("--timeout", type=_positive_time, default=600.0, metavar="SECONDS",
                    help="wall-clock limit of the plant work, which runs in a child process: a plant that "
                         "hangs is stopped, one that crashes or exits is reported (default 600)")
    mo.add_argument("--allow-unstable", action="store_true",
                    help="accept a model with unstable poles: the plant is unstable and the operating point is an "
                         "equilibrium (default: refused unless trimmed; docs/plant-fmu.md)")
    _minreal_options(mo)
    mo.set_defaults(func=_model)


def _build_parser(sub) -> None:
    """``fmu-fdi build DESIGN.json -o FDI.fmu``."""
    b = sub.add_parser("build", help="build the diagnostic FMU (co-simulation) from a design file")
    b.add_argument("design", help="design file (.json) written by 'fmu-fdi design' or Diagnoser.save")
    b.add_argument("-o", "--output", required=True, help="FMU to write (.fmu)")
    b.add_argument("--target", choices=("pythonfmu", "native"), default="pythonfmu",
                   help="pythonfmu (default; the host needs Python + numpy) or native (C, compiled now)")
    b.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (default: 2; 3 needs --target native)")
    b.add_argument("--stop-time", type=_positive_time,
                   help="DefaultExperiment stop time in s, what 'fmpy simulate' runs for without --stop-time "
                        "(default: 1000 samples of the design's Ts)")
    b.set_defaults(func=_build)

def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        with Heartbeat():  # long commands (large models) report their stage on stderr
            return args.func(args)
    except (ModelError, DesignError, BuildError, OutputError, InputFileError, CoSimulationError) as exc:
        print(f"fmu-fdi: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fmu-fdi: interrupted (Ctrl-C)", file=sys.stderr)
        return 130
    except OSError as exc:  # the file system said no (full disk, permissions, a file where a folder belongs)
        where = f": {exc.filename}" if exc.filename else ""
        print(f"fmu-fdi: error: {_one_line(exc.strerror or exc)}{where}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
