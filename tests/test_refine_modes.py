"""The plant's boundary modes a filter must cancel, cancelled exactly (issue 17; refine.py, approximate matching).

* ``approximate_model_matching`` whose shipped filter cancels a fault-only unstable (s = 1) or marginal (z = 1)
  plant mode only to a rounding-size residue that a large gain has amplified — ``Q = Y·Φ·Q0``, Q0 cancelling
  the mode to ~1e-11 of its gain and Y's gain 1e4 (approximate audit seeds 2 and 13) — returns a filter whose
  ``R = Q·Ge`` has no pole there: the residue of R at the mode, read by numpy (the Laurent residue
  ``lim (λ − p) R(λ) = Q(p) Ce v (yᴴ B)/(yᴴ v)`` from numpy's own eigenvectors, and PBH on the series
  realisation), is at the rounding of Q, and the matching error is the designed one;
* ``refine.boundary_residues`` decides which boundary modes u or d excite by the judge's table
  (:func:`fmu_fdi.design.toolkit.plant_modes.boundary_mode_table`, its δ_c), not by a fixed 1e-8, and returns
  the table's eigenvalue to the last bit.
"""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi import FDIModel, component_fault
from fmu_fdi.design import approximate_model_matching, nullspace_design
from fmu_fdi.design.problems import approximate_matching
from fmu_fdi.design.toolkit.plant_modes import boundary_mode_table
from fmu_fdi.design.toolkit.refine import boundary_residues
from fmu_fdi.linalg import EPS
from fmu_fdi.lti import LTI
from test_approximate_random import _assert_case, check_case
from test_synthesis_random import _balanced, _extended, _freqresp, _pbh_poles, _series

#: the shipped filter's residue at the mode before the gain (relative to its peak gain) and the gain
BASIS_RESIDUE, GAIN = 1e-11, 1e4


def _plant(dt: float, fault_mode: float) -> FDIModel:
    """n = 3: stable modes −1, −3 (s; e^{−0.1}, e^{−0.3} in discrete time) that u and the noise w excite, and a
    mode ``fault_mode`` (s; ``e^{fault_mode·dt}``) that only the component fault fc excites; two outputs, every
    mode observable; a non-orthogonal change of state coordinates."""
    S = np.array([[1.0, 0.5, 0.2], [0.0, 1.0, 0.3], [0.0, 0.0, 1.0]])
    modes = np.array([-1.0, -3.0, fault_mode])
    Si = np.linalg.inv(S)
    A = S @ np.diag(np.exp(modes * dt) if dt else modes) @ Si
    Bu, Bw, Bc = S @ [[1.0], [1.0], [0.0]], S @ [[0.0], [1.0], [0.0]], S @ [[1.0], [0.5], [1.0]]
    C = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]) @ Si
    return FDIModel.from_matrices(A, Bu, C, np.zeros((2, 1)), Bw=Bw, Dw=np.array([[0.3], [0.2]]),
                                  faults=[component_fault("fc", Bc)], dt=dt, u_names=["u"], y_names=["y1", "y2"])


def _mode(model: FDIModel):
    """The fault-only mode p (the largest eigenvalue), numpy's unit right eigenvector v and a left one y."""
    A = model.A
    ev, V = np.linalg.eig(A)
    k = int(np.argmax(np.abs(ev) if model.dt else ev.real))
    evl, W = np.linalg.eig(A.T)
    return ev[k], V[:, k] / np.linalg.norm(V[:, k]), W[:, int(np.argmin(np.abs(evl - ev[k])))]


def _laurent_residue(Q: LTI, model: FDIModel) -> float:
    """``||lim_{λ→p} (λ − p) R(λ)||`` at the fault-only mode p, R = Q·Ge: for a simple pole the rank-one
    ``Q(p) Ce v (yᵀ B) / (yᵀ v)``, whose 2-norm is ``||Q(p) c|| · ||yᵀ B|| / |yᵀ v|``, ``c = Ce v``."""
    A, B, Ce, De = _extended(model)
    p, v, y = _mode(model)
    Qp = _freqresp(Q.A, Q.B, Q.C, Q.D, np.array([p]))[0]
    return float(np.linalg.norm(Qp @ Ce @ v) * np.linalg.norm(y @ B) / abs(y @ v))


