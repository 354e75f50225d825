"""Counts ok / refused / broken of the approximate designs on the seeded ill-scaled random models with
noise, judged independently (tests/test_approximate_random.py: numpy frequency responses of
R = Q·[Gu Gd Gw Gf; I 0 0 0], rows normalised to fault gain 1 (β = 1 for model detection),
‖R_u‖, ‖R_d‖ ≤ 1e-7, R stable by PBH, Q nonzero, the reported gap / matching error / MDgap equal to
numpy's refined peaks within the file's FIG_RTOL / ERR_RTOL; a matching error no worse than Q = 0 and
than the exact detection row it takes as reference).

Calls per model: nullspace_design (AFD), afdi_bank on up to 3 rows achievable_structure lists,
approximate_model_matching with Mr = an exact detection row's fault response and with Mr = I,
approximate_model_detection_bank on a three-model set (stable plants only). "broken": a returned
design failing the judge, another exception than DesignError, an achievable AFD/AFDI request refused
(or a detection-row reference whose matching is refused: Q_ref itself is admissible).

Run: python benchmarks/approximate_random_judged.py [N] [first_seed] [-v] [--timeout=SECONDS]
(a call that gives no answer within the timeout counts as "timeout", none by default)
(seeds first_seed … first_seed + N − 1; default 20 models from seed 0)
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_approximate_random  # noqa: E402
from test_approximate_random import check_case, noisy_case  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthesis_random_judged import KINDS, _kind as _kind_exact, tally  # noqa: E402


def _kind(detail: str) -> str:
    """A short class of a breakage for the totals (the exact audit's classes and the figures' mismatches)."""
    return _kind_exact(detail, KINDS + (("gap: reported", "gap mismatch"), ("MDgap|MDperf", "MD figure mismatch"),
                                        ("matching error: reported", "error mismatch"),
                                        ("above", "error above a known filter's")))


def _desc(seed: int) -> str:
    m = noisy_case(seed)
    return f"n={m.n} p={m.ny} m={m.nu} nd={m.nd} nw={m.nw} nf={m.nf} {'disc' if m.dt else 'cont'}"


def run(N: int = 20, first: int = 0, verbose: bool = False):
    return tally(range(first, first + N), check_case, _desc, kind=_kind, width=34, verbose=verbose)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "-v" and not a.startswith("--timeout=")]
    for a in sys.argv[1:]:
        if a.startswith("--timeout="):
            test_approximate_random.CALL_TIMEOUT = int(a.split("=", 1)[1])
    run(int(args[0]) if args else 20, int(args[1]) if len(args) > 1 else 0, "-v" in sys.argv)
