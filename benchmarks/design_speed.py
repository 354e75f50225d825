"""Time nullspace_design and parity_space on a large random model (issue 2, §5).

Model: random stable discrete system with n = 200 states, 50 outputs, 5 inputs,
1 disturbance and 10 faults (5 actuator, 5 sensor). Each design time is printed next to
the time of one ``scipy.linalg.svd`` of the 200×200 A measured in the same run, and the
ratio between them; the target is under 2 s per design on a 2-core machine.

Run: ``python benchmarks/design_speed.py``
"""
from __future__ import annotations

import time

import numpy as np
import scipy.linalg as sla

from fmu_fdi import FDIModel, actuator_fault, leakage, nullspace_design, sensor_fault
from fmu_fdi.design.problems.parity import parity_space


def random_model(n=200, p=50, m=5, md=1, seed=0) -> FDIModel:
    rng = np.random.default_rng(seed)
    Qo, _ = np.linalg.qr(rng.standard_normal((n, n)))
    A = Qo @ np.diag(rng.uniform(-0.95, 0.95, n)) @ Qo.T  # stable, well conditioned
    Bu = rng.standard_normal((n, m))
    Bd = rng.standard_normal((n, md))
    C = rng.standard_normal((p, n))
    faults = [actuator_fault(f"act{j}", f"u{j}") for j in range(m)] + \
             [sensor_fault(f"sen{j}", f"y{j}") for j in range(5)]
    return FDIModel.from_matrices(A, Bu, C, Bd=Bd, dt=0.1, faults=faults, name="random200")


def best_of(fn, repeat=3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    model = random_model()
    t_svd = best_of(lambda: sla.svd(model.A), repeat=5)
    print(f"baseline: one scipy.linalg.svd of the 200x200 A: {t_svd * 1e3:.2f} ms")
    for name, fn in (("nullspace_design", lambda: nullspace_design(model)),
                     ("parity_space(order=4)", lambda: parity_space(model, 4, rdim=1))):
        t = best_of(fn)
        gen = fn()
        print(f"{name:24s} {t:7.3f} s  = {t / t_svd:8.1f} x svd(A)   target < 2 s: "
              f"{'met' if t < 2 else 'MISSED'}   (residuals {gen.n_residuals}, order {gen.Q.n}, "
              f"leakage {leakage(gen):.1e})")


if __name__ == "__main__":
    main()
