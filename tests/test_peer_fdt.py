"""FaultDetectionTools.jl's own test suite as the peer's judge (issue 17, "Show").

Cases of the peer's test/ folder (andreasvarga/FaultDetectionTools.jl, commit 76ec594:
test_efdsyn.jl, test_efdisyn.jl, test_emmsyn.jl, test_emdsyn.jl) that exercise our functions,
re-entered from their data (plants, structure matrices, options) with the properties and numbers
the peer asserts; the code is ours. Peer → ours: efdsyn → nullspace_design; efdisyn / efdsyn per
row → structured_bank; fdigenspec → achievable_structure; emmsyn → model_matching; emdsyn →
model_detection_bank. Designs are judged by the independent numpy judge of
tests/test_synthesis_random.py (R = Q·Ge on a dense grid, rows normalised to smallest required
fault peak 1, ‖R_u‖, ‖R_d‖ ≤ 1e-7, R stable by PBH, Q nonzero, faults visible) plus the peer's own
asserted figures (orders, strong structure at FDfreq, matching, model-detection diagonal).

Not ported: the peer's cases on ``rss`` random systems (Julia's RNG stream cannot be reproduced;
our own seeded random set covers them), HDesign round trips and ``nullspace = false`` /
``simple = true`` variants (options we do not have), improper fault channels (Gf = [s; s²+4]: our
models are proper state space).

Tally (27 tests ported from 11 peer cases files/examples; state of 2026-11-26 ~11:45 UTC):
  ported 27 · passing on main 20 · xfail (strict; fail on main and on main+core+judge+matching) 5 ·
  failing on main but passing with the issue-17 branches 2 (test_afdsyn_ex5_6c_gap_and_poles: core+judge;
  test_fdigenspec_marginal_poles_strong_at_0_and_1: core). bankfix (12:30 UTC): test_afdisyn_ex5_11c_gaps_3_and_inf
  passes (R_u/R_d poles judged against the stability boundary, R_w/R_f against smarg): xfail 4.
  peer (issue 17, ~14:45 UTC): xfail 0 — strong tests at boundary poles on the stable factor of the rows
  (test_efdsyn_strong_at_poles_of_gf), smarg inclusive (the Yuan pole-assignment test; its McMillan degree
  counted from residues: sqrt(eig(Wc·Wo)) put ~1e-7 rounding above the peer's 1e-7 threshold), every ω of
  achievable_structure's strong test on the stable factor (Boeing 747: fdigenspec's 4 rows), numerator
  refinement of near-boundary leaks (Boeing 747 weak rows at the least orders [1, 2, 1, 2, 1, 1, 1]).
Each test names the peer file and case it comes from.
"""
from __future__ import annotations

import control as ct
import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import FDIModel
from fmu_fdi.design.problems.achievable import achievable_structure
from fmu_fdi.design import model_detection_bank, model_matching, nullspace_design, structured_bank
from fmu_fdi.errors import DesignError
from fmu_fdi.faults import component_fault

from test_synthesis_random import _freqresp, _pbh_poles, judge

s = ct.tf("s")


def tf_model(groups: dict, minimal: bool = True) -> FDIModel:
    """An FDIModel from transfer-function columns: ``groups`` maps 'u', 'd', 'w', 'f' to lists of
    columns (each a list of SISO tfs, one per output); faults are named f1, f2, ..."""
    cols, kinds = [], []
    for k in ("u", "d", "w", "f"):
        for c in groups.get(k, []):
            cols.append([x if isinstance(x, ct.TransferFunction) else ct.tf([float(x)], [1.0], 0) for x in c])
            kinds.append(k)
    p = len(cols[0])
    G = ct.combine_tf([[cols[j][i] for j in range(len(cols))] for i in range(p)])
    sys = ct.ss(G)
    idx = {k: [j for j, kk in enumerate(kinds) if kk == k] for k in ("u", "d", "w", "f")}
    A, B, C, D = (np.asarray(X, float) for X in (sys.A, sys.B, sys.C, sys.D))
    faults = [component_fault(f"f{i + 1}", B[:, [j]], D[:, [j]]) for i, j in enumerate(idx["f"])]
    return FDIModel.from_matrices(A, B[:, idx["u"]], C, D[:, idx["u"]],
                                  Bd=B[:, idx["d"]] if idx["d"] else None, Dd=D[:, idx["d"]] if idx["d"] else None,
                                  Bw=B[:, idx["w"]] if idx["w"] else None, Dw=D[:, idx["w"]] if idx["w"] else None,
                                  faults=faults, minimal=minimal or None)


def ss_model(A, Bu, Bd, Bf, C, Du=None, Dd=None, Df=None) -> FDIModel:
    A, Bu, Bd, Bf, C = (np.atleast_2d(np.asarray(X, float)) for X in (A, Bu, Bd, Bf, C))
    p = C.shape[0]
    Df = np.zeros((p, Bf.shape[1])) if Df is None else np.asarray(Df, float)
    faults = [component_fault(f"f{j + 1}", Bf[:, [j]], Df[:, [j]]) for j in range(Bf.shape[1])]
    nd = Bd.shape[1] if Bd.size else 0
    return FDIModel.from_matrices(A, Bu, C, Du, Bd=Bd if nd else None, Dd=Dd if nd else None, faults=faults)


