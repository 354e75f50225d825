"""The one judge reads a row's normalised u/d leak the same whatever the realisation and scale of Q (issue 17).

Judged against an independent numpy computation of the stored filter's leak: every solve ``(λI − A) X = B`` refined
with residuals in numpy's longdouble (``_numpy_refined_leak``; not the package's analysis). The case: the shipped
filter of random H∞ matching seed 4 (tests/test_synthesis_ammp.py's ``_random_case``; order 70, ``|Q|·|Ge|`` ~4e6
times its weakest fault gain), whose u/d leak a double-precision evaluation of Q then Q·Ge read at 1.2e-7 … 4.3e-7 of
that gain depending on the realisation (balanced or not, Hessenberg or dense LU), where it is 2.0e-8 as stored. The
same filter on the plant with d0 declared a fault excludes that fault (S = 0): the judge reads it the same way.
"""
import numpy as np
import pytest

from fmu_fdi import DesignError, FDIModel
from fmu_fdi.design.problems.approximate_matching import (_ud_leak_refused, approximate_model_matching,
                                                          normalised_leak)
from fmu_fdi.design.toolkit.postconditions import DEC_TOL
from fmu_fdi.lti import LTI
from test_synthesis_ammp import _random_case

pytestmark = pytest.mark.skipif(np.finfo(np.longdouble).eps >= np.finfo(float).eps,
                                reason="numpy's longdouble is double here: no refined reading to compare with")


def _refined_response(S, lam):
    """``S(λ)`` at the points lam in longdouble, every solve ``(λI − A) X = B`` refined three times with longdouble
    residuals of the stored data (numpy only)."""
    LD = np.clongdouble
    out = np.empty((lam.size, S.p, S.m), LD)
    A, B, C, D = (X.astype(np.longdouble) for X in (S.A, S.B, S.C, S.D))
    for k, lk in enumerate(lam):
        L = lk * np.eye(S.n) - S.A
        X = np.linalg.solve(L, S.B.astype(complex)).astype(LD)
        for _ in range(3):
            X = X + np.linalg.solve(L, (B - (LD(lk) * X - A @ X)).astype(complex))
        out[k] = C @ X + D
    return out


def _numpy_refined_leak(model, Q, lam):
    """Per row: peak over lam of the u/d block's 2-norm over the weakest fault's peak (every fault required), with
    ``R = Q(λ)·Ge(λ)`` from solves refined three times with longdouble residuals (numpy only)."""
    R = (_refined_response(Q, lam) @ _refined_response(model.augmented(), lam)).astype(complex)
    sl = model.group_slices()
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    fs = [np.arange(sl["f"].start, sl["f"].stop)[f.columns] for f in model.faults]
    low = np.min([np.linalg.norm(R[:, :, c], axis=1).max(axis=0) for c in fs], axis=0)
    return np.linalg.norm(R[:, :, ud], axis=2).max(axis=0) / low


@pytest.fixture(scope="module")
def shipped():
    """Seed 4's filter as Y·Φ·Q0 ships it (dec_tol = 1: the re-decoupling stage leaves it as it is)."""
    model, Mr = _random_case(4)
    gen = approximate_model_matching(model, Mr, dec_tol=1.0)
    assert not gen.info["ud_redecoupling"]["refined"]
    return model, gen.Q


def _figures(model, Q):
    return normalised_leak(model, Q, np.ones((Q.p, len(model.faults)), bool), None, DEC_TOL)


