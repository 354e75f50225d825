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
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from .cosim.errors import CoSimulationError
from .errors import DesignError, ModelError
from .progress import Heartbeat, set_stage

METHODS = {
    # name: (design function, options it takes from the command line)
    "nullspace": ("nullspace_design", ("poles", "rdim")),
    "parity": ("parity_space", ("order", "rdim", "ts_design")),
    "luenberger": ("luenberger", ("poles",)),
    "kalman": ("kalman", ("Qw", "Rv")),
    "uio": ("unknown_input_observer", ("poles",)),
    "fdf": ("fault_detection_filter", ("poles", "faults")),
    "factorized": ("factorized", ("poles",)),
    "dos": ("dedicated_bank", ("kind", "poles")),
    "gos": ("generalized_bank", ("kind", "poles")),
    "structured": ("structured_bank", ("structure", "poles", "faults")),
    "rls": ("rls_estimator", ("order", "ts_design")),
    "data": ("data_driven", ("order", "kind", "record")),
}

DESIGN_HELP = """\
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


def _load_model(path):
    """A model file; a plant FMU is refused with the command that turns it into one."""
    from .model import FDIModel

    if str(path).lower().endswith(".fmu"):
        raise ModelError(f"{path} is an FMU, not a model file: run 'fmu-fdi model {path} --inputs ... --outputs ... "
                         f"-o MODEL.toml' first (see docs/plant-fmu.md)")
    return FDIModel.from_file(path)


def _model(args) -> int:
    from .identify import Excitation, model_from_fmu
    from .identify.fmu_model import parse_values, summary

    exc = Excitation(signal=args.signal, amplitude=parse_values(args.amplitude, "--amplitude") or None,
                     samples=args.samples, settle=args.settle, period=args.period, seed=args.seed)
    model = model_from_fmu(args.plant, args.inputs, args.outputs, args.disturbances or (),
                           at=parse_values(args.at, "--at"), method=args.method, trim=args.trim,
                           sensor_faults=args.sensor_faults, actuator_faults=args.actuator_faults, ts=args.ts,
                           excite=args.excite, excitation=exc, order=args.order, min_fit=args.min_fit,
                           validation_png=args.plot, record=args.record)
    print(f"wrote {model.to_file(args.output)}: {summary(model)}")
    return 0


def _analyze(args) -> int:
    from .analysis import detectability, isolability

    model = _load_model(args.model)
    set_stage(f"detectability analysis (n = {model.n} states, {len(model.faults)} faults)")
    det = detectability(model)
    set_stage(f"isolability analysis (n = {model.n} states, {len(model.faults)} faults)")
    iso = isolability(model)
    print(f"model '{model.name}': n={model.n}, u={model.u_names}, y={model.y_names}, d={model.d_names}, "
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


def _thresholds(text: str, gen, evaluation: dict, calibrate=None):
    from .evaluation import (analytic_threshold, data_driven_threshold, fault_size_thresholds, sensor_gain_plants,
                             threshold_selector)

    kind, _, arg = text.partition(":")
    try:
        if kind == "sigma":
            from scipy.stats import chi2

            alpha = float(arg)
            return [float(np.sqrt(chi2.ppf(1 - alpha, len(g)))) for g in gen.groups]
        if kind == "analytic":
            parts = [float(x) for x in arg.split(",")]
            alpha, std = parts[0], (parts[1] if len(parts) > 1 else 1.0)
            cov = std * std * np.eye(gen.model.nw) if gen.model.nw else None
            return [analytic_threshold(gen, evaluation, alpha, noise_cov=cov, group=i) for i in range(len(gen.groups))]
        if kind == "data":
            if calibrate is None:
                raise DesignError("--threshold data:RATE needs a fault-free record: --calibrate CSV")
            from .diagnoser import Diagnoser

            t, u, y = _read_record(calibrate, gen.model)
            probe = Diagnoser(gen, evaluation=evaluation, thresholds=1e300)  # evaluations only
            out = probe.run(t, u, y)
            rate = float(arg)
            try:
                return [data_driven_threshold(out[f"evaluation_{i + 1}"], rate) for i in range(len(gen.groups))]
            except ValueError as exc:  # the record cannot support the estimate: say why
                raise DesignError(f"--threshold {text} from {calibrate}: {exc}") from None
        if kind == "fixed":
            return float(arg)
        if kind == "fault-size":
            return fault_size_thresholds(gen, evaluation, float(arg or 1.0))
        if kind == "sensor-gain":
            delta, J0 = (float(x) for x in arg.split(","))
            plants = sensor_gain_plants(gen.model, delta)
            return [threshold_selector(gen, evaluation, J0=J0, plants=plants)] * len(gen.groups)
    except ValueError as exc:
        if isinstance(exc, (DesignError, ModelError)):
            raise
    raise DesignError(f"cannot read threshold {text!r}: use fault-size:F, fixed:V, sensor-gain:DELTA,J0, "
                      f"analytic:ALPHA[,STD], data:RATE or sigma:ALPHA")


def _read_record(path, model):
    """A CSV record with a time column and the model's u and y columns (by name)."""
    from .cosim import Result

    rec = Result.from_csv(path)
    head = list(rec.dtype.names)
    missing = [n for n in ["time"] + list(model.u_names) + list(model.y_names) if n not in head]
    if missing:
        raise DesignError(f"{path}: columns {missing} are missing (found {head})")
    u = np.column_stack([rec[n] for n in model.u_names]) if model.nu else np.zeros((len(rec), 0))
    return np.asarray(rec["time"]), u, np.column_stack([rec[n] for n in model.y_names])