def strong_gains(gen, model, omegas) -> np.ndarray:
    """``|R_ij(jω)|`` (group i, fault j; 2-norm over the group's rows) at each ω, shape (len(ω),
    groups, faults), computed as Q(λ)·[Gf; 0](λ) with numpy; at a pole of the plant on the axis
    the limit is taken 1e-6 beside it (R is stable there when the design is right)."""
    lam = 1j * np.asarray(omegas, float)
    ev = np.linalg.eigvals(model.A) if model.n else np.zeros(0)
    lam = np.array([x + (1e-6j if ev.size and np.min(np.abs(ev - x)) < 1e-9 else 0) for x in lam])
    Gf = _freqresp(model.A, model.Bf, model.C, model.Df, lam)
    Gf = np.concatenate([Gf, np.zeros((lam.size, model.nu, model.nf))], axis=1)
    Q = gen.Q
    Qv = _freqresp(Q.A, Q.B, Q.C, Q.D, lam)
    R = Qv @ Gf
    cols = [np.arange(model.nf)[f.columns] for f in model.faults]
    return np.array([[[np.linalg.norm(R[k][np.ix_(g, c)], 2) for c in cols] for g in gen.groups]
                     for k in range(lam.size)])


def peak_gains(gen, model) -> np.ndarray:
    """Peak over a log grid of |R_ij(jω)| (groups × faults)."""
    return strong_gains(gen, model, np.r_[np.logspace(-3, 3, 300)]).max(axis=0)


def strong_structure(gen, model, omegas, FDGainTol) -> np.ndarray:
    """1 where the fault is strongly visible at every ω: ``|R_ij(jω)| > FDGainTol · peak_i`` with
    peak_i the row's largest fault peak (the peer's fdisspec on a normalised row)."""
    g = strong_gains(gen, model, omegas)
    pk = peak_gains(gen, model).max(axis=1)
    return np.all(g > FDGainTol * pk[None, :, None], axis=0).astype(int)


def _orders(bank):
    return [g.Q.n for g in bank.members]


# --------------------------------------------------------------------------- test_efdsyn.jl: TF cases
GF_ZEROS = [[s / (s + 1), (s**2 + 4) / (s + 3) ** 2], [0, 1]]  # columns of Gf = [s/(s+1) 0; (s²+4)/(s+3)² 1]


def test_efdsyn_strong_at_zeros_of_gf_one_fault():
    """efdsyn(sysf; sdeg=-3, rdim=1, FDfreq=[0, 2]) on fault 1 of Gf: exact, fdisspec(Rf, [0, 2]) = [1]
    — the residual sees the fault at ω = 0 and 2 though Gf_1 has zeros at 0 and ±2j."""
    model = tf_model({"f": GF_ZEROS[:1], "w": []})
    gen = nullspace_design(model, sdeg=-3, rdim=1, freqs=[0.0, 2.0])
    assert judge(gen, model, [[1]], model.fault_names) == []
    assert strong_structure(gen, model, [0.0, 2.0], 1e-3).tolist() == [[1]]


def test_efdsyn_strong_at_zeros_of_gf_two_faults_rdim2():
    """efdsyn(sysf (faults 1:2); sdeg=-3, rdim=2, FDfreq=[0, 2]): block structure at [0, 2] is [1 1]."""
    model = tf_model({"f": GF_ZEROS})
    gen = nullspace_design(model, sdeg=-3, rdim=2, freqs=[0.0, 2.0])
    assert gen.Q.p == 2

    class gen:  # noqa: N801 - the two rows are one residual vector (the peer's block structure)
        Q, groups = gen.Q, [[0, 1]]

    assert judge(gen, model, [[1, 1]], model.fault_names) == []
    assert strong_structure(gen, model, [0.0, 2.0], 1e-3).tolist() == [[1, 1]]


def test_efdsyn_strong_at_poles_of_gf():
    """efdsyn(Gf = [1/s; 1/(s²+4)]; sdeg=-3, rdim=1, FDfreq=[0, 2]): designed, R stable (its poles
    at 0 and ±2j cancelled by Q), strongly visible at ω = 0 and 2 (fdisspec(Rf, [0, 2]) = [1])."""
    model = tf_model({"f": [[1 / s, 1 / (s**2 + 4)]]})
    gen = nullspace_design(model, sdeg=-3, rdim=1, freqs=[0.0, 2.0])
    assert judge(gen, model, [[1]], model.fault_names) == []
    assert strong_structure(gen, model, [0.0, 2.0], 1e-3).tolist() == [[1]]


def test_efdsyn_ex5_2_has_no_solution():
    """Example 5.2: Gu = [(s+1)/(s+2); (s+2)/(s+3)], Gd = [1/(s+2); 0], Gf = [(s+1)/(s+2) 0; 0 1]:
    efdsyn throws (fault 1 cannot be seen once d is decoupled) — ours must refuse with DesignError."""
    model = tf_model({"u": [[(s + 1) / (s + 2), (s + 2) / (s + 3)]], "d": [[1 / (s + 2), 0]],
                      "f": [[(s + 1) / (s + 2), 0], [0, 1]]})
    with pytest.raises(DesignError):
        nullspace_design(model)
    assert [1, 1] not in achievable_structure(model).tolist()


