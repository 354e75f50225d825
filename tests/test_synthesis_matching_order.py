"""Least-order exact model matching (design/problems/matching.py) against FaultDetectionTools.jl test/test_emmsyn.jl.

The peer's ``emmsyn(sysf, Rf; atol = 1e-7, minimal = true)`` returns row orders ``order.(QM.sys) ==
[1, 1, 1]`` for the efdisyn bank references of Niemann (1998) and of Xiong & Saif (2000, Example 2),
and ``Q = I`` for ``Mr = Gf`` on a model with faults only. Every returned filter is judged here by
an independent frequency evaluation (numpy solves of ``(λI − A) x = B`` on the model's own
matrices, not the package's LTI code): ``Q [Gu Gd; I 0] = 0`` and ``Q [Gf; 0] = M Mr`` row by row.
"""
import numpy as np
import pytest

from fmu_fdi import DesignError, FDIModel, component_fault, structured_bank
from fmu_fdi.design.problems.matching import model_matching
from fmu_fdi.lti import LTI, vstack
from test_synthesis_published import niemann, xiong_saif_2

W = np.r_[np.logspace(-2, 2, 41), 3.7, 0.61]  # test frequencies (rad/s), none a pole of the examples


def fr(A, B, C, D, lam):
    """``C (λI − A)^{-1} B + D`` at every point, by numpy solves: (K, p, m)."""
    A, B, C, D = (np.atleast_2d(np.asarray(X, float)) for X in (A, B, C, D))
    n = A.shape[0]
    out = np.empty((lam.size, D.shape[0], D.shape[1]), complex)
    for k, l in enumerate(lam):
        out[k] = D + (C @ np.linalg.solve(l * np.eye(n) - A, B) if n else 0.0)
    return out


def hankel_order(A, B, c, rtol=1e-8):
    """McMillan degree of the row ``c (λI − A)^{-1} B``: the rank of its Hankel matrix
    ``O K`` (observability times controllability matrix; SVD, relative tolerance ``rtol``)."""
    n = A.shape[0]
    if n == 0:
        return 0
    O = np.vstack([c @ np.linalg.matrix_power(A, k) for k in range(n)])
    K = np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(n)])
    sv = np.linalg.svd(O @ K, compute_uv=False)
    return int(np.sum(sv > rtol * sv[0])) if sv.size and sv[0] > 0 else 0


def sys_fr(sys: LTI, lam):
    return fr(sys.A, sys.B.reshape(sys.n, sys.m), sys.C.reshape(sys.p, sys.n), sys.D, lam)


def plant_fr(model: FDIModel, lam):
    """``([Gu Gd; I 0], [Gf; 0])`` at the points, from the model's matrices."""
    B = np.hstack([model.Bu, model.Bd, model.Bf])
    D = np.hstack([model.Du, model.Dd, model.Df])
    G = fr(model.A, B, model.C, D, lam)
    k = model.nu + model.nd
    low = np.zeros((lam.size, model.nu, B.shape[1]))
    low[:, :, :model.nu] = np.eye(model.nu)
    Ge = np.concatenate([G, low], axis=1)
    return Ge[:, :, :k], Ge[:, :, k:]


def judge(model, gen, MMr_vals, lam):
    """Relative decoupling ``max ||Q Gud|| / max ||Q|| ||Gud||`` and, per row, the matching error
    ``max |Rf_i − (M Mr)_i| / max |(M Mr)_i|``."""
    Gud, Gf = plant_fr(model, lam)
    Qv = sys_fr(gen.Q, lam)
    Rud, Rf = Qv @ Gud, Qv @ Gf
    dec = 0.0
    if Gud.shape[2]:
        dec = np.max(np.linalg.norm(Rud, 2, axis=(1, 2))) / np.max(
            np.linalg.norm(Qv, 2, axis=(1, 2)) * np.linalg.norm(Gud, 2, axis=(1, 2)))
    err = np.max(np.abs(Rf - MMr_vals), axis=(0, 2)) / np.max(np.abs(MMr_vals), axis=(0, 2))
    return float(dec), err


