"""Approximate audit of seeds 160-199 (benchmarks/approximate_random_judged.py 20 160 / 20 180, --timeout=120, numpy
judge of tests/test_approximate_random.py): 174 ok / 0 refused / 3 broken on ae569eb. All three are fixed: seed 176's
afdi_bank here (the certified H∞ norm); seeds 173 and 199 in tests/test_amm_shipped_leak.py (the shipped
realisation). Neither cause was in the exact synthesis core (nullspace, banks, pencil): the diagnoses as found.

- **Seed 176, afdi_bank** (rows [0 1 1 1 1], [1 1 1 0 1], [1 1 1 1 0]; n 28, continuous): row 2's reported gap
  ``info['gaps'][1]`` = 0.316983 where numpy reads 0.383986 (the member's own ``gap_estimate`` is 0.3839857). The gap
  is ``analysis.fault_noise_gap`` on the group's internal form (``banks.row_gaps``), whose fault fs1's H∞ norm
  ``lti.LTI.hinfnorm`` (SLICOT AB13DD) returns as 0.835288 at 6.38 rad/s on the slice's realisation (order 77,
  minreal removes nothing) — a local peak: numpy's dense grid reads 1.011845 at 11.93 rad/s on the same realisation,
  and AB13DD on the TB01ID-balanced non-minimal slice finds 1.0118477 at 11.953 rad/s. AB13DD's ``equil = 'S'``
  does not help. lti.py / analysis.py (no owner): a peak AB13DD returns is attained, so a lower bound; check it
  against the response on a pole-based grid refined at its top and keep the larger. Tried on this tree by
  replacing ``hinfnorm`` for the run (200-point ``frequency_grid`` of the balanced realisation, three local 41-point
  refinements): seed 176's afdi_bank passes numpy's judge; the same design had two more norms AB13DD read low by
  2.3 % (0.0831539 for 0.0850743, 2.51927 for 2.57745). AB13DD on the balanced minimal slice alone is not enough
  (0.835288 again).
- **Seeds 173 and 199, approximate_model_matching with Mr = an exact detection row's Rf** (discrete n 28): refused
  "the returned filter leaks u/d above dec_tol": 9.46e-5 (173) and 1.21e-7 (199) of the weakest fault gain. The
  basis Q0 decouples to 1.7e-11 (173; 0 for 199) and the product realisation ``Y·Φ·Q0`` (order 122 / 98) leaks
  1.28e-9 / 4.5e-10 by the library's own ``normalised_leak``; ``_shipped_filter`` ships the *minimal* realisation
  of the product (same order, other coordinates) because its fault/noise response passes the comparison — but
  with Y's peak gain 5.4e5 (173) its u/d cancellation is lost (values 1.3e-7 off Y(λ)Φ(λ)Q0(λ), relative), and
  ``_ud_redecoupling``'s candidates, all built from the shipped filter, still leak 2.29e-5 after refits.
  approximate_matching.py (amm17): offer the product realisation ``Y·Φ·Q0`` (the second element of ``Qfull``)
  among the re-decoupling candidates, or let ``_shipped_filter`` prefer, among the candidates within its bound,
  the one with the least normalised u/d leak. Tried on this tree by wrapping ``_shipped_filter`` for the run (ship
  the product where it leaks under a tenth of the shipped realisation; the product's own error comparison skipped):
  both seeds then pass numpy's judge, reported error included (seed 199's shipped leak, 9.17e-8 at that stage,
  passes it and is read 1.21e-7 by the final check: a rule "leak ≤ dec_tol" alone does not fix it).
"""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_approximate_random import check_case  # noqa: E402


def _broken(seed, call):
    return [f"{what}: {detail}" for what, st, detail in check_case(seed, calls=(call,)) if st == "broken"]


@pytest.mark.parametrize("seed", [176, 148])
def test_afdi_bank_gaps_are_numpys(seed):
    """~6 s each: achievable_structure, the three-row afdi_bank and numpy's refined peaks. Broken on ae569eb (seed 176:
    a gap reported 0.316983 where numpy reads 0.383986; seed 148, found by the regression audit 136-159: 0.343525
    where numpy reads 0.425015): ``lti.LTI.hinfnorm`` returned SLICOT AB13DD's value, a local peak of a fault slice
    (176: 0.835288 = ||D|| at 6.38 rad/s, the peak 1.011845 at 11.93 rad/s); fixed by the certified peak
    (``lti.certified_peak``: the Hamiltonian pencil's crossings at the attained level, climbed from)."""
    assert not _broken(seed, "afdi")

