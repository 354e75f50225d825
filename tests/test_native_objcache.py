"""The compiled-object cache of native builds (fmu_fdi/native/objcache.py): the runtime's units are
compiled once and linked into every FMU, the FMU behaves bit for bit as one compiled from all its
sources (the cache switched off is the judge), and the cache is never required: disabled, not
writable or holding a damaged object, the build compiles everything and succeeds.
"""
import os
import shutil
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from fmu_fdi import build_fmu
from fmu_fdi.native import RUNTIME_SOURCES
from fmu_fdi.native import objcache
from fmu_fdi.native.objcache import CACHE_ENV

from test_native_fmu import H, host_diagnoser

CC = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler: the native target cannot be built")


def _objects(folder):
    return sorted(p for p in folder.glob("*.o")) if folder.is_dir() else []


def _outputs(fmu):
    """fmpy's simulation of the FMU on inputs that raise and clear the sensor-bias alarm."""
    import fmpy

    t = np.arange(200) * H
    sig = np.zeros(len(t), dtype=[("time", float), ("u1", float), ("u2", float), ("y1", float)])
    sig["time"], sig["u1"], sig["u2"] = t, np.sin(t), 0.5
    sig["y1"] = np.where((t > 0.5) & (t < 1.2), 0.6, 0.0) + 0.01 * np.cos(7 * t)
    return fmpy.simulate_fmu(str(fmu), input=sig, stop_time=t[-1], step_size=H, output_interval=H)


@pytest.fixture(scope="module")
def dg():
    return host_diagnoser()


def test_cached_build_equals_full_compile(dg, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, "off")
    full = build_fmu(dg, tmp_path / "full.fmu", target="native")
    monkeypatch.setenv(CACHE_ENV, str(cache))
    first = build_fmu(dg, tmp_path / "first.fmu", target="native")
    objs = _objects(cache)
    assert len(objs) == len(RUNTIME_SOURCES)  # one object per runtime unit
    inodes, used = [o.stat().st_ino for o in objs], [o.stat().st_mtime_ns for o in objs]
    second = build_fmu(dg, tmp_path / "second.fmu", target="native", fmi_version=3)
    # reused, not recompiled (a compiled object is renamed in: a new inode), and touched as used
    assert _objects(cache) == objs and [o.stat().st_ino for o in objs] == inodes
    assert all(o.stat().st_mtime_ns >= t for o, t in zip(objs, used))
    want = _outputs(full)
    for fmu in (first, second):
        got = _outputs(fmu)
        for name in want.dtype.names:
            assert np.array_equal(got[name], want[name]), name  # bit for bit: the same code
    assert want["fault_detected"].any() and not want["fault_detected"][-1]  # the run raised and cleared


