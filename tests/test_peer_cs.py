"""Varga's chapter-8 case studies CS1 (flight actuator faults) and CS2 (air-data sensor faults).

Data: tests/data/varga_cs1.json, varga_cs2.json, converted from FaultDetectionTools.jl's
Examples/cs1data.jld2 and cs2data.jld2 (see tests/data/varga_cs_from_jld2.py for the source and
the conversion). The scripts ported are the peer's Examples/CS1_1.jl, CS1_2.jl and CS2_1.jl; the
properties asserted are the ones those scripts assert (``@test``) with their numbers, judged with
the independent numpy judge of tests/test_synthesis_random.py and numpy frequency responses here
(no fmu_fdi analysis code):

CS1_1  nominal model (7 of 11) in series with the actuators, 22 inputs u, 3 disturbances d,
       10 outputs, 8 primary actuator faults; SFDI 6×8. Every SFDI row is achievable; efdisyn with
       FDGainTol = 1e-3 at FDfreq = 0, sdeg = −5, smarg = −0.2 designs it: R_u = R_d = 0,
       structure = SFDI strongly at ω = 0, poles Re ≤ −0.2. Table 8.2 (robustness of the nominal
       filter in the closed loop u = K y + v over the 11 models): NormRu, NormRd, ‖Rf − Rf_nom‖∞
       < 1e-6 for the nominal model (the book's table lists the other ten; we print ours).
CS1_2  the same with the 8 surface positions measured too (18 outputs): all 2^8 − 1 = 255
       specifications strongly achievable at ω = 0 (FDGainTol = 1e-3); SFDI = I8 designed with
       FDGainTol = 0.01, smarg = −1.
CS2_1  11 models (mass variations), 3 inputs, 2 wind disturbances, 8 outputs, faults of the AoA and
       VCAS sensors: 3 = 2^2 − 1 strong specifications; SFDI = I2 designed per model with order 0 and
       ‖R_i − [0 0 I]‖∞ < 1e-7 (rows normalised to R_f = I); the nominal filter on all models:
       max_i ‖R_i − [0 0 I]‖∞ > 643 (Table 8.4, Nnom); the mean gain D0 of the 11 filters: > 504 (N0).

The book's Table 8.2 values for the ten off-nominal models are not in the peer's scripts (they only
assert the nominal row < 1e-6), so only that row is asserted; test_cs1_1_efdisyn_and_table_8_2 prints
ours. Tally (~11:45 UTC): 7 tests · passing on main 4 (data, CS1_1 achievability, CS2_1 strong
specifications, CS2_1 Table 8.4: Nref 9.8e-10, Nnom 643.5, N0 545.3) · xfail 3 (the CS1 designs and
CS1_2's 255 strong specifications fail on main and with the issue-17 branches). peer (~14:55 UTC): xfail 0 —
CS1_1 orders [6, 6, 6, 5, 4, 4] (31), nominal Table 8.2 row NormRu 7.8e-10, NormRd 3.0e-9; CS1_2 SFDI = I8 orders
[1, 1, 1, 2, 1, 1, 1, 1]; all 255 CS1_2 rows strongly achievable (the designs pass the peer's atol = 1e-6).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

from fmu_fdi import FDIModel, actuator_fault, sensor_fault
from fmu_fdi.design.problems.achievable import achievable_structure
from fmu_fdi.design import structured_bank

from test_synthesis_random import _freqresp, _pbh_poles, judge

DATA = Path(__file__).resolve().parent / "data"
NOM = 6  # the peer's nom = 7 (1-based)
ACT_PRIM = [1, 2, 15, 16, 17, 19, 18, 20]  # 1-based, the peer's order: ailerons, elevators, stabilizer, rudder
SFDI_CS1 = np.array([[0, 1, 1, 1, 1, 0, 1, 0],
                     [1, 0, 1, 1, 0, 1, 1, 0],
                     [1, 1, 0, 1, 1, 0, 1, 0],
                     [1, 1, 1, 0, 1, 1, 0, 0],
                     [1, 1, 1, 1, 0, 0, 0, 0],
                     [0, 0, 0, 0, 0, 0, 0, 1]])


def _sys(d):
    return tuple(np.array(d[k], float).reshape(len(d[k]), -1) for k in "ABCD")


def _series_with_actuators(sys, act, md):
    """``sys * blkdiag(ACT, I_md)``: the actuators in front of the first inputs of the aircraft."""
    A1, B1, C1, D1 = sys
    A2, B2, C2, D2 = act  # the peer then takes a minimal realisation (gir): FDIModel's minreal_tol below
    mu = B2.shape[1]
    n1, n2 = A1.shape[0], A2.shape[0]
    B1u, B1d, D1u, D1d = B1[:, :mu], B1[:, mu:], D1[:, :mu], D1[:, mu:]
    A = np.block([[A1, B1u @ C2], [np.zeros((n2, n1)), A2]])
    Bu = np.vstack([B1u @ D2, B2])
    Bd = np.vstack([B1d, np.zeros((n2, md))])
    C = np.hstack([C1, D1u @ C2])
    return A, Bu, C, D1u @ D2, Bd, D1d


@pytest.fixture(scope="module")
def cs1():
    return json.loads((DATA / "varga_cs1.json").read_text())


@pytest.fixture(scope="module")
def cs2():
    return json.loads((DATA / "varga_cs2.json").read_text())


def cs1_models(cs1, positions: bool = False) -> list[FDIModel]:
    act = _sys(cs1["ACT"])
    mu = act[1].shape[1]
    out = []
    for i, s in enumerate(cs1["SYSACM"]):
        A1, B1, C1, D1 = _sys(s)
        md = B1.shape[1] - mu
        if positions:  # [ee[act_prim, :]; SYSACM]: the primary surface positions measured as well
            E = np.eye(B1.shape[1])[np.array(ACT_PRIM) - 1]
            C1 = np.vstack([np.zeros((len(ACT_PRIM), A1.shape[0])), C1])
            D1 = np.vstack([E, D1])
        A, Bu, C, Du, Bd, Dd = _series_with_actuators((A1, B1, C1, D1), act, md)
        u = [f"u{k + 1}" for k in range(mu)]
        faults = [actuator_fault(f"act{j}", f"u{j}") for j in ACT_PRIM]
        out.append(FDIModel.from_matrices(A, Bu, C, Du, Bd=Bd, Dd=Dd, faults=faults, u_names=u,
                                          d_names=[f"d{k + 1}" for k in range(md)], name=f"cs1_{i + 1}",
                                          minreal_tol=1e-10))
    return out


def _peak_grid(models=(), num=400):
    """Points jω for H∞ peaks: a log grid plus, for every lightly damped pole ω_n e^{±jφ} of the
    models, a fine grid of ±3 half-power bandwidths around its resonance (a peak of width ~|Re p|
    that a log grid would step over)."""
    w = [np.logspace(-3, 3, num)]
    for m in models:
        for p in np.linalg.eigvals(m.A) if m.n else []:
            if p.imag > 0:
                w.append(np.abs(p.imag) + np.linspace(-3, 3, 61) * max(abs(p.real), 1e-6))
    w = np.concatenate(w)
    return 1j * np.r_[0.0, np.sort(w[w > 0])]


def _closed_loop_norms(bank, models, K, y_idx):
    """Table 8.2: the filter of the nominal design on model i in the closed loop u = K y + v,
    ``Rtot_i = Q [y; u]`` as a map of (v, d, f); returns per model the peaks of Rtot_v, Rtot_d and
    of Rtot_f − Rf_nom, the rows scaled so each row's smallest required fault peak (nominal) is 1."""
    lam = _peak_grid(models)
    Qv = _freqresp(bank.Q.A, bank.Q.B, bank.Q.C, bank.Q.D, lam)
    out = []
    Rf_nom = None
    for model in [models[NOM]] + list(models):
        p, m = model.ny, model.nu
        B = np.hstack([model.Bu, model.Bd, model.Bf])
        D = np.hstack([model.Du, model.Dd, model.Df])
        G = _freqresp(model.A, B, model.C, D, lam)  # y = G [u d f]
        Gu = G[:, :, :m]
        Kfull = np.zeros((m, p))
        Kfull[:, y_idx] = K
        # y = (I - Gu K)^-1 (Gu v + Gd d + Gf f); u = K y + v
        Y = np.linalg.solve(np.eye(p)[None] - Gu @ Kfull[None], G)
        U = Kfull[None] @ Y
        U[:, :, :m] += np.eye(m)[None]
        R = Qv @ np.concatenate([Y, U], axis=1)
        if Rf_nom is None:
            Rf_nom = R[:, :, m + model.nd:]
            continue
        out.append(R)
    scale = np.array([1.0 / min(np.abs(Rf_nom[:, i, j]).max() for j in np.flatnonzero(SFDI_CS1[i]))
                      for i in range(Rf_nom.shape[1])])
    norms = []
    for R, model in zip(out, models):
        R = R * scale[None, :, None]
        m, nd = model.nu, model.nd
        pk = lambda X: float(np.linalg.norm(X, 2, axis=(1, 2)).max())  # noqa: E731
        norms.append((pk(R[:, :, :m]), pk(R[:, :, m:m + nd]), pk(R[:, :, m + nd:] - Rf_nom * scale[None, :, None])))
    return np.array(norms)


