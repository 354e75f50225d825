"""State-space (pencil) left null-space basis (design/toolkit/pencil.py, Varga's glnull) and its use as the
last fallback of nullspace_design/structured_bank (issue 13, bullet 2).

Properties any correct basis must have, checked on seeded random models (tests/synthesis_models.py):
``Nl(λ) [Gu Gd; I 0](λ) = 0`` at random points, ``rank Nl = p - rank Gd``, stable poles with the
requested margin, order = Σ left minimal indices, and those indices equal the degrees of the
minimal polynomial basis where that one is accurate (an independent computation).
"""
import numpy as np
import pytest

from fmu_fdi import DesignError, nullspace_design, structured_bank
from fmu_fdi.design.toolkit._basis import minimal_basis, normal_rank
from fmu_fdi.design.toolkit.pencil import conjugate_partition, controllable_staircase, pencil_basis
from fmu_fdi.design.toolkit.postconditions import DEC_TOL, check_generator
from fmu_fdi.linalg import EPS
from synthesis_models import contract, random_model, random_structure

# well conditioned (polynomial basis accurate) and badly scaled, continuous and discrete, nd = 0..2
SEEDS = [0, 1, 4, 5, 6, 7, 11, 18]


def _points(model, count=4, seed=3):
    rng = np.random.default_rng(seed)
    if model.dt:
        return np.exp(1j * rng.uniform(0.3, 2.8, count)) * rng.uniform(0.6, 0.95, count)
    return rng.uniform(0.3, 2.0, count) + 1j * rng.uniform(0.3, 2.0, count)


def _G(model, lam):
    """``[Gu Gd; I 0]`` at λ."""
    G = model.lti("u", "d").evalfr(lam)
    return np.vstack([G, np.hstack([np.eye(model.nu), np.zeros((model.nu, model.nd))])])


@pytest.mark.parametrize("seed", SEEDS)
def test_basis_annihilates_has_full_rank_and_is_stable(seed):
    model = random_model(seed)
    pb = pencil_basis(model)
    N = pb.N
    k = model.ny - (normal_rank(model.lti("d")) if model.nd else 0)
    assert N.p == k and N.m == model.ny + model.nu
    # backward-stable orthogonal deflation: N annihilates a realisation perturbed by ~(n+1)·eps relative to
    # ||[A B; C D]||; the pole-moving feedback multiplies that by its norm; 1e3 headroom as in linalg.default_rtol
    tol = 1e3 * (model.n + 1) * EPS * max(1.0, pb.info["feedback_norm"])
    for lam in _points(model):
        Nv, Gv = N.evalfr(lam), _G(model, lam)
        assert np.linalg.norm(Nv @ Gv, 2) <= tol * np.linalg.norm(Nv, 2) * np.linalg.norm(Gv, 2)
        # rank p - rank Gd: the rows are independent (sqrt(eps): the accuracy of a rank from values)
        sv = np.linalg.svd(Nv / np.linalg.norm(Nv, axis=1, keepdims=True), compute_uv=False)
        assert sv[-1] > np.sqrt(EPS) * sv[0]
    poles = N.poles()
    assert np.all(np.abs(poles) < 1.0) if model.dt else np.all(poles.real < 0)
    # order = Σ left minimal indices; the realisation of [Gu Gd] is minimal, so this is a minimal basis
    assert N.n == sum(pb.degrees) == pb.info["order"]


@pytest.mark.parametrize("seed", [0, 1, 4, 6, 11])
def test_minimal_indices_match_polynomial_basis_degrees(seed):
    """Where the parity (polynomial) basis is accurate, its row degrees are the left minimal indices."""
    model = random_model(seed)
    assert pencil_basis(model).degrees == minimal_basis(model).degrees


