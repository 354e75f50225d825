"""Old-vs-new contract check of nullspace_design/structured_bank on the seeded random models.

Prints, per call, whether the design returned a contract-keeping generator ("ok"), raised
DesignError ("refused"; "refused*" when the rank test says the request was achievable), or
returned a generator that breaks its contract ("BROKEN"), and the totals.
Run: python benchmarks/synthesis_random_set.py [N]
"""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


from fmu_fdi import DesignError, nullspace_design, structured_bank  # noqa: E402
from synthesis_models import contract, random_model, random_structure, row_achievable  # noqa: E402


def run(N: int = 40, verbose: bool = True):
    counts = {"ok": 0, "refused": 0, "refused*": 0, "BROKEN": 0, "crash": 0}
    t0 = time.perf_counter()
    for seed in range(N):
        model = random_model(seed)
        S = random_structure(model, seed)
        names = model.fault_names
        for what in ("nullspace", "bank"):
            try:
                if what == "nullspace":
                    gen = nullspace_design(model)
                    bad = contract(gen, model)
                    achievable = True
                else:
                    gen = structured_bank(model, S)
                    bad = contract(gen, model, S, names)
                    achievable = all(row_achievable(model, r, names) for r in S)
                key = "BROKEN" if bad else "ok"
                msg = "; ".join(bad[:3])
            except DesignError as exc:
                achievable = (all(row_achievable(model, r, names) for r in S) if what == "bank"
                              else all(row_achievable(model, [1] * len(names), names) for _ in [0]))
                key = "refused*" if achievable else "refused"
                msg = str(exc)[:150]
            except Exception as exc:  # noqa: BLE001
                key, msg = "crash", f"{type(exc).__name__}: {exc}"[:150]
            counts[key] += 1
            if verbose:
                print(f"seed {seed:3d} n={model.n:2d} p={model.ny} m={model.nu} nd={model.nd} "
                      f"{'disc' if model.dt else 'cont'} {what:9s} {key:8s} {msg}")
    print(counts, f"{time.perf_counter() - t0:.1f} s")
    return counts


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