def _strong_structure(bank, model, names, FDGainTol):
    """The structure at ω = 0 (λ = 0 or, at a plant pole there, just beside it) by numpy: entry (i, j)
    is 1 when |R_ij(0)| > FDGainTol · max_j |R_ij(0)| (the peer's fditspec at FDfreq with its relative
    threshold on the row)."""
    lam = np.array([1e-7j])
    B = np.hstack([model.Bu, model.Bd, model.Bf])
    D = np.hstack([model.Du, model.Dd, model.Df])
    G = _freqresp(model.A, B, model.C, D, lam)[0]
    Ge = np.vstack([G, np.hstack([np.eye(model.nu), np.zeros((model.nu, B.shape[1] - model.nu))])])
    Q0 = _freqresp(bank.Q.A, bank.Q.B, bank.Q.C, bank.Q.D, lam)[0]
    Rf = np.abs(Q0 @ Ge[:, model.nu + model.nd:])
    return (Rf > FDGainTol * Rf.max(axis=1, keepdims=True)).astype(int)


def test_cs1_data_as_published(cs1):
    """The converted data: 11 models, 10 outputs, 25 inputs (22 actuator commands + 3 wind inputs),
    actuators 22×22, K 22×10 — and the peer's own check: every closed loop u = K y + v is stable."""
    models = cs1_models(cs1)
    assert len(models) == 11 and all(m.ny == 10 and m.nu == 22 and m.nd == 3 and m.nf == 8 for m in models)
    K = np.array(cs1["K"])
    assert K.shape == (22, 10)
    for m in models:
        Acl = m.A + m.Bu @ K @ np.linalg.solve(np.eye(10) - m.Du @ K, m.C)
        assert np.linalg.eigvals(Acl).real.max() < 0, m.name


