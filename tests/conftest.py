import sys
from pathlib import Path

# published.py and helpers live next to the tests
sys.path.insert(0, str(Path(__file__).parent))


def pytest_sessionfinish(session, exitstatus):
    """Safety net for the test process itself: pythonfmu FMUs that tests loaded in-process
    without fmu-fdi's own guard (raw pythonfmu test FMUs) would corrupt its heap at exit
    (pythonfmu 0.7's use-after-free, fmu_fdi/fmu/exit_guard.py) and abort pytest after the
    last test passed."""
    from fmu_fdi.fmu.exit_guard import guard_loaded_libraries

    guard_loaded_libraries()
