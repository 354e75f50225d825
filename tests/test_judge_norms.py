"""The judge's 2-norm of a stack of matrices (postconditions._nrm) reads a row or a column as a vector (judge18).

Judged against numpy's SVD (the 2-norm ``σ_max`` of each matrix, computed independently of the vector path): for a
vector x of k entries both are backward-stable evaluations of ``||x||₂``; the scaled sum of squares has relative error
at most (k + 2)·u (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., sec. 3.1: a sum of k
non-negative terms (k − 1)·u, each square and the scaling u, the square root u/2) and LAPACK's σ_max of a vector the
same order, so they differ by at most 2(k + 2)·u relative. Matrices with more than one row and column keep the SVD.
"""
import numpy as np

from fmu_fdi.design.toolkit.postconditions import _nrm
from fmu_fdi.linalg import EPS


def _stack(rng, shape, decades):
    X = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return X * 10.0 ** rng.uniform(-decades, decades, (shape[0], 1, 1))


def test_vectors_read_as_their_euclidean_norm_to_rounding():
    rng = np.random.default_rng(18)
    for shape in ((200, 1, 9), (200, 9, 1), (200, 1, 1), (200, 1, 40)):
        # 1e±300: the squares would overflow / underflow unscaled
        X = _stack(rng, shape, 300)
        X[::7, :, :1] = 0.0  # zero entries, and whole zero points below
        X[::11] = 0.0
        k = shape[1] * shape[2]
        ref = np.linalg.norm(X, ord=2, axis=(1, 2))
        got = _nrm(X)
        assert np.all(np.abs(got - ref) <= 2 * (k + 2) * EPS / 2 * ref)
        assert np.all(got[::11] == 0.0)


def test_matrices_keep_the_svd_bit_for_bit():
    rng = np.random.default_rng(19)
    for shape in ((50, 2, 3), (50, 4, 4), (50, 7, 2)):
        X = _stack(rng, shape, 5)
        assert np.array_equal(_nrm(X), np.linalg.norm(X, ord=2, axis=(1, 2)))
    assert np.array_equal(_nrm(np.zeros((4, 0, 3))), np.zeros(4))


def test_infinite_entries_read_as_the_svd_reads_them():
    X = np.zeros((3, 1, 4), complex)
    X[0, 0, :] = [1, 2, 2, 4]
    X[1, 0, 2] = np.inf
    got = _nrm(X)
    assert got[0] == 5.0 and got[2] == 0.0
    assert np.array_equal(got[1:2], np.linalg.norm(X[1:2], ord=2, axis=(1, 2)), equal_nan=True)  # (NaN in numpy)