@pytest.mark.parametrize("seed, sdeg", [(6, -2.0), (1, 0.5)])
def test_stability_degree_and_given_poles(seed, sdeg):
    """Eigenvalues outside the region Re < sdeg (|z| < sdeg) move there, the given poles first."""
    model = random_model(seed)
    given = [0.2, 0.3] if model.dt else [-3.0, -4.0]
    pb = pencil_basis(model, poles=given, sdeg=sdeg)
    poles = pb.N.poles()
    assert pb.info["moved_poles"] >= 2
    # eigenvalues of a Schur-assigned block: eps·||F||·cond; 1e-6 covers these orders
    for g in given:
        assert np.min(np.abs(poles - g)) < 1e-6
    assert np.all(np.abs(poles) <= sdeg + 1e-6) if model.dt else np.all(poles.real <= sdeg + 1e-6)
    tol = 1e3 * (model.n + 1) * EPS * max(1.0, pb.info["feedback_norm"])
    for lam in _points(model):
        Nv, Gv = pb.N.evalfr(lam), _G(model, lam)
        assert np.linalg.norm(Nv @ Gv, 2) <= tol * np.linalg.norm(Nv, 2) * np.linalg.norm(Gv, 2)


def test_staircase_indices():
    """A chain of integrators driven by one input plus a free second input: indices (0, 3)."""
    a = np.diag([1.0, 1.0], -1)
    b = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    T, taus = controllable_staircase(a, b, 1e-12)
    assert taus == [1, 1, 1] and conjugate_partition(taus, 2) == [0, 3]
    assert np.allclose(T.T @ T, np.eye(3))


# formerly "refused*" calls of benchmarks/synthesis_random_set.py (achievable by the rank test, refused
# before the pencil basis): (seed, what)
REFUSED_BEFORE = [(3, "bank"), (6, "bank"), (7, "bank"), (15, "bank"), (22, "bank"), (29, "nullspace"),
                  (33, "bank"), (39, "bank")]


def _row_model(model, row, names):
    """The model a structure row is designed on: the faults with s_j = 0 are unknown inputs."""
    return model.with_disturbances([nm for nm, s in zip(names, row) if not s])


def _pointwise_leak(Q, model, num=300):
    """``max_λ ||Q(λ) Ge_ud(λ)|| / (||Q(λ)|| ||Ge_ud(λ)||)`` per residual on a grid: relative to |G|
    *at each sample*, not to its peak (the post-condition's measure), so that a row which only
    makes the leak small where |G| is large shows it where |G| is small."""
    from fmu_fdi.design.toolkit.postconditions import _values
    from fmu_fdi.lti import frequency_grid

    om = frequency_grid([model.lti(), Q], num=num)
    lam = np.exp(1j * om * model.dt) if model.dt else 1j * om
    Ge, Qv = _values(model.augmented(), lam), _values(Q, lam)
    ok = np.all(np.isfinite(Ge), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))
    sl = model.group_slices()
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    G, Qv = Ge[ok][:, :, ud], Qv[ok]
    out = []
    for i in range(Q.p):
        R = np.einsum("kq,kqc->kc", Qv[:, i], G)
        out.append(float(np.max(np.linalg.norm(R, axis=1)
                                / (np.linalg.norm(Qv[:, i], axis=1) * np.linalg.norm(G, 2, axis=(1, 2))))))
    return out


@pytest.mark.parametrize("seed, what", [REFUSED_BEFORE[i] for i in (1, 2, 5, 6)])
def test_formerly_refused_designs_keep_their_contract(seed, what):
    """Contract, and exactness: before, these rows came from the frequency-sampled fallback at orders
    9-18 below the smallest left minimal index (13-26) — approximate, pointwise leaks up to 1e-2. Now
    every row is exact: its order is at least the smallest left minimal index of its own decoupling
    problem, and a pencil row (orthogonal reductions only) decouples to 1e-9 *pointwise* — the
    rounding of an order-30 reduction (~1e-13, see test_pencil_basis_alone_decouples_to_rounding) with
    the grid's conditioning as headroom; an approximate row of the same order would show ≥ 1e-5."""
    model = random_model(seed)
    S = random_structure(model, seed)
    names = model.fault_names
    if what == "bank":
        gen = structured_bank(model, S)
        assert contract(gen, model, S, names) == []
        rows = list(zip(gen.members, S))
        assert gen.info["decoupling_kinds"] == ["exact"] * len(S)
    else:
        gen = nullspace_design(model)
        assert contract(gen, model) == []
        rows = [(gen, [1] * len(names))]
    pc = gen.info["postconditions"]
    assert pc["decoupling"] <= DEC_TOL and pc["structure_leak"] <= DEC_TOL and "failures" not in pc
    for g, row in rows:
        mi = _row_model(model, row, names)
        assert g.info["decoupling_kind"] == "exact"
        assert g.Q.n >= min(pencil_basis(mi).degrees)
        if g.info["basis"] == "pencil":
            assert max(_pointwise_leak(g.Q, mi)) <= 1e-9


