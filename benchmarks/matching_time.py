"""model_matching design time: the pencil core against the sampled solver it replaced, same run.

The baseline is matching.py as of a git revision (default 5edb19b, the last with the sampled
least-order solver), loaded from ``git show`` as a sibling module of the current one (its imports
resolve to the current package: the toolkit functions it used are unchanged). Cases: the matching
test cases (Niemann's and Xiong-Saif's bank references, Mr = Gf on a faults-only model, continuous
and discrete, Example 5.4c, Example 5.13c with updating, the seeded random references of
tests/test_synthesis_matching_order.py, stable and with updating). Each design runs ``R`` times
(best time kept); prints per case old and new time, their ratio, the row orders of each, and the
geometric-mean ratio. Run: python benchmarks/matching_time.py [R] [REV]
"""
import importlib.util
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import published as pub  # noqa: E402
from fmu_fdi import DesignError, FDIModel, actuator_fault, nullspace_design, structured_bank  # noqa: E402
from fmu_fdi.design.problems import matching as new  # noqa: E402
from test_synthesis_matching_order import _faults_only, _random_model  # noqa: E402
from test_synthesis_published import niemann, xiong_saif_2  # noqa: E402


def baseline(rev: str, module: str = "matching"):
    """``fmu_fdi/design/problems/<module>.py`` as of ``rev``, as a sibling module of the current one."""
    src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:fmu_fdi/design/problems/{module}.py"],
                         check=True, capture_output=True, text=True).stdout
    name = f"fmu_fdi.design.problems._{module}_baseline"
    spec = importlib.util.spec_from_loader(name, loader=None)
    mod = importlib.util.module_from_spec(spec)
    mod.__package__ = "fmu_fdi.design.problems"
    sys.modules[name] = mod  # (a dataclass resolves its annotations through its module's entry)
    exec(compile(src, f"{rev}:{module}.py", "exec"), mod.__dict__)
    return mod


def cases():
    for make, kw in ((niemann, dict(sdeg=-5.0)), (xiong_saif_2, dict(sdeg=-2.0, smarg=-1.0))):
        model = make()
        bank = structured_bank(model, [[1, 1], [0, 1], [1, 0]], **kw)
        from fmu_fdi.lti import vstack
        yield f"{make.__name__} bank refs", model, vstack([g.Rf for g in bank.members]), dict(atol=1e-7)
    for dt in (0.0, 0.1):
        model = _faults_only(dt=dt)
        yield f"Mr = Gf (dt={dt})", model, model.lti("f"), {}
    model = pub.ex5_4()
    yield "Ex. 5.4c", model, nullspace_design(model, rdim=1, poles=[-3]).Rf, {}
    import control as ct
    s = ct.tf("s")
    G = pub.tfm([[s / (s**2 + 3 * s + 2), 1 / (s + 2)], [s / (s + 1), 0], [0, 1 / (s + 2)]], ["u1", "u2"])
    model = FDIModel.from_control(G, u=["u1", "u2"], faults=[actuator_fault("f1", "u1"), actuator_fault("f2", "u2")])
    yield "Ex. 5.13c updating", model, np.eye(2), dict(updating=True, sdeg=-1)
    for unstable in (False, True):
        for seed in range(12):
            model = _random_model(seed, unstable=unstable)
            try:
                ref = nullspace_design(model, rdim=1)
            except DesignError:
                continue
            yield f"random {seed}{' updating' if unstable else ''}", model, ref.Rf, dict(updating=unstable)


def timed(fn, reps):
    best, out = np.inf, None
    for _ in range(reps):
        t = time.perf_counter()
        try:
            out = fn()
        except DesignError as exc:
            out = exc
        best = min(best, time.perf_counter() - t)
    return best, out


def main():
    reps = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    rev = sys.argv[2] if len(sys.argv) > 2 else "5edb19b"
    old = baseline(rev)
    ratios = []
    print(f"{'case':28s} {'old [ms]':>9s} {'new [ms]':>9s} {'new/old':>8s}  orders old -> new")
    for name, model, Mr, kw in cases():
        t0, g0 = timed(lambda: old.model_matching(model, Mr, **kw), reps)
        t1, g1 = timed(lambda: new.model_matching(model, Mr, **kw), reps)
        o0 = g0.info["row_orders"] if not isinstance(g0, Exception) else "refused"
        o1 = g1.info["row_orders"] if not isinstance(g1, Exception) else "refused"
        ratios.append(t1 / t0)
        print(f"{name:28s} {1e3 * t0:9.1f} {1e3 * t1:9.1f} {t1 / t0:8.2f}  {o0} -> {o1}")
    print(f"geometric mean new/old: {np.exp(np.mean(np.log(ratios))):.2f} over {len(ratios)} cases")


if __name__ == "__main__":
    main()