@pytest.mark.slow  # ~26 s with its fixture on the loaded 2-core machine (four judge readings of an order-70 filter)
def test_reading_is_invariant_under_scalings_and_agrees_with_a_refined_numpy_reading(shipped):
    """The judge's normalised u/d leak of the same filter under output scalings (1e-3, 204: not powers of 2) and a
    diagonal state scaling (random factors in [1e-2, 1e2]): every reading lies within its reported error bound
    (``decoupling_error``) plus the realisations' sensitivities (``decoupling_sensitivity``: new data, rounded) of the
    plain one; and the plain reading is within its error bound (plus 1e-9, the refined numpy reading's own rounding:
    longdouble's 5e-20 times the same conditioning) of numpy's refined reading on the judge's points. Before, the same
    filter read 3.6e-7 (rows scaled) and 5.6e-7 (Q's own realisation) and the scaled-by-204 refit 7e-8 → 2.6e-7."""
    from fmu_fdi.design.toolkit.postconditions import _eval_points

    model, Q = shipped
    base = _figures(model, Q)
    d0, e0, s0 = base["decoupling"], base["decoupling_error"], base["decoupling_sensitivity"]
    assert d0 + e0 < DEC_TOL  # the stored filter's leak is provably within dec_tol
    rng = np.random.default_rng(0)
    t = 10.0 ** rng.uniform(-2, 2, Q.n)
    variants = [LTI(Q.A, Q.B, c * Q.C, c * Q.D, Q.dt) for c in (1e-3, 204.0)]
    variants.append(LTI(Q.A * t[None, :] / t[:, None], Q.B / t[:, None], Q.C * t[None, :], Q.D, Q.dt))
    for V in variants:
        f = _figures(model, V)
        assert abs(f["decoupling"] - d0) <= e0 + f["decoupling_error"] + s0 + f["decoupling_sensitivity"]
    lam = _eval_points(model, Q)[1]
    ref = float(np.max(_numpy_refined_leak(model, Q, lam)))
    assert abs(d0 - ref) <= e0 + 1e-9


def test_a_real_leak_still_fails_and_matching_refuses_it(shipped):
    """A u leak added to the filter — a static path from u of 1e-6 and 1e-3 of the weakest fault gain (the issue's
    leaks were 1e-6 … 3e-3) — reads above dec_tol by more than its error bound: the judge fails it ('decoupling'),
    and matching's post-condition (``_ud_leak_refused``) raises a DesignError naming the row, the leak, the weakest
    required fault's gain and dec_tol."""
    model, Q = shipped
    base = _figures(model, Q)
    gain = 1.0 / base["scales"][0]
    nu = model.nu
    for eps in (1e-6, 1e-3):
        D = Q.D.copy()
        D[:, model.ny:model.ny + nu] += eps * gain / np.sqrt(nu)  # ||ΔD_u||_2 = eps·gain on the single row
        leaky = LTI(Q.A, Q.B, Q.C, D, Q.dt)
        f = _figures(model, leaky)
        assert f["decoupling"] - f["decoupling_error"] > DEC_TOL
        assert any("leak" in m for m in f.get("failures", []))
        with pytest.raises(DesignError, match=r"residual 1: u/d leak .* weakest required fault's gain .* dec_tol"):
            _ud_leak_refused(f, DEC_TOL)


def _d_as_fault(model):
    """The same plant with its unknown input d0 declared a fault (the last inputs of ``from_control``'s f group are
    the original faults): a filter that decouples d decouples this fault, an excluded fault ``S = 0``."""
    P = LTI(model.A, np.hstack([model.Bu, model.Bd, model.Bf]), model.C,
            np.hstack([model.Du, model.Dd, model.Df]), model.dt)
    return FDIModel.from_control(P, u=list(range(model.nu)), f=list(range(model.nu, model.nu + model.nd + model.nf)))


def _numpy_fault_peaks(model, Q, lam):
    """Per fault of ``model``: the peak over lam of ``||R_fj(λ)||_2``, R = Q(λ)·Ge(λ) from solves refined three
    times with longdouble residuals (numpy only; the row is one output)."""
    R = (_refined_response(Q, lam) @ _refined_response(model.augmented(), lam)).astype(complex)
    sl = model.group_slices()
    fs = [np.arange(sl["f"].start, sl["f"].stop)[f.columns] for f in model.faults]
    return np.array([float(np.max(np.linalg.norm(R[:, :, c], axis=(1, 2)) if R.shape[1] > 1
                                  else np.linalg.norm(R[:, 0, c], axis=1))) for c in fs])