def bank_references(model, S, **kw):
    """The bank's fault responses ``Rf_i = Q_i [Gf; 0]`` as LTI (references) and their values
    computed independently from the Q_i matrices and the model's."""
    bank = structured_bank(model, S, **kw)
    lam = 1j * W
    _, Gf = plant_fr(model, lam)
    vals = np.concatenate([sys_fr(g.Q, lam) @ Gf for g in bank.members], axis=1)
    return vstack([g.Rf for g in bank.members]), vals, [g.Q.n for g in bank.members]


# 1e-7: the peer's test asserts iszero(R − M Rf, atol = 1e-7); our rows are exact up to the
# sampled equations' threshold mm_tol = 1e-9 times the conditioning of a degree-1 basis (~1e2)
TOL = 1e-7


@pytest.mark.parametrize("make, kw", [
    (niemann, dict(sdeg=-5.0)),                # test_emmsyn.jl: efdisyn(…; sdeg = -5, smarg = -0.05, FDfreq = 0)
    (xiong_saif_2, dict(sdeg=-2.0, smarg=-1.0)),  # test_emmsyn.jl: efdisyn(…; sdeg = -2, smarg = -1, FDfreq = 0)
])
def test_bank_references_give_order_one_rows(make, kw):
    """emmsyn(sysf, Rf; atol = 1e-7, minimal = true): order.(QM.sys) == [1, 1, 1]. The old
    common-denominator synthesis gave [4, 2, 2] / [3, 3, 3] (9 states for the three rows)."""
    model = make()
    Mr, vals, bank_orders = bank_references(model, [[1, 1], [0, 1], [1, 0]], **kw)
    assert bank_orders == [1, 1, 1]  # the references come from order-1 rows: 1 is attainable
    gen = model_matching(model, Mr, atol=1e-7)
    assert gen.info["row_orders"] == [1, 1, 1] and gen.Q.n == 3
    assert [hankel_order(gen.Q.A, gen.Q.B, gen.Q.C[[i]]) for i in range(3)] == [1, 1, 1]
    dec, err = judge(model, gen, vals, 1j * W)
    assert dec < TOL and np.all(err < TOL), (dec, err)
    assert np.all(gen.Q.poles().real < 0)


def _faults_only(seed=5, n=5, p=3, mf=2, dt=0.0):
    """test_emmsyn.jl: ``sysf = fdimodset(rss(5, 3, 2; stable = true), faults = 1:2)``."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)
    Bf, C, Df = rng.normal(size=(n, mf)), rng.normal(size=(p, n)), rng.normal(size=(p, mf))
    faults = [component_fault(f"f{j + 1}", Bf[:, [j]], Df[:, [j]]) for j in range(mf)]
    model = FDIModel.from_matrices(A, np.zeros((n, 0)), C, faults=faults)
    if dt:
        lti = LTI(A, Bf, C, Df).to_discrete(dt)
        faults = [component_fault(f"f{j + 1}", lti.B[:, [j]], Df[:, [j]]) for j in range(mf)]
        model = FDIModel.from_matrices(lti.A, np.zeros((n, 0)), C, faults=faults, dt=dt)
    return model


@pytest.mark.parametrize("dt", [0.0, 0.1])
def test_reference_equal_to_fault_channel_gives_identity(dt):
    """emmsyn(sysf, sysr = sysf): ``Q = I`` (order 0), and ``Q = [I 0]`` for the first two rows;
    the old synthesis returned an order-15 Q (each row carried the five plant poles of Mr)."""
    model = _faults_only(dt=dt)
    Gf = model.lti("f")
    lam = np.exp(1j * W[W * dt < np.pi] * dt) if dt else 1j * W
    for Mr, want in ((Gf, np.eye(3)), (Gf[:2, :], np.eye(3)[:2])):
        gen = model_matching(model, Mr)
        assert gen.info["row_orders"] == [0] * Mr.p and gen.Q.n == 0
        assert np.allclose(gen.Q.D, want, atol=1e-9)  # exact solution; rounding ~1e-15
        _, err = judge(model, gen, fr(model.A, model.Bf, model.C, model.Df, lam)[:, :Mr.p], lam)
        assert np.all(err < TOL)


def test_bank_of_references_and_badly_scaled_rows():
    """test_emmsyn.jl "bank of two reference models" ``[Gf; Gf]``: Q = [I; I]; and rows of gains
    1 and 1e-8 side by side (the Xiong-Saif bank row of gain ~1e-8): each row is matched to its
    own relative accuracy, not to the other rows' scale (Q = diag(1, 1e-8, 1) exactly)."""
    model = _faults_only()
    Gf = model.lti("f")
    lam = 1j * W
    vals = fr(model.A, model.Bf, model.C, model.Df, lam)
    gen = model_matching(model, vstack([Gf, Gf]))
    assert gen.info["row_orders"] == [0] * 6 and np.allclose(gen.Q.D, np.vstack([np.eye(3)] * 2), atol=1e-9)
    S = np.diag([1.0, 1e-8, 1.0])
    gen = model_matching(model, LTI.static(S) @ Gf)
    assert gen.info["row_orders"] == [0, 0, 0]
    assert np.allclose(gen.Q.D / np.diag(S)[:, None], np.eye(3), atol=1e-9)  # relative to each row's scale
    _, err = judge(model, gen, S @ vals, lam)
    assert np.all(err < TOL)


