"""Strong achievable structures (issue 13, items 1 and 3): ``achievable_structure(model, freqs=...)``
against FaultDetectionTools.jl test/test_fdigenspec.jl (``fdigenspec(sysf; FDfreq, FDGainTol)``),
and its agreement with ``structured_bank(..., freqs=...)``: a row is designable iff achievable.

The printed results are 0/1 matrices: compared exactly (as sets of rows; fdigenspec's row order
is its recursion order).
"""
import control as ct
import numpy as np
import pytest
from test_synthesis_published import boeing747, niemann, xiong_saif_1, xiong_saif_2, yuan

from fmu_fdi import DesignError, FDIModel, actuator_fault, component_fault, sensor_fault, structured_bank
from fmu_fdi.design.problems.achievable import achievable_structure
from fmu_fdi.lti import LTI


def _rows(S):
    return sorted(map(tuple, np.asarray(S).tolist()))


def _tf_model(num, den, groups):
    """A model of the 1-row-per-output transfer matrix num/den with input groups
    ``groups`` = list of 'u', 'd' or 'f' per column (faults named f1, f2, ...)."""
    G = LTI.from_control(ct.minreal(ct.ss(ct.tf(num, den)), verbose=False))
    col = {g: [j for j, x in enumerate(groups) if x == g] for g in "udf"}
    faults = [component_fault(f"f{k + 1}", G.B[:, [j]], G.D[:, [j]]) for k, j in enumerate(col["f"])]
    return FDIModel.from_matrices(G.A, G.B[:, col["u"]], G.C, G.D[:, col["u"]], Bd=G.B[:, col["d"]],
                                  Dd=G.D[:, col["d"]], faults=faults)


YUAN_STRONG = [
    [0, 0, 0, 1, 0, 0, 1, 1], [0, 1, 1, 0, 1, 1, 1, 0], [0, 1, 1, 1, 1, 1, 0, 1], [0, 1, 1, 1, 1, 1, 1, 1],
    [1, 0, 1, 0, 1, 1, 1, 0], [1, 0, 1, 1, 1, 1, 0, 1], [1, 0, 1, 1, 1, 1, 1, 1], [1, 1, 0, 0, 1, 1, 0, 0],
    [1, 1, 0, 1, 1, 1, 1, 1], [1, 1, 1, 0, 1, 1, 1, 0], [1, 1, 1, 1, 1, 1, 0, 1], [1, 1, 1, 1, 1, 1, 1, 1]]


def test_fdigenspec_yuan_strong_12_of_18_rows():
    S = achievable_structure(yuan(), freqs=[0, 1], FDGainTol=1e-3)
    assert _rows(S) == _rows(YUAN_STRONG)


@pytest.mark.parametrize("make", [niemann, xiong_saif_1, xiong_saif_2])
def test_fdigenspec_two_fault_examples_strong_equals_weak(make):
    # xiong_saif_2 has two integrators in its fault channels: ω = 0 is decided on the stable
    # (left coprime) fault response, which keeps both faults there
    assert _rows(achievable_structure(make(), freqs=[0, 1], FDGainTol=1e-3)) == _rows([[1, 1], [0, 1], [1, 0]])


def test_fdigenspec_boeing747_strong():
    """Published with FDGainTol = 1e-5 on Varga's absolute gains of his glnull rows; ours decides by the
    core's design of the row, judged on the row normalised to unit weakest fault peak. At ω = 0 the
    unstable altitude mode (pole 3.1e-5 rad/s) lines up every actuator's response: the three dropped
    rows keep < 1e-5 there on their designs (8.7e-8, 2.2e-7, 6.7e-6 at FDGainTol = 1e-5), the four kept
    rows > 1e-2: FDGainTol = 1e-5 (tests/test_peer_fdt.py), 1e-3 and 1e-2 give the published set."""
    expect = [[1, 1, 1, 1, 1], [0, 0, 1, 1, 1], [1, 1, 0, 0, 1], [1, 1, 1, 1, 0]]
    for tol in (1e-3, 1e-2):
        assert _rows(achievable_structure(boeing747(), freqs=[0, 1], FDGainTol=tol)) == _rows(expect)


def test_fdigenspec_example_5_4_unstable_plant():
    # Gu = [(s+1)/(s-2); (s+2)/(s-3)], Gd = [(s-1)/(s+2); 0], faults: actuator and sensor y2
    G = LTI.from_control(ct.minreal(ct.ss(ct.tf([[[1, 1], [1, -1]], [[1, 2], [0]]],
                                                [[[1, -2], [1, 2]], [[1, -3], [1]]])), verbose=False))
    m = FDIModel.from_matrices(G.A, G.B[:, [0]], G.C, G.D[:, [0]], Bd=G.B[:, [1]], Dd=G.D[:, [1]], u_names=["u"],
                               y_names=["y1", "y2"], faults=[actuator_fault("f1", "u"), sensor_fault("f2", "y2")])
    assert achievable_structure(m).tolist() == [[1, 1]]
    assert achievable_structure(m, freqs=[0, 1], FDGainTol=1e-3).tolist() == [[1, 1]]


def test_fdigenspec_lecture_6_zero_at_dc():
    # Gu = [1/s; 1/s], Gd = [0; s/(s+3)], Gf = [(s+1)/(s+2); 1/(s+2)]: the only residual decoupling
    # u and d is s y1 - u = s (s+1)/(s+2) f, zero at ω = 0 (the integrator of Gu is not Gf's)
    m = _tf_model([[[1], [0], [1, 1]], [[1], [1, 0], [1]]], [[[1, 0], [1], [1, 2]], [[1, 0], [1, 3], [1, 2]]],
                  "udf")
    assert achievable_structure(m).tolist() == [[1]]
    assert achievable_structure(m, freqs=[0, 1], FDGainTol=1e-5).shape == (0, 1)


