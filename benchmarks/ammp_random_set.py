"""approximate_model_matching on the seeded random models: returned / refused / crashed, and time.

For each model of tests/synthesis_models.py (n = 4-30, continuous and discrete, with and without
unknown inputs d, two sensor and two actuator faults) and a random stable first-order reference
Mr (1-2 residuals), the H∞ and the H2 design is run. A returned design is checked against its
contract from the model and the returned filter alone (decoupling of u and d relative to the
data, the error response of Q against M [Mr 0] at 600 points equal to the reported gamma_sub
within 1e-5 relative in H∞); "BROKEN" counts returned designs that fail it, "crash" any exception
other than DesignError. Run: python benchmarks/ammp_random_set.py [N]

The contract is also judged by numpy on the returned Q and the model's matrices alone (tests/test_synthesis_ammp.py's
``_numpy_leak_and_faults`` and ``error_norm``, not the package's analysis): every row's u/d leak at most dec_tol = 1e-7
of its weakest required fault's peak gain (Varga's normalisation; a fault is required by a row where that row of Mr
is not identically zero), and an H2 design's H2 error no larger than the H∞ design's (an admissible filter of the
same problem where both have the same M: 1e-3 for the trapezoid; 1e-6 ||Mr||∞ absolute, the regularised problems'
accuracy: fictitious noise ε = 1e-6 ||Ĝ||∞ on rank-deficient rows moves each optimum by O(ε), continuous seeds 0, 2
differ by 6e-8, 8e-8). A design failing only the leak test is counted "leak" (apart from BROKEN): the package's
post-condition judges a matching row unnormalised (``faults=[]``), so these are rows whose weakest fault is small.

27 Nov, h2exact (same session, numpy judge): main e6079aa ok 45 / refused 8 / BROKEN 7 — the discrete H2 filter DARE
(scipy) returned wrong solutions: seeds 3, 29 H2 errors 41.58, 9.029 above the H∞ filters' H2 errors; after
approximate_matching._filter_dare (SLICOT SB02OD, checked) see the figures printed by the run in the commit message.

N = 30, 27 Nov (same session): integ5 ok 50 / refused 10 (6 "error response differs from the designed one" at the
fixed 1e-6: discrete H2 seeds 7, 9, 13, 17, 21, 27); with the derived rounding bound of
approximate_matching._shipped_filter ok 52 / refused 8 (continuous H∞ seeds 4, 28 designed; H2 seeds 7, 9, 17, 21, 27
refused by the judge for their u/d leaks, seed 13 still for its gap), BROKEN 0, crash 0 both.
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fmu_fdi import DesignError, approximate_model_matching  # noqa: E402
from fmu_fdi.design.problems.approximate_matching import fault_noise_map  # noqa: E402
from fmu_fdi.lti import LTI, hstack  # noqa: E402
from synthesis_models import random_model  # noqa: E402
from test_synthesis_ammp import _numpy_leak_and_faults, error_norm  # noqa: E402

#: the judge's decoupling tolerance on Varga's normalised form (postconditions.DEC_TOL)
DEC_TOL = 1e-7


def reference(model, seed: int) -> LTI:
    rng = np.random.default_rng(100 + seed)
    r = 1 + seed % 2
    pole = np.array([[0.5]]) if model.dt else np.array([[-2.0]])
    return LTI(np.kron(np.eye(r), pole), rng.normal(size=(r, model.nf)), np.eye(r), np.zeros((r, model.nf)),
               model.dt)


def peak_error(gen, Mr) -> float:
    model = gen.model
    F = hstack([Mr, LTI.zero(Mr.p, model.nw, model.dt)]) if model.nw else Mr
    M = gen.info["M"]
    MF = M @ F if M.n else M.D @ F
    top = np.pi / model.dt if model.dt else 1e5
    w = np.concatenate([[0.0], np.logspace(-5, np.log10(top), 600)])
    lam = np.exp(1j * w * model.dt) if model.dt else 1j * w

    def resp(S):
        if S.n == 0:
            return np.broadcast_to(S.D.astype(complex), (w.size,) + S.D.shape)
        X = np.linalg.solve(lam[:, None, None] * np.eye(S.n) - S.A, np.broadcast_to(S.B, (w.size,) + S.B.shape))
        return S.C @ X + S.D

    E = np.einsum("kij,kjl->kil", resp(gen.Q), resp(fault_noise_map(model))) - resp(MF)
    return float(np.max(np.linalg.norm(E, 2, axis=(1, 2))))


def numpy_verdict(gen, Mr, other=None) -> str:
    """'' if the returned design meets the numpy judge (module docstring), else what fails. ``other``: the H∞ design
    of the same case, the H2 design's competitor."""
    model = gen.model
    leak, faults = _numpy_leak_and_faults(model, gen.Q)
    lam = np.exp(1j * np.linspace(0, np.pi, 64)) if model.dt else 1j * np.logspace(-3, 3, 64)
    Mv = Mr.values(lam) if Mr.n else np.broadcast_to(Mr.D, (lam.size,) + Mr.D.shape)
    req = np.abs(Mv).max(axis=0) > 0  # rows × faults
    out = []
    for i in range(gen.Q.p):
        low = faults[i, req[i]].min() if np.any(req[i]) else faults[i].max()
        if not leak[i] <= DEC_TOL * low:
            out.append(f"leak: row {i + 1} {leak[i] / low:.2g} of its weakest fault")
    if other is not None and gen.info["norm"] == "2":
        M = gen.info["M"]
        lam2 = np.exp(1j * np.linspace(0, np.pi, 16)) if model.dt else 1j * np.logspace(-2, 2, 16)
        if np.allclose(M.values(lam2) if M.n else M.D, other.info["M"].values(lam2) if other.info["M"].n
                       else other.info["M"].D, rtol=1e-12, atol=0):
            e2, ei = error_norm(gen, Mr, M, "2"), error_norm(other, Mr, M, "2")
            if not e2 <= ei * (1 + 1e-3) + 1e-6 * Mr.hinfnorm()[0]:
                out.append(f"H2 error {e2:.4g} > the H∞ filter's {ei:.4g}")
    return "; ".join(out)


