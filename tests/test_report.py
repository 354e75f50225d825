"""Plots a user can read without the source (issue 11): panels named by the faults their
group watches, units, the fault onset marked, a real title, only isolable faults on the
isolation axis, adaptive thresholds explained, legends off the data; and the demo's note on
why a fault is reported as 'unknown'."""
import numpy as np
import pytest

FAULTS = ["sensor_h1", "sensor_h2", "leak_T1", "pump_Q1"]
# two groups; leak_T1 and pump_Q1 move both, so their columns coincide: not isolable
DESIGN = {
    "name": "tanks_dos", "faults": [{"name": n, "kind": "sensor"} for n in FAULTS],
    "signals": {"u": ["Q1"], "y": ["h1", "h2"]}, "units": {"Q1": "cm3/s", "h1": "cm", "h2": "cm"},
    "generator": {"method": "dos", "residual_names": ["r1", "r2"], "groups": [[0], [1]]},
    "evaluation": [{"evaluator": {"kind": "rms", "window": 5}, "threshold": {"kind": "majorant"}},
                   {"evaluator": {"kind": "rms", "window": 5}, "threshold": {"kind": "fixed", "value": 1.0}}],
    "decision": {"isolation": "structure", "structure": [[1, 0, 1, 1], [0, 1, 1, 1]]},
}


def _result(prefix="fdi."):
    t = np.arange(100.0)
    names = ["time"] + [prefix + n for n in ("residual_1", "residual_2", "evaluation_1", "evaluation_2",
                                             "threshold_1", "threshold_2", "alarm_1", "alarm_2",
                                             "fault_detected", "isolated_fault")] + ["fault.bias_h1.active"]
    r = np.zeros(t.size, dtype=[(n, float) for n in names])
    on = t >= 50
    r["time"] = t
    r[prefix + "residual_1"] = np.where(on, 2.0, 0.0)
    r[prefix + "evaluation_1"] = np.where(on, 2.0, 0.1)
    r[prefix + "threshold_1"] = 1.0 + t / 100  # an adaptive threshold rises
    r[prefix + "threshold_2"] = 1.0
    r[prefix + "alarm_1"] = r[prefix + "fault_detected"] = on
    r[prefix + "isolated_fault"] = np.where(on, 1, 0)
    r["fault.bias_h1.active"] = on
    return r


@pytest.fixture(scope="module")
def figure():
    import matplotlib.pyplot as plt

    from fmu_fdi.report import diagnosis_figure

    fig = diagnosis_figure(_result(), prefix="fdi.", design=DESIGN)
    fig.canvas.draw()
    yield fig
    plt.close(fig)


def test_panels_are_named_by_the_faults_their_group_watches_and_carry_units(figure):
    res, g1, g2, iso = figure.axes
    assert "sensor_h1" in g1.get_title(loc="left") and "leak_T1" in g1.get_title(loc="left")
    assert "sensor_h2" not in g1.get_title(loc="left")
    assert "sensor_h2" in g2.get_title(loc="left")
    for ax in (res, g1, g2):
        assert ax.get_ylabel().endswith("[cm]"), ax.get_ylabel()
    assert iso.get_xlabel() == "time [s]"


def test_fault_onset_is_marked_on_every_panel_and_the_title_says_what_happened(figure):
    for ax in figure.axes:
        assert any(np.allclose(line.get_xdata(), 50.0) for line in ax.lines), ax.get_title(loc="left")
    legend = [t.get_text() for t in figure.axes[-1].get_legend().get_texts()]
    assert any("bias_h1" in t and "t = 50 s" in t for t in legend), legend
    title = figure._suptitle.get_text()
    assert "tanks_dos" in title and "bias_h1 from t = 50 s" in title and "/" not in title


def test_isolation_axis_lists_only_isolable_faults(figure):
    labels = [t.get_text() for t in figure.axes[-1].get_yticklabels()]
    assert labels == ["unknown / several", "none", "sensor_h1", "sensor_h2"]


def test_adaptive_thresholds_are_explained_and_legends_stay_off_the_data(figure):
    _, g1, g2, _ = figure.axes
    texts1 = " ".join(t.get_text() for t in g1.get_legend().get_texts())
    texts2 = " ".join(t.get_text() for t in g2.get_legend().get_texts())
    assert "adaptive" in texts1 and "rises with the inputs" in texts1.replace("\n", " ")
    assert "fixed" in texts2 and "adaptive" not in texts2
    renderer = figure.canvas.get_renderer()
    for ax in figure.axes:
        box, leg = ax.get_window_extent(renderer), ax.get_legend().get_window_extent(renderer)
        assert leg.x0 >= box.x1, ax.get_title(loc="left")  # right of the axes, not over the curves


def test_without_a_design_a_varying_threshold_is_called_adaptive(tmp_path):
    import matplotlib.pyplot as plt

    from fmu_fdi.report import diagnosis_figure, plot_diagnosis

    fig = diagnosis_figure(_result(""), prefix="")
    labels = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    plt.close(fig)
    assert any("adaptive" in t for t in labels)
    path = plot_diagnosis(_result(""), tmp_path / "p.png", prefix="")
    assert path.stat().st_size > 10_000


def test_demo_note_explains_why_the_leak_is_unknown():
    from fmu_fdi.demo import _why_unknown
    from fmu_fdi.designinfo import indistinguishable, isolable_faults

    assert isolable_faults(DESIGN) == ["sensor_h1", "sensor_h2"]
    assert indistinguishable(DESIGN, "leak_T1") == ["pump_Q1"]
    note = _why_unknown(DESIGN, "leak T1", "leak_T1")
    assert "'unknown' is the correct verdict" in note and "pump_Q1" in note and "group(s) 1, 2" in note
