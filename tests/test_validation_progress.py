"""Signs of life for long commands (issue 12 item 7): the stage is reported while it runs."""
import io
import time

from fmu_fdi.progress import Heartbeat, current_stage, set_stage, stage


def test_heartbeat_reports_the_running_stage_and_stays_quiet_for_fast_commands():
    quiet = io.StringIO()
    with Heartbeat(first=5.0, every=5.0, stream=quiet):
        set_stage("fast work")
    assert quiet.getvalue() == ""  # a command shorter than `first` prints nothing
    out = io.StringIO()
    with Heartbeat(first=0.05, every=0.05, stream=out) as hb:
        set_stage("isolability analysis (n = 500 states, 5 faults)")
        deadline = time.monotonic() + 10
        while hb.reports < 2 and time.monotonic() < deadline:  # bounded wait, no fixed sleep
            time.sleep(0.01)
    lines = out.getvalue().splitlines()
    assert len(lines) >= 2 and all(ln.startswith("fmu-fdi: still working after ") for ln in lines)
    assert lines[-1].endswith("isolability analysis (n = 500 states, 5 faults)")
    n = hb.reports
    time.sleep(0.2)
    assert hb.reports == n  # the thread stopped with the command


def test_nested_stages_restore_the_outer_one():
    set_stage("outer")
    with stage("inner"):
        assert current_stage() == "inner"
    assert current_stage() == "outer"


def test_cli_model_stages_are_named(tmp_path, caplog):
    import logging

    from fmu_fdi import FDIModel, sensor_fault

    path = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], faults=[sensor_fault("s", "y0")]).to_file(
        tmp_path / "m.toml")
    with caplog.at_level(logging.INFO, logger="fmu_fdi"):
        FDIModel.from_file(path)
    assert f"reading the model file {path}" in caplog.text
