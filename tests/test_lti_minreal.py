"""LTI.minreal (SLICOT TB01ID balancing, then TB01PD): a rank tolerance above the data's scale gives the
static part, never a crash (slycot's TB01PD with equil='S' and tol > 1 died in LAPACK with a segmentation
fault; model_matching's least-order solve passes absolute tolerances mm_tol·||data|| that can exceed 1)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from fmu_fdi.lti import LTI


def test_tolerance_above_one_gives_the_static_part_in_a_fresh_process():
    # in a subprocess: a segmentation fault must fail this test, not take the test worker with it
    code = textwrap.dedent("""
        import numpy as np
        from fmu_fdi.lti import LTI
        G = LTI(np.diag([-1.0, -2.0, -3.0]), np.ones((3, 1)), np.ones((1, 3)), [[0.5]])
        for tol in (1.0, 1.0001, 2.0, 100.0):
            for job in "MCO":
                r = G.minreal(tol, job=job)
                assert r.n == 0 and np.array_equal(r.D, [[0.5]]), (tol, job, r.n)
        print("ok")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", (out.returncode, out.stderr[-500:])


@pytest.mark.parametrize("job", ["M", "C", "O"])
def test_balanced_staircase_removes_exactly_the_uncontrollable_and_unobservable_modes(job):
    """(-1) controllable and observable, (-2) uncontrollable, (-3) unobservable, states scaled over
    six decades: the counts are 1 (M), 2 (C: -1, -3), 2 (O: -1, -2); the kept transfer function is
    checked against 1/(s + 1) by numpy at three points (independent of SLICOT)."""
    T = np.diag([1e-3, 1.0, 1e3])  # x = T x'
    A = np.linalg.solve(T, np.diag([-1.0, -2.0, -3.0]) @ T)
    B = np.linalg.solve(T, np.array([[1.0], [0.0], [1.0]]))
    C = np.array([[1.0, 1.0, 0.0]]) @ T
    r = LTI(A, B, C, [[0.0]]).minreal(job=job)
    assert r.n == {"M": 1, "C": 2, "O": 2}[job]
    for s in (0.3j, 1.0, 2.0 + 5.0j):
        g = (r.C @ np.linalg.solve(s * np.eye(r.n) - r.A, r.B))[0, 0]
        # the similarity T has condition 1e6: rounding of the data ~ 1e6 · eps ≈ 2e-10 relative, bounded by 1e-9
        assert abs(g - 1.0 / (s + 1.0)) <= 1e-9
