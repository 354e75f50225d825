"""The compiled-object cache of native builds (fmu_fdi/native/objcache.py): the runtime's units are
compiled once and linked into every FMU, the FMU behaves bit for bit as one compiled from all its
sources (the cache switched off is the judge), and the cache is never required: disabled, not
writable or holding a damaged object, the build compiles everything and succeeds.
"""
import os
import shutil
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from fmu_fdi import build_fmu
from fmu_fdi.native import RUNTIME_SOURCES
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
    stamps = [o.stat().st_mtime_ns for o in objs]
    second = build_fmu(dg, tmp_path / "second.fmu", target="native", fmi_version=3)
    assert _objects(cache) == objs and [o.stat().st_mtime_ns for o in objs] == stamps  # reused, not recompiled
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
