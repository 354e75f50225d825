"""Running a campaign: serially, on a local process pool, or on a Dask cluster; results appended
to ``DIR/runs.jsonl`` as each run finishes.

The results file is JSON lines: a header line ``{"format": "fmu-fdi-campaign-results/1",
"campaign": ..., "runs": N}`` and one record per finished run (:meth:`Worker.run`), in the order
they finished. A record is written and flushed to the operating system the moment its run is
back, so a killed campaign loses only the runs in flight; the file is synced to the disk at most
every :data:`SYNC_EVERY` seconds and at the end (a sync costs milliseconds, as much as a run), so
a crash of the machine itself loses at most that much more; ``resume=True`` reads the file, skips every run whose
scenario key is there, and appends the rest. A torn last line (a writer killed mid-line, a full
disk) is cut off the file before anything is appended, so the file stays readable however often
it is resumed. A record whose run key came before is left out with a warning (each run counts
once). One campaign process at a time writes a folder: it holds an exclusive lock on
``DIR/.lock`` for as long as it runs; a second one is refused with the first one's process id. A run's record
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
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from ..progress import note, own_display, set_stage
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
    """(header, records) of a results file; a torn last line (killed writer) is left out, and a
    record whose run key came before is left out with a :class:`CampaignWarning`."""
    header, records, notes = _read(path)
    for note in notes:
        warnings.warn(note, CampaignWarning, stacklevel=2)
    return header, records


class CampaignWarning(UserWarning):
    """Something in a results file was left out (a duplicated run)."""


def _read(path) -> tuple[dict | None, list, list]:
    """(header, records, notes): the checked content of a results file (see :func:`read_results`)."""
    path = Path(path)
    if not path.is_file():
        return None, [], []
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise CampaignError(f"results file {path}, line {line}: not UTF-8 text (byte {exc.start}); "
                            f"it was not written by fmu-fdi campaign") from None
    header, records, seen, notes = None, [], {}, []
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
        except (json.JSONDecodeError, RecursionError):
            if i == len(lines) - 1 and not text.endswith("\n"):
                break  # the line being written when the campaign was killed
            raise CampaignError(f"results file {path}, line {i + 1}: not JSON") from None
        if i == 0:
            if not isinstance(item, dict) or item.get("format") != RESULTS_FORMAT:
                got = item.get("format") if isinstance(item, dict) else item
                raise CampaignError(f"results file {path}: format {got!r} is not {RESULTS_FORMAT!r}")
            header = item
            continue
        why = _record_problem(item)
        if why:
            raise CampaignError(f"results file {path}, line {i + 1}: not a run record ({why})")
        key = item["run"]["key"]
        if key in seen:
            notes.append(f"results file {path}, line {i + 1}: run {item['run']['index']} (key {key}) is already "
                         f"on line {seen[key]}; counted once")
            continue
        seen[key] = i + 1
        records.append(item)
    return header, records, notes


def _record_problem(item) -> str:
    """What is wrong with the shape of a run record, or '' (see :meth:`Worker.run`)."""
    if not isinstance(item, dict):
        return f"a JSON {type(item).__name__}, not an object"
    run = item.get("run")
    if not isinstance(run, dict) or not isinstance(run.get("key"), str) or isinstance(run.get("index"), bool) \
            or not isinstance(run.get("index"), int):
        return "'run' must hold an integer 'index' and a string 'key'"
    if "fault" not in run or not isinstance(run["fault"], (dict, type(None))):
        return "'run' must hold 'fault' (an object or null)"
    if item.get("status") not in ("ok", "failed"):
        return f"'status' is {item.get('status')!r}, not 'ok' or 'failed'"
    if item["status"] == "ok" and not (isinstance(item.get("diagnosers"), dict)
                                       and all(isinstance(d, dict) for d in item["diagnosers"].values())):
        return "an 'ok' record must hold 'diagnosers', an object of objects"
    return ""


def _repair_tail(path: Path) -> None:
    """Make ``path`` end at a line end before anything is appended: a last line without its
    newline that is a whole record gets the newline, any other (a torn write) is cut off."""
    if not path.is_file():
        return
    with open(path, "rb+") as fh:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        if size == 0:
            return
        fh.seek(max(0, size - 1))
        if fh.read(1) == b"\n":
            return
        back = min(size, 1 << 20)
        while True:  # find the last newline
            fh.seek(size - back)
            chunk = fh.read(back)
            cut = chunk.rfind(b"\n")
            if cut >= 0 or back == size:
                break
            back = min(size, back * 4)
        start = size - back + cut + 1 if cut >= 0 else 0
        fh.seek(start)
        tail = fh.read()
        try:
            whole = isinstance(json.loads(tail.decode("utf-8")), dict)
        except (ValueError, RecursionError):
            whole = False
        if whole:
            fh.seek(0, os.SEEK_END)
            fh.write(b"\n")
        else:
            fh.truncate(start)
            sys.stderr.write(f"fmu-fdi campaign: note: cut a torn last line of {len(tail)} bytes off {path} "
                             f"(a run that was being written when the campaign stopped; it runs again)\n")
        fh.flush()
        os.fsync(fh.fileno())


class FolderLock:
    """An exclusive lock on ``DIR/.lock`` held while a campaign writes ``DIR`` (POSIX ``flock``:
    released by the kernel when the process ends, however it ends)."""

    def __init__(self, folder: Path):
        self.path = Path(folder) / ".lock"
        self._fh = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:  # not POSIX: no lock
            return self
        fh = open(self.path, "a+", encoding="utf-8")
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            holder = fh.read().strip() or "another process"
            fh.close()
            raise CampaignError(f"{self.path.parent} is in use by another fmu-fdi campaign ({holder}); wait for "
                                f"it to finish, or write to another folder") from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"process {os.getpid()}")
        fh.flush()
        self._fh = fh
        return self

    def __exit__(self, *exc):
        if self._fh is not None:
            self._fh.close()  # closing releases the lock
            self._fh = None
        return False


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
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise CampaignError(f"workers must be an integer >= 1, got {workers!r}")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise CampaignError(f"scheduler must be a Dask scheduler address (tcp://HOST:PORT) or 'local', "
                            f"got {scheduler!r}")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise CampaignError(f"output folder {str(out)!r} is a file")
    out.mkdir(parents=True, exist_ok=True)
    all_runs = spec.runs() if runs is None else list(runs)
    with FolderLock(out):
        return _run_locked(spec, out, all_runs, workers, scheduler, resume, progress, tic)


def _run_locked(spec, out, all_runs, workers, scheduler, resume, progress, tic) -> CampaignResults:
    path = out / RESULTS_FILE
    if resume:
        _repair_tail(path)
    header, done, notes = _read(path)
    for text in notes:
        sys.stderr.write(f"fmu-fdi campaign: warning: {text}\n")
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
            synced = [time.monotonic()]

            def take(record):
                _write(fh, record, synced)
                records.append(record)
                report(len(records) - len(done), len(todo), time.perf_counter() - started)
                note(f"campaign {spec.name}: {len(records) - len(done)} of {len(todo)} runs done"
                     + (f" ({len(done)} from before)" if done else ""))

            set_stage(f"campaign {spec.name}: 0 of {len(todo)} runs done" + (f" ({len(done)} from before)"
                                                                             if done else ""))

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
                fh.flush()
                os.fsync(fh.fileno())  # every record on the disk before the campaign returns
            report(None, None, None)
    records.sort(key=lambda r: r["run"]["index"])
    return CampaignResults(spec, records, path, interrupted, time.perf_counter() - tic, len(done),
                           extra={"planned": len(all_runs), "warnings": notes})


# ------------------------------------------------------------------------ backends
#: seconds between two syncs of the results file to the disk (see the module docstring)
SYNC_EVERY = 0.5


def _write(fh, item, synced=None):
    """Append ``item`` as a line and flush it to the operating system (a killed process loses
    nothing written); sync the file to the disk when ``synced`` (the time of the last sync, a
    one-item list) is None or older than :data:`SYNC_EVERY` seconds."""
    fh.write(json.dumps(item, allow_nan=False) + "\n")
    fh.flush()
    now = time.monotonic()
    if synced is None or now - synced[0] >= SYNC_EVERY:
        os.fsync(fh.fileno())
        if synced is not None:
            synced[0] = now


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


def _init_pool(work, parent=None):
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    if parent is not None:
        _watch_parent(parent)
    _WORKERS[work["id"]] = Worker(work)


def _watch_parent(parent: int, every: float = 0.5) -> None:
    """End this worker process when the campaign process ``parent`` is gone (killed with
    SIGKILL it cannot stop its pool): a daemon thread polls the parent process id."""
    import threading

    def watch():
        while True:
            time.sleep(every)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="fmu-fdi parent watch", daemon=True).start()


def _pool_run(work_id, run):
    return _WORKERS[work_id].run(run)


#: runs submitted to the pool at a time, per worker process
POOL_WINDOW = 4

#: a run in flight when its worker process died this many times is recorded as failed
WORKER_DEATHS_PER_RUN = 2


def _on_pool(work, todo, take, workers, stop):
    """Run ``todo`` on a process pool. A worker process that dies (killed, crashed in an FMU)
    breaks the pool: the loss is reported, a new pool takes the unfinished runs, and a run that
    was in flight at WORKER_DEATHS_PER_RUN deaths is recorded as failed (it may be what kills
    its worker) so the campaign always ends."""
    deaths: dict = {}
    remaining = list(todo)
    while remaining and not stop.requested:
        lost = _pool_pass(work, remaining, take, workers, stop)
        if lost is None:
            return
        in_flight, unfinished = lost
        for r in in_flight:
            deaths[r.index] = deaths.get(r.index, 0) + 1
        given_up = [r for r in unfinished if deaths.get(r.index, 0) >= WORKER_DEATHS_PER_RUN]
        for r in given_up:
            record = {"run": r.to_dict(), "status": "failed", "pid": None, "reused": False, "seconds": 0.0,
                      "error": f"its worker process died {deaths[r.index]} times while running it "
                               f"(killed, or crashed inside an FMU)"}
            take(record)
        remaining = [r for r in unfinished if r not in given_up]
        sys.stderr.write(f"fmu-fdi campaign: warning: a worker process died (killed, or crashed inside an FMU) "
                         f"with {len(in_flight)} run(s) in flight; "
                         + (f"{len(given_up)} run(s) recorded as failed; " if given_up else "")
                         + (f"{len(remaining)} unfinished run(s) go to new workers\n" if remaining else "\n"))


def _pool_pass(work, todo, take, workers, stop):
    """One process pool over ``todo``: None when it ended normally (or was stopped), else
    (runs in flight when a worker died, runs not finished)."""
    import concurrent.futures as cf
    import multiprocessing as mp
    from concurrent.futures.process import BrokenProcessPool

    pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=mp.get_context("spawn"),
                                  initializer=_init_pool, initargs=(work, os.getpid()))
    futures = {}
    taken = set()
    broken = False

    def ok(f):
        return f.done() and not f.cancelled() and f.exception() is None

    queued = iter(todo)
    window = max(2, POOL_WINDOW * workers)

    queued_back = []  # a run taken from the queue when the pool was found broken

    def submit(pending) -> bool:
        """Keep ``window`` runs submitted: the waits below then look at a few futures, not at
        every run of the campaign (which would cost the parent O(runs) per finished run).
        False if the pool is broken (a worker died)."""
        while len(pending) < window:
            r = next(queued, None)
            if r is None:
                return True
            try:
                fut = pool.submit(_pool_run, work["id"], r.to_dict())
            except BrokenProcessPool:
                queued_back.append(r)
                return False
            futures[fut] = r
            pending.add(fut)
        return True

    try:
        pending = set()
        broken = not submit(pending)
        running = set()
        while pending and not stop.requested and not broken:
            running = {f for f in pending if f.running()}
            finished, pending = cf.wait(pending, timeout=0.25, return_when=cf.FIRST_COMPLETED)
            for fut in finished:
                if ok(fut):
                    take(fut.result())
                    taken.add(fut)
                elif isinstance(fut.exception(), BrokenProcessPool):
                    broken = True
                else:
                    fut.result()  # a bug of ours in the worker: raise it
            if not broken:
                broken = not submit(pending)
        if broken:
            for fut in pending:  # finished before the pool broke
                if ok(fut):
                    take(fut.result())
                    taken.add(fut)
            unfinished = [r for f, r in futures.items() if f not in taken] + queued_back + list(queued)
            in_flight = [futures[f] for f in running if f not in taken]
            return in_flight or unfinished[:1], unfinished
        return None
    finally:
        for fut in futures:
            fut.cancel()
        if broken or stop.requested or any(not f.done() for f in futures):
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
    own_display(True)  # the bar says it all: no heartbeat line spliced into it

    def show(done, total, elapsed):
        if done is None:
            own_display(False)
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