def test_disabled_cache_writes_nothing(dg, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    build_fmu(dg, tmp_path / "x.fmu", target="native")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.fmu"]


def test_unwritable_cache_falls_back(dg, tmp_path, monkeypatch):
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache folder would be")
    monkeypatch.setenv(CACHE_ENV, str(blocker / "objects"))
    fmu = build_fmu(dg, tmp_path / "x.fmu", target="native")
    assert fmu.is_file() and blocker.read_text().startswith("a file")


def test_damaged_object_is_recompiled_not_fatal(dg, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    good = build_fmu(dg, tmp_path / "good.fmu", target="native")
    victim = _objects(cache)[0]
    victim.write_bytes(b"not an object file")
    again = build_fmu(dg, tmp_path / "again.fmu", target="native")  # the link fails, the full compile does not
    assert not victim.exists()  # the damaged object is dropped; the next build compiles it again
    want, got = _outputs(good), _outputs(again)
    assert all(np.array_equal(got[n], want[n]) for n in want.dtype.names)


def test_concurrent_builds_share_a_cold_cache(dg, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    with ThreadPoolExecutor(max_workers=3) as pool:  # the compilers run in subprocesses, in parallel
        fmus = list(pool.map(lambda k: build_fmu(dg, tmp_path / f"x{k}.fmu", target="native"), range(3)))
    assert len(_objects(cache)) == len(RUNTIME_SOURCES)
    assert not [p for p in cache.iterdir() if p.suffix != ".o"]  # no temporary left behind
    want = _outputs(fmus[0])
    for fmu in fmus[1:]:
        got = _outputs(fmu)
        assert all(np.array_equal(got[n], want[n]) for n in want.dtype.names)


# ------------------------------------------------------------------------------ pruning
def _fake_objects(cache, count, age):
    """``count`` objects of an older runtime, last used ``age``, ``age`` + 1, ... seconds ago (k = 0 newest)."""
    cache.mkdir(parents=True, exist_ok=True)
    now = time.time()
    out = []
    for k in range(count):
        p = cache / f"fdi_old-{k:064x}.o"
        p.write_bytes(b"an object of an earlier runtime")
        os.utime(p, (now - age - k, now - age - k))
        out.append(p)
    return out


def _age(paths, seconds):
    for p in paths:
        t = time.time() - seconds
        os.utime(p, (t, t))


def test_a_compiling_build_keeps_the_most_recently_used_objects(dg, tmp_path, monkeypatch):
    import fmu_fdi.native.build as nb

    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    monkeypatch.setattr(objcache, "MAX_OBJECTS", 12)
    old = _fake_objects(cache, 30, age=1000)
    killed, running = cache / ".build-killed", cache / ".build-running"
    killed.mkdir()
    running.mkdir()
    _age([killed], 2 * objcache.STALE_BUILD_SECONDS)
    first = build_fmu(dg, tmp_path / "first.fmu", target="native")  # a miss: compiles, then prunes
    objs = _objects(cache)
    ours = [o for o in objs if not o.name.startswith("fdi_old-")]
    assert len(objs) == 12 and len(ours) == len(RUNTIME_SOURCES)
    assert sorted(o for o in objs if o in old) == sorted(old[:12 - len(RUNTIME_SOURCES)])  # the newest others
    assert not killed.exists() and running.is_dir()  # a killed build's folder goes, a running one's stays
    # a hit counts as a use: the set, made the oldest, is touched by the next build that links it
    _age(ours, 10_000)
    build_fmu(dg, tmp_path / "hit.fmu", target="native")
    assert _objects(cache) == objs
    # a change of the compile flags is a new set: compiled, and the pruning keeps the set just used
    monkeypatch.setattr(nb, "COMPILE_FLAGS", nb.COMPILE_FLAGS + ("-DFDI_CACHE_TEST=1",))
    changed = build_fmu(dg, tmp_path / "changed.fmu", target="native")
    now = _objects(cache)
    assert len(now) == 12 and set(ours) <= set(now)
    assert len([o for o in now if o not in objs]) == len(RUNTIME_SOURCES)
    assert sorted(o for o in now if o in old) == sorted(old[:12 - 2 * len(RUNTIME_SOURCES)])
    want = _outputs(first)
    got = _outputs(changed)
    assert all(np.array_equal(got[n], want[n]) for n in want.dtype.names)


_PROCESS = """
import sys
import fmu_fdi.native.build as nb
import fmu_fdi.native.objcache as oc
from fmu_fdi import build_fmu
from fmu_fdi.native import RUNTIME_SOURCES
oc.MAX_OBJECTS = len(RUNTIME_SOURCES)  # room for one set: each process's compile prunes the other's
nb.COMPILE_FLAGS = nb.COMPILE_FLAGS + ("-DFDI_PROCESS=" + sys.argv[2],)
for k in range(2):
    build_fmu(sys.argv[1], sys.argv[3] + f"{k}.fmu", target="native")
"""


@pytest.mark.slow  # two processes compiling at once: ~15 s on a busy machine
def test_pruning_builds_in_two_processes_lose_nothing(dg, tmp_path, monkeypatch):
    """Two processes compile different sets into one cache at once, each pruning the other's set away
    (room for one): every FMU is built and computes what the full compile does."""
    import subprocess
    import sys

    cache = tmp_path / "cache"
    _fake_objects(cache, 20, age=1000)
    monkeypatch.setenv(CACHE_ENV, "off")
    want = _outputs(build_fmu(dg, tmp_path / "full.fmu", target="native"))
    design = dg.save(tmp_path / "d.json")
    env = dict(os.environ, **{CACHE_ENV: str(cache)})
    procs = [subprocess.Popen([sys.executable, "-c", _PROCESS, str(design), str(k), str(tmp_path / f"p{k}_")],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for k in (1, 2)]
    for p in procs:
        out, _ = p.communicate(timeout=300)
        assert p.returncode == 0, out
    for k in (1, 2):
        for j in range(2):
            got = _outputs(tmp_path / f"p{k}_{j}.fmu")
            assert all(np.array_equal(got[n], want[n]) for n in want.dtype.names)
    assert len(_objects(cache)) <= 2 * len(RUNTIME_SOURCES)  # the old objects are gone, at most the two sets
    assert not [o for o in _objects(cache) if o.name.startswith("fdi_old-")]
    assert not [p for p in cache.iterdir() if p.suffix != ".o"]  # no build folder left behind
