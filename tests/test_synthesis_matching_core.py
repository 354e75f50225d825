"""model_matching on the pencil core (design/toolkit/least_solve.py), judged independently.

Every returned filter is evaluated here by numpy solves of ``(λI − A) x = B`` on the model's and the
filter's own matrices — at points the design never sees: off the imaginary axis / unit circle
(``λ = σ + jω`` with σ ≠ 0, where a rational identity cannot hold by accident of a frequency grid).
Least order is argued independently of the code: by uniqueness of the solution (one output, no
freedom) and a hand count of its denominator's degree, or by the polynomial null-space construction
stated in the test.
"""
import control as ct
import numpy as np
import pytest

from fmu_fdi import DesignError, FDIModel, component_fault
from fmu_fdi.design.problems.matching import model_matching
from fmu_fdi.lti import LTI

# points off the stability boundary, none a pole or zero of the examples (continuous; discrete below)
LAM_C = np.array([0.31 + 1.7j, -0.45 + 0.2j, 1.3 - 2.9j, 0.07 + 11.0j, -3.7 + 0.9j, 2.2 + 0.0j])
LAM_D = np.array([0.3 + 0.8j, -0.55 + 0.1j, 1.2 - 0.4j, 0.05 + 0.3j, 0.9 + 0.0j])


def fr(A, B, C, D, lam):
    """``C (λI − A)^{-1} B + D`` by numpy solves: (K, p, m)."""
    A, B, C, D = (np.atleast_2d(np.asarray(X, float)) for X in (A, B, C, D))
    n = A.shape[0]
    out = np.empty((lam.size, D.shape[0], D.shape[1]), complex)
    for k, l in enumerate(lam):
        out[k] = D + (C @ np.linalg.solve(l * np.eye(n) - A, B.reshape(n, -1)) if n else 0.0)
    return out


def residual_map(model, Q, lam):
    """``Q [Gu Gd Gf; I 0 0]`` at the points, from the matrices: (K, rows, mu + md + mf)."""
    B = np.hstack([model.Bu, model.Bd, model.Bf])
    D = np.hstack([model.Du, model.Dd, model.Df])
    G = fr(model.A, B, model.C, D, lam)
    low = np.zeros((lam.size, model.nu, B.shape[1]))
    low[:, :, :model.nu] = np.eye(model.nu)
    return fr(Q.A, Q.B, Q.C, Q.D, lam) @ np.concatenate([G, low], axis=1)


# rounding of order ≤ 3 realisations of O(1) data evaluated at O(1) points: eps · 1e3
TOL = 1e-12 * 1e3


def _siso_u_f(dt=0.0):
    """y = Gu u + Gf f with Gu = 1/(λ − a), Gf = 1/(λ − b): (a, b) = (−1, −2), or (0.5, 0.2) discrete."""
    a, b = (0.5, 0.2) if dt else (-1.0, -2.0)
    return FDIModel.from_matrices(np.diag([a, b]), [[1.0], [0.0]], [[1.0, 1.0]],
                                  faults=[component_fault("f", [[0.0], [1.0]], [[0.0]])], dt=dt), a, b


@pytest.mark.parametrize("dt", [0.0, 0.1])
def test_unique_solution_has_its_hand_counted_degree(dt):
    """One output, one u, one f: ``[Gu Gf; 1 0]`` is square and invertible, so the solution of
    ``Q Ge = [0 Mr]`` is unique: ``Q = Mr/Gf · [1, −Gu] = (λ−b)/(λ−c) · [1, −1/(λ−a)]`` for
    ``Mr = 1/(λ − c)`` — denominator ``(λ−c)(λ−a)``, McMillan degree 2 (no cancellation: a, b, c
    distinct). So the least order is 2 and the row is exactly this one."""
    model, a, b = _siso_u_f(dt)
    c = 0.7 if dt else -3.0
    Mr = LTI([[c]], [[1.0]], [[1.0]], [[0.0]], dt)
    gen = model_matching(model, Mr)
    assert gen.info["row_orders"] == [2] and gen.Q.n == 2
    lam = LAM_D if dt else LAM_C
    want = np.stack([(lam - b) / (lam - c), -(lam - b) / ((lam - c) * (lam - a))], axis=1)[:, None, :]
    Qv = fr(gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D, lam)
    assert np.abs(Qv - want).max() <= TOL * np.abs(want).max()
    R = residual_map(model, gen.Q, lam)
    assert np.abs(R[:, :, 0]).max() <= TOL and np.allclose(R[:, 0, 1], 1 / (lam - c), rtol=TOL, atol=0)