@pytest.mark.parametrize("seed, what", REFUSED_BEFORE)
def test_pencil_basis_alone_decouples_to_rounding(seed, what):
    """Forced pencil basis on every formerly refused model: the first structure row (the hardest,
    most faults decoupled) or the detector decouples to 1e-9 (the rounding of an orthogonal
    reduction of an order-30 realisation, ~1e-13, with the grid's conditioning as headroom)."""
    model = random_model(seed)
    names = model.fault_names
    if what == "bank":
        row = random_structure(model, seed)[0]
        ignore = [nm for nm, s in zip(names, row) if not s]
        keep = [nm for nm, s in zip(names, row) if s]
        mi = model.with_disturbances(ignore)
        mi = mi._replace(faults=[f for f in mi.faults if f.name in keep])
    else:
        mi = model
    gen = nullspace_design(mi, basis="pencil")
    # 1e-9 is rounding relative to |Q||Ge| (contract(), the issue-13 measure this docstring means);
    # the judge of issue 17 (absolute on the unit-gain row) holds at its default tolerance
    assert contract(gen, mi, leak_tol=1e-9) == [] and gen.info["basis"] == "pencil"
    assert check_generator(gen, block=True)["decoupling"] <= DEC_TOL
    # not least order, but never above the basis' McMillan degree Σ indices
    assert gen.Q.n <= sum(gen.info["left_minimal_indices"])
    assert gen.Q.is_stable()


def test_basis_option_is_validated():
    from fmu_fdi import DesignError

    with pytest.raises(DesignError, match="basis must be"):
        nullspace_design(random_model(11), basis="kronecker")


def test_polynomial_basis_is_explicit_and_never_a_fallback():
    """n = 29: the polynomial (parity) basis, chosen explicitly, breaks the judge and is refused —
    nothing falls back to it, and it falls back to nothing (issue 17: one core); 'auto' is the exact
    pencil row at the smallest left minimal index.
    (The judge is absolute on the normalised form; that row's residual moves with u far more than
    1e-7 times its weakest fault.)"""
    model = random_model(29)
    import warnings

    import scipy.linalg as sla

    # and refused quietly: the row scaling reads R_f = Q·Gf point by point, not from the order-38 series
    # realisation (non-minimal, singular at 96 of 202 grid points: a LinAlgWarning beside the result)
    with warnings.catch_warnings():
        warnings.simplefilter("error", sla.LinAlgWarning)
        with pytest.raises(DesignError, match=r"decoupling.*leak [0-9.e-]+ (\(± [0-9.e-]+\) )?× the weakest fault"):
            nullspace_design(model, basis="polynomial")
    # basis='auto' is the exact pencil row: a simple row at the smallest index (the least order of any exact row)
    auto = nullspace_design(model)
    assert auto.info["basis"] == "pencil" and auto.info["decoupling_kind"] == "exact"
    assert auto.Q.n == min(auto.info["left_minimal_indices"]) and "replaces" not in auto.info
    assert max(_pointwise_leak(auto.Q, model)) <= 1e-9