def test_cs1_1_structure_is_achievable(cs1):
    """CS1_1: each row of SFDI is a weakly achievable specification (fdigenspec, FDtol = 1e-5)."""
    model = cs1_models(cs1)[NOM]
    listed = {tuple(r) for r in achievable_structure(model, max_faults=8, atol=1e-6)}
    missing = [r.tolist() for r in SFDI_CS1 if tuple(r) not in listed]
    assert not missing, f"SFDI rows not listed as achievable: {missing}"


@pytest.mark.slow
def test_cs1_1_efdisyn_and_table_8_2(cs1, capsys):
    """CS1_1 Part 3–4: the 6×8 bank is designed, exact, strongly structured at ω = 0 as SFDI, with
    poles Re ≤ smarg = −0.2, and Table 8.2's nominal row is below 1e-6."""
    models = cs1_models(cs1)
    model = models[NOM]
    names = model.fault_names
    t0 = time.perf_counter()
    # the peer's efdisyn(sysactf[nom], SFDI; atol, FDGainTol, FDfreq, rdim = 1, sdeg = -5, smarg = -0.2), atol = 1e-6
    bank = structured_bank(model, SFDI_CS1, freqs=[0.0], FDGainTol=1e-3, sdeg=-5, smarg=-0.2, atol=1e-6)
    elapsed = time.perf_counter() - t0
    assert judge(bank, model, SFDI_CS1, names) == []
    poles = np.linalg.eigvals(bank.Q.A) if bank.Q.n else np.zeros(0)
    assert np.all(poles.real <= -0.2 + 1e-9), poles.real.max()
    np.testing.assert_array_equal(_strong_structure(bank, model, names, 1e-3), SFDI_CS1)
    norms = _closed_loop_norms(bank, models, np.array(cs1["K"]), np.arange(10))
    orders = [g.Q.n for g in bank.members]
    with capsys.disabled():
        print(f"\nCS1_1 orders {orders} (total {bank.Q.n}), design {elapsed:.1f} s; Table 8.2 (rows normalised):")
        for i, r in enumerate(norms):
            print(f"  model {i + 1:2d}: NormRu {r[0]:.3e}  NormRd {r[1]:.3e}  NormRf-Rfnom {r[2]:.3e}")
    assert np.all(norms[NOM] < 1e-6), norms[NOM]


@pytest.mark.slow  # 255 rows, each a basis and its stable factor: ~15 s of CPU
def test_cs1_2_all_specifications_strongly_achievable(cs1):
    """CS1_2: with the surface positions measured, all 2^8 − 1 = 255 specifications are strongly
    achievable for constant faults (FDGainTol = 1e-3 at FDfreq = 0)."""
    model = cs1_models(cs1, positions=True)[NOM]
    S = achievable_structure(model, max_faults=8, freqs=[0.0], FDGainTol=1e-3, atol=1e-6)
    assert S.shape == (255, 8)


