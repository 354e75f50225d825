"""Campaign records that survive crashes and never count a run twice (issue 22 item 1).

The results file ``runs.jsonl`` is appended to by one campaign process at a time (a lock on the
folder), a torn last line is cut before anything is appended, a record whose run key came
before is counted once (with a warning), a killed pool worker is reported and its runs
finished by new workers, and a killed campaign process takes its workers with it. Every
scenario is judged against a reference campaign run once, serially, in a fresh folder: the
outcome of each run (its summary) depends only on the run, never on how often the folder was
resumed.

The campaign: the DTS200 plant FMU and its sensor bank (fmu_fdi.campaign.example), 120 s runs
so a CLI invocation takes about 2 s.
"""
from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest


SEED = 20261126


def cli(*args, timeout=180):
    return subprocess.run([sys.executable, "-m", "fmu_fdi", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """(campaign file, reference folder) of a 7-run campaign run once in a fresh folder."""
    from fmu_fdi.campaign.example import build_fmus, write_campaign

    folder = tmp_path_factory.mktemp("records")
    build_fmus(folder)
    spec = write_campaign(folder, "records", stop=120.0, fault_free=5, targets=("plant.f_sensor_h1",),
                          magnitudes=(0.4, 1.5), onset=60.0, rate=0.01, scales=(0.8, 1.6, 5), zone=20.0)
    ref = folder / "ref"
    r = cli("campaign", spec, "-o", ref, "--no-progress")
    assert r.returncode == 0, r.stderr
    return spec, ref


def records(path) -> list:
    return [json.loads(x) for x in Path(path).read_text().splitlines()[1:] if x.strip()]


def outcome(recs) -> dict:
    """run key -> what the run's record says about the diagnosis (not when or where it ran)."""
    return {r["run"]["key"]: (r["run"]["index"], r["status"], r.get("diagnosers")) for r in recs}


@pytest.mark.slow
def test_torn_last_line_is_cut_and_the_folder_resumes_again_and_again(campaign, tmp_path):
    spec, ref = campaign
    text = (ref / "runs.jsonl").read_text()
    lines = text.splitlines(keepends=True)
    out = tmp_path / "torn"
    out.mkdir()
    # header, two records, and half of the third (a disk that filled up mid-write)
    (out / "runs.jsonl").write_text("".join(lines[:3]) + lines[3][: len(lines[3]) // 2])
    for attempt in range(2):
        r = cli("campaign", spec, "-o", out, "--resume", "--no-progress")
        assert r.returncode == 0, (attempt, r.stderr)
        assert "Traceback" not in r.stderr
    assert "torn last line" in r.stderr or attempt == 1
    got = records(out / "runs.jsonl")  # every line is JSON (json.loads raises otherwise)
    assert len(got) == len(records(ref / "runs.jsonl")) == len({x["run"]["key"] for x in got})
    assert outcome(got) == outcome(records(ref / "runs.jsonl"))


@pytest.mark.slow
def test_a_whole_last_record_without_its_newline_is_kept(campaign, tmp_path):
    spec, ref = campaign
    text = (ref / "runs.jsonl").read_text()
    out = tmp_path / "nonl"
    out.mkdir()
    (out / "runs.jsonl").write_text(text.rstrip("\n"))
    r = cli("campaign", spec, "-o", out, "--resume", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert f"({len(records(ref / 'runs.jsonl'))} from before" in r.stdout  # nothing ran again
    assert outcome(records(out / "runs.jsonl")) == outcome(records(ref / "runs.jsonl"))


@pytest.mark.slow
def test_duplicated_records_are_counted_once_with_a_warning(campaign, tmp_path):
    spec, ref = campaign
    lines = (ref / "runs.jsonl").read_text().splitlines(keepends=True)
    n = len(lines) - 1
    out = tmp_path / "dup"
    out.mkdir()
    (out / "runs.jsonl").write_text("".join(lines + [lines[2], lines[-1]]))
    r = cli("campaign", spec, "-o", out, "--resume", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("counted once") == 2, r.stderr
    assert f"{n} of {n} planned runs" in r.stdout, r.stdout
    html = (out / "report.html").read_text()
    assert f"{n} of {n} planned runs" in html and "counted once" in html
    # the figures are the reference's: the same fault-free sample count, not more
    assert (out / "false_alarms.csv").read_text() == (ref / "false_alarms.csv").read_text()


def test_a_second_campaign_on_the_same_folder_is_refused(campaign, tmp_path):
    import fcntl

    spec, _ = campaign
    out = tmp_path / "locked"
    out.mkdir()
    with open(out / ".lock", "a+") as fh:  # as a running campaign holds it
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        fh.write("process 12345")
        fh.flush()
        r = cli("campaign", spec, "-o", out, "--no-progress")
    assert r.returncode == 2 and "in use by another fmu-fdi campaign" in r.stderr and "12345" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (out / "runs.jsonl").exists()
    # released: the same command now runs
    assert cli("campaign", spec, "-o", out, "--no-progress").returncode == 0


@pytest.mark.slow
def test_two_concurrent_invocations_never_double_count(campaign, tmp_path):
    spec, ref = campaign
    out = tmp_path / "race"
    procs = [subprocess.Popen([sys.executable, "-m", "fmu_fdi", "campaign", str(spec), "-o", str(out), "--resume",
                               "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    results = [p.communicate(timeout=180) for p in procs]
    codes = sorted(p.returncode for p in procs)
    assert codes in ([0, 0], [0, 2]), results  # the second either waits its turn (resumes nothing) or is refused
    for (_, err), p in zip(results, procs):
        assert "Traceback" not in err
        if p.returncode == 2:
            assert "in use by another fmu-fdi campaign" in err
    got = records(out / "runs.jsonl")
    assert len(got) == len({x["run"]["key"] for x in got}) == len(records(ref / "runs.jsonl"))


def _children(pid) -> list:
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry.name))
    return out


def _alive(pid) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.slow
def test_a_killed_pool_worker_is_reported_and_its_runs_finished(campaign, tmp_path):
    from fmu_fdi.campaign.example import write_campaign

    spec0, ref = campaign
    spec = write_campaign(spec0.parent, "many", stop=120.0, fault_free=24, targets=("plant.f_sensor_h1",),
                          magnitudes=(0.4, 1.5), onset=60.0, rate=0.01, scales=(0.8, 1.6, 5), zone=20.0)
    out = tmp_path / "pool"
    proc = subprocess.Popen([sys.executable, "-m", "fmu_fdi", "campaign", str(spec), "-o", str(out), "--workers",
                             "2", "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    victim = None
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "runs.jsonl").exists() and records(out / "runs.jsonl"):
            victim = records(out / "runs.jsonl")[0]["pid"]
            break
        time.sleep(0.02)
    assert victim and victim != proc.pid
    os.kill(victim, signal.SIGKILL)
    stdout, stderr = proc.communicate(timeout=180)
    assert proc.returncode == 0, stderr
    assert "Traceback" not in stderr and "BrokenProcessPool" not in stderr
    assert "worker process died" in stderr, stderr
    got = records(out / "runs.jsonl")
    assert len(got) == 26 == len({x["run"]["key"] for x in got}), len(got)
    assert "26 of 26 planned runs" in stdout


@pytest.mark.slow
def test_killing_the_campaign_process_ends_its_workers(campaign, tmp_path):
    from fmu_fdi.campaign.example import write_campaign

    spec0, _ = campaign
    spec = write_campaign(spec0.parent, "orphans", stop=120.0, fault_free=40, targets=("plant.f_sensor_h1",),
                          magnitudes=(0.4,), onset=60.0, rate=0.01, scales=(0.8, 1.6, 5), zone=20.0)
    out = tmp_path / "orphans"
    proc = subprocess.Popen([sys.executable, "-m", "fmu_fdi", "campaign", str(spec), "-o", str(out), "--workers",
                             "2", "--no-progress"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not ((out / "runs.jsonl").exists() and records(out / "runs.jsonl")):
        time.sleep(0.02)
    kids = _children(proc.pid)
    assert kids, "no worker processes found"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    deadline = time.monotonic() + 10  # the workers poll their parent every 0.5 s
    while time.monotonic() < deadline and any(map(_alive, kids)):
        time.sleep(0.1)
    assert not [k for k in kids if _alive(k)], "workers outlived the killed campaign"


def test_fuzz_torn_duplicated_and_interleaved_results(campaign, tmp_path):
    """Seeded hostile edits of a valid results file: a cut at any byte, duplicated lines, two
    writers' lines interleaved, a second header. After _repair_tail every file either reads
    (each key once, every record one of the reference's) or is refused with CampaignError;
    appending a record then leaves it readable with that record last."""
    from fmu_fdi.campaign.runner import _read, _repair_tail
    from fmu_fdi.campaign.spec import CampaignError

    _, ref = campaign
    text = (ref / "runs.jsonl").read_bytes()
    lines = text.splitlines(keepends=True)
    want = outcome(records(ref / "runs.jsonl"))
    rng = random.Random(SEED)
    stats = {"read": 0, "refused": 0}
    path = tmp_path / "runs.jsonl"
    for k in range(300):
        body = list(lines[1:])
        op = k % 4
        if op == 1:  # duplicates
            for _ in range(rng.randint(1, 4)):
                body.insert(rng.randint(0, len(body)), rng.choice(lines[1:]))
        elif op == 2:  # two writers: the same records appended twice, interleaved
            other = list(lines[1:])
            rng.shuffle(other)
            merged = []
            while body or other:
                src = body if (body and (not other or rng.random() < 0.5)) else other
                merged.append(src.pop(0))
            body = merged
        elif op == 3:  # a record of the header's shape, or a scalar
            body.insert(rng.randint(0, len(body)), rng.choice([lines[0], b"42\n", b"[]\n", b"{}\n", b"null\n"]))
        data = lines[0] + b"".join(body)
        data = data[: rng.randint(len(lines[0]), len(data))] if rng.random() < 0.7 else data  # torn tail
        path.write_bytes(data)
        _repair_tail(path)
        repaired = path.read_bytes()
        assert repaired == b"" or repaired.endswith(b"\n")
        assert data.startswith(repaired[: max(0, len(repaired) - 1)])
        try:
            header, recs, notes = _read(path)
        except CampaignError:
            stats["refused"] += 1
            assert op == 3, "only a foreign line may make the file unreadable"
            continue
        stats["read"] += 1
        assert header is not None
        keys = [r["run"]["key"] for r in recs]
        assert len(keys) == len(set(keys))
        assert all(outcome([r])[r["run"]["key"]] == want[r["run"]["key"]] for r in recs)
        extra = records(ref / "runs.jsonl")[0]
        with open(path, "a") as fh:
            fh.write(json.dumps(extra) + "\n")
        _, recs2, _ = _read(path)
        assert extra["run"]["key"] in {r["run"]["key"] for r in recs2}
    assert stats["read"] > 150 and stats["refused"] > 10, stats
