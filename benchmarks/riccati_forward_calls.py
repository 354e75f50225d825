"""Does the forward check of ``spectral_riccati`` (on by default since kalman17) refuse answers its callers accepted?

``toolkit.approximate.spectral_riccati`` is wrapped: every call is made as the code makes it (``forward=True``) and,
where it returns None, again with ``forward=False`` (the residual line alone, the acceptance before kalman17). A call
the second accepts and the first refuses is a refusal by the forward check. For every call the caller
(``coouter_inverse`` — noise normalisers, the unified design's factorisation — or approximate_matching's
``_filter_dare``), the accepted answer's forward figure and the Newton steps the forward refinement took (steps > 0: the
answer returned differs from the direct solver's, which the residual line alone returned) are recorded.

Sets: ``benchmarks/ammp_random_set.py``'s seeded matching cases 0..N−1 (H∞ and H2), then the approximate audit's
``tests/test_approximate_random.check_case`` on the seeds given (every call: AFD, AFDI, amm(Mr = row), amm(Mr = I),
model-detection bank). The designs' verdicts are those scripts' own.

Run: OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_forward_calls.py [N_AMMP] [AUDIT_SEEDS, e.g. 0-40 or 0,3,7]

27 Nov, kalman18 (on 253b4cb; spectral_riccati and coouter_inverse unchanged since; 2-core machine shared with four
sessions, ~60 min): ammp_random_set 30: ok 60 / refused 0 / leak 0 / BROKEN 0 / crash 0 (as without the wrapper);
_filter_dare 28 calls, all accepted by both lines, none after a Newton step (the direct answers met the forward line),
forward figure max 7.4e-9, median 5.6e-13. Audit seeds 0–40 (every call of check_case; all ok but seed 26 amm(Mr = I),
refused as at the last check, no Riccati refusal in it): coouter_inverse 70 calls, all accepted, none stepped,
forward max 1.4e-12, median 6.4e-15. So no call of either set is refused by the forward check, and none of their
answers is changed by it.
"""
from __future__ import annotations

import sys
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from fmu_fdi.design.toolkit import approximate  # noqa: E402

RECORDS: list[dict] = []
_original = approximate.spectral_riccati


def _caller() -> str:
    for frame in reversed(traceback.extract_stack()[:-2]):
        if frame.name in ("coouter_inverse", "_filter_dare", "_deflated_riccati"):
            return frame.name
    return "other"


def _wrapped(A, B, C, D, dt, *, figures=None, forward=True):
    got: dict = {}
    t0 = time.perf_counter()
    X = _original(A, B, C, D, dt, figures=got, forward=forward)
    sec = time.perf_counter() - t0
    rec = {"caller": _caller(), "n": A.shape[0], "dt": dt, "forward_on": forward, "sec": sec,
           "accepted": X is not None, "forward": got.get("forward"), "steps": got.get("steps", 0),
           "why": got.get("why", "")}
    if X is None and forward:
        rec["residual_only"] = _original(A, B, C, D, dt, forward=False) is not None
    RECORDS.append(rec)
    if figures is not None:
        figures.clear()
        figures.update(got)
    return X


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def _summary(label: str, recs: list[dict]) -> None:
    by = Counter(r["caller"] for r in recs)
    for caller in sorted(by):
        rs = [r for r in recs if r["caller"] == caller and r["forward_on"]]
        acc = [r for r in rs if r["accepted"]]
        refused_fwd = [r for r in rs if not r["accepted"] and r.get("residual_only")]
        refused_both = [r for r in rs if not r["accepted"] and not r.get("residual_only")]
        stepped = [r for r in acc if r["steps"]]
        fw = np.array([r["forward"] for r in acc if r["forward"] is not None] or [np.nan])
        print(f"{label} {caller}: {len(rs)} calls; accepted {len(acc)} (of which {len(stepped)} after Newton steps, "
              f"steps {sorted(Counter(r['steps'] for r in stepped).items())}); refused by the forward check alone "
              f"{len(refused_fwd)}; refused by both lines {len(refused_both)}; accepted answers' forward figure max "
              f"{np.nanmax(fw):.2e}, median {np.nanmedian(fw):.2e}; time {sum(r['sec'] for r in rs):.2f} s",
              flush=True)
        for r in refused_fwd:
            print(f"   REFUSED BY FORWARD: n={r['n']} dt={r['dt']} forward {r['forward']} why {r['why']}", flush=True)


def main(n_ammp: int = 30, audit: str = "0-40") -> None:
    approximate.spectral_riccati = _wrapped
    if n_ammp:
        import ammp_random_set

        ammp_random_set.run(n_ammp, verbose=True)
        _summary(f"ammp_random_set {n_ammp}:", RECORDS)
    start = len(RECORDS)
    if audit:
        from test_approximate_random import check_case

        for seed in _seeds(audit):
            before = len(RECORDS)
            t0 = time.perf_counter()
            try:
                out = check_case(seed)
            except Exception as exc:  # the audit's own harness; reported, not hidden
                out = [("check_case", "crash", repr(exc))]
            recs = RECORDS[before:]
            fwd_refusals = sum(1 for r in recs if r["forward_on"] and not r["accepted"] and r.get("residual_only"))
            calls = sum(r["forward_on"] for r in recs)
            stepped = sum(1 for r in recs if r["accepted"] and r["steps"])
            print(f"audit seed {seed}: {[(c, s) for c, s, *_ in out]} riccati calls {calls}, forward refusals "
                  f"{fwd_refusals}, stepped {stepped} ({time.perf_counter() - t0:.1f} s)", flush=True)
        _summary(f"audit {audit}:", RECORDS[start:])


if __name__ == "__main__":
    args = sys.argv[1:]
    main(int(args[0]) if args else 30, args[1] if len(args) > 1 else "0-40")
