"""analysis.fault_noise_gap, read on column slices of the one realisation of R = Q·[Gu Gd Gw Gf; I 0 0 0],
equals the gap numpy reads on the frequency responses of Q and Ge (an independent computation):
per row group i of an afdi bank, ``min_{S_ij = 1} ‖R_f,ij‖∞ / ‖[R_f,ij (S_ij = 0)  R_d,i  R_w,i]‖∞``;
without S, ``min_j ‖R_f,j‖∞ / ‖[R_d R_w]‖∞`` of a detection filter (Varga 2017, §5.3, fdif2ngap).

Seeds of the approximate audit's noisy models (tests/test_approximate_random.py); the time of the
reading is measured in benchmarks/gap_speed.py.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fmu_fdi.analysis import fault_noise_gap  # noqa: E402
from fmu_fdi.design import afdi_bank, nullspace_design  # noqa: E402
from fmu_fdi.design.problems.achievable import achievable_structure  # noqa: E402
from test_approximate_random import _cols, _freqresp, _ge_values, _points, _refined_peak, noisy_case  # noqa: E402

#: numpy's refined peak (1500-point grid, three rounds of 21-point refinement) is within 1e-6 (relative)
#: of the H∞ norm for resonances of damping ζ ≥ 1e-3 (tests/test_approximate_random.py), AB13DD within
#: 1e-10; a ratio of two such peaks is within ~2e-6. 1e-4 leaves a margin of 50 and still catches a
#: norm of another block (the excluded faults' or the decoupled inputs' columns change the figure by
#: factors, not parts per million).
GAP_RTOL = 1e-4
ATOL = np.sqrt(np.finfo(float).eps)


def _numpy_gap(Q, model, rows, required, noise_cols) -> float:
    lam = _points(model, [Q])
    cols = _cols(model)

    def peak(c):
        return _refined_peak(lambda L: _freqresp(Q.A, Q.B, Q.C[rows], Q.D[rows], L) @ _ge_values(model, L)[:, :, c],
                             lam, model.dt)

    beta = min(peak(cols[nm]) for nm in required)
    noise = peak(noise_cols)
    # fault_noise_gap counts a noise norm ≤ atol = √eps (1.5e-8) as zero: an exactly decoupled w is read by
    # numpy as rounding, eps·‖Q‖‖Ge‖ ≤ 2e-12 on these models (gains ≤ 1e4), 1e-3·atol keeps 4 decades apart
    return np.inf if noise <= 1e-3 * ATOL else beta / noise


def _agree(gap: float, ref: float) -> bool:
    return (np.isinf(gap) and np.isinf(ref)) or (np.isfinite(ref) and abs(gap - ref) <= GAP_RTOL * ref)


def _dw(model):
    cols = _cols(model)
    return np.r_[np.arange(model.nu + model.nd + model.nw)[cols["d"]], np.arange(model.nu + model.nd + model.nw)[cols["w"]]]


@pytest.mark.parametrize("seed", [1, 2])
def test_row_gaps_are_numpys(seed):
    model = noisy_case(seed)
    names = model.fault_names
    rows = np.asarray(achievable_structure(model), int)[:3]
    bank = afdi_bank(model, rows)
    cols = _cols(model)
    gaps = fault_noise_gap(bank, rows)
    for i, g in enumerate(bank.groups):
        noise = np.concatenate([_dw(model)] + [cols[nm] for nm, s in zip(names, rows[i]) if not s]).astype(int)
        ref = _numpy_gap(bank.Q, model, g, [nm for nm, s in zip(names, rows[i]) if s], noise)
        assert ref > 0
        assert _agree(gaps[i], ref), (i, gaps[i], ref)


@pytest.mark.parametrize("seed", [0, 6])  # seeds whose detection filter leaves w in r (a finite gap)
def test_detection_gap_is_numpys(seed):
    model = noisy_case(seed)
    gen = nullspace_design(model)
    ref = _numpy_gap(gen.Q, model, list(range(gen.Q.p)), model.fault_names, _dw(model))
    assert np.isfinite(ref) and ref > 0
    assert _agree(fault_noise_gap(gen), ref), (fault_noise_gap(gen), ref)


@pytest.mark.parametrize("seed", [0, 6])
def test_undecoupled_faults_of_a_zero_in_s_count_as_noise(seed):
    """The detection filter read against S rows with one zero: the excluded fault is not decoupled by
    this filter, so it is the noise that matters (the afdi banks above decouple theirs exactly)."""
    model = noisy_case(seed)
    names = model.fault_names
    gen = nullspace_design(model)
    cols = _cols(model)
    for j, nm in enumerate(names):
        S = np.ones((1, len(names)), int)
        S[0, j] = 0
        ref = _numpy_gap(gen.Q, model, list(range(gen.Q.p)), [x for x in names if x != nm],
                         np.concatenate([_dw(model), cols[nm]]).astype(int))
        without = _numpy_gap(gen.Q, model, list(range(gen.Q.p)), [x for x in names if x != nm], _dw(model))
        gap = fault_noise_gap(gen, S)[0]
        assert _agree(gap, ref), (nm, gap, ref)
        assert ref < without * (1 - 10 * GAP_RTOL) or len(names) == 1  # the excluded fault does count here
