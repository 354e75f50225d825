"""afdi_bank's reported gaps (banks.row_gaps, each row read on its own member's internal form) are the
bank's own gaps (analysis.fault_noise_gap on the stacked bank, rows of its internal form).

The two read the same transfer functions on different realisations: the stacked bank's rows carry
every member's states (approximate audit seed 68: 143 states in its internal form, 564 in the noise
block of the former hstack reading, one H∞ norm of which took 140–180 s), a member's only its own. Seeds here are small (n 6, 7; discrete, continuous) so that the stacked
reading, the baseline, stays cheap; the time is measured in
``benchmarks/approximate_random_judged.py --gap-time`` and ``benchmarks/gap_speed.py``.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fmu_fdi.analysis import fault_noise_gap  # noqa: E402
from fmu_fdi.design import afdi_bank  # noqa: E402
from fmu_fdi.design.problems.achievable import achievable_structure  # noqa: E402
from fmu_fdi.design.problems.banks import row_gaps  # noqa: E402
from test_approximate_random import noisy_case  # noqa: E402

#: AB13DD computes each H∞ norm to a relative 1e-10 (slycot's default tol) and the two realisations
#: differ by rounding (‖·‖ ≤ 1e4 on these seeds, eps·1e4 ≈ 2e-12); 1e-8 leaves two decades over both
GAP_RTOL = 1e-8


@pytest.mark.parametrize("seed", [1, 2])
def test_afdi_gaps_are_the_banks_own_gaps(seed):
    model = noisy_case(seed)
    rows = np.asarray(achievable_structure(model), int)[:3]
    bank = afdi_bank(model, rows)
    stacked = fault_noise_gap(bank, rows)
    assert len(bank.info["gaps"]) == len(rows)
    assert row_gaps(bank, rows) == bank.info["gaps"]
    for mine, theirs in zip(bank.info["gaps"], stacked):
        assert (np.isinf(mine) and np.isinf(theirs)) or abs(mine - theirs) <= GAP_RTOL * abs(theirs), (mine, theirs)