def test_efdsyn_ex5_4c():
    """Example 5.4c: Gu = [(s+1)/(s-2); (s+2)/(s-3)], Gd = [(s-1)/(s+2); 0], Gf = [Gu [0; 1]];
    efdsyn(sdeg=-3, rdim=1): R_u = R_d = 0, fdisspec(Rf, [0]) = [1 1]. Least order 1: d forces
    q_y1 = 0, then q_y2 must cancel the unstable pole 3 of Gu's second row (one state)."""
    Gu = [(s + 1) / (s - 2), (s + 2) / (s - 3)]
    model = tf_model({"u": [Gu], "d": [[(s - 1) / (s + 2), 0]], "f": [Gu, [0, 1]]})
    gen = nullspace_design(model, sdeg=-3, rdim=1)
    assert judge(gen, model, [[1, 1]], model.fault_names) == []
    assert strong_structure(gen, model, [0.0], 1e-2).tolist() == [[1, 1]]
    assert gen.Q.n == 1


# ------------------------------------------------------------ test_efdsyn.jl / test_efdisyn.jl: banks
NIEMANN = dict(
    A=np.array([[-0.0782, 0.2939, 0.0220, 0.0208, -0.0291],
                [0.0077, -0.0278, 0.0015, -0.0015, 0.0026],
                [-1.3251, 5.32608, -0.5263, 0.2214, -0.4777],
                [1.0809, -4.4452, 0.3770, -0.4631, 0.4032],
                [2.1532, -8.6386, 0.7811, -0.5745, 0.7816]]) * 1000,
    Bd=np.array([[0.0443], [-0.0042], [0.7910], [-0.6598], [-1.2881]]) * 1000,
    Bu=np.array([[-0.007197, 0.003005], [0.003473, 0.000284], [1.218502, -0.032866], [1.322502, 0.020147],
                 [-0.082265, 0.024388]]),
)
XS1_A = np.array([[-9.9477, -0.7476, 0.2632, -5.0337], [52.1659, 2.7452, 5.5532, -24.4221],
                  [26.0922, 2.6361, -4.1975, -19.2774], [0.0, 0.0, 1.0, 0.0]])
XS1_BU = np.array([[0.4422, 0.1761], [3.5446, -7.5922], [-5.52, 4.49], [0.0, 0.0]])
XS2_A = np.array([[0, 0, -0.0034, 0, 0], [0, -0.041, 0.0013, 0, 0], [0, 0, -1.1471, 0, 0],
                  [0, 0, -0.0036, 0, 0], [0, 0.094, 0.0057, 0, -0.051]])
XS2_BU = np.array([[-1, 0, 0], [0, 0, 0], [0, 0, 0.948], [0.916, -1, 0], [-0.598, 0, 0]])
XS2_BD = np.array([[0, 1], [0.062, -0.132], [0, -7.189], [0, 0], [0, 0]])


def niemann():
    return ss_model(NIEMANN["A"], NIEMANN["Bu"], NIEMANN["Bd"], NIEMANN["Bu"], np.eye(5))


def xiong_saif_1():
    Df = np.zeros((4, 2))
    Df[2, 1] = 1.0
    Bf = np.hstack([XS1_BU[:, :1], np.zeros((4, 1))])
    C = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 1, 1, 1.0]])
    return ss_model(XS1_A, XS1_BU, np.array([[0, 0], [0, 1], [1, 0], [0, 0.0]]), Bf, C, Df=Df)


def xiong_saif_2():
    C = np.array([[1, 0, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 1, 0.0]])
    return ss_model(XS2_A, XS2_BU, XS2_BD, XS2_BU[:, :2], C)


S3 = np.array([[1, 0], [0, 1], [1, 1]])


@pytest.mark.parametrize("name, build, orders", [("Niemann 1998", niemann, [1, 1, 1]),
                                                 ("Xiong & Saif 2000 ex. 1", xiong_saif_1, [2, 1, 1]),
                                                 ("Xiong & Saif 2000 ex. 2", xiong_saif_2, [1, 1, 1])])
def test_efdsyn_rows_strong_structure_and_orders(name, build, orders):
    """test_efdsyn.jl: S_strong = [1 0; 0 1; 1 1] (fdigenspec, FDfreq = 0), one efdsyn per row with
    sdeg = -5, smarg = -0.05, FDfreq = 0, FDGainTol = 1e-4, rdim = 1: R_u = R_d = 0, the strong
    structure at 0 equals SFDI, and the orders are the peer's."""
    model = build()
    listed = achievable_structure(model, freqs=[0.0], FDGainTol=1e-4).tolist()
    assert all(r in listed for r in S3.tolist()), f"{name}: rows listed {listed}"
    bank = structured_bank(model, S3, freqs=[0.0], FDGainTol=1e-4, sdeg=-5, smarg=-0.05)
    assert judge(bank, model, S3, model.fault_names) == []
    np.testing.assert_array_equal(strong_structure(bank, model, [0.0], 1e-4), S3)
    assert _orders(bank) == orders, f"{name}: orders {_orders(bank)}, the peer's {orders}"