def _design(args) -> int:
    from . import design as design_pkg
    from .diagnoser import Diagnoser

    model = _load_model(args.model)
    fname, takes = METHODS[args.method]
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
        kw["S"] = np.array([[int(x) for x in row.split(",")] for row in args.structure.split(";")])
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
        thresholds = _thresholds(args.threshold or "fault-size:1", gen, evaluation, args.calibrate)
    decision = {"persistence": [int(x) for x in args.persistence.split("/")], "latch": args.latch}
    dg = Diagnoser(gen, evaluation=evaluation, thresholds=thresholds, decision=decision, name=args.name)
    path = dg.save(args.output)
    order = gen.Q.n if hasattr(gen, "Q") else "-"
    print(f"wrote {path}: method {gen.method}, {gen.n_residuals} residual(s) in {len(gen.groups)} group(s), "
          f"order {order}, Ts = {gen.dt:g} s, isolation "
          f"'{dg.design['decision']['isolation']}'")
    return 0


def _plot(args) -> int:
    import json

    from .cosim import Result
    from .report import plot_diagnosis

    res = Result.from_csv(args.result)
    prefix = args.prefix
    if prefix is None:  # the diagnoser instance of a co-simulation result, or none for Diagnoser.run
        hits = [n[: -len("fault_detected")] for n in res.dtype.names if n.endswith("fault_detected")]
        if len(hits) != 1:
            raise DesignError(f"{args.result}: give --prefix, found diagnoser outputs under {hits or 'no prefix'}")
        prefix = hits[0]
    faults = []
    if args.design:
        faults = [f["name"] for f in json.loads(open(args.design, encoding="utf-8").read())["faults"]]
    path = plot_diagnosis(res, args.output, prefix=prefix, fault_names=faults, title=str(args.result))
    t = res["time"]
    det = res[f"{prefix}fault_detected"].astype(bool)
    iso = res[f"{prefix}isolated_fault"]
    first = float(t[det][0]) if det.any() else None
    named = sorted({int(v) for v in iso if v != 0})
    label = {0: "none", -1: "unknown"}
    names = [label.get(v) or (faults[v - 1] if faults and v <= len(faults) else str(v)) for v in named]
    print(f"wrote {path}; first alarm at t = {first if first is not None else '-'} s; isolated as: "
          f"{', '.join(names) or '-'}")
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

    path = build_fmu(args.design, args.output, target=args.target, fmi_version=args.fmi)
    print(f"wrote {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="fmu-fdi", description="Model-based fault detection and isolation as FMUs.")
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("analyze", help="detectability / isolability table of a model file")
    a.add_argument("model", help="model file (.toml or .json)")
    a.set_defaults(func=_analyze)

    pl = sub.add_parser("plants", help="benchmark plant FMUs (plant_fmus)")
    pl_sub = pl.add_subparsers(dest="plants_command", required=True)
    pb = pl_sub.add_parser("build", help="build every benchmark plant FMU")
    pb.add_argument("--out", default="out", help="output folder (default: out)")
    pb.set_defaults(func=_plants_build)

    pp = sub.add_parser("plot", help="PNG of residuals, thresholds, alarms and isolation from a result CSV")
    pp.add_argument("result", help="CSV from 'fmu-fdi simulate' or Result.to_csv")
    pp.add_argument("-o", "--output", required=True, help="PNG to write")
    pp.add_argument("--prefix", help="column prefix of the diagnoser outputs (default: found)")
    pp.add_argument("--design", help="design file, to label the isolated faults by name")
    pp.set_defaults(func=_plot)

    dm = sub.add_parser("demo", help="the three-tank demo: plant FMU, diagnoser design, diagnostic FMU, "
                                     "co-simulations, table and plot")
    dm.add_argument("--out", default="fmu-fdi-demo", help="output folder (default: fmu-fdi-demo)")
    dm.add_argument("--target", choices=("pythonfmu", "native"), default="pythonfmu",
                    help="diagnostic FMU target (native: C, FMI 2.0, compiled with the system C compiler)")
    dm.set_defaults(func=_demo)

    from .cosim import cli as cosim_cli

    cosim_cli.add_parser(sub)

    from .campaign import cli as campaign_cli

    campaign_cli.add_parser(sub)

    d = sub.add_parser("design", help="design a diagnoser and write its design file",
                       formatter_class=argparse.RawDescriptionHelpFormatter, epilog=DESIGN_HELP)
    d.add_argument("model", help="model file (.toml or .json)")
    d.add_argument("--method", required=True, choices=sorted(METHODS))
    d.add_argument("-o", "--output", required=True, help="design file to write (.json)")
    d.add_argument("--ts", type=float, help="diagnosis sample time for a continuous model (s)")
    d.add_argument("--poles", type=float, nargs="+", help="filter poles (real)")
    d.add_argument("--rdim", type=int, help="number of residuals")
    d.add_argument("--order", type=int, help="parity order / ARX order")
    d.add_argument("--kind", default="sensor", choices=("sensor", "actuator", "detection"),
                   help="faults of a DOS/GOS bank; data: 'sensor' (a bank) or 'detection' (one relation)")
    d.add_argument("--structure", help="structure matrix for --method structured, rows separated by ';'")
    d.add_argument("--Qw", type=float, nargs="+", help="Kalman: noise variances (diagonal of Qw)")
    d.add_argument("--Rv", type=float, nargs="+", help="Kalman: measurement noise variances (diagonal of Rv)")
    d.add_argument("--evaluation", help="evaluation function (default rms:10; norm for rls)")
    d.add_argument("--threshold", help="threshold (default fault-size:1; sigma:1e-4 for rls)")
    d.add_argument("--faults", nargs="+", help="fdf: the faults to give fixed directions (state-entering ones); "
                                               "structured: the faults the columns of --structure refer to")
    d.add_argument("--calibrate", help="fault-free record (CSV) for --threshold data:RATE and --method data")
    d.add_argument("--persistence", default="1/1", help="alarm persistence k/n (default 1/1)")
    d.add_argument("--latch", action="store_true", help="latch alarms until reset")
    d.add_argument("--name", help="diagnoser name (default MODEL_METHOD)")
    d.set_defaults(func=_design)

    mo = sub.add_parser("model", help="linear model file of a plant FMU: linearised (model exchange) or "
                                      "identified from an experiment (co-simulation)")
    mo.add_argument("plant", help="plant FMU (FMI 2.0 or 3.0)")
    mo.add_argument("-o", "--output", required=True, help="model file to write (.toml or .json)")
    mo.add_argument("--inputs", nargs="+", help="known inputs u (FMU variables)")
    mo.add_argument("--outputs", nargs="+", help="measured outputs y (FMU outputs)")
    mo.add_argument("--disturbances", nargs="+", help="unknown inputs d (FMU inputs)")
    mo.add_argument("--at", nargs="+", metavar="NAME=VALUE", help="operating point: inputs, parameters, states")
    mo.add_argument("--trim", action=argparse.BooleanOptionalAction, default=True,
                    help="model exchange: find the steady state from the inputs (default on)")
    mo.add_argument("--method", default="auto", choices=("auto", "linearise", "identify"))
    mo.add_argument("--sensor-faults", nargs="+", help="'all' or output names: additive sensor faults")
    mo.add_argument("--actuator-faults", nargs="+", help="'all' or input names: additive actuator faults")
    mo.add_argument("--ts", type=float, help="identification sample time (default: the FMU's default step)")
    mo.add_argument("--excite", nargs="+", help="FMU inputs to excite (default: the model inputs that are FMU inputs)")
    mo.add_argument("--signal", default="multisine", choices=("multisine", "prbs"))
    mo.add_argument("--amplitude", nargs="+", metavar="NAME=A", help="peak excitation per input (default 5 %%)")
    mo.add_argument("--samples", type=int, default=2000, help="recorded steps per run (default 2000)")
    mo.add_argument("--settle", type=float, help="seconds at the operating point first (default 200 steps)")
    mo.add_argument("--period", type=int, default=1, help="PRBS clock period in steps")
    mo.add_argument("--seed", type=int, default=0, help="excitation seed (validation run: seed + 1)")
    mo.add_argument("--order", type=int, help="model order (default: from the singular values)")
    mo.add_argument("--min-fit", type=float, default=50.0, help="refuse a validation fit below this (%%, default 50)")
    mo.add_argument("--plot", help="PNG of measured vs model outputs on the validation run")
    mo.add_argument("--record", help="CSV of the identification run (a fault-free log for --method data)")
    mo.set_defaults(func=_model)

    b = sub.add_parser("build", help="build the diagnostic FMU (co-simulation) from a design file")
    b.add_argument("design", help="design file (.json) written by 'fmu-fdi design' or Diagnoser.save")
    b.add_argument("-o", "--output", required=True, help="FMU to write (.fmu)")
    b.add_argument("--target", choices=("pythonfmu", "native"), default="pythonfmu",
                   help="pythonfmu (default; the host needs Python + numpy) or native (C, compiled now)")
    b.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (3 needs --target native)")
    b.set_defaults(func=_build)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        with Heartbeat():  # long commands (large models) report their stage on stderr
            return args.func(args)
    except (ModelError, DesignError, CoSimulationError) as exc:
        print(f"fmu-fdi: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