def _nonminimum_least_row():
    """Faults only, two outputs: Gf = [−(s−1); −(s+2)(s²+3s+1)]/den, Mr = (s+2)/den, den = (s+1)(s+4)(s+5).

    The column ``n = [−(s−1), −(s+2)(s²+3s+1), s+2]`` is the cross product of ``P1 = [s+2, 0, s−1]``
    and ``P2 = [0, 1, s²+3s+1]``: ``{P1, P2}`` is a minimal polynomial basis of the null rows of ``n``
    (row-reduced: leading rows [1 0 1], [0 0 1]; coprime entries), degrees 1 and 2. The only null rows
    of degree ≤ 1 with a nonzero last entry are multiples of P1, so the least-order solution is unique,
    ``Q = −[s+2, 0]/(s−1)`` — order 1, unstable. A stable one of order 2 exists:
    ``(−(3/5)s − 7/5) P1 + (8/5) P2`` has last entry ``(s+1)(s+3)``."""
    s = ct.tf("s")
    den = (s + 1) * (s + 4) * (s + 5)
    Gf = ct.tf([[(-(s - 1) / den).num[0][0]], [(-(s + 2) * (s**2 + 3 * s + 1) / den).num[0][0]]],
               [[den.num[0][0]], [den.num[0][0]]])
    model = FDIModel.from_control(ct.ss(Gf), f=[0])
    return model, LTI.from_control(ct.ss((s + 2) / den))


def test_unstable_least_order_row_gives_a_stable_row_of_the_next_order():
    """Without updating the least-order row (pole +1) is not admissible: the stable solution of the
    core (left inverse of the basis' Mr-column) has order 2 — the least stable order by the
    construction above — and matches Mr exactly (numpy, off-axis points)."""
    model, Mr = _nonminimum_least_row()
    gen = model_matching(model, Mr)
    assert gen.info["row_methods"] == ["stable solution"] and gen.Q.n == 2
    assert gen.info["left_minimal_indices"] == [[1, 2]]
    assert np.all(gen.Q.poles().real < 0)
    R = residual_map(model, gen.Q, LAM_C)
    want = fr(Mr.A, Mr.B, Mr.C, Mr.D, LAM_C)
    assert np.abs(R - want).max() <= TOL * np.abs(want).max()


@pytest.mark.parametrize("kw, poles", [(dict(sdeg=-2.0), [-2.0, -2.0]), (dict(sdeg=-3.0), [-3.0, -3.0]),
                                       (dict(poles=[-2.0, -3.0]), [-3.0, -2.0])])
def test_least_stable_order_with_the_requested_poles(kw, poles):
    """The same example with poles/sdeg: by the construction above every order-2 null row
    ``p1 P1 + c2 P2`` (deg p1 ≤ 1) has last entry ``(a + c2) s² + (b − a + 3 c2) s + (c2 − b)`` — an invertible
    linear map of (a, b, c2), so any degree-2 denominator, i.e. any two poles: the least stable order is 2 and
    its poles are free. The core's stable left inverse gave order 4 here (a pole −0.41 kept from the basis'
    Mr-column); the stable cover of the least-order row by the null-space basis of Gf gives order 2 with the
    requested poles. Judged by numpy at off-axis points (exact match) and the poles."""
    model, Mr = _nonminimum_least_row()
    gen = model_matching(model, Mr, **kw)
    assert gen.Q.n == 2 and gen.info["row_methods"] == ["least stable order"]
    # a double pole is computed to ~sqrt(eps) (its eigenvalues split by ±sqrt(eps·||A||)): 1e-6
    assert np.allclose(np.sort(gen.Q.poles().real), np.sort(poles), atol=1e-6)
    R = residual_map(model, gen.Q, LAM_C)
    want = fr(Mr.A, Mr.B, Mr.C, Mr.D, LAM_C)
    assert np.abs(R - want).max() <= TOL * np.abs(want).max()


