"""Seeded ill-scaled random plants for the judge's tests (issue 17): n 4-30 states, state
scalings over eight decades, more actuators than sensors (m > p), optional unknown input d
and noise w, continuous or discrete. Faults: actuator faults on u1, u2 and a sensor fault on y1."""
import numpy as np
import scipy.linalg as sla

from fmu_fdi import FDIModel, actuator_fault, sensor_fault


def ill_scaled_model(seed: int, input_decades: float = 0.0) -> FDIModel:
    """``input_decades``: the known inputs' channels are scaled by 10^U(0, input_decades) too
    (units: a valve in % next to one in m³/s)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 31))
    p = int(rng.integers(2, 4))
    m = p + int(rng.integers(1, 4))
    nd = int(rng.integers(0, 2))
    nw = int(rng.integers(0, 2))
    dt = 0.1 if seed % 2 else 0.0
    blocks = []  # stable modes over three decades of speed, real and complex pairs
    while sum(b.shape[0] for b in blocks) < n:
        if n - sum(b.shape[0] for b in blocks) >= 2 and rng.random() < 0.4:
            a, b = -10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1)
            blocks.append(np.array([[a, b], [-b, a]]))
        else:
            blocks.append(np.array([[-10 ** rng.uniform(-1.5, 1)]]))
    J = sla.block_diag(*blocks)
    if dt:
        J = sla.expm(J * dt)
    U, _ = np.linalg.qr(rng.standard_normal((n, n)))
    A = U @ J @ U.T
    Bu, Bd, Bw = (rng.standard_normal((n, k)) for k in (m, nd, nw))
    C = rng.standard_normal((p, n))
    Bu = Bu * 10 ** rng.uniform(0, input_decades, m)[None, :]
    t = 10 ** rng.uniform(-4, 4, n)  # x_new = diag(t) x: eight decades
    A = (t[:, None] * A) / t[None, :]
    Bu, Bd, Bw, C = t[:, None] * Bu, t[:, None] * Bd, t[:, None] * Bw, C / t[None, :]
    y = [f"y{k + 1}" for k in range(p)]
    u = [f"u{k + 1}" for k in range(m)]
    faults = [actuator_fault("fa1", "u1"), actuator_fault("fa2", "u2"), sensor_fault("fs1", "y1")]
    return FDIModel.from_matrices(A, Bu, C, Bd=Bd if nd else None, Bw=Bw if nw else None, faults=faults, dt=dt,
                                  u_names=u, y_names=y, name=f"illscaled{seed}")
