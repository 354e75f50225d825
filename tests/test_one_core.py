"""One state-space synthesis core (issue 17, Build 2): every automatic design comes from the pencil basis.

Published: Varga 2017, Examples 5.3/5.4 (acceptance A3): the least-order detector with pole -3 is
unique up to scaling, Q = [0, 1, -(s+2)/(s+3)] and [0, (s-3)/(s+3), -(s+2)/(s+3)]; compared to 1e-6
(six printed digits). Given poles are the filter's poles (the docstring's promise), and rows of
indices 1 and 2 combine at order 2 (one common denominator), as a polynomial basis row has it.
"""
import numpy as np
import pytest

import published as pub
from fmu_fdi import nullspace_design


@pytest.mark.parametrize("example, expect", [
    (pub.ex5_3, lambda s: [0, 1, -(s + 2) / (s + 3)]),
    (pub.ex5_4, lambda s: [0, (s - 3) / (s + 3), -(s + 2) / (s + 3)]),
])
def test_published_least_order_detectors(example, expect):
    """The least-order detector of pole -3 is unique up to a constant: the core's row, scaled by one
    entry, equals the published one at three frequencies (1e-6: the printed digits)."""
    gen = nullspace_design(example(), poles=[-3.0])
    assert gen.info["basis"] == "pencil" and gen.Q.n == 1 and np.allclose(gen.Q.poles(), [-3.0])
    for w in (0.0, 0.7, 3.0):
        q = gen.Q.freqresp([w])[0][0]
        e = np.array(expect(1j * w), complex)
        c = e[1] / q[1]
        assert np.allclose(c * q, e, atol=1e-6)


def test_given_poles_and_sdeg_on_a_basis_of_several_rows():
    """Yuan's model has left minimal indices [1, 1, 2]; no combination of the rows of index 1 sees every fault, so the least
    order is 2 — reached by a row of index 1 and one of index 2 over one common denominator (their poles
    drawn from one pool), not 1 + 2 = 3. poles=[-4] with sdeg=-6: the filter's poles are exactly -4 and
    -6 (the order allows one given pole, the rest at sdeg), and the residual decouples u (numpy
    evaluation of Q·[Gu; I])."""
    from test_synthesis_published import yuan

    model = yuan()
    gen = nullspace_design(model, poles=[-4.0], sdeg=-6.0)
    assert gen.info["basis"] == "pencil" and gen.info["left_minimal_indices"] == [1, 1, 2] and gen.Q.n == 2
    # eigenvalues of an order-2 realisation placed by a 1×1 Schur step each: rounding, ~1e-14
    assert np.allclose(np.sort(gen.Q.poles().real), [-6.0, -4.0], atol=1e-8)
    assert np.allclose(gen.Q.poles().imag, 0.0, atol=1e-8)
    G = model.lti("u")
    for w in (0.0, 0.3, 3.0):
        Gu = G.C @ np.linalg.solve(1j * w * np.eye(G.n) - G.A, G.B) + G.D
        Qv = gen.Q.freqresp([w])[0]
        Ru = Qv[:, :model.ny] @ Gu + Qv[:, model.ny:]
        # rounding of an order-≤2 filter against |Q||[Gu; I]| ~ 1: eps·1e3
        assert np.linalg.norm(Ru) <= 1e-12 * np.linalg.norm(Qv) * max(1.0, np.linalg.norm(Gu, 2))


def test_noise_design_comes_from_the_core():
    """Procedure AFD (Varga's Example 5.11 model, acceptance A5(a)): the approximate design is built on
    the pencil bases, never on another basis."""
    gen = nullspace_design(pub.a5a_model(), poles=[-3.0])
    assert gen.info["basis"] == "pencil"
    assert np.all(gen.Q.poles().real < 0)
