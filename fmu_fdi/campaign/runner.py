"""Running a campaign: serially, on a local process pool, or on a Dask cluster; results appended
to ``DIR/runs.jsonl`` as each run finishes.

The results file is JSON lines: a header line ``{"format": "fmu-fdi-campaign-results/1",
"campaign": ..., "runs": N}`` and one record per finished run (:meth:`Worker.run`), in the order
they finished. A record is written and flushed the moment its run is back, so a killed
campaign loses only the runs in flight; ``resume=True`` reads the file (a torn last line is
dropped), skips every run whose scenario key is there, and appends the rest. A run's record
depends only on the run (its seeds are part of it; instances are reset between runs), never on
the worker or the order, so a resumed or parallel campaign gives the records of a serial one.

Execution
---------
- ``workers=1``: in this process (no pickling, the simplest to debug).
- ``workers=N > 1``: a ``concurrent.futures.ProcessPoolExecutor`` of N spawned processes.
- ``scheduler="tcp://host:port"``: an existing Dask distributed scheduler; ``scheduler="local"``:
  a ``dask.distributed.LocalCluster`` of ``workers`` single-threaded worker processes.

Traces (``[output] traces``, ``--traces``) are written by the worker that ran the run into
``DIR/traces``: with a remote scheduler that folder must be on a file system the workers share.

Every worker process receives the FMUs' bytes once (pool initialiser; Dask: one scattered,
broadcast payload), extracts and instantiates each FMU once and resets it between runs
(:class:`~fmu_fdi.campaign.execute.PooledInstance`). Ctrl-C (KeyboardInterrupt) cancels what is
queued, stops the workers and returns what finished, marked ``interrupted``.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from .execute import Worker
from .spec import CampaignError, CampaignSpec

RESULTS_FORMAT = "fmu-fdi-campaign-results/1"
RESULTS_FILE = "runs.jsonl"

_WORKERS: dict = {}  # this process's Worker per campaign payload id (pool and Dask workers)


@dataclass
class CampaignResults:
    """The records of a campaign run, sorted by run index.

    Attributes
    ----------
    spec : CampaignSpec
    records : list of dict
        One per finished run (see :mod:`fmu_fdi.campaign.execute`).
    path : Path
        The results file.
    interrupted : bool
        True if the campaign stopped (Ctrl-C) before every run finished.
    seconds : float
        Wall time of this invocation.
    skipped : int
        Runs found finished in the results file (``resume``).
    """

    spec: CampaignSpec
    records: list
    path: Path
    interrupted: bool = False
    seconds: float = 0.0
    skipped: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def failed(self) -> list:
        """Records of runs an FMU failed in."""
        return [r for r in self.records if r["status"] != "ok"]


def payload(spec: CampaignSpec, traces_dir=None) -> dict:
    """What a worker needs: the set-up, the FMUs' bytes and the sweep's scales (picklable)."""
    return {"id": f"{spec.name}-{os.getpid()}-{time.time_ns()}",
            "fmus": {name: Path(p).read_bytes() for name, p in spec.fmus.items()},
            "connections": spec.connections, "inputs": spec.inputs, "step": spec.step, "stop": spec.stop,
            "start": spec.start, "order": spec.order, "parameters": spec.parameters,
            "diagnosers": spec.diagnosers, "zone_start": spec.analysis["zone_start"],
            "scales": spec.scales.tolist(), "traces_dir": None if traces_dir is None else str(traces_dir)}


def read_results(path) -> tuple[dict | None, list]:
    """(header, records) of a results file; a torn last line (killed writer) is left out."""
    path = Path(path)
    if not path.is_file():
        return None, []
    header, records = None, []
    lines = path.read_text(encoding="utf-8").splitlines()
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
        except json.JSONDecodeError:
            if i == len(lines) - 1:
                break  # the line being written when the campaign was killed
            raise CampaignError(f"results file {path}, line {i + 1}: not JSON") from None
        if i == 0:
            if item.get("format") != RESULTS_FORMAT:
                raise CampaignError(f"results file {path}: format {item.get('format')!r} is not {RESULTS_FORMAT!r}")
            header = item
        else:
            records.append(item)
    return header, records


def run_campaign(spec, out_dir, *, workers: int = 1, scheduler: str | None = None, resume: bool = False,
                 progress=None, runs=None) -> CampaignResults:
    """Run every run of ``spec`` not yet in ``out_dir/runs.jsonl``; return all the records.

    Parameters
    ----------
    spec : CampaignSpec or path
    out_dir : path
        Created if needed; holds ``runs.jsonl`` and (``[output] traces``) ``traces/``.
    workers : int
        Worker processes (1: in this process).
    scheduler : str, optional
        Dask scheduler address, or ``"local"`` for a LocalCluster of ``workers`` processes.
    resume : bool
        Keep the finished runs of an existing results file and run the others. Without it an
        existing, non-empty results file is an error (nothing is overwritten).
    progress : bool or callable, optional
        True: a progress line on stderr (runs done, rate, time left); a callable gets
        ``(done, total, elapsed_seconds)``; default: on when stderr is a terminal.
    runs : list of Run, optional
        A subset of ``spec.runs()`` (tests, partial campaigns).
    """
    tic = time.perf_counter()
    spec = spec if isinstance(spec, CampaignSpec) else CampaignSpec.load(spec)
    if not isinstance(workers, int) or workers < 1:
        raise CampaignError(f"workers must be an integer >= 1, got {workers!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / RESULTS_FILE
    all_runs = spec.runs() if runs is None else list(runs)
    header, done = read_results(path)
    if done or header:
        if not resume:
            raise CampaignError(f"{path} already holds {len(done)} finished run(s): resume them (--resume) "
                                f"or write to another folder")
        if header and header.get("campaign") != spec.name:
            raise CampaignError(f"{path} belongs to campaign {header.get('campaign')!r}, not {spec.name!r}")
    keys = {r.key for r in all_runs}
    done = [r for r in done if r["run"]["key"] in keys]
    finished = {r["run"]["key"] for r in done}
    todo = [r for r in all_runs if r.key not in finished]
    traces = out / "traces" if spec.traces else None
    if traces is not None:
        traces.mkdir(exist_ok=True)
    report = _progress(progress)
    records = list(done)
    interrupted = False
    with open(path, "a", encoding="utf-8") as fh:
        if header is None:
            _write(fh, {"format": RESULTS_FORMAT, "campaign": spec.name, "runs": len(all_runs),
                        "scales": spec.scales.tolist()})
        if todo:
            work = payload(spec, traces)
            started = time.perf_counter()

            def take(record):
                _write(fh, record)
                records.append(record)
                report(len(records) - len(done), len(todo), time.perf_counter() - started)

            with _StopOnInterrupt() as stop:
                try:
                    if scheduler is not None:
                        _on_dask(work, todo, take, scheduler, workers, stop)
                    elif workers > 1:
                        _on_pool(work, todo, take, workers, stop)
                    else:
                        _serial(work, todo, take, stop)
                except KeyboardInterrupt:
                    stop.requested = True
                interrupted = stop.requested and len(records) < len(done) + len(todo)
            report(None, None, None)
    records.sort(key=lambda r: r["run"]["index"])
    return CampaignResults(spec, records, path, interrupted, time.perf_counter() - tic, len(done))


# ------------------------------------------------------------------------ backends
def _write(fh, item):
    fh.write(json.dumps(item, allow_nan=False) + "\n")
    fh.flush()


class _StopOnInterrupt:
    """Ctrl-C asks the campaign to stop: no new run starts, the finished ones are kept (a run in
    this process is never cut in the middle: the FMU would report a bogus failure). A second
    Ctrl-C interrupts at once."""

    def __enter__(self):
        import threading

        self.requested = False
        self._old = None
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        sys.stderr.write("\nfmu-fdi campaign: stopping (finished runs are kept; Ctrl-C again to abort)\n")

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        return False


def _serial(work, todo, take, stop):
    worker = Worker(work)
    try:
        for run in todo:
            if stop.requested:
                break
            take(worker.run(run.to_dict()))
    finally:
        worker.close()


def _init_pool(work):
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    _WORKERS[work["id"]] = Worker(work)


def _pool_run(work_id, run):
    return _WORKERS[work_id].run(run)


def _on_pool(work, todo, take, workers, stop):
    import concurrent.futures as cf
    import multiprocessing as mp

    pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=mp.get_context("spawn"),
                                  initializer=_init_pool, initargs=(work,))
    futures = []
    try:
        futures = [pool.submit(_pool_run, work["id"], r.to_dict()) for r in todo]
        pending = set(futures)
        while pending and not stop.requested:
            finished, pending = cf.wait(pending, timeout=0.25, return_when=cf.FIRST_COMPLETED)
            for fut in finished:
                take(fut.result())
    finally:
        for fut in futures:
            fut.cancel()
        if stop.requested or any(not f.done() for f in futures):
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()  # a worker may be deep in a long run: stop it now
        pool.shutdown(wait=True, cancel_futures=True)


def _dask_run(work, run):
    """A Dask task: the calling worker process keeps one Worker per campaign payload."""
    worker = _WORKERS.get(work["id"])
    if worker is None:
        for old in list(_WORKERS):  # one campaign at a time per process: free the previous one's FMUs
            _WORKERS.pop(old).close()
        worker = _WORKERS[work["id"]] = Worker(work)
    return worker.run(run)


def _on_dask(work, todo, take, scheduler, workers, stop):
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler == "local":
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        client = Client(scheduler)
    futures = []
    try:
        shipped = client.scatter(work, broadcast=True)
        futures = [client.submit(_dask_run, shipped, r.to_dict(), key=f"fmu-fdi-run-{work['id']}-{r.index}",
                                 pure=False) for r in todo]
        for fut in as_completed(futures):  # a stop request is seen at the next finished run
            take(fut.result())
            if stop.requested:
                break
    finally:
        if futures:
            client.cancel(futures)
        client.close()
        if cluster is not None:
            cluster.close()


# ------------------------------------------------------------------------ progress
def _progress(progress):
    if callable(progress):
        return lambda d, n, s: None if d is None else progress(d, n, s)
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return lambda d, n, s: None
    state = {"last": 0.0}

    def show(done, total, elapsed):
        if done is None:
            sys.stderr.write("\n")
            return
        if done < total and elapsed - state["last"] < 0.2:
            return
        state["last"] = elapsed
        rate = done / elapsed if elapsed > 0 else 0.0
        left = (total - done) / rate if rate > 0 else float("inf")
        width = 30
        filled = int(width * done / total)
        bar = "#" * filled + "-" * (width - filled)
        eta = "?" if left == float("inf") else _clock(left)
        sys.stderr.write(f"\r[{bar}] {done}/{total} runs  {rate:.2f} runs/s  {_clock(elapsed)} elapsed  "
                         f"{eta} left ")
        sys.stderr.flush()

    return show


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"