@pytest.mark.parametrize("seed", [0, 4, 20, 29])
def test_simple_basis_rows_have_their_own_index(seed):
    """A simple basis (Type 1 minimum dynamic covers of each row by the others): row i alone has McMillan
    degree ν_i (the left minimal indices), annihilates [Gu Gd; I 0], is stable, and together the rows keep
    rank p - rank Gd (they are a basis, not k copies of one row)."""
    from fmu_fdi.design.toolkit.pencil import simple_rows

    model = random_model(seed)
    pb = pencil_basis(model)
    rows = simple_rows(pb, model.dt)
    assert [nu for _, nu, _ in rows] == pb.degrees and [N.n for N, _, _ in rows] == pb.degrees
    for N, _, cond in rows:
        assert N.is_stable()
        # as above, with the cover's non-orthogonal transformations and feedback (cond) as the amplification
        tol = 1e3 * (model.n + 1) * EPS * max(1.0, pb.info["feedback_norm"], cond)
        for lam in _points(model):
            Nv, Gv = N.evalfr(lam), _G(model, lam)
            assert np.linalg.norm(Nv @ Gv) <= tol * np.linalg.norm(Nv) * np.linalg.norm(Gv, 2)
    for lam in _points(model, 2):
        Nv = np.vstack([N.evalfr(lam) for N, _, _ in rows])
        sv = np.linalg.svd(Nv / np.linalg.norm(Nv, axis=1, keepdims=True), compute_uv=False)
        assert sv[-1] > np.sqrt(EPS) * sv[0]


@pytest.mark.parametrize("seed", [20, 29])
def test_pencil_row_is_least_order(seed):
    """Several basis rows (seed 20: indices [9, 9, 9]; 29: [14, 14]), formerly a pencil row of order 27 / 28:
    every exact row has order ≥ the smallest left minimal index (each null row is a polynomial combination
    of the minimal basis rows, predictable degree property), so a returned order equal to it is least
    order; the row decouples pointwise to 1e-9 (the rounding of order-30 orthogonal reductions, ~1e-13,
    with the cover's transformations and the grid's conditioning as headroom)."""
    model = random_model(seed)
    gen = nullspace_design(model)
    assert contract(gen, model) == []
    assert gen.info["basis"] == "pencil" and gen.info["decoupling_kind"] == "exact"
    assert gen.Q.n == min(pencil_basis(model).degrees) == min(gen.info["left_minimal_indices"])
    assert max(_pointwise_leak(gen.Q, model)) <= 1e-9
    forced = nullspace_design(model, basis="pencil")
    assert forced.Q.n == gen.Q.n and max(_pointwise_leak(forced.Q, model)) <= 1e-9


