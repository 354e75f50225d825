"""Seeded random FDI models for synthesis regression (issue 13) and an independent contract check.

``random_model(seed)``: n = 4-30 states, 3-7 outputs, 1-4 inputs, 0-2 unknown inputs,
two sensor and two actuator faults; half of them continuous, half discrete; half well
scaled and half with a diagonal state scaling spread over eight decades
(``x -> T x``, ``T = diag(10^U(-4, 4))``), which leaves every transfer function unchanged
but makes the state-space data badly scaled.

``contract(gen, model, S, names)`` judges a returned generator/bank from its frequency
responses alone (``R(λ) = Q(λ) Ge(λ)`` point by point on a grid, no design code): relative
leakage of u and d, the weak structure per residual group, and stable poles.
"""
from __future__ import annotations

import numpy as np

from fmu_fdi import FDIModel, actuator_fault, sensor_fault
from fmu_fdi.design.toolkit._basis import normal_rank


def random_model(seed: int) -> FDIModel:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 31))
    p = int(rng.integers(3, 8))
    m = int(rng.integers(1, 5))
    nd = int(rng.integers(0, 3))
    discrete = bool(seed % 2)
    badly_scaled = bool((seed // 2) % 2)
    # eigenvalues: real and complex pairs with a spread of speeds
    eig = []
    while len(eig) < n:
        if n - len(eig) >= 2 and rng.random() < 0.4:
            re, im = -10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1)
            eig += [complex(re, im), complex(re, -im)]
        else:
            eig.append(complex(-10 ** rng.uniform(-1.5, 1), 0))
    eig = np.array(eig)
    dt = 0.0
    if discrete:
        dt = 0.1
        eig = np.exp(eig * dt)
    # real block-diagonal form, then a random orthogonal change of basis
    J = np.zeros((n, n))
    i = 0
    while i < n:
        if abs(eig[i].imag) > 0:
            a, b = eig[i].real, eig[i].imag
            J[i:i + 2, i:i + 2] = [[a, b], [-b, a]]
            i += 2
        else:
            J[i, i] = eig[i].real
            i += 1
    U, _ = np.linalg.qr(rng.standard_normal((n, n)))
    A = U @ J @ U.T
    Bu = rng.standard_normal((n, m))
    Bd = rng.standard_normal((n, nd))
    C = rng.standard_normal((p, n))
    if badly_scaled:
        t = 10 ** rng.uniform(-4, 4, n)
        A = (t[:, None] * A) / t[None, :]
        Bu, Bd, C = t[:, None] * Bu, t[:, None] * Bd, C / t[None, :]
    y = [f"y{k + 1}" for k in range(p)]
    u = [f"u{k + 1}" for k in range(m)]
    faults = [sensor_fault(f"fs{k + 1}", y[k]) for k in range(2)]
    faults += [actuator_fault(f"fa{k + 1}", u[k % m]) for k in range(min(2, m))]
    return FDIModel.from_matrices(A, Bu, C, Bd=Bd if nd else None, faults=faults, dt=dt, u_names=u, y_names=y,
                                  name=f"random{seed}")


def random_structure(model: FDIModel, seed: int) -> np.ndarray:
    """A structure matrix over all faults: identity rows plus a random row, no zero rows."""
    rng = np.random.default_rng(1000 + seed)
    k = len(model.faults)
    S = np.vstack([np.eye(k, dtype=int), rng.integers(0, 2, (1, k))])
    S[-1, rng.integers(k)] = 1
    return S


def row_achievable(model: FDIModel, row, names) -> bool:
    """Rank test (normal ranks at random points): every required fault stays visible once
    d and the row's zero faults are decoupled."""
    zero = [nm for nm, s in zip(names, row) if not s]
    mi = model.with_disturbances(zero)
    Gd = mi.lti("d") if mi.nd else None
    rd = normal_rank(Gd) if Gd is not None else 0
    for nm, s in zip(names, row):
        if s:
            f = mi.fault(nm)
            cols = list(range(mi.nd)) + list(mi.nd + np.arange(mi.nf)[f.columns])
            if normal_rank(mi.lti("d", "f")[:, cols]) <= rd:
                return False
    return True


def _points(model: FDIModel, num: int = 60) -> np.ndarray:
    w = np.logspace(-3, 3, num)
    if model.dt:
        w = np.linspace(1e-3, np.pi / model.dt * 0.999, num)
        return np.exp(1j * w * model.dt)
    return 1j * w


def contract(gen, model: FDIModel, S=None, names=None, leak_tol: float = 1e-6, gain_tol: float = 1e-6) -> list[str]:
    """Violations of the design contract, judged from frequency responses only.

    Relative figures at each point λ: ``|R_x(λ)| / (|Q(λ)| |Ge_x(λ)|)`` (2-norms; |Q_y| for faults) — the
    size of a response against the largest it could have with this filter, so that
    rounding of an exact decoupling is ~1e-12 whatever the scaling. Leakage of u, d and of
    the faults with S = 0 must stay below ``leak_tol``; faults with S = 1 must reach
    ``gain_tol`` at some point; poles must be stable.
    """
    names = list(model.fault_names if names is None else names)
    groups = gen.groups
    if S is None:
        S = np.ones((len(groups), len(names)), dtype=int)
    S = np.asarray(S)
    Ge = model.augmented()
    sl = model.group_slices()
    lam = _points(model)
    out = []
    fcols = {f.name: np.arange(sl["f"].start, sl["f"].stop)[f.columns] for f in model.faults}
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    Gv = np.stack([Ge.evalfr(x) for x in lam])
    ok = np.all(np.isfinite(Gv), axis=(1, 2))
    for i, g in enumerate(groups):
        Qv = np.stack([gen.Q[g, :].evalfr(x) for x in lam])
        keep = ok & np.all(np.isfinite(Qv), axis=(1, 2))
        Q, G = Qv[keep], Gv[keep]
        R = Q @ G
        n2 = lambda X: np.linalg.norm(X, 2, axis=(1, 2)) if X.shape[2] else np.zeros(X.shape[0])  # noqa: E731
        # peak response over peak bound (a pointwise ratio is 0/0 at a zero of Ge)
        rel = lambda X, B: float(n2(X).max() / max(B.max(), 1e-300))  # noqa: E731
        if ud.size and rel(R[:, :, ud], n2(Q) * n2(G[:, :, ud])) > leak_tol:
            out.append(f"group {i}: u/d leakage {rel(R[:, :, ud], n2(Q) * n2(G[:, :, ud])):.2e}")
        for j, nm in enumerate(names):
            c = fcols[nm]
            if S[i, j]:
                gam = rel(R[:, :, c], n2(Q[:, :, :model.ny]) * n2(G[:, :model.ny, c]))
                if gam <= gain_tol:
                    out.append(f"group {i}: fault {nm} gain {gam:.2e}")
            else:
                z = rel(R[:, :, c], n2(Q) * n2(G[:, :, c]))
                if z > leak_tol:
                    out.append(f"group {i}: decoupled-fault {nm} leakage {z:.2e}")
    poles = gen.Q.poles()
    if poles.size:
        bad = np.abs(poles) >= 1 if model.dt else poles.real >= 0
        if np.any(bad):
            out.append(f"unstable poles {poles[bad][:3]}")
    return out


def aircraft_loop() -> FDIModel:
    """Real-size regression model: the shipped lateral aircraft (Varga 2017, Ex. 6.1) with
    first-order actuators in series (time constants 0.05 s and 0.08 s) and a closed loop
    with a dynamic controller (roll PI on φ, yaw-damper washout on r, static β/p gains).

    Faults: both actuators (at the surfaces, after the actuator dynamics) and all four
    sensors; a side-gust disturbance d enters the β and r equations.
    """
    from fmu_fdi.lti import LTI
    from fmu_fdi.modelset import feedback, series
    from plant_fmus.lateral_aircraft import lateral_physics as phys

    y, u = list(phys.Y), list(phys.U)
    faults = [actuator_fault(f"fa_{x}", x) for x in u] + [sensor_fault(f"fs_{x}", x) for x in y]
    gust = np.array([[0.2], [0.0], [0.0], [1.0]])
    plant = FDIModel.from_matrices(phys.A, phys.BU, phys.C, Bd=gust, faults=faults, u_names=u, y_names=y,
                                   d_names=["gust"], name="lateral_aircraft")
    act = LTI(np.diag([-1 / 0.05, -1 / 0.08]), np.diag([1 / 0.05, 1 / 0.08]), np.eye(2), np.zeros((2, 2)))
    # controller from y = [beta, phi, p, r] to u (u = r_ref - K y): states: ∫φ, washout of r
    Ak = np.diag([0.0, -1.0])
    Bk = np.array([[0, 1, 0, 0], [0, 0, 0, 1.0]])
    Ck = np.array([[-0.5, 0.0], [0.0, -2.0]])
    Dk = np.array([[0.0, -2.0, -0.8, 0.0], [1.0, 0.0, 0.0, 2.0]])
    return feedback(series(plant, act), LTI(Ak, Bk, Ck, Dk), name="aircraft_loop")