@pytest.mark.slow
def test_cs1_2_efdisyn_identity(cs1, capsys):
    """CS1_2 Part 3–4: SFDI = I8 with FDGainTol = 0.01 at ω = 0, sdeg = −5, smarg = −1: exact,
    structure I8 strongly at ω = 0, poles Re ≤ −1, and Table 8.3's nominal row below 1e-6."""
    models = cs1_models(cs1, positions=True)
    model = models[NOM]
    S = np.eye(8, dtype=int)
    t0 = time.perf_counter()
    # the peer's efdisyn(sysactf[nom], SFDI; atol, FDGainTol = 0.01, FDfreq, ...), atol = 1e-6 (CS1_2.jl)
    bank = structured_bank(model, S, freqs=[0.0], FDGainTol=0.01, sdeg=-5, smarg=-1, atol=1e-6)
    with capsys.disabled():
        print(f"\nCS1_2 orders {[g.Q.n for g in bank.members]} (total {bank.Q.n}), "
              f"design {time.perf_counter() - t0:.1f} s")
    assert judge(bank, model, S, model.fault_names) == []
    poles = np.linalg.eigvals(bank.Q.A) if bank.Q.n else np.zeros(0)
    assert np.all(poles.real <= -1 + 1e-9), poles.real.max()
    np.testing.assert_array_equal(_strong_structure(bank, model, model.fault_names, 0.01), S)


# ------------------------------------------------------------------------------------------- CS2
SEN = [2, 4]  # 1-based: AoA, VCAS


def cs2_models(cs2) -> list[FDIModel]:
    out = []
    for i, s in enumerate(cs2["SYSACSM"]):
        A, B, C, D = _sys(s)
        mu = B.shape[1] - 2
        y = [f"y{k + 1}" for k in range(C.shape[0])]
        out.append(FDIModel.from_matrices(A, B[:, :mu], C, D[:, :mu], Bd=B[:, mu:], Dd=D[:, mu:],
                                          faults=[sensor_fault(f"s{j}", f"y{j}") for j in SEN], y_names=y,
                                          name=f"cs2_{i + 1}"))
    return out


def _cs2_ref_error(D, model) -> float:
    """``‖D·[Gu Gd Gf; I 0 0] − [0 0 I]‖∞`` on a dense grid for a constant filter gain D."""
    B = np.hstack([model.Bu, model.Bd, model.Bf])
    Dm = np.hstack([model.Du, model.Dd, model.Df])
    G = _freqresp(model.A, B, model.C, Dm, _peak_grid([model], 2000))
    mu = model.nu
    Ge = np.concatenate([G, np.broadcast_to(np.hstack([np.eye(mu), np.zeros((mu, B.shape[1] - mu))]),
                                            (G.shape[0], mu, B.shape[1]))], axis=1)
    ref = np.hstack([np.zeros((2, B.shape[1] - 2)), np.eye(2)])
    return float(np.linalg.norm(D[None] @ Ge - ref[None], 2, axis=(1, 2)).max())


def test_cs2_1_strong_specifications(cs2):
    model = cs2_models(cs2)[NOM]
    S = achievable_structure(model, freqs=[0.0], FDGainTol=1e-4, atol=1e-6)
    assert S.shape == (3, 2)


def test_cs2_1_table_8_4(cs2, capsys):
    """CS2_1: per model the SFDI = I2 bank (FDGainTol = 1e-4 at ω = 0, sdeg = −5, smarg = −0.05)
    has order 0 and, rows normalised to R_f = I, Nref = ‖R_i − [0 0 I]‖∞ < 1e-7; the nominal
    filter on every model gives Nnom > 643 and the mean gain D0 gives N0 > 504 (Table 8.4)."""
    models = cs2_models(cs2)
    S = np.eye(2, dtype=int)
    Ds = []
    for model in models:
        bank = structured_bank(model, S, freqs=[0.0], FDGainTol=1e-4, sdeg=-5, smarg=-0.05)
        assert bank.Q.n == 0, f"{model.name}: order {bank.Q.n}, the peer's least order is 0"
        assert judge(bank, model, S, model.fault_names) == []
        D = np.array(bank.Q.D, float)
        sen = np.array(SEN) - 1
        D = D / np.diag(D[:, sen])[:, None]  # R_f = Q_y[:, sen] = I
        Ds.append(D)
    Nref = [_cs2_ref_error(D, m) for D, m in zip(Ds, models)]
    Nnom = [_cs2_ref_error(Ds[NOM], m) for m in models]
    D0 = np.mean(Ds, axis=0)
    N0 = [_cs2_ref_error(D0, m) for m in models]
    with capsys.disabled():
        print("\nCS2_1 Table 8.4: Nref", f"{max(Nref):.2e}", "Nnom", f"{max(Nnom):.4g}", "N0", f"{max(N0):.4g}")
    assert max(Nref) < 1e-7
    assert max(Nnom) > 643
    assert max(N0) > 504
