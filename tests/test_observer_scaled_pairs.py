"""Observer gains on pairs whose states are scaled over many decades: placed in the balanced coordinates, checked in
the caller's.

``observer_gain`` split ``(A, C)`` by the observability staircase in the caller's coordinates, whose rank decisions
are relative to ``‖[A; C]‖``, and checked the placement only in the staircase's coordinates. On 300 random pairs
scaled over nine decades (tests/test_riccati_failure_messages.scaled_random_case: ``A = T Ã T⁻¹``, ``C = C̃ T⁻¹``,
``Ã`` random, ``C̃`` random of full row rank — observable) 27 gains came back with ``A − L C`` unstable and 23 pairs
were refused as 'not detectable'. The judge is numpy in the unscaled coordinates: the eigenvalues of
``T⁻¹(A − L C)T = Ã − (T⁻¹L) C̃`` — a well-scaled matrix, computed to ~eps of its norm — against the poles requested.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from fmu_fdi.design.observers._observer import observer_gain, pole_error

from test_riccati_failure_messages import scaled_random_case

# (seed, what 253b4cb did): 'unstable' = with the default poles a gain returned with A − L C unstable (with n poles
# given, as here: refused, '(A, C) has n − 1 observable (assignable) modes', a stable mode read as unobservable);
# 'refused' = '(A, C) is not detectable'
CASES = [(14, "unstable"), (19, "unstable"), (22, "unstable"), (72, "unstable"), (139, "unstable"),
         (11, "refused"), (57, "refused"), (102, "refused")]


def _unscaled(seed):
    A, C, Qx, R, dt, Pstar, (At, Ct, Qt, Pt) = scaled_random_case(seed)
    s = np.sqrt(np.diag(Qx) / np.diag(Qt))  # T = diag(s): Qx = T Qt T
    return A, C, dt, At, Ct, s


@pytest.mark.parametrize("seed, old", CASES)
def test_observer_gain_places_the_poles_of_the_loop_the_model_runs(seed, old):
    A, C, dt, At, Ct, s = _unscaled(seed)
    n = A.shape[0]
    poles = (np.linspace(0.2, 0.6, n) if dt else -np.linspace(1.0, 3.0, n)).astype(complex)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = observer_gain(A, C, poles, dt)
    assert g.fixed.size == 0  # C̃ random: observable, every pole assigned
    ev = np.linalg.eigvals(At - (g.L / s[:, None]) @ Ct)  # T⁻¹(A − L C)T, with C = C̃ T⁻¹
    # line: the placement's own check allows max(1e3·eps·κ, √eps) of the loop's norm (observer_gain's comment); the
    # distinct poles here are 0.1 … 1 apart, so 1e-6 relative is that line with the scaling's rounding on top and still
    # 1e5 below what the old gains missed by (unstable loops)
    assert pole_error(ev, poles) <= 1e-6 * max(1.0, float(np.abs(poles).max()))
    assert np.all(np.abs(ev) < 1.0) if dt else np.all(ev.real < 0.0)


def test_luenberger_design_on_a_scaled_pair_returns_a_stable_residual_filter():
    """The design a user calls (``luenberger``), seed 19 (continuous, n = 4): 253b4cb placed a gain whose loop was
    unstable and the post-condition refused it (NumericalDesignError, 'largest Re(pole) = 3.68683'); the returned
    filter's poles (numpy, in the unscaled coordinates) are now the defaults', all stable."""
    from fmu_fdi import FDIModel
    from fmu_fdi.design.observers.output_observer import luenberger

    A, C, dt, At, Ct, s = _unscaled(19)
    n, p = A.shape[0], C.shape[0]
    model = FDIModel.from_matrices(A, np.zeros((n, 1)), C, np.zeros((p, 1)), dt=dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gen = luenberger(model)
    L = np.array(gen.info["gain"])
    ev = np.linalg.eigvals(At - (L / s[:, None]) @ Ct)
    assert np.all(ev.real < 0.0)
    assert pole_error(ev, np.array(gen.info["poles"], complex)) <= 1e-6 * max(1.0, float(np.abs(ev).max()))
