"""Seeded ill-scaled random plants for the judge's tests (issue 17): n 4-30 states, state
scalings over eight decades, more actuators than sensors (m > p), optional unknown input d
and noise w, continuous or discrete. Faults: actuator faults on u1, u2 and a sensor fault on y1."""
import numpy as np

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
    eig = []
    while len(eig) < n:  # stable modes over three decades of speed, real and complex pairs
        if n - len(eig) >= 2 and rng.random() < 0.4:
            re, im = -10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1)
            eig += [complex(re, im), complex(re, -im)]
        else:
            eig.append(complex(-10 ** rng.uniform(-1.5, 1), 0))
    J = np.zeros((n, n))
    i = 0
    while i < n:
        if eig[i].imag:
            a, b = eig[i].real, eig[i].imag
            J[i:i + 2, i:i + 2] = [[a, b], [-b, a]]
            i += 2
        else:
            J[i, i] = eig[i].real
            i += 1
    if dt:
        import scipy.linalg as sla

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