@pytest.mark.slow  # ~15 s beside its shared fixture (five judge readings of an order-70 filter, one numpy reading)
def test_excluded_fault_is_read_on_the_stored_filter_whatever_the_scaling(shipped):
    """An excluded fault is read as accurately as u/d (issue 17, the judge's 'structure' verdict): seed 4's shipped
    filter on the same plant with d0 declared a fault 'u4' (excluded, S = 0; its leak is the filter's d leak).

    numpy's refined reading of the stored filter: ~9e-10 of the weakest required fault. On main the judge read the
    excluded fault in double, Q(λ) then Q(λ)·Ge(λ): 1.18e-7 as stored (refused: > dec_tol) and 7.5e-8 under a
    diagonal state scaling (passed) — the verdict moved with the realisation. Now every reading (as stored, rows
    scaled by 204 — not a power of 2 —, a diagonal state scaling by random factors in [1e-2, 1e2]) lies within its
    reported error bound (``f_error``) of numpy's refined reading of the stored data plus the realisations'
    sensitivities (``f_sensitivity``: a similarity is new data, rounded), and below dec_tol; so does d0 declared a
    noise the row decouples (the w block). Injected leaks of 1e-6 and 1e-3 of the weakest fault gain (the fault
    column mixed with the weakest required one's) still fail."""
    from fmu_fdi.design.toolkit.postconditions import _eval_points, internal_figures
    from fmu_fdi.generator import ResidualGenerator

    model, Q = shipped
    m2 = _d_as_fault(model)
    assert m2.fault_names[0] == "u4" and m2.nf == model.nf + 1
    fig = internal_figures(ResidualGenerator(Q, m2, "probe"))
    gain = float(np.min(fig["peaks"]["f"][0, 1:]))  # the weakest required fault
    Qn = LTI(Q.A, Q.B, Q.C / gain, Q.D / gain, Q.dt)  # the normalised row (a rounding of the stored one)
    lam = _eval_points(m2, Qn)[1]
    ref = _numpy_fault_peaks(m2, Qn, lam)
    ref_leak = ref[0] / np.min(ref[1:])
    assert ref_leak < DEC_TOL / 10  # the stored filter does not leak the excluded fault
    rng = np.random.default_rng(0)
    t = 10.0 ** rng.uniform(-2, 2, Q.n)
    variants = [Qn, LTI(Qn.A, Qn.B, 204.0 * Qn.C, 204.0 * Qn.D, Q.dt),
                LTI(Qn.A * t[None, :] / t[:, None], Qn.B / t[:, None], Qn.C * t[None, :], Qn.D, Q.dt)]
    base = None
    for V in variants:
        f = internal_figures(ResidualGenerator(V, m2, "probe"))
        pk = f["peaks"]
        low = np.min(pk["f"][0, 1:])
        leak = pk["f"][0, 0] / low
        assert leak <= DEC_TOL, leak  # main: 1.18e-7 as stored
        e, s = (pk.get(k, np.zeros_like(pk["f"]))[0, 0] / low for k in ("f_error", "f_sensitivity"))
        assert e > 0  # the excluded fault was read on the stored filter, with its bound
        base = base or s
        assert abs(leak - ref_leak) <= e + s + base, (leak, ref_leak, e, s)
    # d0 declared a noise w the row decouples: the same block, read the same way (main: the plain reading, 1.18e-7)
    P = LTI(model.A, np.hstack([model.Bu, model.Bd, model.Bf]), model.C,
            np.hstack([model.Du, model.Dd, model.Df]), model.dt)
    mw = FDIModel.from_control(P, u=list(range(model.nu)), w=list(range(model.nu, model.nu + model.nd)),
                               f=list(range(model.nu + model.nd, model.nu + model.nd + model.nf)))
    pk = internal_figures(ResidualGenerator(Qn, mw, "probe"))["peaks"]
    low = np.min(pk["f"][0])
    assert pk["w"][0] / low <= DEC_TOL and pk.get("w_error", [0.0])[0] > 0, pk["w"][0] / low
    assert abs(pk["w"][0] / low - ref_leak) <= (pk["w_error"][0] + pk["w_sensitivity"][0]) / low + base
    # injected leaks: fault u4's column plus eps times the weakest required fault's (its gain is 1 on Qn)
    j = 1 + int(np.argmin(ref[1:]))
    for eps in (1e-6, 1e-3):
        Bf, Df = m2.Bf.copy(), m2.Df.copy()
        cx, cw = m2.faults[0].columns, m2.faults[j].columns
        Bf[:, cx] += eps * Bf[:, cw]
        Df[:, cx] += eps * Df[:, cw]
        P = LTI(m2.A, np.hstack([m2.Bu, Bf]), m2.C, np.hstack([m2.Du, Df]), m2.dt)
        m3 = FDIModel.from_control(P, u=list(range(m2.nu)), f=list(range(m2.nu, m2.nu + m2.nf)))
        pk = internal_figures(ResidualGenerator(Qn, m3, "probe"))["peaks"]
        leak = pk["f"][0, 0] / np.min(pk["f"][0, 1:])
        assert leak - pk["f_error"][0, 0] > DEC_TOL and leak == pytest.approx(eps, rel=0.1), leak