def test_unstable_least_order_row_with_updating_factor():
    """updating=True: ``[Q  m Mr] = m [Q0  Mr]`` with m moving only the pole +1 of the least row, to
    sdeg = −2: ``m = (s−1)/(s+2)`` (unit zpk gain) and ``Q = m Q0 = −[s+2, 0]/(s+2) = −[1 0]``, static;
    judged as ``Q Gf = m Mr`` and m itself, by numpy."""
    model, Mr = _nonminimum_least_row()
    gen = model_matching(model, Mr, updating=True, sdeg=-2.0)
    M = gen.info["M"]
    assert gen.info["row_orders"] == [0] and gen.info["row_degrees"] == [1]
    assert np.allclose(gen.Q.D, [[-1.0, 0.0]], atol=TOL)
    lam = LAM_C
    m = fr(M.A, M.B, M.C, M.D, lam)[:, 0, 0]
    assert np.allclose(m, (lam - 1) / (lam + 2), rtol=TOL, atol=0)
    R = residual_map(model, gen.Q, lam)
    assert np.allclose(R[:, 0, 0], m * fr(Mr.A, Mr.B, Mr.C, Mr.D, lam)[:, 0, 0], rtol=TOL, atol=0)


def test_unstable_zero_of_the_fault_channel_is_refused_without_updating():
    """One output: ``Gf = (s−1)/((s+1)(s+2))``, ``Mr = 1/(s+3)``. The unique solution
    ``Mr/Gf = (s+1)(s+2)/((s−1)(s+3))`` has the pole 1: refused, naming it and the updating factor;
    with updating=True, ``M`` carries the zero 1 and Q is stable."""
    s = ct.tf("s")
    model = FDIModel.from_control(ct.ss((s - 1) / ((s + 1) * (s + 2))), f=[0])
    Mr = LTI.from_control(ct.ss(1 / (s + 3)))
    with pytest.raises(DesignError, match=r"poles \[\(1(\.0+)?\+0j\)\].*updating"):
        model_matching(model, Mr)
    gen = model_matching(model, Mr, updating=True)
    assert np.allclose(gen.info["M_zeros"][0], [1.0], atol=1e-9) and np.all(gen.Q.poles().real < 0)
    M = gen.info["M"]
    R = residual_map(model, gen.Q, LAM_C)
    want = fr(M.A, M.B, M.C, M.D, LAM_C) * fr(Mr.A, Mr.B, Mr.C, Mr.D, LAM_C)
    assert np.abs(R - want).max() <= TOL * np.abs(want).max()


def test_improper_least_solution_gets_a_least_degree_updating_factor():
    """``Gf = 1/(s+1)``, ``Mr = 1``: the unique solution ``s + 1`` is improper (refused without updating);
    with updating every m has relative degree ≥ 1, so degree 1 is least: ``m = 1/(s+2)`` at sdeg = −2
    (unit zpk gain) and ``Q = (s+1)/(s+2)``."""
    model = FDIModel.from_matrices([[-1.0]], np.zeros((1, 0)), [[1.0]],
                                   faults=[component_fault("f", [[1.0]], [[0.0]])])
    with pytest.raises(DesignError, match="improper.*updating=True"):
        model_matching(model, [[1.0]])
    gen = model_matching(model, [[1.0]], updating=True, sdeg=-2.0)
    assert gen.info["row_degrees"] == [1] and gen.Q.n == 1
    lam = LAM_C
    M = gen.info["M"]
    assert np.allclose(fr(M.A, M.B, M.C, M.D, lam)[:, 0, 0], 1 / (lam + 2), rtol=TOL, atol=0)
    assert np.allclose(fr(gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D, lam)[:, 0, 0], (lam + 1) / (lam + 2), rtol=TOL, atol=0)


def test_max_degree_bounds_the_least_order():
    """The unique solution of the first example has degree 2: max_degree = 1 refuses it, naming 2."""
    model, _, _ = _siso_u_f()
    with pytest.raises(DesignError, match="least-order solution has degree 2 > max_degree = 1"):
        model_matching(model, LTI([[-3.0]], [[1.0]], [[1.0]], [[0.0]]), max_degree=1)