@pytest.mark.parametrize("den2, expect", [
    ([1, 0], []),  # [1/(s^2+1), 1/s]: a stable residual has s(s^2+1) in its numerator
    (list(np.polymul([1, 0, 1, 0], [1, 2])), [[1, 1]]),  # [1/(s(s^2+1)), 1/(s(s^2+1)(s+2))]
])
def test_fdigenspec_fault_poles_on_the_axis(den2, expect):
    den1 = [1, 0, 1] if den2 == [1, 0] else [1, 0, 1, 0]
    m = _tf_model([[[1], [1]]], [[den1, den2]], "ff")
    assert achievable_structure(m).tolist() == [[1, 1]]
    assert _rows(achievable_structure(m, freqs=[0, 1], FDGainTol=1e-5)) == _rows(expect)


@pytest.mark.parametrize("freqs, expect", [
    ([0], [[1, 1]]),  # decoupling f2 leaves s/(s+1) f1, decoupling f1 leaves -s (s+3)^2 f2: zero at 0
    ([2], [[1, 1], [1, 0], [0, 1]]),  # (s^2+4) vanishes at 2j only in y2, which both rows still use
    ([0, 2], [[1, 1]]),
])
def test_fdigenspec_zeros_at_the_frequencies(freqs, expect):
    # Gf = [s/(s+1) 0; (s^2+4)/(s+3)^2 1] (FaultDetectionTools.jl: strong == weak rows fdichkspec keeps)
    m = _tf_model([[[1, 0], [0]], [[1, 0, 4], [1]]], [[[1, 1], [1]], [[1, 6, 9], [1]]], "ff")
    assert _rows(achievable_structure(m, freqs=freqs, FDGainTol=1e-3)) == _rows(expect)


def test_random_models_strong_equals_weak():
    # rss-like models (fdigenspec test): generic Gf has no zeros at 0 or 1, all 15 rows strong
    rng = np.random.default_rng(1)
    A = -np.diag(rng.uniform(0.5, 3.0, 2))
    B, C, D = rng.standard_normal((2, 4)), rng.standard_normal((4, 2)), rng.standard_normal((4, 4))
    m = FDIModel.from_matrices(A, np.zeros((2, 0)), C,
                               faults=[component_fault(f"f{j}", B[:, [j]], D[:, [j]]) for j in range(4)])
    W = achievable_structure(m)
    assert W.shape == (15, 4) and _rows(achievable_structure(m, freqs=[0, 1], FDGainTol=1e-3)) == _rows(W)


def _designable(model, row, freqs, FDGainTol):
    try:
        structured_bank(model, [row], freqs=freqs, FDGainTol=FDGainTol)
        return True
    except DesignError:
        return False


@pytest.mark.parametrize("make", [yuan, xiong_saif_1, niemann, xiong_saif_2, boeing747])
def test_designable_iff_achievable(make):
    """Every weakly achievable row is designed by structured_bank(freqs=[0, 1]) iff it is strongly
    achievable (FDGainTol = 1e-3, the published sets above). Niemann: a combination of its three
    degree-1 rows whose fault gain is rounding noise must not be chosen; Xiong-Saif 2: ω = 0 is a
    pole of the plant (two integrators), decided on the limit of the stable fault response; Boeing
    747: the altitude mode (3.1e-5 rad/s) must not become a filter pole that hides ω = 1."""
    model = make()
    strong = set(_rows(achievable_structure(model, freqs=[0, 1], FDGainTol=1e-3)))
    for row in achievable_structure(model).tolist():
        assert _designable(model, row, [0, 1], 1e-3) == (tuple(row) in strong), row


def test_weak_but_flat_fault_is_designable():
    """Gf = diag(1, 1e-4)/(s + 1): at ω = 1 each fault keeps 1/sqrt(2) of its own peak gain, so both rows
    with f2 are strongly achievable at FDGainTol = 1e-3 although f2 is 1e-4 of f1 (strong detectability
    compares a fault's gain with its own peak, in the analysis and in the post-condition alike)."""
    m = _tf_model([[[1], [0]], [[0], [1e-4]]], [[[1, 1], [1]], [[1], [1, 1]]], "ff")
    S = achievable_structure(m, freqs=[1], FDGainTol=1e-3)
    assert _rows(S) == _rows([[1, 1], [0, 1], [1, 0]])
    for row in S.tolist():
        assert _designable(m, row, [1], 1e-3), row


@pytest.mark.parametrize("kw, message", [
    ({"freqs": [-1.0]}, "finite non-negative"), ({"freqs": [np.nan]}, "finite non-negative"),
    ({"freqs": [0], "FDGainTol": 0.0}, "FDGainTol must be in (0, 1)"),
])
def test_bad_arguments(kw, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        achievable_structure(xiong_saif_1(), **kw)


@pytest.mark.parametrize("kw, message", [
    ({"freqs": [-1.0]}, "finite non-negative"), ({"freqs": [np.inf]}, "finite non-negative"),
    ({"freqs": []}, "finite non-negative"), ({"freqs": [0], "FDGainTol": 1.5}, "FDGainTol must be in (0, 1)"),
])
@pytest.mark.parametrize("design", ["nullspace_design", "structured_bank"])
def test_bad_strong_options_refused_by_every_design(design, kw, message):
    """One check (analysis.strong_frequencies / check_strong_options) behind every entry point that takes freqs."""
    import fmu_fdi

    m = xiong_saif_1()
    call = {"nullspace_design": lambda: fmu_fdi.nullspace_design(m, **kw),
            "structured_bank": lambda: fmu_fdi.structured_bank(m, [[1] * len(m.fault_names)], **kw)}[design]
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        call()