def _rounding(Q: LTI, model: FDIModel) -> float:
    """The Laurent residue a filter that cancels p exactly in exact arithmetic shows in floating point:
    ``N·eps·κ · ||yᵀ B|| / |yᵀ v|``, κ the componentwise condition of ``Q(p) c`` in Q's (balanced) data,
    ``||(|D| + |C||X| + |Z||B| + |Z||A||X|)|c| ||`` with ``X = (pI − A)⁻¹ B``, ``Z = C (pI − A)⁻¹`` (Higham,
    *Accuracy and Stability of Numerical Algorithms*, 2nd ed., sec. 7.2: relative perturbations eps of the
    stored data move ``Q(p) c`` by ≤ eps·κ), N = n_q + n the order of Q and plant, times 10 for the eigenvector
    of this plant (eigenvalues ≥ 1 apart, cond ≲ 3: its own rounding ≲ 10 n eps)."""
    A, B, Ce, De = _extended(model)
    p, v, y = _mode(model)
    c = Ce @ v
    Aq, Bq, Cq = _balanced(np.asarray(Q.A, float), np.asarray(Q.B, float), np.asarray(Q.C, float))
    L = p * np.eye(Aq.shape[0]) - Aq
    X, Z = np.linalg.solve(L, Bq), np.linalg.solve(L.T, Cq.T).T
    kappa = np.linalg.norm((np.abs(Q.D) + np.abs(Cq) @ np.abs(X) + np.abs(Z) @ np.abs(Bq)
                            + np.abs(Z) @ np.abs(Aq) @ np.abs(X)) @ np.abs(c))
    return 10 * (Aq.shape[0] + A.shape[0]) * EPS * float(kappa) * float(np.linalg.norm(y @ B) / abs(y @ v))


def _error(Q: LTI, model: FDIModel, M: LTI, Mr: LTI) -> float:
    """numpy's peak of ``||Q [Gf Gw; 0 0] − M [Mr 0]||`` on a dense boundary grid ≥ 1e-3 from the plant's poles."""
    A, B, Ce, De = _extended(model)
    lam = np.exp(1j * np.linspace(0.0, np.pi, 3000)) if model.dt else 1j * np.r_[0.0, np.logspace(-3, 4, 3000)]
    lam = lam[np.min(np.abs(lam[:, None] - np.linalg.eigvals(A)[None, :]), axis=1) > 1e-3]
    f0 = model.nu + model.nd
    cols = np.r_[np.arange(f0 + model.nw, B.shape[1]), np.arange(f0, f0 + model.nw)]  # [f w]
    MMr = _freqresp(M.A, M.B, M.C, M.D, lam) @ _freqresp(Mr.A, Mr.B, Mr.C, Mr.D, lam)
    E = _freqresp(Q.A, Q.B, Q.C, Q.D, lam) @ _freqresp(A, B[:, cols], Ce, De[:, cols], lam)
    E[:, :, :model.nf] -= MMr
    return float(np.max(np.linalg.norm(E, 2, axis=(1, 2))))


# continuous H2 (an H∞ optimum here has a pole at −2.8e4: κ ~1e6 and a rounding bound 30× larger); discrete H∞
CASES = {"s=1": (0.0, 1.0, "2"), "z=e^0.1": (0.1, 1.0, "inf"), "z=1": (0.1, 0.0, "inf")}


@pytest.mark.parametrize("case", list(CASES))
def test_an_amplified_rounding_residue_of_a_fault_only_mode_is_cancelled(case, monkeypatch):
    dt, fault_mode, norm = CASES[case]
    model = _plant(dt, fault_mode)
    Mr = nullspace_design(model, noise="ignore").Rf  # an exact detection row's Rf: an exact solution exists
    gen0 = approximate_model_matching(model, Mr, norm=norm)
    designed = _error(gen0.Q, model, gen0.info["M"], Mr)

    # the shipped filter as seeds 2 and 13 ship it, Q + ε·E: E = T [I  −Gu] decouples u exactly and has
    # ||E(p) c|| ~ 1, ε = GAIN × BASIS_RESIDUE × Q's peak gain (a residue ~1e-7 of Q's gain)
    G = model.lti()
    Gu = LTI(G.A, G.B[:, :model.nu], G.C, G.D[:, :model.nu], dt).minreal()  # without the mode u does not excite
    assert Gu.n == 2
    T = np.array([[1.0, 0.0]])
    E = LTI(Gu.A, np.hstack([np.zeros((Gu.n, model.ny)), -Gu.B]), T @ Gu.C, np.hstack([T, -T @ Gu.D]), dt)
    grid = np.exp(1j * np.linspace(0, np.pi, 400)) if dt else 1j * np.logspace(-3, 4, 400)
    peak = float(np.max(np.linalg.norm(_freqresp(gen0.Q.A, gen0.Q.B, gen0.Q.C, gen0.Q.D, grid), 2, axis=(1, 2))))
    shipped = {}
    original = approximate_matching._shipped_filter

    def amplified(*args, **kw):
        Q, lam = original(*args, **kw)
        shipped["Q"] = Q + (GAIN * BASIS_RESIDUE * peak) * E
        return shipped["Q"], lam

    monkeypatch.setattr(approximate_matching, "_shipped_filter", amplified)
    gen = approximate_model_matching(model, Mr, norm=norm)  # main: refused, "R = Q·Ge keeps the plant pole"

    before, after = _laurent_residue(shipped["Q"], model), _laurent_residue(gen.Q, model)
    assert before > 1e3 * _rounding(shipped["Q"], model)  # the test can fail: the shipped R keeps the mode
    assert after <= _rounding(gen.Q, model), (before, after, _rounding(gen.Q, model))
    AR, BR, CR, DR = _series(gen.Q, model)
    assert _pbh_poles(AR, BR, CR, dt, DR).size == 0
    note = gen.info["plant_mode_cancellation"]
    assert note["corrected"] and len(note["modes"]) == 1
    # the error unchanged: that of the filter designed without the residue, to the γ-iteration's reltol = 1e-4 (the
    # bound the stage keeps a correction within). What moves it is the residue's stable part, ε·E·[Gf Gw] with ε =
    # 1e-7 of Q's gain: relative 2e-7 (s = 1, z = e^0.1, errors 0.33, 0.36) and 4e-5 (z = 1, error 3.9e-3)
    assert abs(_error(gen.Q, model, gen.info["M"], Mr) - designed) <= 1e-4 * designed
    assert abs(gen.info["error"] - gen0.info["error"]) <= 1e-4 * gen0.info["error"]