def test_unstable_reference_needs_updating_factor():
    """Gf = 1/s, no u, d: Q0 = 1 matches Mr = Gf, but Rf = 1/s is not stable. Without updating a
    clear DesignError; with it, the coprime factor m = s/(s + 1) of the whole row [Q0 Mr] gives
    the stable Q = s/(s + 1) and Rf = M Mr = 1/(s + 1) (sdeg = -1: the moved pole)."""
    model = FDIModel.from_matrices([[0.0]], np.zeros((1, 0)), [[1.0]],
                                   faults=[component_fault("f", [[1.0]], [[0.0]])])
    with pytest.raises(DesignError, match="row 1 of Mr is not stable.*updating=True"):
        model_matching(model, model.lti("f"))
    gen = model_matching(model, model.lti("f"), updating=True, sdeg=-1.0)
    lam = 1j * W
    M = sys_fr(gen.info["M"], lam)[:, 0, 0]
    assert np.allclose(M, lam / (lam + 1), atol=1e-9)
    assert np.allclose(sys_fr(gen.Q, lam)[:, 0, 0], lam / (lam + 1), atol=1e-9)
    assert gen.info["row_degrees"] == [1] and np.all(gen.Q.poles().real < 0)
    _, err = judge(model, gen, (M / lam)[:, None, None], lam)
    assert np.all(err < TOL)


def test_options_are_validated_as_design_errors():
    model = _faults_only()
    for kw in (dict(atol=-1.0), dict(atol=np.nan), dict(mm_tol=0.0), dict(max_degree=-1)):
        with pytest.raises(DesignError):
            model_matching(model, model.lti("f"), **kw)
    with pytest.raises(DesignError, match="row 2 of Mr is zero"):
        model_matching(model, np.array([[1.0, 0.0], [0.0, 0.0]]))