@pytest.mark.parametrize("weak", [1e-3, 1e-7])
def test_weakly_controllable_bad_mode_is_placed_accurately(weak):
    """A discrete single-input pair whose bad eigenvalue 48 has controllability ``|wᵀb| = weak`` (w its unit left
    eigenvector), rotated by a fixed random orthogonal matrix so that every entry is dense; kept eigenvalues 0.9,
    0.8, 0.5, -0.3, target 0.2. (Random seed 207's w-decoupling row: λ = 48.04, |wᵀb| = 2.07e-4.)

    Gain: every F with a + bF stable has ``‖F‖·κ(V) ≥ dist(48, Λ(a + bF))/|wᵀb| ≥ 47/weak`` (pencil.schur_feedback's
    docstring): no method pays less at κ = 1; the Schur step's minimum-norm gain is exactly ``|0.2 − 48|/|wᵀb|``
    (asserted to 1e-6 relative: the rounding of a 1 × 1 division and of wᵀb from numpy's eig).

    Accuracy, judged in closed form: with one input ``H_F(λ) = H(λ)·p(λ)/p_F(λ)`` (``p``, ``p_F`` the open and
    closed loop characteristic polynomials, the latter the kept eigenvalues and the target), evaluated on the
    ORIGINAL data by numpy. In the Schur coordinates the realisation is backward stable: exact for the data perturbed
    by eps·‖a‖ (the orthogonal reductions) and by ≤ 2·eps·‖b‖‖F‖ in the moved column (the update's rounding; its
    diagonal entry is the target itself), so H_F is off by a condition number times eps·‖b‖‖F‖ — first order in
    the gain (measured: 3.8e-3 and 2.5e-3 of it at weak = 1e-3, 1e-7); asserted ≤ n·eps·‖b‖‖F‖ relative to H_F's
    peak. Formed in the original coordinates (``a + bF``, entries ‖b‖‖F‖ ≈ 1e9 at weak = 1e-7) the eigenvalues come
    out of cancellation, an error of second order in the gain (κ of the closed loop grows with F): asserted to miss
    by more than 1e-4 there at weak = 1e-7 (measured 1.0: the test's sensitivity); at weak = 1e-3 3.3e-6."""
    from fmu_fdi.design.toolkit.pencil import assign_poles, schur_feedback

    rng = np.random.default_rng(5)
    kept, lam0, t = np.array([0.9, 0.8, 0.5, -0.3]), 48.0, 0.2
    n = kept.size + 1
    a0 = np.diag(np.r_[kept, lam0]) + np.triu(rng.standard_normal((n, n)), 1) * 0.5  # 48 last: span(e1..e4) kept
    w = np.linalg.svd(a0 - lam0 * np.eye(n))[0][:, -1]  # unit left eigenvector of 48
    b0 = rng.standard_normal(n)
    b0 = b0 - w * (w @ b0) + weak * w
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    a, b, c = Q @ a0 @ Q.T, (Q @ b0)[:, None], rng.standard_normal((1, n))
    good = lambda re, im: np.hypot(re, im) <= 0.999  # noqa: E731
    T, Z, Fz, moved = schur_feedback(a, b, 1.0, lambda bad: np.full(bad.size, t), good)
    F = Fz @ Z.T
    assert moved == 1
    assert np.allclose(Z.T @ Z, np.eye(n), atol=1e-14) and np.allclose(np.tril(T, -2), 0.0)
    np.testing.assert_allclose(F, assign_poles(a, b, 1.0, lambda bad: np.full(bad.size, t), good)[0], rtol=0, atol=0)
    assert np.linalg.norm(F) == pytest.approx(abs(t - lam0) / weak, rel=1e-6)
    ev = np.linalg.eigvals(T)
    assert np.all(np.abs(ev) <= 0.999), ev
    # kept to a few eps·‖a‖ (the kept blocks are only reordered: dtrsen's backward error) and the target exact
    assert all(np.min(np.abs(ev - k)) <= 1e-12 * np.linalg.norm(a0) for k in np.r_[kept, t]), ev
    pts = np.exp(1j * np.linspace(0.05, np.pi - 0.05, 120))

    def H(A, B, C, z):
        return np.array([(C @ np.linalg.solve(zz * np.eye(A.shape[0]) - A, B))[0, 0] for zz in z])

    exact = H(a, b, c, pts) * np.array([np.prod(z - np.r_[kept, lam0]) / np.prod(z - np.r_[kept, t]) for z in pts])
    peak = np.max(np.abs(exact))
    err_schur = np.max(np.abs(H(T, Z.T @ b, c @ Z, pts) - exact)) / peak
    assert err_schur <= n * EPS * np.linalg.norm(b) * np.linalg.norm(F), err_schur
    if weak <= 1e-6:
        err_orig = np.max(np.abs(H(a + b @ F, b, c, pts) - exact)) / peak
        assert err_orig > 1e-4, err_orig


def test_random_seed207_row_decouples_noise_exactly():
    """Random seed 207 (discrete, n = 13, noise w), row [1 1 0 1 0]: the one row that decouples w as well has a
    pencil-basis pole at 48.04 of controllability |wᵀb| = 2.07e-4, so moving it takes a feedback of norm ≥ 2.3e5
    whatever the method or targets (pencil.schur_feedback). Formed as ``a + bF`` in the basis' coordinates that
    row leaked 1.9e-6 … 2.6e-6 of its weakest fault gain, and the design fell back to attenuating w
    (``info['noise_decoupling_refused']``); realised in the closed loop's Schur coordinates it is designed with w
    decoupled exactly, and the independent numpy judge of tests/test_synthesis_random.py, told that w is
    decoupled, finds nothing (u, d, w and the excluded faults ≤ 1e-7 of the weakest required fault's peak, R stable
    by PBH)."""
    from fmu_fdi.design.problems.achievable import achievable_structure
    from test_synthesis_random import judge, random_case

    model, row = random_case(207), [1, 1, 0, 1, 0]
    assert row in np.asarray(achievable_structure(model)).tolist()
    gen = structured_bank(model, [row])
    info = gen.members[0].info
    assert info.get("noise") == "decoupled exactly" and "noise_decoupling_refused" not in info, info.get("noise")
    assert judge(gen, model, [row], model.fault_names, w_decoupled=True) == []
