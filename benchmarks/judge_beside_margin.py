"""The one judge beside a slow pole at the stability margin: what it reads, and how close its grid comes.

A plant (n = 6, three outputs, two actuators with a fault on u1, a sensor fault on y1, one unknown input d) whose
slowest mode sits at s = −δ, mixed by a random orthogonal similarity and a diagonal state scaling over four decades;
``nullspace_design`` decouples u and d. Printed per δ: the judge's u/d reading (``decoupling`` ± its bound,
sensitivity), numpy's reading of the same stored filter on the judge's points (every solve refined three times with
longdouble residuals, tests/test_judge_ud_reading.py's ``_refined_response``), the grid's lowest frequency and its
distance to the slow pole, the boundary modes removed from R, R's poles.

Measured 27 Nov (judge10, before the fix; continuous, default margin −sqrt(eps) = −1.5e-8, BOUNDARY_GAP·||A_bal|| ≈
1e-5 here):

    δ       judge leak ± bound (sens)       numpy     grid's distance   removed
    1e-3    3.1e-12 ± 0       (0)           3.4e-12   1e-3              0
    1e-5    2.6e-11 ± 0       (0)           3.3e-13   1e-5              0
    1e-6    5.1e-10 ± 5.6e-6  (3.0e-10)     3.2e-10   1e-6              0
    1e-7    2.9e-10 ± 2.9e-4  (4.7e-9)      5.5e-11   1e-7              0
    3e-8    4.9e-8  ± 1.8e-2  (1.9e-7)      6.3e-8    3e-8              0
    1e-8    1.7e-14 ± 2.3e-7  (4.0e-10)     4.4e-10   1.04e-5           1
    0       6.8e-14 ± 2.4e-7  (5.9e-10)     1.6e-10   9.1e-6            1

A pole outside the margin (δ = 1e-8, the integrator) is a boundary pole: the grid keeps BOUNDARY_GAP·||A_bal|| from it
(1.04e-5, 9.1e-6 rad/s; its only points nearer are the two at twice that gap) and the mode the row cancels to rounding
is removed from R. A stable pole inside the margin was not: the grid reached it (distance δ, lowest point ~δ/100) and
read the row's rounding residue ρ as ρ/δ — an accurate reading of the stored filter (numpy agreed: 6.3e-8 at
δ = 3e-8), but one that grew towards dec_tol as δ approached the margin, then dropped by six decades across it.

Measured 27 Nov (judge11, after: a stable pole within the gap of the boundary is in the judge's mode table,
``plant_modes.boundary_mode_table(beside=True)``; where the row cancels it to rounding the grid keeps the gap from it
and the mode is removed, as beside a boundary pole; numpy: the stored filter's R at the judge's points, refined):

    δ       judge leak ± bound (sens)       numpy     grid's distance   removed
    1e-3    3.1e-12 ± 0       (0)           3.4e-12   1e-3              0
    1e-5    2.6e-11 ± 0       (0)           3.3e-13   1e-5              0     (beyond this plant's gap, 3.1e-6)
    1e-6    1.5e-14 ± 0       (0)           5.1e-11   6.2e-6            1
    1e-7    7.4e-15 ± 0       (0)           1.2e-10   6.8e-6            1
    3e-8    2.3e-14 ± 1.6e-7  (5.7e-10)     5.2e-10   1.01e-5           1
    1e-8    1.7e-14 ± 2.3e-7  (4.0e-10)     4.4e-10   1.04e-5           1
    0       6.8e-14 ± 2.4e-7  (5.9e-10)     1.6e-10   9.1e-6            1

The reading of a cancelled slow mode is now the same on both sides of the margin (rounding); numpy's column is the
stored filter with its pole part, read two gaps beside the pole (ρ/(2·gap) ≤ 1e-9). A mode the row does not cancel
keeps the points beside it (its peak ρ/δ at ω = Im p is what the residual shows): tests/test_judge_beside_margin.py.
The error bound of the refined reading grows as a point nears a pole: reported, not subtracted.

Run: python benchmarks/judge_beside_margin.py
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fmu_fdi import DesignError  # noqa: E402
from fmu_fdi.design import nullspace_design  # noqa: E402
from fmu_fdi.design.toolkit import postconditions as pc  # noqa: E402
from test_judge_beside_margin import _plant  # noqa: E402
from test_judge_ud_reading import _refined_response  # noqa: E402


def main() -> None:
    rng = np.random.default_rng(3)
    for delta in (1e-3, 1e-4, 3e-5, 1e-5, 1e-6, 1e-7, 3e-8, 1e-8, 0.0):
        m = _plant(delta, rng)[0]  # the draws continue across δ, as measured before
        try:
            gen = nullspace_design(m)
        except DesignError as exc:
            print(f"δ={delta:g}: refused: {str(exc)[:150]}")
            continue
        fig = gen.info["postconditions"]
        lam = pc.judge_points(m, gen.Q, gen.groups)[0]  # the judge's points (one row group here)
        om = lam.imag
        poles = np.linalg.eigvals(m.A)
        slow = poles[np.argmin(np.abs(poles))]
        R = (_refined_response(gen.Q, lam) @ _refined_response(m.augmented(), lam)).astype(complex)
        sl = m.group_slices()
        ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
        fs = [np.arange(sl["f"].start, sl["f"].stop)[f.columns] for f in m.faults]
        low = min(np.linalg.norm(R[:, :, c], axis=(1, 2)).max() for c in fs)
        leak = np.linalg.norm(R[:, :, ud], axis=(1, 2)).max() / low
        print(f"δ={delta:g}: slow pole {slow.real:.3g}, judge {fig['decoupling']:.3g} ± {fig['decoupling_error']:.2g} "
              f"(sens {fig['decoupling_sensitivity']:.2g}), numpy {leak:.3g}, lowest ω {om[om > 0].min():.3g}, "
              f"grid's distance {float(np.min(np.abs(lam - slow))):.3g}, "
              f"removed {len(pc.internal_figures(gen)['removed'])}, R_poles {fig['R_poles']}")


if __name__ == "__main__":
    main()
