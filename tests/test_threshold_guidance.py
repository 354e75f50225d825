"""Threshold guidance (issue 18): the false-alarm rate a threshold implies under the model's noise,
and the smallest step fault it detects, judged by closed forms and a Monte Carlo run."""
from __future__ import annotations

import numpy as np
from scipy import stats
from scipy.signal import lfilter

from fmu_fdi import LTI, FDIModel, ResidualGenerator
from fmu_fdi.evaluation.guidance import WARN_RATE, describe, threshold_guidance
from fmu_fdi.faults import sensor_fault


def _open_loop_observer(a=0.9):
    """x+ = a x + u + w, y = x (+ sensor fault); r = y − ŷ with ŷ the noise-free model: r is AR(1),
    r+ = a r + w, stationary variance 1/(1 − a²)."""
    m = FDIModel.from_matrices([[a]], [[1.0]], [[1.0]], Bw=[[1.0]], dt=1.0, faults=[sensor_fault("s", "y")],
                               y_names=["y"], u_names=["u"])
    Q = LTI([[a]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]], 1.0)
    return ResidualGenerator(Q, m, "open-loop observer")


def test_norm_threshold_false_alarm_rate_is_the_gaussian_tail():
    gen = _open_loop_observer()
    sigma = 1 / np.sqrt(1 - 0.81)
    for th in (1.0, 4.0, 9.0):
        g, = threshold_guidance(gen, {"kind": "norm"}, [th])
        assert np.isclose(g.alpha, 2 * stats.norm.sf(th / sigma), rtol=1e-6), (th, g.alpha)
        # the residual's settled response to a unit sensor bias is 1 (r = y − ŷ): a bias of th reaches th
        assert np.isclose(g.smallest["s"], th)


def test_rms_threshold_false_alarm_rate_matches_a_simulation():
    gen = _open_loop_observer()
    rng = np.random.default_rng(4)
    r = lfilter([1.0], [1.0, -0.9], rng.standard_normal(400_000))[1000:]
    N = 10
    J = np.sqrt(np.convolve(r * r, np.ones(N) / N, mode="valid"))
    for th in (2.0, 3.0, 4.5):
        g, = threshold_guidance(gen, {"kind": "rms", "window": N}, [th])
        p = float(np.mean(J >= th))
        # the empirical rate of a correlated sequence: its standard error is inflated by the correlation
        # time of J (≈ N + 2/(1 − 0.9) = 30 samples): sqrt(p (1 − p) · 30 / n), 5 of them
        se = np.sqrt(p * (1 - p) * 30 / J.size)
        assert abs(g.alpha - p) <= 5 * se + 1e-4, (th, g.alpha, p, se)


def test_threshold_inside_the_noise_warns_with_its_rate():
    gen = _open_loop_observer()
    lines, warnings = [], []
    describe(gen, threshold_guidance(gen, {"kind": "rms", "window": 10}, [1.0]), lines.append, warnings.append)
    assert "false alarms" in lines[0] and "smallest step fault detected: s 1" in lines[0]
    assert len(warnings) == 1 and "lies within the noise" in warnings[0]
    lines, warnings = [], []
    g = threshold_guidance(gen, {"kind": "rms", "window": 10}, [8.0])
    assert g[0].alpha < WARN_RATE
    describe(gen, g, lines.append, warnings.append)
    assert not warnings


def test_data_threshold_explains_effective_samples_and_asks_for_a_log_long_enough():
    """A slowly correlated evaluation (AR(1), pole 0.999) refused on 60 001 samples: the message says what
    an effective sample is and how long a log is needed at least — and a log 4 times that long (an
    independent realisation; the 60 001-sample log underestimates the correlation length, 1113 against
    the true ln 0.05 / ln 0.999 = 2993, which the message warns of) is accepted."""
    import re

    import pytest

    from fmu_fdi.evaluation import data_driven_threshold

    rng = np.random.default_rng(0)
    J = lfilter([1.0], [1.0, -0.999], rng.standard_normal(60_001))
    with pytest.raises(ValueError, match="effective samples: the evaluation stays correlated over") as err:
        data_driven_threshold(J, 0.001)
    need = int(re.search(r"a fault-free log of at least about (\d+) samples", str(err.value)).group(1))
    L = int(re.search(r"correlated over (\d+) samples", str(err.value)).group(1))
    assert need > 60_001 and need % L == 0
    longer = lfilter([1.0], [1.0, -0.999], rng.standard_normal(4 * need))
    est = data_driven_threshold(longer, 0.001)
    assert est.n_effective >= need // L


def test_guidance_reads_estimated_thresholds_and_leaves_adaptive_ones_out():
    from types import SimpleNamespace

    gen = _open_loop_observer()
    g, = threshold_guidance(gen, {"kind": "norm"}, [SimpleNamespace(value=4.4965)])   # a ThresholdEstimate
    assert g.group == 0 and np.isclose(g.alpha, 0.05, rtol=1e-3)
    assert threshold_guidance(gen, {"kind": "norm"}, [{"kind": "adaptive"}]) == []
