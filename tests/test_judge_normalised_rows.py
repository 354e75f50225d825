"""check_generator leaves rows that already have unit weakest fault gain as they are (postconditions.NORMALISED_RTOL).

A bank's members are normalised by their own designs' judgements; the bank's judgement reads each member's weakest
required fault gain again as 1 to rounding (random exact seed 379: 1 ± 4.8e-13). Scaling such a row by 1 + 1e-13
changes the filter by rounding and costs the judge a second reading of every group (benchmarks/judge_bank_speed.py:
the bank's check 1.13 … 1.54× faster). Judged by numpy: the weakest required fault's peak of each row on a grid of our
own (numpy frequency responses of the stored data) is 1 within 1e-3 — the contract; the filter is bit for bit the one
passed; the report equals leakage()/structure_matrix() of the object (same numbers); and a row whose weakest gain is
off by 1e-6 (above the 1e-10 rule) is still scaled to 1.
"""
import copy

import numpy as np

from fmu_fdi import leakage, structure_matrix
from fmu_fdi.design import structured_bank
from fmu_fdi.design.problems.achievable import achievable_structure
import published as pub
from fmu_fdi.design.toolkit.postconditions import NORMALISED_RTOL, check_generator


def _weakest_gains(gen, S):
    """Per group: the smallest required fault peak over ω ∈ {0} ∪ logspace(−3, 3, 400) (numpy only)."""
    model, Q = gen.model, gen.Q
    G = model.augmented()
    lam = 1j * np.r_[0.0, np.logspace(-3, 3, 400)]
    val = lambda S_, x: S_.C @ np.linalg.solve(x * np.eye(S_.n) - S_.A, S_.B) + S_.D if S_.n else S_.D  # noqa: E731
    R = np.stack([val(Q, x) @ val(G, x) for x in lam])
    sl = model.group_slices()["f"]
    cols = [np.arange(sl.start, sl.stop)[f.columns] for f in model.faults]
    return [min(float(np.max(np.linalg.norm(R[:, g][:, :, cols[j]], axis=(1, 2)))) for j in np.flatnonzero(S[i]))
            for i, g in enumerate(gen.groups)]


def test_normalised_rows_are_left_as_they_are_and_others_are_scaled():
    model = pub.ex5_3()
    S = np.asarray(achievable_structure(model), int)
    bank = structured_bank(model, S, poles=[-3])
    for low in _weakest_gains(bank, S):
        assert abs(low - 1.0) <= 1e-3, low  # numpy's grid vs the judge's: a peak read between points
    again = copy.deepcopy(bank)
    Q0 = again.Q
    fig = check_generator(again, structure=S)
    assert fig["scales"] == [1.0] * len(S)  # read 1 ± rounding: not rescaled
    for X, Y in ((again.Q.C, Q0.C), (again.Q.D, Q0.D)):
        assert np.array_equal(X, Y)
    assert fig["leakage"] == leakage(again)
    assert np.array_equal(np.asarray(fig["structure_matrix"]), structure_matrix(again))
    off = copy.deepcopy(bank)
    off.scale_rows(np.full(off.Q.p, 1.0 + 1e-6))  # 1e4 times the rule: must be normalised again
    fig = check_generator(off, structure=S)
    assert all(abs(s * (1.0 + 1e-6) - 1.0) <= NORMALISED_RTOL for s in fig["scales"])
    for low in _weakest_gains(off, S):
        assert abs(low - 1.0) <= 1e-3, low
    assert fig["leakage"] == leakage(off)
