"""The judge's u/d reading on a host whose ``np.longdouble`` is plain double (Windows, ARM macOS), simulated in a
subprocess (tests/test_double_host.py's :data:`PATCH`): a leak the judge accepts is one it proves.

The case: random H∞ matching seed 4 (tests/test_synthesis_ammp.py's ``_random_case``, ``norm='inf'``,
``reltol=1e-6``), designed on the simulated host (~7 s). Its filters are decoupling cancellations (``|Q_g|·|Ge|`` ~4e6
times the weakest fault gain), whose double reading has a bound of the size of dec_tol = 1e-7. Before
(d4fb7a0), where longdouble is double nothing was refined: the returned filter's u/d leak read 4.65e-9 ± 1.77e-7
by the judge's defaults and was accepted against dec_tol 1e-7, unproven (host20 saw 2.2e-8 ± 1.8e-7 on this seed in
its audit's judgement). Now the refined reading is formed in double-double
(``postconditions._dd_refined_values``) and charged at ``REFINED_UNIT`` = 2^-64, as on x86.

Asserted, on the simulated host's final judgement of the returned filter:

* the verdict is proven: the design is refused, or ``decoupling + decoupling_error ≤ dec_tol`` in its own
  judgement and in ``check_generator(gen, raise_error=False, normalize=False)`` (defaults: u, d decoupled, every
  fault required) — before, that second judgement read 4.65e-9 ± 1.77e-7 and accepted it (this test fails there);
* points were refined, and the refined reading is right, judged independently: at every refined point of each
  u/d reading the judge made (captured from ``_decoupled_values``), each entry is within its own bound
  (``3N·u_x·err``, u_x = 2^-64) of this test's own value of ``R_X = C_q Z + D_q G`` — computed natively in numpy with
  longdouble (x87, unit 2^-64) residuals: Ge's and Q's solves by numpy's LU in double, refined 4 steps with the
  residual ``b − (λI − A)x`` and the products formed in longdouble (Higham, *Accuracy and Stability*, ch. 12: to
  ``~n·2^-64·(|b| + |λI − A||x|)``). The comparison is taken with twice that bound: the judge's reading and this
  test's, each within it of the stored filter's value. (The points left at their double reading are not compared:
  there the plain bound ``3N·u·err`` is exceeded up to 5.6× on this case, far below the peak — a leak 6.4e-12
  against 8.5e-13 at a point whose bound is 1.1e-12 — on x86 the same; see the judge21 report.)

Measured 28 Nov (judge21), simulated host: design's judgement 2.28e-11 ± 8.7e-10 → 2.28e-11 ± 4.2e-13, the
defaults' 4.65e-9 ± 1.77e-7 → 4.66e-9 ± 8.6e-11 (x86: the same points refined at the same unit); refined readings
within 7.8e-4 of their bound of this test's. ~12 s, most of it the design on the simulated host.
"""
from __future__ import annotations

import numpy as np

from test_double_host import PATCH, simulated_host

EPS = float(np.finfo(float).eps)

_SCRIPT = PATCH + """
import json
import numpy as np
from fmu_fdi.design import approximate_model_matching
from fmu_fdi.design.toolkit import postconditions as pc
from fmu_fdi.errors import DesignError
from test_synthesis_ammp import _random_case

model, Mr = _random_case(4)
out = {"host": [pc.EXT_UNIT, pc.__dict__.get("REFINED_UNIT", pc.EXT_UNIT)]}
try:
    gen = approximate_model_matching(model, Mr, norm="inf", reltol=1e-6)
except DesignError as exc:
    out["refused"] = str(exc)
    print(json.dumps(out))
    raise SystemExit
fig = gen.info["postconditions"]
out["fig"] = [fig["decoupling"], fig["decoupling_error"]]
calls = []
plain = pc._decoupled_values


def kept(Qi, Geb, lam, blocks, with_refined=False):
    res = plain(Qi, Geb, lam, blocks, True)
    Qb = Qi.balanced()[0] if Qi.n else Qi
    calls.append({k: [np.asarray(v).real.tolist(), np.asarray(v).imag.tolist()] for k, v in
                  dict(A=Qb.A, B=Qb.B, C=Qb.C, D=Qb.D, Ae=Geb.A, Be=Geb.B, Ce=Geb.C, De=Geb.D, lam=lam,
                       val=res[0], err=res[1], refined=res[3]).items()})
    return res if with_refined else res[:3]


pc._decoupled_values = kept
pc._UD_CACHE.clear()
again = pc.check_generator(gen, raise_error=False, normalize=False)
out["again"] = [again["decoupling"], again["decoupling_error"]]
out["calls"] = calls
print(json.dumps(out))
"""


def _refined_native(A, B, lam, steps: int = 4):
    """``(λI − A)^{-1} B`` (B: (K, n, c), longdouble) refined in longdouble, per point; numpy only."""
    n = A.shape[0]
    Al = A.astype(np.longdouble)
    X = np.empty(B.shape, np.clongdouble)
    for k, lk in enumerate(lam):
        M = lk * np.eye(n) - A
        x = np.linalg.solve(M, B[k].astype(complex)).astype(np.clongdouble)
        for _ in range(steps):
            r = B[k] - (np.clongdouble(lk) * x - Al @ x)
            x = x + np.linalg.solve(M, r.astype(complex))
        X[k] = x
    return X


def _arr(pair):
    return np.asarray(pair[0]) + 1j * np.asarray(pair[1])


def test_simulated_double_host_proves_the_leak_it_accepts():
    got = simulated_host(_SCRIPT, timeout=240)
    assert got["host"][0] == EPS / 2, got["host"]
    if "refused" in got:
        return  # refused: allowed (the judge proves nothing it accepts)
    dec_tol = 1e-7
    # each accepted leak is proven below dec_tol: the design's own judgement and the judge's again with its defaults
    # (u and d decoupled, every fault required; before: 4.65e-9 ± 1.77e-7 accepted there)
    for name in ("fig", "again"):
        d, e = got[name]
        assert d > dec_tol or d + e <= dec_tol, f"{name}: leak {d:.3g} ± {e:.2g} accepted against dec_tol {dec_tol}"
    assert got["calls"], "no u/d reading made: nothing judged"
    if np.finfo(np.longdouble).eps >= EPS:  # pragma: no cover  (a real double host: no independent x87 judge here)
        return
    for c in got["calls"]:
        A, B, C, D = (_arr(c[k]).real for k in "ABCD")
        Ae, Be, Ce, De = (_arr(c[k]).real for k in ("Ae", "Be", "Ce", "De"))
        lam, val, err = _arr(c["lam"]), _arr(c["val"]), _arr(c["err"]).real
        refined = _arr(c["refined"]).real.astype(bool)
        K = lam.size
        G = Ce.astype(np.longdouble) @ _refined_native(Ae, np.broadcast_to(Be, (K,) + Be.shape), lam) + De
        Z = _refined_native(A, B.astype(np.longdouble) @ G, lam)
        R = (C.astype(np.longdouble) @ Z + D.astype(np.longdouble) @ G).astype(complex)
        N = max(A.shape[0], Ae.shape[0], 1)
        assert np.any(refined), "no point refined: the reading proves nothing beyond double"
        # the judge's bound at a refined point (3N·2^-64·err) and this test's own error (the same at x87's unit)
        tol = 2 * 3 * N * 2.0 ** -64 * err[refined]
        worst = float(np.max(np.abs(val[refined] - R[refined]) / tol))
        assert worst <= 1, f"a refined reading off by {worst:.3g} × its bound ({int(refined.sum())} points)"