def _random_model(seed, unstable=False, sensor_fault_y0=False):
    """Seeded random model: n 1-6, p 2-4, up to two u, d of rank < p, one or two faults, every
    third one discrete (dt = 0.1); stable, or with poles up to 1 right of the axis. With
    ``sensor_fault_y0`` a sensor fault on the first output is added to the fault set."""
    rng = np.random.default_rng(seed)
    n, p = int(rng.integers(1, 7)), int(rng.integers(2, 5))
    mu, md, mf = int(rng.integers(0, 3)), int(rng.integers(0, p - 1)), int(rng.integers(1, 3))
    dt = 0.1 if seed % 3 == 0 else 0.0
    A = rng.normal(size=(n, n))
    shift = -rng.uniform(0.1, 1.0) if unstable else rng.uniform(0.1, 1.0)
    A -= (np.max(np.linalg.eigvals(A).real) + shift) * np.eye(n)
    if dt:
        import scipy.linalg as sla

        A = sla.expm(A * dt)
    Bf, Df = rng.normal(size=(n, mf)), rng.normal(size=(p, mf)) * (seed % 2)
    faults = [component_fault(f"f{j}", Bf[:, [j]], Df[:, [j]]) for j in range(mf)]
    if sensor_fault_y0:
        from fmu_fdi import sensor_fault

        faults.append(sensor_fault("s0", "y0"))
    return FDIModel.from_matrices(A, rng.normal(size=(n, mu)), rng.normal(size=(p, n)), Bd=rng.normal(size=(n, md)),
                                  faults=faults, dt=dt)


def _points(model):
    w = np.logspace(-2, 1.4, 30)  # below the Nyquist frequency 31.4 rad/s of dt = 0.1
    return np.exp(1j * w * model.dt) if model.dt else 1j * w


def _detection_reference(seed, unstable=False):
    """``(model, Q*)``: a least-order detection row of the seeded model. Where no row sees the model's
    faults once d is decoupled (seed 14: n = 1, ``rank [Gd Gf] = rank Gd``, so ``achievable_structure``
    lists no row), the model gets a sensor fault on y0 as well and the reference is the first row that
    model's ``achievable_structure`` lists, designed by ``structured_bank`` (here [0 1]: f0 decoupled, s0
    seen): its fault response has a zero column and a nonzero one, both to be matched."""
    from fmu_fdi import nullspace_design
    from fmu_fdi.design.problems.achievable import achievable_structure

    model = _random_model(seed, unstable)
    try:
        return model, nullspace_design(model, rdim=1)
    except DesignError:
        assert not np.asarray(achievable_structure(model)).size  # refused only where nothing is achievable
    model = _random_model(seed, unstable, sensor_fault_y0=True)
    rows = np.asarray(achievable_structure(model), int).reshape(-1, len(model.fault_names))
    return model, structured_bank(model, rows[:1]).members[0]


@pytest.mark.parametrize("seed", range(36))
def test_random_references_are_matched_at_no_higher_order(seed):
    """Reference = the fault response of a least-order detection row Q* (any admissible row):
    model_matching must match it exactly by a row of order ≤ order(Q*) (least order), judged
    by numpy evaluation of Q* [Gf; 0] and Q [Gu Gd; I 0], Q [Gf; 0]."""
    model, ref = _detection_reference(seed)
    lam = _points(model)
    _, Gf = plant_fr(model, lam)
    vals = sys_fr(ref.Q, lam) @ Gf
    gen = model_matching(model, ref.Rf)
    assert gen.info["row_orders"][0] <= ref.Q.n
    dec, err = judge(model, gen, vals, lam)
    assert dec < TOL and np.all(err < TOL), (dec, err)


@pytest.mark.parametrize("seed", range(36))
def test_unstable_plants_get_a_stable_updating_factor(seed):
    """Unstable plants: the reference Q* [Gf; 0] of a detection row is unstable, so updating=True
    must return a stable Q and a stable (minimal) diagonal M with Q [Gf; 0] = M Mr, judged by numpy."""
    model, ref = _detection_reference(seed, unstable=True)
    gen = model_matching(model, ref.Rf, updating=True)
    M = gen.info["M"]
    assert gen.Q.is_stable() and M.is_stable() and M.minreal().n == M.n
    lam = _points(model)
    _, Gf = plant_fr(model, lam)
    vals = sys_fr(M, lam) @ sys_fr(ref.Q, lam) @ Gf
    dec, err = judge(model, gen, vals, lam)
    assert dec < TOL and np.all(err < TOL), (dec, err)


