"""The native runtime's matrix exponential and ZOH discretisation (fdi_linalg.c) against the
Python runtime's (fmu_fdi/runtime/expm.py, the same Higham 2005 [13/13] Padé scaling and
squaring) and scipy's, over norms that need from 0 to 12 squarings."""
import ctypes

import numpy as np
import pytest
import scipy.linalg

from fmu_fdi.runtime.expm import expm, zoh
from native_designs import feature_designs
from native_runtime import compile_runtime


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    lib = ctypes.CDLL(str(compile_runtime(feature_designs()["chi2_cusum_glr_none"], tmp_path_factory.mktemp("expm"))))
    P = ctypes.POINTER(ctypes.c_double)
    lib.fdi_expm.argtypes = [P, ctypes.c_long, P, P]
    lib.fdi_zoh.argtypes = [P, P, ctypes.c_long, ctypes.c_long, ctypes.c_double, P, P, P]
    lib.fdi_zoh_work.argtypes = [ctypes.c_long, ctypes.c_long]
    lib.fdi_zoh_work.restype = ctypes.c_size_t
    return lib


def _ptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def c_expm(lib, A):
    A = np.ascontiguousarray(A, float)
    n = A.shape[0]
    E, work = np.zeros((n, n)), np.zeros(8 * n * n + 1)
    assert lib.fdi_expm(_ptr(A), n, _ptr(E), _ptr(work)) == 1
    return E


@pytest.mark.parametrize("scale", [1e-3, 0.5, 5.0, 40.0, 1e3])
def test_expm_matches_the_python_runtime_and_scipy(lib, scale):
    rng = np.random.default_rng(int(scale * 1000))
    for n in (1, 3, 8):
        A = rng.standard_normal((n, n))
        A = -scale * (A @ A.T) / n - 0.1 * scale * np.eye(n) + 0.3 * scale * (A - A.T)  # stable, non-normal
        E = c_expm(lib, A)
        # same algorithm, other summation order: rounding amplified by the 2^s squarings and
        # the solve, bounded by 1e3 ulps of the largest entry for these well-scaled cases
        tol = 1e3 * np.finfo(float).eps * max(1.0, np.abs(expm(A)).max())
        assert np.abs(E - expm(A)).max() <= tol
        assert np.abs(E - scipy.linalg.expm(A)).max() <= tol


def test_zoh_matches_the_python_runtime(lib):
    rng = np.random.default_rng(3)
    n, m, h = 5, 3, 0.037
    A = rng.standard_normal((n, n)) - 3 * np.eye(n)
    B = rng.standard_normal((n, m))
    Ad, Bd = np.zeros((n, n)), np.zeros((n, m))
    work = np.zeros(lib.fdi_zoh_work(n, m))
    assert lib.fdi_zoh(_ptr(A), _ptr(B), n, m, h, _ptr(Ad), _ptr(Bd), _ptr(work)) == 1
    Ad_py, Bd_py = zoh(A, B, h)
    assert np.abs(Ad - Ad_py).max() <= 64 * np.finfo(float).eps  # no squaring at this norm: a few ulps
    assert np.abs(Bd - Bd_py).max() <= 64 * np.finfo(float).eps * np.abs(Bd_py).max()


def test_expm_refuses_a_non_finite_matrix(lib):
    A = np.array([[np.inf, 0.0], [0.0, 1.0]])
    E, work = np.zeros((2, 2)), np.zeros(64)
    assert lib.fdi_expm(_ptr(A), 2, _ptr(E), _ptr(work)) == 0