@pytest.mark.slow
def test_audit_seed_13_meets_the_judge():
    """Approximate audit seed 13 (z = 1, residue 3.0e-11 against δ_i = 1.6e-11 before); seed 2 (s = 1) runs in
    tests/test_approximate_random.py's slow range."""
    _assert_case(13, ("amm_ref",))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [2, 6, 8, 12, 16])
def test_audit_matches_to_the_identity_are_refused_by_their_rank_bound(seed):
    """Mr = I on these seeds (admissible fault-response ranks 4, 1, 2, 3, 3 for 5, 5, 5, 4, 4 faults): every filter
    that decouples u and d has ||Q Gf - I||_inf >= sigma_{r+1}(I) = 1 = ||I||_inf, the error of Q = 0, so the design
    refuses early, naming the rank and the bound (approximate_matching._unapproachable_reference). Their boundary
    modes (s = 1, 1, +-2j, 1, 0: once refused for a fault-only mode kept in R_f above its rounding bound) are still
    designed and judged by numpy with Mr = the first r rows of I in tests/test_amm_unapproachable.py."""
    (what, status, detail), = check_case(seed, calls=("amm_eye",))
    assert status == "refused", (status, detail)
    assert "cannot be approached" in detail and "normal rank" in detail, detail


@pytest.mark.parametrize("dt", [0.0, 0.1], ids=["continuous", "discrete"])
def test_boundary_residues_decide_excitation_by_the_judges_coupling_bound(dt):
    """An integrator (z = 1) that u excites through a coupling of 1e-10 of ||b_u||: far above the judge's δ_c
    (n·eps·(4||A||/sep + 1)||b|| ≈ 1e-14 here) so the decoupling row must cancel it and refine constrains it —
    the fixed 1e-8 called it unexcited; with the coupling exactly 0, no mode. The eigenvalue is the table's,
    bit for bit."""
    modes = np.exp(np.array([-1.0, -2.0, 0.0]) * dt) if dt else np.array([-1.0, -2.0, 0.0])
    for coupling, expected in ((1e-10, 1), (0.0, 0)):
        model = FDIModel.from_matrices(np.diag(modes), [[1.0], [1.0], [coupling]],
                                       [[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]], np.zeros((2, 1)),
                                       faults=[component_fault("fc", [[0.0], [1.0], [1.0]])], dt=dt,
                                       u_names=["u"], y_names=["y1", "y2"])
        table = boundary_mode_table(model)
        got = boundary_residues(model)
        assert len(got) == expected, (coupling, got, table["coupling"], table["coupling_tol"])
        if expected:
            k = int(np.flatnonzero(table["poles"] == got[0][0])[0])  # exact equality: the table's own number
            assert table["coupling"][k][0] > table["coupling_tol"][k][0]
            # the direction: Ce v of the integrator's state (x3 enters y1 and y2), unit norm
            assert np.allclose(np.abs(got[0][1]), np.r_[1.0, 1.0, 0.0] / np.sqrt(2.0), atol=1e-12)
