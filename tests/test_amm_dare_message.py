"""The discrete H2 synthesis' filter DARE (``approximate_matching._filter_dare``) says why it refuses: "no stabilising
solution" only where the data has none, "a stabilising solution exists" with the numerical figures where the solve
failed — before, every refusal (the forward-accuracy line's included) said "no stabilising solution".

The cases are scalar (``x⁺ = a x + b v``, ``y = c x + d v``), where existence is decided by hand: with one noise input
correlated between process and measurement (``B = b``, ``D21 = d ≠ 0``) the state is recoverable from y, ``P = 0``
solves the DARE, and the filter's loop ``a − L c`` (``L = b/d``) is the noise channel's zero ``a − b c/d``; a
stabilising solution exists iff that zero lies strictly inside the unit circle (Zhou, Doyle & Glover, Thm. 21.x:
the symplectic pencil's eigenvalues are the zero and its reciprocal). With two independent noises (``B = [b 0]``,
``D21 = [0 d]``, ``b, c, d ≠ 0``) the scalar DARE ``c²P² + (d²(1 − a²) − b²c²)P − b²d² = 0`` has a positive root and
``(a, c)`` is observable, ``(a, b)`` controllable: a stabilising solution exists.
"""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi.design.problems.approximate_matching import _filter_dare
from fmu_fdi.errors import DesignError


def test_a_noise_zero_on_the_unit_circle_is_refused_as_no_stabilising_solution():
    """``a = 0.5``, ``b = 0.5``, ``c = 1``, ``d = −1``: the channel's zero ``a − b c/d = 1`` is on the circle, so no
    stabilising solution exists (``P = 0`` leaves the loop at 1: the maximal solution). The old code returned that
    ``P`` (its loop read ``1 − 1e-16 < 1``), the filter's pole on the circle. Now refused, naming the pencil's
    eigenvalue at 1."""
    a, b, c, d = 0.5, 0.5, 1.0, -1.0
    assert a - b * c / d == 1.0  # the zero, by hand
    with pytest.raises(DesignError, match=r"has no stabilising solution \(the Hamiltonian pencil has the eigenvalue "
                                          r"\[1\], .* from the unit circle"):
        _filter_dare(np.array([[a]]), np.array([[b]]), np.array([[c]]), np.array([[d]]))


def test_an_unobservable_marginal_mode_is_refused_as_no_stabilising_solution():
    """``a = 1``, ``c = 0``: the mode at 1 is unseen by y, ``(a, c)`` is not detectable — no stabilising solution."""
    with pytest.raises(DesignError, match=r"has no stabilising solution \(\(A, C\) is not detectable: the modes "
                                          r"\[1\]"):
        _filter_dare(np.array([[1.0]]), np.array([[1.0, 0.0]]), np.array([[0.0]]), np.array([[0.0, 1.0]]))


def test_a_refusal_by_the_forward_line_says_the_solution_exists_with_its_figure(monkeypatch):
    """``a = 1.2``, ``b = 0.7``, ``c = 2``, ``d = 1e-6`` (independent noises): a stabilising solution exists (module
    docstring; the default line designs it, tests/test_synthesis_ammp.py checks it against the closed form). With the
    forward line at 1e-20 — below the rounding of any double-precision P, so Newton's corrections stall (as
    tests/test_riccati_forward.py forces it) — the solve fails numerically: the message must say the solution exists,
    that this is a numerical failure, and name the closed-loop correction against the line."""
    from fmu_fdi.design.toolkit import approximate

    args = np.array([[1.2]]), np.array([[0.7, 0.0]]), np.array([[2.0]]), np.array([[0.0, 1e-6]])
    assert _filter_dare(*args)[0, 0] > 0  # the default line designs it
    monkeypatch.setattr(approximate, "FORWARD_RTOL", 1e-20)
    with pytest.raises(DesignError) as err:
        _filter_dare(*args)
    msg = str(err.value)
    assert "has a stabilising solution" in msg and "numerical failure" in msg, msg
    assert "no stabilising solution" not in msg, msg
    assert "closed-loop correction" in msg and "FORWARD_RTOL = 1e-20" in msg, msg
