"""Published synthesis examples A1-A5 of acceptance.md (Varga 2017, FaultDetectionTools.jl).

Tolerances: published figures carry 6 significant digits, so they are compared to 1e-6;
exact decoupling is asserted below 1e-9 (the filters are O(1), rounding is ~1e-15, and
1e-9 leaves room for the conditioning of the minimal-realisation step). A gap that must
be "at least" a published value may fall short by rounding only: 1e-9 relative.
"""
import numpy as np
import pytest

import published as pub
from fmu_fdi import (DesignError, fault_gains, fault_noise_gap, fault_sensitivity_condition, hinf_minus,
                     leakage, nullspace_design, structure_matrix, structured_bank)
from fmu_fdi.lti import LTI

DECOUPLED = 1e-9
PUBLISHED = 1e-6


# ----------------------------------------------------------------------------- A1
@pytest.mark.parametrize("w, gains", [
    (0.0, [[0.5, 1, 0], [0.666667, 0, 1]]),
    (1.0, [[0.632456, 1, 0], [0.707107, 0, 1]]),
    (np.inf, [[1, 1, 0], [1, 0, 1]]),
])
def test_a1_gains_and_strong_structure(w, gains):
    G = pub.a1_system()
    assert np.allclose(fault_gains(G, [w])[0], gains, atol=PUBLISHED)
    assert structure_matrix(G, freqs=[w]).tolist() == [[1, 1, 0], [1, 0, 1]]


def test_a1_block_gains_and_structure():
    G = pub.a1_system()
    assert np.allclose(fault_gains(G, [0.0], block=True)[0], [[0.833333, 1, 1]], atol=PUBLISHED)
    assert structure_matrix(G, freqs=[0.0], block=True).tolist() == [[1, 1, 1]]


# ----------------------------------------------------------------------------- A2
def test_a2_gains_and_structures():
    G = pub.a2_system()
    assert np.allclose(fault_gains(G, [0.0])[0], [[0, 0], [0.444444, 1]], atol=PUBLISHED)
    assert np.allclose(fault_gains(G, [2.0])[0], [[0.894427, 0], [0, 1]], atol=PUBLISHED)
    assert structure_matrix(G, freqs=[0.0], tol=1e-3).tolist() == [[0, 0], [1, 1]]
    assert structure_matrix(G, freqs=[2.0], tol=1e-3).tolist() == [[1, 0], [0, 1]]
    assert structure_matrix(G).tolist() == [[1, 0], [1, 1]]


def test_a2_design_strongly_sensitive_at_0_and_2():
    from fmu_fdi import FDIModel

    G = LTI.from_control(pub.a2_system())
    model = FDIModel.from_control(G, f=[0], ignore=[1], name="a2")
    gen = nullspace_design(model, rdim=1, poles=[-3], freqs=[0.0, 2.0])
    assert gen.n_residuals == 1
    assert structure_matrix(gen, freqs=[0.0], tol=1e-3).tolist() == [[1]]
    assert structure_matrix(gen, freqs=[2.0], tol=1e-3).tolist() == [[1]]


# ----------------------------------------------------------------------------- A3
def test_ex5_2_fault_not_detectable_is_named():
    with pytest.raises(DesignError) as err:
        nullspace_design(pub.ex5_2())
    msg = str(err.value)
    assert "fault 'f1' is not detectable once d is decoupled" in msg
    assert "rank" in msg and "[0, 1]" in msg  # the achievable weak structure


def _scaled(gen):
    """Scale as the published result: Rf[0](∞) = 1."""
    k = gen.Rf.freqresp([np.inf])[0][0, 0].real
    return 1.0 / k


def test_ex5_3_exact_detection():
    gen = nullspace_design(pub.ex5_3(), rdim=1, poles=[-3])
    assert leakage(gen) < DECOUPLED
    assert np.allclose(gen.Q.poles(), [-3.0])
    c = _scaled(gen)
    # Q = [0, 1, -(s+2)/(s+3)], Rf = [(s+2)/(s+3), 1]
    for w in (0.0, 0.7, 3.0, np.inf):
        lam = 1j * w
        Q = c * gen.Q.freqresp([w])[0][0]
        expect = [0, 1, -(lam + 2) / (lam + 3)] if np.isfinite(w) else [0, 1, -1]
        assert np.allclose(Q, expect, atol=PUBLISHED)
        Rf = c * gen.Rf.freqresp([w])[0][0]
        assert np.allclose(Rf, [(lam + 2) / (lam + 3) if np.isfinite(w) else 1, 1], atol=PUBLISHED)
    assert structure_matrix(gen).tolist() == [[1, 1]]


