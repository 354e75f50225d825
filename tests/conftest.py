import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

# published.py and helpers live next to the tests
sys.path.insert(0, str(Path(__file__).parent))


def pytest_configure(config):
    """Native builds cache the runtime's compiled objects (fmu_fdi/native/objcache.py); the tests
    use a cache of their own, removed at exit, so they neither read nor fill the user's
    (~/.cache/fmu-fdi): a stale or foreign object can never decide a test. Subprocesses inherit it."""
    if "FMU_FDI_NATIVE_CACHE" not in os.environ:
        folder = tempfile.mkdtemp(prefix="fmu-fdi-test-objects-")
        os.environ["FMU_FDI_NATIVE_CACHE"] = folder
        atexit.register(shutil.rmtree, folder, ignore_errors=True)


def pytest_sessionfinish(session, exitstatus):
    """Safety net for the test process itself: pythonfmu FMUs that tests loaded in-process
    without fmu-fdi's own guard (raw pythonfmu test FMUs) would corrupt its heap at exit
    (pythonfmu 0.7's use-after-free, fmu_fdi/fmu/exit_guard.py) and abort pytest after the
    last test passed."""
    from fmu_fdi.fmu.exit_guard import guard_loaded_libraries

    guard_loaded_libraries()
