"""freqresp.transfer_values' small-order path solves its points as stacks (freqresp.dense_values): the values must be
bit for bit those of one dense LU solve per point (the path it replaced; benchmarks/transfer_values_speed.py times
both), with NaN at an exactly singular point only — also when that point shares a stack with regular ones."""
import numpy as np

from fmu_fdi import freqresp


def _per_point(A, B, C, D, lams):
    """The replaced loop: one numpy.linalg.solve per point, NaN where LAPACK finds an exactly zero pivot."""
    out = np.empty((lams.size,) + D.shape, complex)
    eye, Bc = np.eye(A.shape[0]), B.astype(complex)
    for k, lam in enumerate(lams):
        try:
            out[k] = C @ np.linalg.solve(lam * eye - A, Bc) + D
        except np.linalg.LinAlgError:
            out[k] = np.nan
    return out


def test_stacked_dense_solves_are_the_per_point_solves_bit_for_bit():
    rng = np.random.default_rng(7)
    n, p, m = 12, 3, 5
    # eigenvalue 0 exactly (a zero first row and column: λ = 0 gives LAPACK an exactly zero pivot) and stable ones,
    # upper triangular, ill-scaled by a diagonal similarity over eight decades
    A = np.diag(np.r_[0.0, -10 ** rng.uniform(-2, 2, n - 1)])
    A[1:, 1:] += np.triu(rng.standard_normal((n - 1, n - 1)), 1)
    t = 10 ** rng.uniform(-4, 4, n)
    A = (t[:, None] * A) / t[None, :]
    B, C, D = rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m))
    # more points than one stack holds, λ = 0 (singular) inside the second stack
    lams = 1j * np.r_[np.logspace(-3, 3, freqresp.DENSE_CHUNK + 40)]
    lams[freqresp.DENSE_CHUNK + 7] = 0.0
    freqresp.clear_caches()
    got = freqresp.transfer_values(A, B, C, D, lams)
    want = _per_point(A, B, C, D, lams)
    assert np.array_equal(got, want, equal_nan=True)
    bad = np.flatnonzero(np.isnan(got).any(axis=(1, 2)))
    assert bad.tolist() == [freqresp.DENSE_CHUNK + 7]
    assert np.isfinite(got[np.arange(lams.size) != bad[0]]).all()