def test_ex5_4_unstable_plant_stable_generator():
    model = pub.ex5_4()
    assert not model.lti().is_stable()
    gen = nullspace_design(model, rdim=1, poles=[-3])
    assert gen.Q.is_stable()
    assert np.allclose(gen.Q.poles(), [-3.0])
    assert leakage(gen) < DECOUPLED
    c = _scaled(gen)
    for w in (0.0, 1.3, np.inf):
        lam = 1j * w
        Q = c * gen.Q.freqresp([w])[0][0]
        expect = [0, (lam - 3) / (lam + 3), -(lam + 2) / (lam + 3)] if np.isfinite(w) else [0, 1, -1]
        assert np.allclose(Q, expect, atol=PUBLISHED)
    assert hinf_minus(gen) * c == pytest.approx(1.0, abs=PUBLISHED)
    assert fault_sensitivity_condition(gen) == pytest.approx(1.0, abs=PUBLISHED)
    assert fault_sensitivity_condition(gen, freqs=[0.0]) == pytest.approx(2 / 3, abs=PUBLISHED)


# ----------------------------------------------------------------------------- A4
@pytest.mark.parametrize("poles", [None, [-1], [-3], [-10]])
def test_a4_approximate_detection_reaches_gap_2(poles):
    gen = nullspace_design(pub.a4_model(), rdim=1, poles=poles)
    assert gen.Ru.hinfnorm()[0] < DECOUPLED
    assert structure_matrix(gen).tolist() == [[1, 1, 1]]
    assert fault_noise_gap(gen) >= 2.0 * (1 - 1e-9)


def test_a4_published_design_figures():
    """The published Q reproduces the published figures through our analysis."""
    s = pub.s
    import control as ct

    Q = LTI.from_control(ct.minreal(pub.tfm([[(s + 2) / (s + 1), (s + 3) / (s + 1), -(2 * s + 3) / (s + 1)]],
                                            ["y1", "y2", "u"]), verbose=False))
    from fmu_fdi import ResidualGenerator

    gen = ResidualGenerator(Q, pub.a4_model(), "published")
    assert gen.Ru.hinfnorm()[0] < DECOUPLED
    norms = [gen.fault_response(j).hinfnorm()[0] for j in range(3)]
    assert np.allclose(norms, [3, 2, 3], atol=PUBLISHED)
    assert gen.Rw.hinfnorm()[0] == pytest.approx(1.0, abs=PUBLISHED)
    assert fault_noise_gap(gen) == pytest.approx(2.0, abs=PUBLISHED)
    assert fault_sensitivity_condition(gen) == pytest.approx(2 / 3, abs=PUBLISHED)


# ----------------------------------------------------------------------------- A5
def test_a5a_isolation_with_noise():
    bank = structured_bank(pub.a5a_model(), np.eye(2, dtype=int), poles=[-3])
    assert structure_matrix(bank).tolist() == [[1, 0], [0, 1]]
    gaps = fault_noise_gap(bank, np.eye(2))
    assert gaps[0] >= 3.0 * (1 - 1e-9)
    assert np.isinf(gaps[1])
    assert all(np.allclose(m.Q.poles(), -3.0) for m in bank.members)


def test_a5b_isolation_reaches_published_gaps():
    S = np.array([[0, 1, 1], [1, 0, 1], [1, 1, 0]])
    bank = structured_bank(pub.a4_model(), S)
    assert structure_matrix(bank).tolist() == S.tolist()
    assert leakage(bank) < DECOUPLED
    gaps = fault_noise_gap(bank, S)
    assert gaps[0] >= 1.5 * (1 - 1e-9)
    assert np.isinf(gaps[1])
    assert gaps[2] >= 1.0 * (1 - 1e-9)
