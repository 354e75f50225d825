"""Which realisation of ``Q = Y Φ Q0`` approximate model matching ships, by its u/d leak (issue 17, approximate audit
seeds 173 and 199).

``_shipped_filter`` takes the first of its realisations (the minimal one first, the product ``Y Φ Q0`` last) whose
fault/noise error response is the designed one within the comparison's rounding. That comparison does not see the u/d
block ``Q [Gu Gd; I 0]``, which is zero only as a cancellation that Y's gain multiplies: on the audit's discrete n 28
models with Mr = an exact detection row's Rf, the minimal realisation it took leaked 9.46e-5 (seed 173, peak gain of
Y 5.4e5) and 1.21e-7 (seed 199) of the weakest required fault where the product leaks 1.28e-9 and 4.5e-10, and the
re-decoupling refits of the minimal one could not bring it under dec_tol: an achievable request was refused. Now,
where the taken realisation's leak (reading + sensitivity, the final check's rule) exceeds 0.1·dec_tol, another
realisation whose leak is within 0.1·dec_tol and whose error is as admissible is shipped (``_decoupled_candidate``).

Judged by numpy: the audit seeds by tests/test_approximate_random.py's judge (``check_case``: u/d leak at most
dec_tol of the weakest required fault's gain, the error as reported, stability, from numpy solves); the constructed
case by test_synthesis_ammp's ``_numpy_leak_and_faults`` and ``error_norm`` on the returned Q and the model's matrices.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fmu_fdi.design.problems.approximate_matching as am  # noqa: E402
from fmu_fdi import approximate_model_matching  # noqa: E402
from fmu_fdi.lti import LTI  # noqa: E402
from test_approximate_random import check_case  # noqa: E402
from test_synthesis_ammp import MR17, _numpy_leak_and_faults, error_norm, ex5_16  # noqa: E402

#: the issue's decoupling tolerance on the normalised form (postconditions.DEC_TOL)
DEC_TOL = 1e-7
#: the leak the constructed realisation adds: ε on every u column of Q, a static term that moves Q [Gu Gd; I 0] by ε
#: per entry and Q [Gf Gw; 0 0] not at all (the u columns of [Gf Gw; 0 0] are zero)
EPS = 1e-4


@pytest.mark.slow
@pytest.mark.parametrize("seed", [173, 199])
def test_matching_a_detection_row_is_shipped_decoupled(seed):
    """~9 s (173), ~3 s (199) on an idle core (42 s, 21 s measured at load ~10 on 2 cores): the exact detection row (the
    reference), the matching and numpy's judge. Before: refused "the returned filter leaks u/d above dec_tol" (9.46e-5,
    1.21e-7 of the weakest fault gain) — an achievable request, so check_case counts it broken."""
    res = check_case(seed, calls=("amm_ref",))
    assert [st for _, st, _ in res] == ["ok"], res


def _leaky_first(monkeypatch):
    """Every design's first realisations made leaky: ``_shipped_filter`` receives the pair (Q + E, Q), E = [0 ε·1] on
    Q's u columns — its candidates are then Q + E's minimal and own realisation (taken first: their fault/noise
    response is Q's exactly) and Q itself last, the situation of the audit seeds (a realisation with the designed
    error whose u/d cancellation is lost, the product keeping it). The re-decoupling stage is made to keep what it is
    given (its figures read at dec_tol = 1, where it returns at once), so that the shipping stage alone is judged:
    its refits would otherwise mend this static term."""
    real_ship, real_redecouple = am._shipped_filter, am._ud_redecoupling

    def leaky(model, *args, **kw):
        args = list(args)
        Qf = args[4]
        Q = Qf[-1] if isinstance(Qf, tuple) else Qf
        E = np.zeros((Q.p, Q.m))
        E[:, model.ny:model.ny + model.nu] = EPS
        args[4] = (Q + LTI.static(E, Q.dt), Q)
        return real_ship(model, *args, **kw)

    def keep(model, Q, required, fnm, MF, lam, norm, systems, budget, smarg, dec_tol, *a, **kw):
        return real_redecouple(model, Q, required, fnm, MF, lam, norm, systems, budget, smarg, 1.0, *a, **kw)

    monkeypatch.setattr(am, "_shipped_filter", leaky)
    monkeypatch.setattr(am, "_ud_redecoupling", keep)


def test_the_realisation_that_keeps_u_and_d_decoupled_is_shipped(monkeypatch):
    """Varga's Ex. 5.16 (n 3, two actuator faults, two noise inputs, Mr = 10/(s+10) I), H∞ (<1 s). The leaky
    realisations leak ε·|[1 1]|-ish: numpy reads ≥ 1e-5 of the weakest fault peak (~0.1 … 1), far above dec_tol; the
    product Q leaks at rounding level. Shipped: numpy reads every row's u/d leak ≤ dec_tol of its weakest fault peak,
    and its error (numpy's peak, error_norm) is the undisturbed design's within 1e-5 (two peaks read on grids; the
    shipped filter is the same Q). Before: the leaky minimal realisation was shipped and refused "leaks u/d above
    dec_tol"."""
    model = ex5_16()
    gen0 = approximate_model_matching(model, MR17)
    e0 = error_norm(gen0, MR17, gen0.info["M"], "inf")
    _leaky_first(monkeypatch)
    gen = approximate_model_matching(model, MR17)
    leak, faults = _numpy_leak_and_faults(model, gen.Q)
    assert np.all(leak / faults.min(axis=1) <= DEC_TOL), leak / faults.min(axis=1)
    assert error_norm(gen, MR17, gen.info["M"], "inf") <= e0 * (1 + 1e-5)
    assert any("u/d leak" in n and "is shipped" in n for n in gen.info.get("notes", [])), gen.info.get("notes")


def test_the_constructed_realisation_leaks(monkeypatch):
    """The premise of the test above, read by numpy alone: Q + E leaks above dec_tol (so that shipping it is
    refused and the test above can fail)."""
    model = ex5_16()
    gen0 = approximate_model_matching(model, MR17)
    E = np.zeros((gen0.Q.p, gen0.Q.m))
    E[:, model.ny:model.ny + model.nu] = EPS
    leak, faults = _numpy_leak_and_faults(model, gen0.Q + LTI.static(E, gen0.Q.dt))
    assert np.all(leak / faults.min(axis=1) > 100 * DEC_TOL), leak / faults.min(axis=1)
