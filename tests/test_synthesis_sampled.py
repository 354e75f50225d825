"""Frequency-sampled least-order synthesis (design/toolkit/sampled.py), the fallback of
nullspace_design when the polynomial basis is too ill-conditioned.

Published: Varga 2017, Example 5.3/5.4 (acceptance A3): the least-order detector with pole
-3 is unique up to scaling, Q = [0, 1, -(s+2)/(s+3)] and [0, (s-3)/(s+3), -(s+2)/(s+3)];
compared to 1e-6 (6 printed digits). Exact decoupling: relative leak < 1e-9 (rounding of an
order-1 filter, ~1e-15, with room for the grid's conditioning).
"""
import numpy as np
import pytest

import published as pub
from fmu_fdi import DesignError
from fmu_fdi.design.toolkit._basis import pole_chooser
from fmu_fdi.design.problems.nullspace import _sampled, fault_columns
from fmu_fdi.design.toolkit.sampled import cascade, sampled_rows
from synthesis_models import contract, random_model


@pytest.mark.parametrize("example, expect", [
    (pub.ex5_3, lambda s: [0, 1, -(s + 2) / (s + 3)]),
    (pub.ex5_4, lambda s: [0, (s - 3) / (s + 3), -(s + 2) / (s + 3)]),
])
def test_published_least_order_detectors(example, expect):
    model = example()
    Q, info = sampled_rows(model, pole_chooser(model, [-3], None), fault_columns(model), 1)
    assert info["degree"] == 1 and np.allclose(Q.poles(), [-3.0])
    for w in (0.0, 0.7, 3.0):
        q = Q.freqresp([w])[0][0]
        e = np.array(expect(1j * w), complex)
        c = e[1] / q[1]
        assert np.allclose(c * q, e, atol=1e-6)


def test_cascade_holds_poles_exactly():
    poles = np.array([-1.0, -2 + 3j, -2 - 3j, -1.0, -0.5])
    A, C = cascade(poles)
    assert np.allclose(np.sort_complex(np.linalg.eigvals(A)), np.sort_complex(poles))
    # observable: rank of the observability matrix
    O = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(A.shape[0])])
    assert np.linalg.matrix_rank(O) == A.shape[0]


def test_fallback_on_high_degree_model():
    """Seed 18 (n = 28, badly scaled): the parity basis leaks 3e-3; the sampled design is exact
    only by the issue-13 relative measure (contract(): < 1e-6 of |Q||Ge|). Its residual moves with
    d 1.3e-6 times as much as with its weakest fault (independent numpy evaluation, issue 17):
    the judge on the normalised form refuses it, naming the leak."""
    model = random_model(18)
    with pytest.raises(DesignError, match=r"decoupling\): residual 1: u\+d leak [0-9.e-]+ × the weakest fault"):
        _sampled(model, 1, None, None, None, 1e-4, 0.01, 0, None, 1e-7)