def test_reference_known_to_1e_9_keeps_its_least_order():
    """Seed 32 of the unstable family: the detection row Q* (order 3) matches its own fault response
    with M = 1 up to the cancelled unstable mode; the least-order row has order ≤ 3. (Order 7 with the
    old judge; met since the judge reads each row's cancelled boundary modes from the row's own realisation —
    measured, the mechanism through the reference Q* is not traced.)"""
    from test_synthesis_matching_order import _random_model

    from fmu_fdi import nullspace_design

    model = _random_model(32, unstable=True)
    ref = nullspace_design(model, rdim=1)
    gen = model_matching(model, ref.Rf, updating=True)
    assert gen.info["row_orders"][0] <= ref.Q.n == 3


@pytest.mark.parametrize("kw, pole", [(dict(), -6.0), (dict(poles=[-9.0]), -9.0), (dict(sdeg=-7.0), -7.0)])
def test_rows_of_equal_index_are_combined_into_a_stable_least_order_row(kw, pole):
    """Faults only: ``Gf = [−s²; 5 − s²]/den``, ``Mr = (s² + 5s + 5)/den``, den = (s+6)(s+8), smarg = −5.
    No static row matches (``X Gf = (−(a+b)s² + 5b)/den`` has no s-term), so the least order is ≥ 1.
    The null rows of degree 1 are the combinations of ``P1 = [s+3, 1, s−1]`` and ``P2 = [1, s+2, s−2]``
    (``[−s², 5 − s², s²+5s+5] = P1 × P2``): their last entry ``(α+β)s − (α+2β)`` can have any root,
    so an order-1 row with any pole exists — the requested one (the plant's −6 without poles/sdeg).
    The individual basis rows of this model have a pole right of the margin: the combination is needed.
    Judged by numpy at off-axis points."""
    s = ct.tf("s")
    den = (s + 6) * (s + 8)
    num = den.num[0][0]
    Gf = ct.tf([[(-s**2 + 0 * s).num[0][0]], [(5 - s**2 + 0 * s).num[0][0]]], [[num], [num]])
    model = FDIModel.from_control(ct.ss(Gf), f=[0])
    Mr = LTI.from_control(ct.ss((s**2 + 5 * s + 5) / den))
    gen = model_matching(model, Mr, smarg=-5.0, **kw)
    assert gen.info["row_orders"] == [1] and gen.info["row_methods"] == ["least order"]
    assert np.allclose(gen.Q.poles(), [pole], atol=1e-9)
    R = residual_map(model, gen.Q, LAM_C)
    want = fr(Mr.A, Mr.B, Mr.C, Mr.D, LAM_C)
    assert np.abs(R - want).max() <= TOL * np.abs(want).max()


@pytest.mark.parametrize("mm_tol", [1e-9, 1e-8, 1e-7])
def test_reference_of_an_optimal_row_is_matched_at_every_mm_tol(mm_tol):
    """Seed 14 of the AMMP family: the H∞-optimal row (order 23) gives the reference ``[Rf_1 Rw_1] = Q_1 [Gf Gw]``
    on the model whose faults are ``[f w]``; the row itself solves it, so the least-order solve must return a
    row that matches it (not the zero row, not a leak). The augmented system's reduction decided its ranks
    against the unbalanced norm while SLICOT judged balanced matrices (1e4 apart): at mm_tol ≥ 1e-8 every
    state of the reference was removed. Judged by numpy at off-axis points: ``Q [Gu Gd; I 0] = 0`` and
    ``Q [Gf Gw] = [Rf_1 Rw_1]`` to 1e-6 of the reference's size (the reference is known to ~1e-9; the
    returned row's relative matching error is bounded by sqrt(mm_tol) ≤ 3.2e-4 by contract — and order 2)."""
    from test_synthesis_ammp import _random_case

    from fmu_fdi import approximate_model_matching
    from fmu_fdi.faults import FaultSpec

    model, Mr = _random_case(14)
    g0 = approximate_model_matching(model, Mr, reltol=1e-6)
    Q1 = g0.Q[0, :].minreal()
    fw = FaultSpec(name="fw", kind="component", Bf=np.hstack([model.Bf, model.Bw]), Df=np.hstack([model.Df, model.Dw]))
    aug = FDIModel(model.A, model.Bu, model.C, model.Du, Bd=model.Bd, Dd=model.Dd, faults=[fw], dt=model.dt)
    ref = residual_map(aug, Q1, LAM_C)
    gen = model_matching(aug, LTI(*_ref_realisation(model, Q1)), mm_tol=mm_tol)
    assert gen.info["row_orders"] == [2]
    R = residual_map(aug, gen.Q, LAM_C)
    nud = model.nu + model.nd
    size = np.abs(ref[:, :, nud:]).max()
    assert np.abs(R[:, :, :nud]).max() <= 1e-6 * size
    assert np.abs(R[:, :, nud:] - ref[:, :, nud:]).max() <= 1e-6 * size


