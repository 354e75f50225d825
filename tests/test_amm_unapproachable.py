"""approximate_model_matching refuses a reference no admissible filter approaches better than Q = 0 (issue 17,
approximate audit seeds 26, 240, 270, 282 with ``Mr = I``: ``approximate_matching._unapproachable_reference`` and
``_certified_at_zero_filter``), and designs every reference whose rank bound is below ``||Mr||∞``.

Small constructed plants, judged by numpy on the matrices (nothing of fmu_fdi's analysis): one output y, one known
input u, two faults, one noise input,

    y = f1/(s + 1) + f2/(s + 2) + u/(s + 3) + 0.1 w/(s + 4),

so the filters that decouple u are ``Q = q [1  −1/(s + 3)]`` (q a stable row of as many entries as Mr has rows): one
admissible row, the fault response ``q [1/(s + 1)  1/(s + 2)]`` of rank 1 at every λ. For ``Mr = I₂`` every
admissible error is at least ``σ_2(I) = 1 = ||Mr||∞`` (Weyl), Q = 0's error: refused, the message naming the rank
and the bound. ``Mr`` of rank 1, and ``Mr = diag(1, 0.5)`` (bound σ_2 = 0.5 < 1), are designed, their errors below
Q = 0's by numpy. On five audit seeds whose ``Mr = I`` is refused by the rank bound, ``Mr = [I_r 0]`` (r their
admissible rank) is refused too (amm23): the first r admissible fault columns lose rank at a point of the closed right
half plane, where ``[Mr 0]`` is at distance 1 from every admissible response (maximum modulus; numpy's limit there).
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from fmu_fdi import FDIModel, component_fault
from fmu_fdi.design import approximate_model_matching
from fmu_fdi.errors import DesignError
from fmu_fdi.lti import LTI

A = np.diag([-1.0, -2.0, -3.0, -4.0])
BU = np.array([[0.0], [0.0], [1.0], [0.0]])
BF = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
BW = np.array([[0.0], [0.0], [0.0], [0.1]])
C = np.ones((1, 4))


def _model() -> FDIModel:
    return FDIModel.from_matrices(A, BU, C, np.zeros((1, 1)), Bw=BW, Dw=np.zeros((1, 1)),
                                  faults=[component_fault("f1", BF[:, :1]), component_fault("f2", BF[:, 1:])],
                                  y_names=["y"], u_names=["u"])


def _resp(A_, B_, C_, D_, lam: np.ndarray) -> np.ndarray:
    """numpy: ``C (λI − A)⁻¹ B + D`` at the points ``lam``, shape (points, p, m)."""
    n = A_.shape[0]
    if not n:
        return np.broadcast_to(np.asarray(D_, complex), (lam.size,) + np.shape(D_))
    X = np.linalg.solve(lam[:, None, None] * np.eye(n) - A_, np.broadcast_to(B_, (lam.size,) + B_.shape))
    return C_ @ X + D_


#: numpy's grid: 0 and 4000 log points 1e-3 … 1e4 rad/s (every pole here is at 1 … 4 rad/s and the filter's at
#: most ~1e2: the peak of a smooth error read on 0.2 % steps is low by ≲ 1e-5 relative, below ERR_RTOL)
LAM = 1j * np.r_[0.0, np.logspace(-3, 4, 4000)]
#: reported error against numpy's: the design's reltol 1e-4 plus the grid's 1e-5, with margin
ERR_RTOL = 1e-3


def _numpy_error(Q: LTI, M: LTI, Mr: np.ndarray) -> tuple[float, float]:
    """numpy: the peaks of ``σ_max([Q_y Gf − M Mr,  Q_y Gw])`` (Q's u columns multiply no fault or noise) and of
    ``σ_max(M Mr)`` (Q = 0's error) on LAM, and the largest ``σ_2(M Mr)`` there (the rank-1 bound)."""
    Qy = _resp(Q.A, Q.B, Q.C, Q.D, LAM)[:, :, :1]
    Gf = _resp(A, BF, C, np.zeros((1, 2)), LAM)
    Gw = _resp(A, BW, C, np.zeros((1, 1)), LAM)
    MMr = _resp(M.A, M.B, M.C, M.D, LAM) @ Mr
    E = np.concatenate([Qy @ Gf - MMr, Qy @ Gw], axis=2)
    sv = np.linalg.svd(MMr, compute_uv=False)
    return float(np.max(np.linalg.norm(E, 2, axis=(1, 2)))), float(np.max(sv[:, 0])), float(np.max(sv[:, 1]))


def _admissible_fault_rank(lam: np.ndarray) -> int:
    """numpy: the largest rank over ``lam`` of ``N(λ) [Gf; 0](λ)``, N(λ) an orthonormal basis of the left null space
    of ``[Gu; I](λ)`` (SVD), singular values above 1e-10 of the largest (the gains here are O(1): rounding ~1e-16)."""
    out = 0
    for L in lam:
        Gu = _resp(A, BU, C, np.zeros((1, 1)), np.array([L]))[0]
        Gf = _resp(A, BF, C, np.zeros((1, 2)), np.array([L]))[0]
        U, s, _ = np.linalg.svd(np.vstack([Gu, np.eye(1)]))
        N = U[:, int(np.sum(s > 1e-10 * s[0])):].conj().T
        sv = np.linalg.svd(N @ np.vstack([Gf, np.zeros((1, 2))]), compute_uv=False)
        out = max(out, int(np.sum(sv > 1e-10 * sv[0])) if sv.size and sv[0] > 0 else 0)
    return out


def _figures(msg: str) -> tuple[int, int, float, float]:
    """(rank, i, σ_i(Mr), ||Mr||∞) as the refusal states them."""
    rank = int(re.search(r"normal rank (\d+)", msg).group(1))
    m = re.search(r"σ_(\d+)\(Mr\(λ\)\) = ([0-9.eE+-]+), which reaches \|\|Mr\|\|∞ = ([0-9.eE+-]+)", msg)
    return rank, int(m.group(1)), float(m.group(2)), float(m.group(3))


def test_identity_on_more_faults_than_admissible_rows_is_refused_with_the_rank_bound():
    """< 1 s. ``Mr = I₂`` on two faults with one admissible row: DesignError naming the normal rank (numpy: 1 at 12
    points) and the bound ``σ_2(I) = 1`` reaching ``||I||∞ = 1`` (numpy SVD of I; exact, so to 1e-12). Old code
    (ac7dadb): designed, error 1.0000388 with a note 'cannot be approached' — no DesignError."""
    with pytest.raises(DesignError, match="cannot be approached") as exc:
        approximate_model_matching(_model(), np.eye(2))
    rank, i, bound, norm = _figures(str(exc.value))
    r_np = _admissible_fault_rank(1j * np.logspace(-2, 2, 12))
    assert rank == r_np == 1 and i == r_np + 1
    sv = np.linalg.svd(np.eye(2), compute_uv=False)
    assert abs(bound - sv[r_np]) <= 1e-12 and abs(norm - sv[0]) <= 1e-12


@pytest.mark.parametrize("Mr", [np.array([[1.0, 1.0], [0.5, 0.5]]), np.diag([1.0, 0.5])],
                         ids=["rank-one", "bound-below-norm"])
def test_reference_within_reach_is_designed_below_the_zero_filters_error(Mr):
    """~1-3 s each. A rank-1 Mr (bound σ_2 = 0) and ``diag(1, 0.5)`` (bound σ_2 = 0.5 below ||Mr||∞ = 1) are designed.
    G1 is strictly proper, so the design matches the updated reference ``M Mr``, ``M = 1/(s + 1) I`` (module
    docstring, step 2), and Q = 0's error is ``||M Mr||∞``. numpy, on the returned Q, the plant's matrices and M: the
    error equals the reported one within ERR_RTOL, is at least the rank-1 bound ``sup σ_2(M Mr)`` (Weyl; 1e-9 for
    rounding) and below Q = 0's ``||M Mr||∞`` by more than ERR_RTOL (for diag(1, 0.5): the optimum lies in
    [0.5, 1]; at ω = 0 the first row alone, q = 0.8, has ``||[0.8 − 1, 0.8/2]|| = 0.45`` — below 1)."""
    gen = approximate_model_matching(_model(), Mr)
    err, top, low = _numpy_error(gen.Q, gen.info["M"], Mr)
    assert abs(err - gen.info["error"]) <= ERR_RTOL * err
    assert low * (1 - 1e-9) <= err < top * (1 - ERR_RTOL), (low, err, top)
    assert gen.info["rank_bound"]["rank"] == 1


def test_noise_at_infinity_is_refused_with_its_distance_near_infinity():
    """< 1 s. ``y = f/(s + 1) + u/(s + 3) + w`` (noise with a feedthrough), ``Mr = 1``: one row, one fault — the rank
    bound is 0 — but every admissible Q = q [1  −1/(s + 3)] has the fault and noise response ``q [1/(s + 1), 1]``,
    whose row space at s = jω tends to the noise direction: the distance of ``F = [1 0]`` to it,
    ``d(jω) = (1 − |g_f|²/||g||²)^½`` with ``g = [1/(jω + 1), 1]`` (numpy), tends to 1 = ||Mr||∞, Q = 0's error.
    Refused by ``_unapproachable_reference``'s distance reading at the design grid's highest point, naming it; numpy's
    ``d`` there equals the stated bound within 1e-12 (both are 1 − 1/(2ω²) to rounding). Before amm23 the γ-iteration's
    certified lower bound (its error at infinity, 1) refused it after the iteration; ac7dadb: "the filter is
    numerically zero"."""
    model = FDIModel.from_matrices(np.diag([-1.0, -3.0]), [[0.0], [1.0]], [[1.0, 1.0]], [[0.0]], Bw=[[0.0], [0.0]],
                                   Dw=[[1.0]], faults=[component_fault("f", [[1.0], [0.0]])], y_names=["y"],
                                   u_names=["u"])
    with pytest.raises(DesignError, match="cannot be approached") as exc:
        approximate_model_matching(model, np.eye(1))
    s0, bound, norm = _distance_figures(str(exc.value))
    g = np.array([1.0 / (s0 + 1.0), 1.0])
    d = float(np.sqrt(max(0.0, 1.0 - abs(g[0]) ** 2 / np.sum(np.abs(g) ** 2))))
    assert abs(s0.real) <= 1e-12 * abs(s0) and abs(bound - d) <= 1e-12 and abs(norm - 1.0) <= 1e-12
    assert bound >= 1.0 - 2e-8


def test_the_iterations_certificate_refuses_at_the_zero_filters_error():
    """< 1 s. ``_certified_at_zero_filter``'s rule on the γ-iteration's figures (the cases it catches — a refused level
    within HINF_F_RTOL of ||F||∞ — are now all caught before it, above): a lower bound at ||F||∞ refuses, one below it
    by more than HINF_F_RTOL does not, and no lower bound never does."""
    from fmu_fdi.design.problems.approximate_matching import HINF_F_RTOL, _certified_at_zero_filter

    with pytest.raises(DesignError, match="certifies every admissible filter's error at least 1"):
        _certified_at_zero_filter({"lower_bound": 1.0, "fnorm": 1.0})
    _certified_at_zero_filter({"lower_bound": 1.0 - 2 * HINF_F_RTOL, "fnorm": 1.0})
    _certified_at_zero_filter({"fnorm": 1.0})


def _distance_figures(msg: str) -> tuple[complex, float, float]:
    """(the point s0, the bound d(s0), ||Mr||∞) as a refusal by the distance reading states them."""
    m = re.search(r"at s = ([0-9.eE+-]+[+-][0-9.eE+-]+j) .* is at distance ([0-9.eE+-]+) .*which reaches "
                  r"\|\|Mr\|\|∞ = ([0-9.eE+-]+)", msg)
    assert m, msg
    return complex(m.group(1)), float(m.group(2)), float(m.group(3))


def _numpy_distance(model, rows: int, s: complex) -> float:
    """numpy: ``d(s) = ||F (I − P)||``, F = [I_rows 0] on the fault and noise columns, P the orthogonal projector onto
    the row space of ``N(s) [Gf Gw; 0 0](s)``, N(s) an orthonormal basis of the left null space of ``[Gu Gd; I 0](s)``
    (SVD, singular values above 1e-10 of the largest; the plant's values by test_approximate_random's
    ``_ge_values``). Away from the plant's poles and N's zeros this row space is that of every admissible filter's
    ``Q0 [Gf Gw; 0 0](s)``; P from the singular vectors above 1e-10 of the largest singular value."""
    from test_approximate_random import _cols, _ge_values

    cols = _cols(model)
    fw = np.r_[np.concatenate([cols[f.name] for f in model.faults]), np.arange(cols["w"].start, cols["w"].stop)]
    Gk = _ge_values(model, np.array([s]))[0]
    nud = model.nu + model.nd
    U, sv, _ = np.linalg.svd(Gk[:, :nud])
    N = U[:, int(np.sum(sv > 1e-10 * sv[0])):].conj().T
    _, sg, Vh = np.linalg.svd(N @ Gk[:, fw])
    V = Vh[:int(np.sum(sg > 1e-10 * sg[0]))].conj().T
    F = np.zeros((rows, fw.size))
    F[:, :rows] = np.eye(rows)
    return float(np.linalg.norm(F - (F @ V) @ V.conj().T, 2))


@pytest.mark.parametrize("seed, rank", [(2, 4), (6, 1), (8, 2), (12, 3), (16, 3)])
def test_audit_seeds_matching_their_admissible_rows_are_refused_where_the_rows_lose_rank(seed, rank):
    """~1 s each. Approximate audit seeds 2, 6, 8, 12, 16 with ``Mr = [I_r 0]``, r their admissible fault rank (numpy:
    test_audit_seeds18._admissible_fault_rank at 40 grid points; the rank bound σ_{r+1}(Mr) is 0). The first r fault
    columns of the admissible fault response lose rank at a point s0 of the closed right half plane (the fault-only
    plant modes s = 1 of seeds 2, 6, 12, ±2j of seed 8, 0 of seed 16; non-minimum-phase zeros), so ``[Mr 0]`` is at
    distance 1 = ||Mr||∞ from every ``X Q0 [Gf Gw; 0 0](s0)`` and, by the maximum modulus principle, every admissible
    filter's H∞ error is at least 1, Q = 0's: refused by the distance reading, naming s0. numpy judges the premise
    independently: s0 lies in the closed right half plane, and ``d(s)`` (:func:`_numpy_distance`, from the model's
    matrices) at ``s = s0 + δ·e^{jφ}`` inside it (along the axis for s0 on it) tends to 1 as δ → 0 — at δ = 1e-6 … 1e-4
    (relative to max(1, |s0|)) ``1 − d`` falls at least 5-fold per decade and is ≤ 1e-3 at δ = 1e-6 (a limit that is
    1 − O(δ); d is continuous at s0 where G1 keeps its rank, and is 1 there). Old code (7bc7918): designed, errors
    1.0000133, 1.0000219, 1.0000292, 1.0000230, 1.0000292 (numpy judge_amm agreed) against Q = 0's 1 with a note —
    filters no better than none."""
    from test_approximate_random import _points, noisy_case
    from test_audit_seeds18 import _admissible_fault_rank

    model = noisy_case(seed)
    lam = _points(model)
    assert _admissible_fault_rank(model, lam[:: max(1, lam.size // 40)]) == rank < model.nf
    Mr = LTI.static(np.eye(model.nf)[:rank], model.dt)
    with pytest.raises(DesignError, match="cannot be approached") as exc:
        approximate_model_matching(model, Mr)
    s0, bound, norm = _distance_figures(str(exc.value))
    assert bound >= 1.0 - 2e-8 and abs(norm - 1.0) <= 1e-12
    scale = max(1.0, abs(s0))
    on_axis = abs(s0.real) <= 1e-9 * scale
    assert s0.real >= 0.0
    gaps = []
    for delta in (1e-4, 1e-5, 1e-6):
        s = s0 + (1j if on_axis else 1.0) * delta * scale
        gaps.append(1.0 - _numpy_distance(model, rank, s))
    assert gaps[-1] <= 1e-3 and all(b <= a / 5 + 1e-12 for a, b in zip(gaps, gaps[1:])), gaps



@pytest.mark.parametrize("seed", [1, 11, 12, 19])
def test_the_distance_bound_is_below_every_returned_filters_error_at_its_point(seed):
    """~1-4 s each. benchmarks/ammp_random_set.py's H∞ seeds whose distance reading is positive (continuous 12; discrete
    1, 11, 19, two at points off the unit circle): the returned filter is admissible, so at the reported point λ* the
    numpy value of its error ``Q(λ*) [Gf Gw; 0 0](λ*) − [Mr 0](λ*)`` (the reference without M: at a point, ``Q G1``
    is an ``X G1``) has norm at least ``info['rank_bound']['bound']`` (the distance is a minimum over every X; 1e-9
    relative for numpy's rounding, gains ~1-10). A bound that over-read would fail here. Measured with the design:
    bounds 3.842543, 5.19502, 0.801031, 2.77419 against returned errors 3.843, 5.195, 0.8012, 3.872."""
    from test_approximate_random import _cols, _ge_values
    from test_synthesis_ammp import _random_case
    from test_synthesis_random import _freqresp

    model, Mr = _random_case(seed)
    gen = approximate_model_matching(model, Mr)
    rb = gen.info["rank_bound"]
    assert rb["reading"] == "distance" and rb["bound"] > 0
    lam = np.array([complex(rb["at"])])
    inside = abs(lam[0]) >= 1 - 1e-12 if model.dt else lam[0].real >= 0
    assert inside
    cols = _cols(model)
    fw = np.r_[np.concatenate([cols[f.name] for f in model.faults]), np.arange(cols["w"].start, cols["w"].stop)]
    Q = gen.Q
    E = _freqresp(Q.A, Q.B, Q.C, Q.D, lam)[0] @ _ge_values(model, lam)[0][:, fw]
    E[:, :model.nf] -= _freqresp(Mr.A, Mr.B, Mr.C, Mr.D, lam)[0]
    assert np.linalg.norm(E, 2) >= rb["bound"] * (1 - 1e-9), (np.linalg.norm(E, 2), rb["bound"])
