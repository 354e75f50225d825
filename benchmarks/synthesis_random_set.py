"""Old-vs-new contract check of nullspace_design/structured_bank on the seeded random models.

Prints, per call, whether the design returned a contract-keeping generator ("ok"), raised
DesignError ("refused"; "refused*" when the rank test says the request was achievable), or
returned a generator that breaks its contract ("BROKEN"), and the totals; for returned designs the
order of every residual with the basis it came from (pe: the pencil state-space core, 'auto'; po: the
polynomial basis, only with the explicit ``basis='polynomial'``; sa: frequency-sampled rows, retired in
issue 17), and the totals of residuals per basis and per ``info['decoupling_kind']``, and for the
pencil rows from a null space of several rows how many sit at the smallest left minimal index (the least
order of any exact row) and their total order above it.
Run: python benchmarks/synthesis_random_set.py [N] [auto|polynomial|pencil] (the ``basis`` option: 'polynomial'
shows what the least-order methods alone achieve).
"""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


from fmu_fdi import DesignError, nullspace_design, structured_bank  # noqa: E402
from synthesis_models import contract, random_model, random_structure, row_achievable  # noqa: E402


def _indices(gen) -> str:
    """For a pencil row from a null space of several rows, its left minimal indices: the least
    order is at least the smallest (a one-row null space's row is least order)."""
    idx = gen.info.get("left_minimal_indices", [])
    return str(idx).replace(" ", "") if len(idx) > 1 else ""


def run(N: int = 40, verbose: bool = True, basis: str = "auto"):
    counts = {"ok": 0, "refused": 0, "refused*": 0, "BROKEN": 0, "crash": 0}
    bases: dict[str, int] = {}  # residuals per basis: polynomial / sampled / pencil
    kinds: dict[str, int] = {}  # residuals per decoupling kind: exact / approximate
    multi = {"pencil rows": 0, "at min index": 0, "excess order": 0}  # pencil rows, null space of several rows
    t0 = time.perf_counter()
    for seed in range(N):
        model = random_model(seed)
        S = random_structure(model, seed)
        names = model.fault_names
        for what in ("nullspace", "bank"):
            try:
                if what == "nullspace":
                    gen = nullspace_design(model, basis=basis)
                    bad = contract(gen, model)
                    achievable = True
                else:
                    gen = structured_bank(model, S, basis=basis)
                    bad = contract(gen, model, S, names)
                    achievable = all(row_achievable(model, r, names) for r in S)
                key = "BROKEN" if bad else "ok"
                members = getattr(gen, "members", [gen])
                how = [g.info.get("basis", "sampled" if g.info.get("synthesis") else "?") for g in members]
                for h in how:
                    bases[h] = bases.get(h, 0) + 1
                for g, h in zip(members, how):
                    idx = g.info.get("left_minimal_indices", [])
                    if h == "pencil" and len(idx) > 1:
                        multi["pencil rows"] += 1
                        multi["at min index"] += int(g.Q.n == min(idx))
                        multi["excess order"] += int(g.Q.n - min(idx))
                    kind = str(g.info.get("decoupling_kind", "exact")).split(" ")[0].rstrip(":")
                    kinds[kind] = kinds.get(kind, 0) + 1
                msg = "; ".join(bad[:3]) or ("orders " + " ".join(f"{g.info.get('order')}{h[:2]}{_indices(g)}"
                                                                  for g, h in zip(members, how)))
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
    print(counts, "residuals by basis:", bases, "by decoupling kind:", kinds, multi, f"{time.perf_counter() - t0:.1f} s")
    return counts


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 40, basis=sys.argv[2] if len(sys.argv) > 2 else "auto")