def _ref_realisation(model, Q1):
    """``Q_1 [Gf Gw; 0 0]`` as a product realisation (the reference as approximate_model_matching's mindeg
    formed it): ``(A, B, C, D, dt)``."""
    Bfw, Dfw = np.hstack([model.Bf, model.Bw]), np.hstack([model.Df, model.Dw])
    G = LTI(model.A, Bfw, np.vstack([model.C, np.zeros((model.nu, model.n))]),
            np.vstack([Dfw, np.zeros((model.nu, Bfw.shape[1]))]), model.dt)
    P = Q1 @ G
    return P.A, P.B, P.C, P.D, P.dt


def _faults_only_random(seed):
    """Seeded model: n = 3..5 stable states, 2..3 outputs, 0..1 input, one fault; Mr = 1/(s+2)."""
    rng = np.random.default_rng(seed)
    n, p, mu = 3 + seed % 3, 2 + seed % 2, seed % 2
    A = rng.standard_normal((n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)
    model = FDIModel.from_matrices(A, rng.standard_normal((n, mu)), rng.standard_normal((p, n)),
                                   faults=[component_fault("f", rng.standard_normal((n, 1)), np.zeros((p, 1)))])
    return model, LTI([[-2.0]], [[1.0]], [[1.0]], [[0.0]])


@pytest.mark.parametrize("seed, sdeg", [(10, None), (26, None), (26, -2.0), (32, -2.0), (40, None)])
def test_stable_solution_is_lowered(seed, sdeg):
    """Seeded models whose least-order row is unstable (without updating): the returned stable row has fewer
    states than the core's stable left inverse of the basis' Mr-column (least_solve.stable_solution, measured
    on the same least row: orders 4-10 here), matches Mr exactly (numpy, off-axis points: eps·1e3 of the
    reference's size), decouples u exactly, is stable, and with sdeg has every pole at or left of sdeg."""
    from fmu_fdi.design.problems.matching import _drop_cancelled, pole_chooser
    from fmu_fdi.design.toolkit.least_solve import least_row, stable_solution

    model, Mr = _faults_only_random(seed)
    kw = {} if sdeg is None else dict(sdeg=sdeg)
    gen = model_matching(model, Mr, **kw)
    assert gen.info["row_methods"] == ["least stable order"]
    choose = pole_chooser(model, None, sdeg)
    good = lambda re, im: re <= -1e-7  # noqa: E731
    lr = least_row(model, _drop_cancelled(Mr, -1e-7, 1e-9), tol=1e-9, good=good, choose=choose, sdeg=sdeg)
    assert gen.Q.n < stable_solution(lr, choose, good, 1e-9).n
    R = residual_map(model, gen.Q, LAM_C)
    want = fr(Mr.A, Mr.B, Mr.C, Mr.D, LAM_C)
    assert np.abs(R[:, :, model.nu:] - want).max() <= TOL * np.abs(want).max()
    assert np.abs(R[:, :, :model.nu]).max(initial=0.0) <= TOL * np.abs(want).max()
    # a k-fold pole at sdeg (every free pole goes there) is computed to ~(eps·||A||)^(1/k): 5.6e-5 for k = 3
    top = -1e-7 if sdeg is None else sdeg + 1e-3
    assert np.all(gen.Q.poles().real <= top)


def test_stable_solution_ignores_the_rounding_zeros_of_the_pencil_basis():
    """Matching seed 197 (continuous, n = 6, p = 4): the pencil's basis of the augmented null space has order 6,
    four of its modes unobservable only to rounding (an output-nulling feedback of norm 790), one of them at
    +3.16, which the Mr-column's zeros then contained: stable_solution refused "every exact solution has the
    pole 3.16" although the reference row Q* is a stable exact solution of order 2. Decided on the basis at
    the core's relative tolerance, a stable solution is returned; judged by numpy at off-axis points:
    ``X [Gu Gd Gf; I 0 0] = [0 0 Mi]`` to 1e-8 of Mi's size (the reduced basis is accepted when it matches
    the pencil's to mm_tol = 1e-9 of its peak on a grid; 10× for the off-grid points), no higher order than
    Q*, stable."""
    from test_synthesis_matching_order import _detection_reference

    from fmu_fdi.design.problems.matching import _drop_cancelled, _peak, pole_chooser
    from fmu_fdi.design.toolkit.least_solve import least_row, stable_solution

    model, ref = _detection_reference(197)
    Mi = _drop_cancelled((ref.Rf * (1.0 / _peak(model, ref.Rf))).minreal(), -1e-7, 1e-9)
    good = lambda re, im: re <= -1e-7  # noqa: E731
    choose = pole_chooser(model, None, None)
    lr = least_row(model, Mi, tol=1e-9, good=good, choose=choose)
    assert np.max(np.linalg.eigvals(lr.basis.A).real) > 1.0  # the case: the pencil's realisation holds +3.16
    X = stable_solution(lr, choose, good, 1e-9)
    assert X.n <= ref.Q.n and np.all(np.linalg.eigvals(X.A).real < 0)
    R = residual_map(model, X, LAM_C)
    want = fr(Mi.A, Mi.B, Mi.C, Mi.D, LAM_C)
    nud = model.nu + model.nd
    assert np.abs(R[:, :, :nud]).max() <= 1e-8 * np.abs(want).max()
    assert np.abs(R[:, :, nud:] - want).max() <= 1e-8 * np.abs(want).max()


def _rhp_zero_models():
    """Gf with a zero at s = 1 that Mr = 1/(s+3) does not have: one output ``(s−1)/((s+1)(s+2))`` (the unique
    solution Mr/Gf has the pole 1), and two outputs ``[(s−1)/(s+2); (s−1)/(s+3)]`` (the column vanishes at 1,
    so ``X(1) Gf(1) = 0 ≠ Mr(1)`` for every X analytic at 1: every exact solution has the pole 1; the null
    space has a dynamic row [Gf2, −Gf1] beside the solution rows, a basis of two rows)."""
    one = FDIModel.from_matrices(np.diag([-1.0, -2.0]), np.zeros((2, 0)), [[-2.0, 3.0]],
                                 faults=[component_fault("f", [[1.0], [1.0]], [[0.0]])])
    two = FDIModel.from_matrices(np.diag([-2.0, -3.0]), np.zeros((2, 0)), [[-3.0, 0.0], [0.0, -4.0]],
                                 faults=[component_fault("f", [[1.0], [1.0]], [[1.0], [1.0]])])
    return [one, two]


@pytest.mark.parametrize("which", [0, 1])
def test_genuine_unstable_zero_is_refused_and_named(which):
    """A right-half-plane zero of Gf that the reference does not share is a pole of every exact solution: refused
    (no updating factor) with that pole named; with updating=True matched (M has the zero)."""
    import re

    model = _rhp_zero_models()[which]
    Mr = LTI([[-3.0]], [[1.0]], [[1.0]], [[0.0]])
    assert np.allclose(fr(model.A, model.Bf, model.C, model.Df, np.array([1.0 + 0j])), 0.0, atol=1e-14)
    with pytest.raises(DesignError, match="every exact solution has the poles") as exc:
        model_matching(model, Mr)
    named = [complex(z) for z in re.findall(r"\(([-+0-9.ej]+)\)", str(exc.value).split("the poles")[1])[:1]]
    assert named and abs(named[0] - 1.0) < 1e-8
    gen = model_matching(model, Mr, updating=True)
    assert gen.Q.is_stable()


def _weak_unstable_plant():
    """``x1' = x1 + f`` (unstable), ``x2' = −x2 + f``, ``y = [x1 + x2; x2]``: ``Gf = [1/(s−1) + 1/(s+1); 1/(s+1)]``.
    A static row ``[q1 q2]`` gives ``R = q1/(s−1) + (q1 + q2)/(s+1)``: the plant pole cancels iff ``q1 = 0``,
    and ``[0 1]`` matches ``Mr = 1/(s+1)`` exactly."""
    return FDIModel.from_matrices(np.diag([1.0, -1.0]), np.zeros((2, 0)), [[1.0, 1.0], [0.0, 1.0]],
                                  faults=[component_fault("f", [[1.0], [1.0]], [[0.0], [0.0]])])


def _numpy_error(model, Q, target, lam):
    """``max_k ||Q(λ_k) [Gf; I] − target(λ_k)|| / max_k ||target(λ_k)||`` by numpy solves."""
    R = residual_map(model, Q, lam)
    T = fr(target.A, target.B, target.C, target.D, lam)
    return float(np.max(np.abs(R - T)) / np.max(np.abs(T)))


@pytest.mark.parametrize("case", ["improves", "worsens"])
def test_plant_mode_cancellation_never_worsens_the_match(case):
    """``_cancel_plant_modes`` makes the plant's unstable mode cancel exactly by a minimum-norm change of Q's
    y-part; it must return the better match of before/after (or one within mm_tol) and record both.
    'improves': Q = [1e-8 1] against Mr = 1/(s+1) (a residue 1e-8 at s = 1): corrected to [0 1], the
    error drops from ~1e-8 to rounding. 'worsens': the target is that Q's own response (residue included), so
    the correction would move the match from 0 to ~1e-8 > mm_tol = 1e-9: Q is kept, the note says why.
    Errors judged by numpy on points along the axis (1e-2 … 1e2 rad/s)."""
    from fmu_fdi.design.problems.matching import _cancel_plant_modes

    model = _weak_unstable_plant()
    Q = LTI.static(np.array([[1e-8, 1.0]]))
    Mr = LTI([[-1.0]], [[1.0]], [[1.0]], [[0.0]])
    if case == "worsens":  # Q's own fault response, realised in modal form: 1e-8/(s−1) + (1 + 1e-8)/(s+1)
        Mr = LTI(np.diag([1.0, -1.0]), [[1.0], [1.0]], [[1e-8, 1.0 + 1e-8]], [[0.0]])
    lam = 1j * np.logspace(-2, 2, 200)
    Qc, note = _cancel_plant_modes(model, Q, 0.0, Mr, 1e-9)
    e_in, e_out = _numpy_error(model, Q, Mr, lam), _numpy_error(model, Qc, Mr, lam)
    e_exact = _numpy_error(model, LTI.static(np.array([[0.0, 1.0]])), Mr, lam)
    assert e_out <= max(e_in, 1e-9) + 1e-15  # never silently worse (rounding of O(1) data: 1e-15)
    assert note["error_before"] is not None and note["error_after"] is not None
    if case == "improves":
        assert note["corrected"] and abs(Qc.D[0, 0]) < 1e-15 and e_out < 1e-14 < e_in
    else:
        assert e_in < 1e-14 and e_exact > 1e-9  # the exact cancellation is the worse match here
        assert not note["corrected"] and np.array_equal(Qc.D, Q.D) and "worsen the match" in note["reason"]


def test_matching_records_the_plant_mode_cancellation():
    """An unstable plant with updating: info['plant_mode_cancellation'] says whether the correction was made,
    and the returned match is within mm_tol of the reference (numpy, off-axis points)."""
    model = FDIModel.from_matrices(np.diag([1.0, -2.0]), [[1.0], [0.0]], [[1.0, 1.0]],
                                   faults=[component_fault("f", [[0.0], [1.0]], [[0.0]])])
    Mr = LTI([[-3.0]], [[1.0]], [[1.0]], [[0.0]])
    gen = model_matching(model, Mr, updating=True)
    note = gen.info["plant_mode_cancellation"]
    assert set(note) >= {"corrected", "error_before", "error_after", "correction", "reason"}
    M = gen.info["M"]
    MMr = M @ Mr
    R = residual_map(model, gen.Q, LAM_C)
    want = fr(MMr.A, MMr.B, MMr.C, MMr.D, LAM_C)
    assert np.abs(R[:, :, :1]).max() <= 1e-9 * np.abs(want).max()
    assert np.abs(R[:, :, 1:] - want).max() <= 1e-9 * np.abs(want).max()
