"""``fmu-fdi campaign CAMPAIGN.toml -o DIR``: run a fault-injection campaign and write its report —
a veneer over :func:`~fmu_fdi.campaign.runner.run_campaign`, :func:`~fmu_fdi.campaign.aggregate.aggregate`
and :func:`~fmu_fdi.campaign.report.write_report`.

Exit status: 0 done (failed runs are listed in the report); 2 a set-up error (bad campaign file,
FMU, existing results without --resume); 130 stopped by Ctrl-C (finished runs are kept: rerun
with --resume).
"""
from __future__ import annotations

import sys

_DESCRIPTION = """\
Run every scenario of a campaign file (fault kind, target, magnitude, onset, duration, noise
seeds, plant parameters; format in fmu_fdi.campaign.spec) as a co-simulation, append each run's
summary to DIR/runs.jsonl as it finishes, then write DIR/report.html and the CSV tables.
--dry-run lists the runs. --resume skips the runs already in DIR/runs.jsonl. Runs go to a local
process pool (--workers N) or a Dask scheduler (--scheduler tcp://HOST:PORT, or 'local' for a
LocalCluster of --workers processes)."""


def add_parser(subparsers):
    """Add the ``campaign`` command to an ``argparse`` sub-parser set; returns the parser."""
    p = subparsers.add_parser("campaign", help="run a fault-injection campaign and write its report",
                              description=_DESCRIPTION)
    p.add_argument("campaign", nargs="?", help="campaign file (.toml, format fmu-fdi-campaign/1)")
    p.add_argument("-o", "--output", metavar="DIR", help="results and report folder (no default: required to run)")
    p.add_argument("--example", metavar="DIR", help="write the example campaign DIR/dts200.toml and the FMUs it "
                                                    "runs (the DTS200 plant and a sensor observer bank), then stop "
                                                    "(default: none)")
    p.add_argument("--dry-run", action="store_true", help="list the runs and stop (default: run them)")
    p.add_argument("--resume", action="store_true", help="keep the finished runs of DIR/runs.jsonl, run the rest (default: start afresh)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1: this process)")
    p.add_argument("--scheduler", metavar="ADDR", help="Dask scheduler address, or 'local' for a LocalCluster (default: none, a local process pool)")
    p.add_argument("--traces", action="store_true", help="also keep every run's full record as DIR/traces/*.csv "
                                                         "(as [output] traces = true; default: summaries only)")
    p.add_argument("--no-progress", action="store_true", help="no progress line (default: a progress line on stderr)")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Execute ``fmu-fdi campaign`` with parsed ``args``; returns the exit status."""
    from ..cosim import CoSimulationError
    from .aggregate import aggregate
    from .report import write_report
    from .runner import run_campaign
    from .spec import CampaignSpec

    if args.example:
        from .example import write_example

        return write_example(args.example)
    if not args.campaign or not args.output:
        missing = [x for x, v in (("CAMPAIGN", args.campaign), ("-o DIR", args.output)) if not v]
        print(f"fmu-fdi campaign: error: give {' and '.join(missing)} (or --example DIR for a campaign to start "
              f"from)", file=sys.stderr)
        return 2
    try:
        spec = CampaignSpec.load(args.campaign)
        spec.traces = spec.traces or args.traces
        if args.dry_run:
            runs = spec.runs()
            for r in runs:
                f = r.fault
                what = ("fault-free" if f is None else
                        f"{f['kind']} {f['target']} {f['magnitude']:g} from {f['onset']:g} s"
                        + ("" if f["duration"] is None else f" for {f['duration']:g} s"))
                params = " ".join(f"{k}={v}" for k, v in r.parameters.items())
                held = " ".join(f"{k}={v:g}" for k, v in (r.operating_point or {}).items() if "." not in k)
                print(f"{r.index:6d}  {r.key}  {what}  {params}" + (f"  at {held}" if held else ""))
            print(f"{len(runs)} runs, {len(spec.fmus)} FMUs, {spec.stop - spec.start:g} s each")
            return 0
        results = run_campaign(spec, args.output, workers=args.workers, scheduler=args.scheduler,
                               resume=args.resume, progress=None if not args.no_progress else False)
        files = write_report(aggregate(results), args.output)
    except (CoSimulationError, FileNotFoundError) as exc:
        print(f"fmu-fdi campaign: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    done = len(results.records)
    planned = results.extra.get("planned", done)
    print(f"{done} of {planned} planned runs in {results.path} ({results.skipped} from before, "
          f"{len(results.failed)} failed, {results.seconds:.1f} s); report {files['report']}")
    if results.interrupted:
        print("fmu-fdi campaign: stopped before the end; run again with --resume", file=sys.stderr)
        return 130
    return 0