def run(N: int = 30, verbose: bool = True) -> dict:
    counts = {"ok": 0, "refused": 0, "leak": 0, "BROKEN": 0, "crash": 0}
    reasons: dict[str, int] = {}
    times = []
    for seed in range(N):
        model = random_model(seed)
        Mr = reference(model, seed)
        ginf = None
        for norm in ("inf", "2"):
            t = time.perf_counter()
            try:
                gen = approximate_model_matching(model, Mr, norm=norm)
                elapsed = time.perf_counter() - t
                bad = gen.info["postconditions"]["decoupling"] > 1e-6
                if norm == "inf":
                    ginf = gen
                    e = peak_error(gen, Mr)
                    bad |= e > gen.info["gamma_sub"] * (1 + 1e-5) + 1e-9 * max(1.0, Mr.hinfnorm()[0])
                why = numpy_verdict(gen, Mr, ginf if norm == "2" else None)
                leak_only = why and all(w.startswith("leak") for w in why.split("; "))
                key = "BROKEN" if bad or (why and not leak_only) else "leak" if why else "ok"
                msg = f"gamma_sub={gen.info['gamma_sub']:.4g} {why}"
            except DesignError as exc:
                elapsed = time.perf_counter() - t
                key, msg = "refused", str(exc)[:110]
                reasons[msg[:60]] = reasons.get(msg[:60], 0) + 1
            except Exception as exc:  # noqa: BLE001 - a crash is what this benchmark counts
                elapsed = time.perf_counter() - t
                key, msg = "crash", repr(exc)[:110]
            times.append(elapsed)  # (the design only, not the numpy judge)
            counts[key] += 1
            if verbose:
                print(f"seed {seed:2d} n={model.n:2d} {'dt' if model.dt else 'ct'} d={model.nd} {norm:>3}: "
                      f"{key:8s} {times[-1]:5.2f} s  {msg}")
    print("totals:", counts, f"| median time {np.median(times):.2f} s, max {np.max(times):.2f} s")
    for r, c in sorted(reasons.items(), key=lambda x: -x[1]):
        print(f"  refused {c:2d}x: {r}")
    return counts


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 30)