def _static_plant(Du, faults=(), name="static", dt=0.0):
    """A static plant y = Du u (+ sensor faults); skipped where FDIModel has no n = 0 support yet."""
    from fmu_fdi.errors import ModelError

    try:
        return FDIModel.from_matrices(np.zeros((0, 0)), np.zeros((0, Du.shape[1])), np.zeros((Du.shape[0], 0)),
                                      Du=Du, faults=list(faults), name=name, dt=dt)
    except ModelError as exc:
        pytest.skip(f"static plants need FDIModel n = 0 support (issue 17, core): {exc}")


def test_static_plant():
    """y = [1; 2] u + f (two sensor faults), n = 0: Q = [1 0 −1] gives Q [Du; I] = 1 − 1 = 0 and
    Q [I; 0] = [1 0] = Mr. A static Mr gives a static Q, a dynamic Mr = [1/(s+1) 0] a first-order
    one; updating=True on a static plant gives M = 1. Judged by numpy: Q [Du Df; I 0] = [0 M Mr]."""
    from fmu_fdi import sensor_fault

    Du = np.array([[1.0], [2.0]])
    model = _static_plant(Du, [sensor_fault("s1", "y0"), sensor_fault("s2", "y1")])
    Ge = np.block([[Du, np.eye(2)], [np.eye(1), np.zeros((1, 2))]])
    gen = model_matching(model, np.array([[1.0, 0.0]]))
    assert gen.Q.n == 0 and np.allclose(gen.Q.D @ Ge, [[0.0, 1.0, 0.0]], atol=1e-12)
    Mr = LTI([[-1.0]], [[1.0, 0.0]], [[1.0]], [[0.0, 0.0]])
    gen = model_matching(model, Mr)
    assert gen.info["row_orders"] == [1]
    lam = 1j * W
    R = sys_fr(gen.Q, lam) @ Ge
    assert np.abs(R[:, :, :1]).max() < 1e-12 and np.allclose(R[:, :, 1:], sys_fr(Mr, lam), atol=1e-12)
    gen = model_matching(model, np.array([[2.0, -1.0]]), updating=True)
    assert gen.info["M"].n == 0 and np.allclose(gen.info["M"].D, 1.0)
    assert np.allclose(gen.Q.D @ Ge, [[0.0, 2.0, -1.0]], atol=1e-12)


# The audit of new seeds (benchmarks/synthesis_random_judged.py 200 36 --matching: 199 / 0 / 1 in each family)
# found these two; both were in the matching core (design/toolkit/least_solve.py), not in the reference or the judge.
def test_seed197_reference_of_a_stable_row_is_matched():
    """Seed 197 (continuous, n = 6, p = 4, two u, two d, two faults): Q* [Gf; 0] of a stable order-2 row is
    matched at order ≤ 2 by a stable Q (the pencil had computed index 6 for 2, with four spurious zeros)."""
    model, ref = _detection_reference(197)
    assert ref.Q.is_stable()  # the reference row is itself a stable exact solution
    gen = model_matching(model, ref.Rf)
    assert gen.info["row_orders"][0] <= ref.Q.n and gen.Q.is_stable()
    lam = _points(model)
    _, Gf = plant_fr(model, lam)
    dec, err = judge(model, gen, sys_fr(ref.Q, lam) @ Gf, lam)
    assert dec < TOL and np.all(err < TOL), (dec, err)


def test_seed156_unstable_reference_is_matched_to_tolerance():
    """Seed 156 unstable (discrete, plant poles 1.0000856 and 1.0797, one fault): with updating, Q [Gf; 0] =
    M Mr to 1e-7 of the peak (the joint reduction of the augmented model had perturbed the plant rows)."""
    model, ref = _detection_reference(156, unstable=True)
    gen = model_matching(model, ref.Rf, updating=True)
    lam = _points(model)
    _, Gf = plant_fr(model, lam)
    vals = sys_fr(gen.info["M"], lam) @ sys_fr(ref.Q, lam) @ Gf
    dec, err = judge(model, gen, vals, lam)
    assert dec < TOL and np.all(err < TOL), (dec, err)