YUAN = dict(A=np.array([[-1, 1, 0, 0], [1, -2, 1, 0], [0, 1, -2, 1], [0, 0, 1, -2.0]]),
            Bu=np.array([[1.0], [0], [0], [0]]),
            Bf=np.array([[1, 0, 0, 0, 1, 0, 0, 0], [0, 1, 0, 0, -1, 1, 0, 0], [0, 0, 1, 0, 0, -1, 1, 0],
                         [0, 0, 0, 1, 0, 0, -1, 1.0]]),
            C=np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
YUAN_STRONG = np.array([[0, 0, 0, 1, 0, 0, 1, 1], [0, 1, 1, 0, 1, 1, 1, 0], [0, 1, 1, 1, 1, 1, 0, 1],
                        [0, 1, 1, 1, 1, 1, 1, 1], [1, 0, 1, 0, 1, 1, 1, 0], [1, 0, 1, 1, 1, 1, 0, 1],
                        [1, 0, 1, 1, 1, 1, 1, 1], [1, 1, 0, 0, 1, 1, 0, 0], [1, 1, 0, 1, 1, 1, 1, 1],
                        [1, 1, 1, 0, 1, 1, 1, 0], [1, 1, 1, 1, 1, 1, 0, 1], [1, 1, 1, 1, 1, 1, 1, 1]])
YUAN_WEAK = np.array([[0, 0, 0, 1, 0, 0, 1, 1], [0, 1, 1, 0, 1, 1, 1, 0], [0, 1, 1, 1, 1, 1, 0, 1],
                      [0, 1, 1, 1, 1, 1, 1, 1], [1, 0, 1, 0, 1, 1, 1, 0], [1, 0, 1, 1, 1, 1, 0, 1],
                      [1, 0, 1, 1, 1, 1, 1, 1], [1, 1, 0, 0, 1, 1, 0, 0], [1, 1, 0, 1, 1, 1, 1, 1],
                      [1, 1, 1, 0, 0, 1, 1, 0], [1, 1, 1, 0, 1, 0, 1, 0], [1, 1, 1, 0, 1, 1, 1, 0],
                      [1, 1, 1, 1, 0, 1, 0, 1], [1, 1, 1, 1, 0, 1, 1, 1], [1, 1, 1, 1, 1, 0, 0, 1],
                      [1, 1, 1, 1, 1, 0, 1, 1], [1, 1, 1, 1, 1, 1, 0, 1], [1, 1, 1, 1, 1, 1, 1, 1]])
YUAN_STRONG_ORDERS = [1, 2, 2, 2, 1, 1, 1, 2, 2, 2, 2, 2]
YUAN_WEAK_ORDERS = [1, 2, 2, 2, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2]


def yuan():
    return ss_model(YUAN["A"], YUAN["Bu"], np.zeros((4, 0)), YUAN["Bf"], YUAN["C"])


def test_yuan_achievable_structures():
    """Yuan et al. (1997): the weak specifications (18 rows) and the strong ones at ω = 0 (12 rows)
    that the peer's fdigenspec gives (listed in test_efdsyn.jl)."""
    model = yuan()
    np.testing.assert_array_equal(achievable_structure(model), YUAN_WEAK)
    np.testing.assert_array_equal(achievable_structure(model, freqs=[0.0], FDGainTol=0.01), YUAN_STRONG)


@pytest.mark.slow
def test_yuan_strong_synthesis_orders():
    """efdsyn per row of S_strong, FDfreq = 0, FDGainTol = 1e-4, sdeg = -5, smarg = -0.05:
    orders [1, 2, 2, 2, 1, 1, 1, 2, 2, 2, 2, 2] and the strong structure at 0 equals S_strong."""
    model = yuan()
    bank = structured_bank(model, YUAN_STRONG, freqs=[0.0], FDGainTol=1e-4, sdeg=-5, smarg=-0.05)
    assert judge(bank, model, YUAN_STRONG, model.fault_names) == []
    np.testing.assert_array_equal(strong_structure(bank, model, [0.0], 1e-4), YUAN_STRONG)
    assert _orders(bank) == YUAN_STRONG_ORDERS


@pytest.mark.slow
def test_yuan_weak_synthesis_orders():
    """efdsyn per row of S_weak (18 rows), FDtol = 1e-4, sdeg = -5, smarg = -0.05: the peer's orders."""
    model = yuan()
    bank = structured_bank(model, YUAN_WEAK, FDtol=1e-4, sdeg=-5, smarg=-0.05)
    assert judge(bank, model, YUAN_WEAK, model.fault_names) == []
    assert _orders(bank) == YUAN_WEAK_ORDERS


def _mcmillan_degree_stable(Q, rtol=1e-7) -> int:
    """McMillan degree of a stable continuous Q with semisimple poles (Gilbert's realisation):
    ``Σ_λ rank Res_λ`` over its distinct poles, ``Res_λ = C P_λ B`` with ``P_λ`` the spectral
    projector (numpy eig), a residue direction counting when its singular value over ``2|Re λ|``
    (the Hankel singular value of ``σ/(s − λ)``) exceeds ``rtol`` (absolute 1e-7 as the peer's
    ``count(ghanorm(Qtot) > 1e-7)`` on rows of unit peak fault gain). Not the square roots of
    ``eig(Wc·Wo)``: the Gramians of a 32-state bank with 18-fold poles carry rounding ~eps·||W||,
    whose square roots (~1e-7 here) would count as Hankel singular values."""
    if Q.A.shape[0] == 0:
        return 0
    lam, V = np.linalg.eig(Q.A)
    assert np.linalg.cond(V) < 1e8, "Q has a (nearly) defective pole: the residue count does not apply"
    W = np.linalg.inv(V)
    CV, WB = Q.C @ V, W @ Q.B
    degree, done = 0, np.zeros(lam.size, bool)
    for i in range(lam.size):
        if done[i]:
            continue
        grp = np.abs(lam - lam[i]) <= 1e-6 * max(1.0, abs(lam[i]))
        done |= grp
        res = CV[:, grp] @ WB[grp, :]
        degree += int(np.sum(np.linalg.svd(res, compute_uv=False) / (2 * abs(lam[i].real)) > rtol))
    return degree


@pytest.mark.slow
def test_yuan_weak_synthesis_with_pole_assignment_global_order_6():
    """efdsyn per row of S_weak with poles = [-5, -6], sdeg = -5, smarg = -5: orders as above and,
    the rows sharing their poles, the whole bank has McMillan degree 6 (count(ghanorm(Qtot) > 1e-7))."""
    model = yuan()
    bank = structured_bank(model, YUAN_WEAK, FDtol=1e-4, poles=[-5, -6], sdeg=-5, smarg=-5)
    assert judge(bank, model, YUAN_WEAK, model.fault_names) == []
    assert _orders(bank) == YUAN_WEAK_ORDERS
    assert np.all(np.linalg.eigvals(bank.Q.A).real <= -5 + 1e-9)
    # rows normalised to unit peak fault gain before counting (the peer's rows are normalised)
    pk = peak_gains(bank, model).max(axis=1)
    from fmu_fdi.lti import LTI
    Qn = LTI(bank.Q.A, bank.Q.B, bank.Q.C / pk[:, None], bank.Q.D / pk[:, None])
    assert _mcmillan_degree_stable(Qn) == 6


# --------------------------------------------------------------------------------- test_emmsyn.jl
def test_emmsyn_ex5_13c_updating_factor():
    """Example 5.13c: Gu = [s/(s²+3s+2) 1/(s+2); s/(s+1) 0; 0 1/(s+2)], actuator faults (Gf = Gu),
    Mr = I, sdeg = -1: emmsyn returns Q and a diagonal M with Q·[Gu Gf; I 0] = [0 M·Mr] (Gf has a
    zero at 0 in its first column, so the exact Q without M would be improper/unstable)."""
    Gu = [[s / (s**2 + 3 * s + 2), s / (s + 1), 0], [1 / (s + 2), 0, 1 / (s + 2)]]
    model = tf_model({"u": Gu, "f": Gu})
    gen = model_matching(model, ct.ss(ct.tf([[[1], [0]], [[0], [1]]], [[[1], [1]], [[1], [1]]])),
                         sdeg=-1, updating=True)
    M = gen.info["M"]
    lam = 1j * np.logspace(-3, 3, 300)
    from test_synthesis_random import _extended
    A, B, Ce, De = _extended(model)
    R = _freqresp(gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D, lam) @ _freqresp(A, B, Ce, De, lam)
    Mv = _freqresp(M.A, M.B, M.C, M.D, lam)
    scale = np.abs(Mv).max()
    assert np.abs(R[:, :, :model.nu]).max() / scale <= 1e-7
    assert np.abs(R[:, :, model.nu:] - Mv).max() / scale <= 1e-7
    assert _pbh_poles(gen.Q.A, gen.Q.B, gen.Q.C, 0.0).size == 0
    assert _pbh_poles(M.A, M.B, M.C, 0.0).size == 0
    assert np.allclose(Mv[:, 0, 1], 0) and np.allclose(Mv[:, 1, 0], 0)


# --------------------------------------------------------------------------------- test_emdsyn.jl
@pytest.mark.slow
def test_emdsyn_ex6_1c_lateral_aircraft_loe():
    """Example 6.1c: lateral aircraft with loss-of-effectiveness models Gu·Γ_i, Γ_i = diag of
    1 − [0 0; 0 .5; 0 1; .5 0; .5 .5; .5 1; 1 0; 1 .5; 1 1] (9 models); emdsyn(sdeg=-1, poles=[-1]):
    norm(diag(MDperf)) < 1e-7 (filter i is exact for model i) — and, the Γ_i being distinct, every
    other model is seen (off-diagonal distances > 0)."""
    A = np.array([[-.4492, 0.046, .0053, -.9926], [0, 0, 1, 0.0067], [-50.8436, 0, -5.2184, .722],
                  [16.4148, 0, .0026, -.6627]])
    Bu = np.array([[0.0004, 0.0011], [0, 0], [-1.4161, .2621], [-0.0633, -0.1205]])
    G = 1 - np.array([[0, 0, 0, .5, .5, .5, 1, 1, 1], [0, .5, 1, 0, .5, 1, 0, .5, 1]]).T
    models = [FDIModel.from_matrices(A, Bu @ np.diag(g), np.eye(4), name=f"m{i + 1}") for i, g in enumerate(G)]
    bank = model_detection_bank(models, sdeg=-1, poles=[-1])
    lam = 1j * np.logspace(-3, 3, 300)
    dist = _detection_distances(bank, models, lam)
    dist /= dist.max(axis=1, keepdims=True)
    assert np.all(np.diag(dist) < 1e-7), np.diag(dist)
    off = dist[~np.eye(9, dtype=bool)]
    assert off.min() > 1e-3, off.min()
    assert _pbh_poles(bank.Q.A, bank.Q.B, bank.Q.C, 0.0).size == 0


# ----------------------------------------------------------- Examples/Ex5_6c, Ex5_11c, Ex6_2c (noise)
EX56 = dict(u=[[(s + 1) / (s + 2), (s + 2) / (s + 3)]], f=[[(s + 1) / (s + 2), 0], [0, 1]], w=[[1 / (s + 2), 0]])
GRID = 1j * np.r_[0.0, np.logspace(-4, 4, 2000)]


def _responses(gen, model, lam=GRID):
    """R = Q·[Gu Gd Gw Gf; I 0 0 0] at ``lam`` (numpy), with the column slices of u, w and each fault."""
    from test_synthesis_random import _extended
    A, B, Ce, De = _extended(model)
    R = _freqresp(gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D, lam) @ _freqresp(A, B, Ce, De, lam)
    nu, nd, nw = model.nu, model.nd, model.nw
    f0 = nu + nd + nw
    return R, slice(0, nu + nd), slice(nu + nd, f0), [f0 + np.arange(model.nf)[f.columns] for f in model.faults]


def _detection_distances(bank, models, lam) -> np.ndarray:
    """``dist[i, j]``: peak over ``lam`` of the bank's residual group i driven by model j's u channels,
    ``‖Q_i(λ)·[G_u,j(λ); I]‖``, computed with numpy (not the library's analysis)."""
    Qv = _freqresp(bank.Q.A, bank.Q.B, bank.Q.C, bank.Q.D, lam)
    dist = np.zeros((len(bank.groups), len(models)))
    for j, m in enumerate(models):
        Ge = _freqresp(m.A, m.Bu, np.vstack([m.C, np.zeros((m.nu, m.n))]), np.vstack([m.Du, np.eye(m.nu)]), lam)
        R = Qv @ Ge
        for i, g in enumerate(bank.groups):
            dist[i, j] = _peak(R[:, g, :])
    return dist


def _peak(X):
    return float(np.linalg.norm(X, 2, axis=(1, 2)).max()) if X.shape[2] else 0.0


def test_afdsyn_ex5_6c_gap_and_poles():
    """Example 5.6c: Gu = [(s+1)/(s+2); (s+2)/(s+3)], Gf = [(s+1)/(s+2) 0; 0 1], Gw = [1/(s+2); 0];
    afdsyn(smarg = -3, sdeg = -3): R_u = 0, both faults seen (fdisspec block = [1 1]), the poles of Q
    at -3 (smarg = -3 met inclusively) and the fault-to-noise gap min_j ‖Rf_j‖∞ / ‖Rw‖∞ = 3."""
    model = tf_model(EX56)
    gen = nullspace_design(model, noise="optimize", smarg=-3, sdeg=-3)
    R, ud, w, fc = _responses(gen, model)
    pf = [_peak(R[:, :, c]) for c in fc]
    assert _peak(R[:, :, ud]) / min(pf) <= 1e-7
    gap = min(pf) / _peak(R[:, :, w])
    assert gap >= 3 * (1 - 1e-3), gap  # grid peaks: ≤ 1e-3 below the H∞ norms on this fine grid
    poles = np.linalg.eigvals(gen.Q.A) if gen.Q.n else np.zeros(0)
    assert np.all(poles.real <= -3 + 1e-9), poles


def test_afdisyn_ex5_11c_gaps_3_and_inf():
    """Example 5.11c: the same plant, SFDI = I2, afdisyn(smarg = -3, sdeg = -3): gaps [3, Inf] —
    row 2 (fault 2, fault 1 decoupled) decouples w exactly; row 1 keeps the gap 3."""
    from fmu_fdi.design import afdi_bank

    model = tf_model(EX56)
    bank = afdi_bank(model, np.eye(2, dtype=int), smarg=-3, sdeg=-3)
    R, ud, w, fc = _responses(bank, model)
    g1, g2 = bank.groups
    pf1 = _peak(R[:, g1][:, :, fc[0]])
    assert _peak(R[:, g1][:, :, fc[1]]) / pf1 <= 1e-7 and _peak(R[:, g1][:, :, ud]) / pf1 <= 1e-7
    assert pf1 / _peak(R[:, g1][:, :, w]) >= 3 * (1 - 1e-3)
    pf2 = _peak(R[:, g2][:, :, fc[1]])
    assert _peak(R[:, g2][:, :, fc[0]]) / pf2 <= 1e-7 and _peak(R[:, g2][:, :, ud]) / pf2 <= 1e-7
    assert _peak(R[:, g2][:, :, w]) / pf2 <= 1e-7  # gap ∞
    assert np.all(np.linalg.eigvals(bank.Q.A).real <= -3 + 1e-9)


@pytest.mark.slow
def test_amdsyn_ex6_2c_distances():
    """Example 6.2c: the lateral aircraft LOE models with noise (Bw = I4, Dw = [0 I2], C = 180/π [I2 0]);
    amdsyn(sdeg = -1, poles = [-1], minimal = false): all(diag(MDperf) < 1e-7) and every off-diagonal
    distance ≥ 1 (filters scaled to β_i = min_j≠i ‖R_ij‖∞ = 1)."""
    from fmu_fdi.design import approximate_model_detection_bank

    A = np.array([[-.4492, 0.046, .0053, -.9926], [0, 0, 1, 0.0067], [-50.8436, 0, -5.2184, .722],
                  [16.4148, 0, .0026, -.6627]])
    Bu = np.array([[0.0004, 0.0011], [0, 0], [-1.4161, .2621], [-0.0633, -0.1205]])
    C = 180 / np.pi * np.eye(2, 4)
    Dw = np.hstack([np.zeros((2, 4)), np.eye(2)])
    G = 1 - np.array([[0, 0, 0, .5, .5, .5, 1, 1, 1], [0, .5, 1, 0, .5, 1, 0, .5, 1]]).T
    models = [FDIModel.from_matrices(A, Bu @ np.diag(g), C, Bw=np.eye(4, 6), Dw=Dw, name=f"m{i + 1}")
              for i, g in enumerate(G)]
    bank = approximate_model_detection_bank(models, rdim="all", sdeg=-1, poles=[-1])
    lam = 1j * np.r_[0.0, np.logspace(-3, 3, 600)]
    dist = _detection_distances(bank, models, lam)
    assert np.all(np.diag(dist) < 1e-7), np.diag(dist)
    # ≥ 1 up to the grid's underestimate of an H∞ peak (1e-2 on this grid for poles at -1 and slower)
    assert dist[~np.eye(9, dtype=bool)].min() >= 1 - 1e-2, dist


# ------------------------------------------------------------------------------ test_fdigenspec.jl
BOEING_A = np.array([[-0.4861, 0.000317, -0.5588, 0, -2.04e-6], [0, -0.0199, 3.0796, -9.8048, 8.98e-5],
                     [1.0053, -0.0021, -0.5211, 0, 9.30e-6], [1, 0, 0, 0, 0], [0, 0, -92.6, 92.6, 0]])
BOEING_BU = np.array([
    [-0.1455, -0.1455, -0.1494, -0.1494, -1.2860, 0.0013, 0.0035, 0.0035, 0.0013],
    [0, 0, 0, 0, -0.3122, 0.1999, 0.1999, 0.1999, 0.1999],
    [-0.0071, -0.0071, -0.0074, -0.0074, -0.0676, -0.0004, -0.0004, -0.0004, -0.0004],
    [0] * 9, [0] * 9])
BOEING_C = np.array([[0, 0, 1, 0, 0], [0, -0.0199, 3.0796, -9.8048, 8.98e-5], [0, 0, 0, 1, 0], [1, 0, 0, 0, 0],
                     [0, 0, -92.6, 92.6, 0], [0, 0, 0, 0, 1.0]])
BOEING_DU = np.zeros((6, 9))
BOEING_DU[1, 4:] = [-0.3122, 0.1999, 0.1999, 0.1999, 0.1999]
BOEING_WEAK = np.array([[0, 0, 0, 0, 1], [0, 0, 1, 1, 0], [0, 0, 1, 1, 1], [1, 1, 0, 0, 0], [1, 1, 0, 0, 1],
                        [1, 1, 1, 1, 0], [1, 1, 1, 1, 1]])
BOEING_WEAK_LEAST = [1, 2, 1, 2, 1, 1, 1]
BOEING_STRONG = np.array([[0, 0, 1, 1, 1], [1, 1, 0, 0, 1], [1, 1, 1, 1, 0], [1, 1, 1, 1, 1]])


def boeing747():
    """Linearised Boeing 747 (Varga 2007): 9 inputs, 6 outputs, faults of the first 5 actuators."""
    return ss_model(BOEING_A, BOEING_BU, np.zeros((5, 0)), BOEING_BU[:, :5], BOEING_C, Du=BOEING_DU,
                    Df=BOEING_DU[:, :5])


def test_boeing747_achievable_structures():
    """fdigenspec: 7 weak specifications; 4 strong ones at FDfreq = [0, 1] (FDGainTol = 1e-5)."""
    model = boeing747()
    np.testing.assert_array_equal(achievable_structure(model), BOEING_WEAK)
    np.testing.assert_array_equal(achievable_structure(model, freqs=[0.0, 1.0], FDGainTol=1e-5), BOEING_STRONG)


@pytest.mark.slow
def test_boeing747_every_weak_row_designed_at_least_order():
    """fdichkspec(minimal = true): every weak row is designable with least orders [1, 2, 1, 2, 1, 1, 1];
    issue 17: structured_bank refused 6 of the 7 rows."""
    model = boeing747()
    bank = structured_bank(model, BOEING_WEAK, FDtol=1e-5)
    assert judge(bank, model, BOEING_WEAK, model.fault_names) == []
    assert _orders(bank) == BOEING_WEAK_LEAST


@pytest.mark.slow
def test_boeing747_every_strong_row_designed_at_least_order():
    """fdichkspec(FDfreq = [0, 1], FDGainTol = 1e-5, minimal = true): least orders [1, 1, 1, 1]."""
    model = boeing747()
    bank = structured_bank(model, BOEING_STRONG, freqs=[0.0, 1.0], FDGainTol=1e-5, FDtol=1e-5)
    assert judge(bank, model, BOEING_STRONG, model.fault_names) == []
    np.testing.assert_array_equal(strong_structure(bank, model, [0.0, 1.0], 1e-5), BOEING_STRONG)
    assert _orders(bank) == [1, 1, 1, 1]


@pytest.mark.parametrize("name, build, least", [("Niemann 1998", niemann, [1, 1, 1]),
                                                ("Xiong & Saif 2000 ex. 1", xiong_saif_1, [1, 2, 1]),
                                                ("Xiong & Saif 2000 ex. 2", xiong_saif_2, [1, 1, 1])])
def test_fdichkspec_least_orders(name, build, least):
    """fdigenspec: weak = strong (FDfreq = [0, 1], FDGainTol = 1e-3) = all three rows; fdichkspec
    least orders for the rows [0 1; 1 0; 1 1] as the peer's."""
    model = build()
    rows = np.array([[0, 1], [1, 0], [1, 1]])
    np.testing.assert_array_equal(achievable_structure(model), rows)
    np.testing.assert_array_equal(achievable_structure(model, freqs=[0.0, 1.0], FDGainTol=1e-3), rows)
    bank = structured_bank(model, rows, FDtol=1e-5)
    assert judge(bank, model, rows, model.fault_names) == []
    assert _orders(bank) == least, f"{name}: {_orders(bank)} vs the peer's least orders {least}"


def test_fdigenspec_ex5_4_only_the_full_row():
    """Example 5.4m: S_weak = S_strong (FDfreq = [0, 1]) = [1 1]; fdichkspec: rows [0 1], [1 0] not
    designable (structured_bank must refuse them with DesignError), [1 1] of least order 1."""
    Gu = [(s + 1) / (s - 2), (s + 2) / (s - 3)]
    model = tf_model({"u": [Gu], "d": [[(s - 1) / (s + 2), 0]], "f": [Gu, [0, 1]]})
    assert achievable_structure(model).tolist() == [[1, 1]]
    assert achievable_structure(model, freqs=[0.0, 1.0], FDGainTol=1e-3).tolist() == [[1, 1]]
    for row in ([0, 1], [1, 0]):
        with pytest.raises(DesignError):
            structured_bank(model, [row])
    bank = structured_bank(model, [[1, 1]])
    assert judge(bank, model, [[1, 1]], model.fault_names) == [] and _orders(bank) == [1]


def test_fdigenspec_lecture6_not_strongly_detectable_at_0():
    """Gu = [1/s; 1/s], Gd = [0; s/(s+3)], Gf = [(s+1)/(s+2); 1/(s+2)]: weakly detectable, but not
    strongly at [0, 1] (S_strong empty; fdichkspec(FDfreq = 0) → rdims 0): a design at ω = 0 is a
    DesignError, the weak one is returned."""
    model = tf_model({"u": [[1 / s, 1 / s]], "d": [[0, s / (s + 3)]], "f": [[(s + 1) / (s + 2), 1 / (s + 2)]]})
    assert achievable_structure(model).tolist() == [[1]]
    assert achievable_structure(model, freqs=[0.0, 1.0], FDGainTol=1e-5).shape[0] == 0
    with pytest.raises(DesignError):
        nullspace_design(model, freqs=[0.0], FDGainTol=1e-5)
    gen = nullspace_design(model)
    assert judge(gen, model, [[1]], model.fault_names) == []


def test_fdigenspec_marginal_poles_strong_at_0_and_1():
    """Gf = [1/(s(s²+1)) 1/(s(s²+1)(s+2))] (one output, two faults): S_weak = S_strong (FDfreq = [0, 1])
    = [1 1] and fdichkspec(FDfreq = [0, 1]) designs it: R stable (Q cancels 0 and ±j) and both faults
    strongly visible at 0 and 1."""
    model = tf_model({"f": [[1 / s / (s**2 + 1)], [1 / s / (s**2 + 1) / (s + 2)]]})
    assert achievable_structure(model).tolist() == [[1, 1]]
    assert achievable_structure(model, freqs=[0.0, 1.0], FDGainTol=1e-5).tolist() == [[1, 1]]
    gen = nullspace_design(model, freqs=[0.0, 1.0], FDGainTol=1e-5)
    assert judge(gen, model, [[1, 1]], model.fault_names) == []
    assert strong_structure(gen, model, [0.0, 1.0], 1e-5).tolist() == [[1, 1]]


def test_fdigenspec_marginal_poles_not_strong_at_1():
    """Gf = [1/(s²+1) 1/s]: S_weak = [1 1], S_strong at [0, 1] empty — a design strong at ω = 1 must
    be refused with DesignError (never another exception)."""
    model = tf_model({"f": [[1 / (s**2 + 1)], [1 / s]]})
    assert achievable_structure(model).tolist() == [[1, 1]]
    with pytest.raises(DesignError):
        nullspace_design(model, freqs=[1.0], FDGainTol=1e-5)
