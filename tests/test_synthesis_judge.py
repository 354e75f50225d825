"""The one judge (issue 17, items 1-5): rows come back normalised to unit weakest fault gain,
and u/d leakage is judged ABSOLUTE on that normalised internal form R = Q·[Gu Gd Gw Gf; I 0 0 0];
``leakage()``, ``structure_matrix()`` and ``info['postconditions']`` are one computation;
R's own poles (not only Q's) must respect the margin, inclusively.

Every property is judged here by an independent computation: the state-space matrices of the
model and of Q, diagonally balanced by scipy (LAPACK gebal) and evaluated at frequency points
with numpy.linalg.solve, on our own grid — none of fmu_fdi's LTI/analysis code.
"""
import functools

import numpy as np
import published as pub
import pytest
import scipy.linalg as sla
from judge_models import ill_scaled_model

from fmu_fdi import (DesignError, FDIModel, component_fault, leakage, nullspace_design, sensor_fault, structure_matrix,
                     structured_bank)
from fmu_fdi.design.problems.achievable import achievable_structure
from fmu_fdi.design.toolkit.postconditions import DEC_TOL, check_generator
from fmu_fdi.generator import ResidualGenerator
from fmu_fdi.lti import LTI

GROUPS = ("u", "d", "w", "f")


# ------------------------------------------------------------------ independent numerics
def _values(A, B, C, D, lam):
    """C (λI - A)^{-1} B + D at the points lam, on the gebal-balanced realisation."""
    A, B, C, D = (np.atleast_2d(np.asarray(X, float)) for X in (A, B, C, D))
    if A.size == 0:
        return np.repeat(D[None].astype(complex), lam.size, axis=0)
    _, (s, _) = sla.matrix_balance(A, permute=False, separate=True)
    A, B, C = A * s[None, :] / s[:, None], B / s[:, None], C * s[None, :]
    n = A.shape[0]
    return np.stack([C @ np.linalg.solve(x * np.eye(n) - A, B) + D for x in lam])


def _plant(model):
    """(A, B, C, D) of Ge = [Gu Gd Gw Gf; I 0 0 0] from the model's own matrices."""
    Bs, Ds = zip(*(model.matrices(g) for g in GROUPS))
    B, D = np.hstack(Bs), np.hstack(Ds)
    low = np.zeros((model.nu, B.shape[1]))
    low[:, :model.nu] = np.eye(model.nu)
    return model.A, B, np.vstack([model.C, np.zeros((model.nu, model.n))]), np.vstack([D, low])


def _grid(model, num=600):
    if model.dt:  # the unit circle up to Nyquist
        return np.exp(1j * np.linspace(0.0, np.pi, num))
    return 1j * np.concatenate([[0.0], np.logspace(-4, 4, num)])


def _blocks(model):
    """Column indices of u, d, w and of every fault in Ge's inputs."""
    k, out = 0, {}
    for g, cnt in zip(GROUPS, (model.nu, model.nd, model.nw, model.nf)):
        out[g] = np.arange(k, k + cnt)
        k += cnt
    for f in model.faults:
        out[f.name] = out["f"][f.columns]
    return out


def _peak(X):
    return float(np.max(np.linalg.norm(X, 2, axis=(1, 2)))) if X.shape[1] and X.shape[2] else 0.0


def independent(gen, lam=None):
    """Per residual group: peaks over our grid of ||R_X||, X = u, d, w and every fault."""
    model, Q = gen.model, gen.Q
    if lam is None:
        # points within 1e-9 (relative) of a pole of the realisations are that pole (ω = 0 next
        # to an integrator rounded to -9e-17: the realisation's 1e-16 junk is the value there)
        lam = _grid(model)
        poles = np.concatenate([np.linalg.eigvals(X) for X in (model.A, Q.A) if X.size] or [np.zeros(0)])
        if poles.size:
            lam = lam[np.min(np.abs(lam[:, None] - poles[None, :]), axis=1) > 1e-9 * max(1, np.abs(poles).max())]
    Gv = _values(*_plant(model), lam)
    Qv = _values(Q.A, Q.B, Q.C, Q.D, lam)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))
    R = Qv[ok] @ Gv[ok]
    cols = _blocks(model)
    return [{x: _peak(R[:, g][:, :, c]) for x, c in cols.items()} for g in gen.groups], (Qv[ok], Gv[ok])


def old_relative_leak(gen):
    """The issue-13 measure this judge replaces: max ||R_ud|| / max ||Q|| ||Ge_ud||."""
    figs, (Qv, Gv) = independent(gen)
    cols = _blocks(gen.model)
    ud = np.r_[cols["u"], cols["d"]]
    R = Qv @ Gv
    n2 = lambda X: np.linalg.norm(X, 2, axis=(1, 2))  # noqa: E731
    return float(n2(R[:, :, ud]).max() / (n2(Qv) * n2(Gv[:, :, ud])).max())


def assert_normalised_contract(gen, S=None, names=None):
    """Independent check of a returned design: weakest required fault gain ≈ 1 per row (our grid's
    peak of a block the judge peaked at 1 on its grid: within [0.9, 1.5] — a lower bound from a
    coarser grid, raised by what it missed between its points), u/d leakage ≤ 10·dec_tol on our
    grid (rounding of a decoupled block is flat; a factor 10 covers a narrow peak between the
    judge's points), the 0-faults alike."""
    model = gen.model
    names = list(model.fault_names if names is None else names)
    S = np.ones((len(gen.groups), len(names)), int) if S is None else np.asarray(S)
    figs, _ = independent(gen)
    for i, f in enumerate(figs):
        req = [f[nm] for nm, s in zip(names, S[i]) if s]
        assert 0.9 <= min(req) <= 1.5, (i, req)
        assert max(f["u"], f["d"]) <= 10 * DEC_TOL, (i, f)
        for nm, s in zip(names, S[i]):
            if not s:
                assert f[nm] <= 10 * DEC_TOL, (i, nm, f[nm])
    return figs


def same_report(gen):
    """info['postconditions'] is what leakage() and structure_matrix() report for the object."""
    pc = gen.info["postconditions"]
    assert pc["leakage"] == leakage(gen)
    assert np.array_equal(np.asarray(pc["structure_matrix"]), structure_matrix(gen))


# ------------------------------------------------------------------ the random ill-scaled set
SEEDS = [0, 1, 2, 5]  # continuous and discrete, n 16-26, with and without d (fast subset)


@pytest.mark.parametrize("seed", SEEDS)
def test_ill_scaled_designs_meet_the_judge_or_refuse(seed):
    model = ill_scaled_model(seed)
    try:
        gen = nullspace_design(model)
    except DesignError as exc:
        assert "post-conditions" in str(exc) or "no residual" in str(exc)
        return
    assert_normalised_contract(gen)
    same_report(gen)
    # the judge and leakage() agree with the independent figure: both below dec_tol/10 (both
    # decide "decoupled", rounding differs), or within 10 % (a flat leak)
    ours = max(independent(gen)[0][0]["u"], independent(gen)[0][0]["d"])
    assert abs(ours - leakage(gen)) <= max(0.1 * ours, DEC_TOL / 10)


@functools.lru_cache(maxsize=None)
def _leaky_base(seed):
    model = ill_scaled_model(seed, input_decades=4.0)
    return model, nullspace_design(model, rdim=1)


@pytest.mark.parametrize("seed", [0, 2])
@pytest.mark.parametrize("eps", [1e-5, 3e-3])
def test_leaky_filter_is_refused_although_old_measure_passed(seed, eps):
    """A good design, perturbed on purpose: ``Q' = Q + ε [0 e_1ᵀ]`` (a static path from u1 to r)
    gives ``R_u' = R_u + ε e_1ᵀ`` — a flat leak ε — with R_f unchanged (the u-columns of Ge's
    lower block carry no fault). Input channels scaled over four decades make ||Q|| ||Ge_u||
    large, so the issue-13 relative measure sees only ε/(||Q|| ||Ge_u||)."""
    model, gen = _leaky_base(seed)
    Q = gen.Q
    D = Q.D.copy()
    D[0, model.ny] += eps
    bad = ResidualGenerator(LTI(Q.A, Q.B, Q.C, D, Q.dt), model, "nullspace")
    leak = independent(bad)[0][0]["u"]
    assert leak == pytest.approx(eps, rel=1e-3)
    assert leakage(bad) == pytest.approx(leak, rel=1e-3)  # the judge's figure is the user's
    with pytest.raises(DesignError, match=r"u\+?d? ?leak|leak"):
        check_generator(bad)
    # the failure of issue 17: the old relative figure (here ~1e-14 … 1e-10 of the leak's
    # 1e-5 … 3e-3) stays below its 1e-6 tolerance, so the old judge passed this filter
    assert old_relative_leak(bad) < 1e-6


def test_normalisation_is_unit_weakest_gain_and_leakage_scales_with_it():
    """check_generator scales a row by 1/min_j ||R_fj||; an unnormalised exact filter scaled by
    1e-6 comes back with unit weakest gain, the same leakage figure relative to it."""
    model = pub.ex5_3()
    gen = nullspace_design(model, rdim=1, poles=[-3])
    Q = gen.Q
    small = ResidualGenerator(LTI(Q.A, Q.B, 1e-6 * Q.C, 1e-6 * Q.D, Q.dt), model, "nullspace")
    fig = check_generator(small)
    assert fig["scales"][0] == pytest.approx(1e6, rel=1e-9)
    figs, _ = independent(small)
    assert min(figs[0][nm] for nm in model.fault_names) == pytest.approx(1.0, rel=1e-2)
    same_report(small)


# ------------------------------------------------------------------ zero filter, R's poles
def _siso_model(num_den_f, num_den_w=None):
    import control as ct

    cols = [num_den_f] + ([num_den_w] if num_den_w else [])
    G = LTI.from_control(ct.minreal(ct.ss(ct.tf([[c[0] for c in cols]], [[c[1] for c in cols]])), verbose=False))
    return FDIModel.from_matrices(G.A, np.zeros((G.n, 0)), G.C, Bw=G.B[:, 1:] if num_den_w else None,
                                  Dw=G.D[:, 1:] if num_den_w else None,
                                  faults=[component_fault("f", G.B[:, [0]], G.D[:, [0]])])


def _r_keeps_pole(gen, p0):
    """Independently: does R have a pole at p0? ||R(p0 + δ)|| grows like 1/δ there."""
    near = np.array([p0 + 1e-3, p0 + 1e-6])
    figs, (Qv, Gv) = independent(gen, near)
    g = np.linalg.norm(Qv @ Gv, 2, axis=(1, 2))
    return bool(g[1] > 100 * g[0])


def test_zero_filter_is_refused_or_normalised():
    """One output, Gf = 1/s, Gw = 1/(s²+4): the old design returned Q = 2.9e-16 as a success."""
    model = _siso_model(([1], [1, 0]), ([1], [1, 0, 4]))
    for kw in ({}, {"noise": "ignore"}):
        try:
            gen = nullspace_design(model, **kw)
        except DesignError as exc:
            assert "post-conditions" in str(exc) or "noise" in str(exc)
            continue
        figs, _ = independent(gen)
        assert 0.9 <= figs[0]["f"] <= 1.5 and figs[0]["w"] < 1e6
        assert not _r_keeps_pole(gen, 0.0) and not _r_keeps_pole(gen, 2j)


def test_rounding_noise_filter_is_refused():
    model = _siso_model(([1], [1, 1]))
    noise = ResidualGenerator(LTI.static(np.array([[2.9e-16]])), model, "nullspace")
    with pytest.raises(DesignError, match="numerically zero"):
        check_generator(noise)
    fine = ResidualGenerator(LTI.static(np.array([[3.0]])), model, "nullspace")
    check_generator(fine)
    assert fine.Q.D[0, 0] == pytest.approx(1.0)  # |Gf| = 1/|s+1| peaks at 1 (ω = 0): scale 1/3


@pytest.mark.parametrize("den", [[1, -1], [1, 0], [1, 0, 4]])
def test_fault_pole_outside_margin_is_not_in_r(den):
    """Gf = [1/(s−1); 1/(s+2)] (and 1/s, 1/(s²+4)) with no u/d: a static Q seeing y1 keeps the pole
    in R although Q is stable; the judge refuses it, names R's pole, and passes Q = [0 1]."""
    import control as ct

    G = LTI.from_control(ct.minreal(ct.ss(ct.tf([[[1]], [[1]]], [[den], [[1, 2]]])), verbose=False))
    model = FDIModel.from_matrices(G.A, np.zeros((G.n, 0)), G.C, faults=[component_fault("f", G.B, G.D)])
    p0 = complex(np.roots(den)[0])
    both = ResidualGenerator(LTI.static(np.array([[1.0, 1.0]])), model, "nullspace")
    assert _r_keeps_pole(both, p0)
    with pytest.raises(DesignError, match="R stability.*keeps the plant pole"):
        check_generator(both)
    good = ResidualGenerator(LTI.static(np.array([[0.0, 1.0]])), model, "nullspace")
    assert not _r_keeps_pole(good, p0)
    fig = check_generator(good)
    assert fig["R_poles"] == [] and good.Q.D[0, 1] == pytest.approx(2.0)  # 1/(s+2) peaks at 1/2
    try:  # a design either returns a stable R or refuses
        gen = nullspace_design(model)
    except DesignError:
        return
    assert not _r_keeps_pole(gen, p0)
    assert_normalised_contract(gen)


def test_unstable_plant_cancelled_mode_is_not_a_pole_of_r():
    """Varga's Ex. 5.4 (poles 2, 3 in Gu): R_f = -Q_u is stable although the series realisation
    Q·Ge has the unstable modes (unobservable): the judge must not count them."""
    gen = nullspace_design(pub.ex5_4(), rdim=1, poles=[-1.0])
    assert gen.info["postconditions"]["R_poles"] == []
    assert not _r_keeps_pole(gen, 2.0) and not _r_keeps_pole(gen, 3.0)
    assert_normalised_contract(gen)


# ------------------------------------------------------------------ smarg inclusive
def test_smarg_is_inclusive():
    """Re p ≤ smarg passes (FaultDetectionTools.jl's stability domain is closed)."""
    gen = nullspace_design(pub.ex5_3(), rdim=1, poles=[-3])
    pole = float(np.max(np.linalg.eigvals(gen.Q.A).real))
    check_generator(gen, smarg=pole)
    with pytest.raises(DesignError, match="stability margin"):
        check_generator(gen, smarg=pole - 1e-9)


def test_smarg_is_inclusive_discrete():
    model = pub.ex5_3().discretize(0.1)
    gen = nullspace_design(model, rdim=1, poles=[0.5])
    radius = float(np.max(np.abs(np.linalg.eigvals(gen.Q.A))))
    check_generator(gen, smarg=radius)
    with pytest.raises(DesignError, match="stability margin"):
        check_generator(gen, smarg=radius - 1e-9)


# ------------------------------------------------------------------ banks: one report, one row test
def test_bank_rows_normalised_and_reports_agree():
    model = pub.ex5_3()
    S = achievable_structure(model)
    bank = structured_bank(model, S, poles=[-3])
    assert_normalised_contract(bank, S)
    same_report(bank)
    np.testing.assert_array_equal(structure_matrix(bank), S)
    for g, member in zip(bank.groups, bank.members):  # the members carry the bank's scaling
        np.testing.assert_allclose(member.Q.D, bank.Q.D[g], rtol=0, atol=0)


def test_strong_report_agrees_with_postconditions():
    model = pub.ex5_3()
    bank = structured_bank(model, [[1, 1]], poles=[-3], freqs=[0.0])
    pc = bank.info["postconditions"]
    assert np.array_equal(np.asarray(pc["strong_structure_matrix"]), structure_matrix(bank, freqs=[0.0]))
    # independently: the normalised row's gains at ω = 0 reach FDGainTol
    figs, (Qv, Gv) = independent(bank, np.array([0j]))
    cols = _blocks(model)
    for nm in model.fault_names:
        assert np.linalg.norm((Qv @ Gv)[0][:, cols[nm]], 2) >= 0.01


def test_refused_row_is_not_listed_and_listed_rows_are_designed():
    """structured_bank refuses, with the reason achievable_structure uses, a row it does not list."""
    model = pub.ex5_3()
    listed = {tuple(r) for r in achievable_structure(model).tolist()}
    for row in ([1, 0], [0, 1], [1, 1]):
        if tuple(row) in listed:
            bank = structured_bank(model, [row], poles=[-3])
            assert_normalised_contract(bank, [row])
        else:
            with pytest.raises(DesignError, match="not achievable"):
                structured_bank(model, [row], poles=[-3])


@pytest.mark.slow
def test_boeing747_every_listed_row_is_designed():
    """Row [0 0 1 1 0] sees f3/f4 only through the 4th digit of the data (relative gain 3e-3) and not
    at all at DC; with the moved altitude mode (+3.1e-5 rad/s) mirrored to -3.1e-5 the filter's DC gain
    (5e5) lifted the rounding of the decoupling to 2e-5 of that gain. Moved poles now go to Varga's
    sdeg = -0.05 at least, and the row is designed (the whole contract re-judged below)."""
    from test_synthesis_published import boeing747

    model = boeing747()
    for row in achievable_structure(model).tolist():
        bank = structured_bank(model, [row])
        assert_normalised_contract(bank, [row])


def test_fault_pole_outside_margin_discrete():
    """The same on the sampled plant (Ts = 0.1): z = e^0.1 kept by Q = [1 1], not by Q = [0 1]."""
    import control as ct

    G = LTI.from_control(ct.minreal(ct.ss(ct.tf([[[1]], [[1]]], [[[1, -1]], [[1, 2]]])), verbose=False))
    model = FDIModel.from_matrices(G.A, np.zeros((G.n, 0)), G.C, faults=[component_fault("f", G.B, G.D)])
    model = model.discretize(0.1)
    z0 = complex(np.exp(0.1))
    both = ResidualGenerator(LTI.static(np.array([[1.0, 1.0]]), 0.1), model, "nullspace")
    assert _r_keeps_pole(both, z0)
    with pytest.raises(DesignError, match=r"R stability.*largest \|pole\| = 1.10517"):
        check_generator(both)
    good = ResidualGenerator(LTI.static(np.array([[0.0, 1.0]]), 0.1), model, "nullspace")
    assert not _r_keeps_pole(good, z0)
    assert check_generator(good)["R_poles"] == []


def test_fault_visibility_exactly_fdtol_is_accepted():
    """FDtol is inclusive everywhere (issue 17: a combination landing on FDtol exactly was refused):
    Niemann's example designs with relative fault gain γ; the same design with FDtol = γ (the very
    number the judge computed, so equality is exact, not approximate) passes the judge and the
    design's own gates (before, the combination search's gate was strict and refused γ = FDtol)."""
    from test_synthesis_published import niemann

    model = niemann()
    gen = nullspace_design(model)
    gamma = gen.info["postconditions"]["fault_visibility"]
    assert 0 < gamma < 1
    again = nullspace_design(model, FDtol=gamma)
    assert again.info["postconditions"]["fault_visibility"] >= gamma
    assert again.info["postconditions"]["FDtol"] == gamma and not again.info["postconditions"].get("failures")


def test_combination_gate_is_inclusive():
    """The combination search's visibility gate (``_select.visibility_gated``) admits a combination
    whose cosine γ equals FDtol exactly, as the judge does (``γ ≥ FDtol``). One point, one row,
    one output, one fault: ||h P|| = 0.5, ||h Y|| ||Gf|| = 1·1, so γ = 0.5 exactly in binary."""
    from fmu_fdi.design.toolkit._select import visibility_gated

    P = [np.array([[[0.5]]])]
    Y = np.array([[[1.0]]])
    G = np.array([[[1.0]]])
    h = np.array([1.0])
    assert visibility_gated(P, Y, G, [np.array([0])], 0.5)(h) >= 0  # admitted (a refused one is γ - 1 < 0)
    assert visibility_gated(P, Y, G, [np.array([0])], np.nextafter(0.5, 1))(h) < 0



# ------------------------------------------------------------------ R's unstable poles decided with δ_i
def _weakly_coupled_unstable(eps: float, dt: float):
    """One output y = u/(λ − a) + f with an unstable plant pole a = 1 (sampled: z = 1.5) and the row
    ``r = q_y y + q_u u``, ``q_y = (λ − a − ε)/(λ − c)``, ``q_u = −1/(λ − c)`` (c = −1; sampled 0.3): the zero
    of ``q_y`` cancels the pole through Q's dynamics (a transmission zero, not a static annihilator), as the
    designs' rows do. ``R_f = q_y`` and ``R_u = q_y/(λ − a) + q_u = −ε/((λ − c)(λ − a))``: the unstable mode stays
    in R_u with the residue ``−ε/(a − c)`` (closed form). Realisation ``q = 1·[1 0] + (c − a − ε, −1)/(λ − c)``."""
    a, c = (1.5, 0.3) if dt else (1.0, -1.0)
    model = FDIModel.from_matrices(np.array([[a]]), [[1.0]], [[1.0]], dt=dt, y_names=["y"],
                                   faults=[sensor_fault("f", "y")])
    Q = LTI(np.array([[c]]), np.array([[c - a - eps, -1.0]]), np.array([[1.0]]), np.array([[1.0, 0.0]]), dt)
    return model, Q, a, c


def _laurent_residue(model, Q, p, cols):
    """``lim_{h→0} h·R(p + h)`` for the columns ``cols`` of Ge, by numpy (:func:`_values` of this file, not the
    library's evaluation) and Richardson's step: ``2·f(h/2) − f(h)`` removes the O(h) term of
    ``h·R(p + h) = ρ + h·(regular part)``; h = 1e-4 leaves O(h²) = 1e-8 relative, the cancelling product Q·Ge
    (terms ~1/h) rounds to ~eps/h = 2e-12 of R's size ρ/h, i.e. ~2e-12 absolute in ρ."""
    def f(h):
        lam = np.array([p + h])
        R = _values(Q.A, Q.B, Q.C, Q.D, lam) @ _values(*_plant(model), lam)
        return h * R[0][:, cols]
    h = 1e-4
    return 2 * f(h / 2) - f(h)


@pytest.mark.parametrize("dt", [0.0, 0.1])
@pytest.mark.parametrize("eps, refused", [(1e-9, True), (0.0, False), (2.0 ** -50, False)])
def test_unstable_mode_kept_below_the_leak_tolerance_is_a_pole_of_r(eps, refused, dt):
    """A row whose u-leak stays under dec_tol at every frequency but whose R_u keeps an unstable plant mode with
    a residue far above its rounding bound must be refused as an unstable pole of R (issue 17: the staircase's
    fixed tolerance 1e-8 missed a residue 8.4e-9 of approximate-matching seed 32's row, against δ_i = 2e-14); its
    twin cancelling the mode exactly (ε = 0) passes.

    Independently (numpy): the normalised u-leak on a dense grid is at most ε·(1 … 1.5) (continuous: R_f is
    all-pass, |R_u| ≤ ε at ω = 0; sampled: |R_u| ≤ ε/(0.7·0.5) at z = 1 over the fault gain 2.5/1.3 at z = −1), so
    the leak alone cannot refuse it; the Laurent coefficient of R_u at the unstable pole is ε/(a − c) (continuous
    ε/2, sampled ε/1.2). The judge's rounding bound of the row's zero is, by hand, δ_i = N·eps·(max ||Q|| ||c_p||)
    (n = 1: the eigen-direction is exact, sep = ∞) with N = 2, max ||Q|| = √2 (λ = 0; sampled ≤ 2.6 at z = −1) and
    ||c_p|| = O(1) on the balanced data: ~1e-15 (the judge's, with the slope and evaluation terms: 2.4e-15,
    sampled 1.5e-15), so ε = 1e-9 is ~2e5 δ_i, and ε = 2⁻⁵⁰ (exact in c − a − ε; residue 4.4e-16 ≈ 0.2 δ_i) is a
    cancellation to rounding, as ε = 0 is one by construction: both pass."""
    model, Q, a, c = _weakly_coupled_unstable(eps, dt)
    cols = _blocks(model)
    # the normalised u-leak by numpy: ||R_u|| / max ||R_f|| on a dense grid
    lam = _grid(model, 2000)
    R = _values(Q.A, Q.B, Q.C, Q.D, lam) @ _values(*_plant(model), lam)
    fgain = float(np.max(np.abs(R[:, 0, cols["f"]])))
    leak = float(np.max(np.abs(R[:, 0, cols["u"]]))) / fgain
    assert leak <= 1.5 * eps * (1 + 1e-6) + 1e-15 < DEC_TOL
    # the residue of the normalised R_u at the unstable pole, by numpy against its closed form
    rho = abs(_laurent_residue(model, Q, a, cols["u"])[0, 0]) / fgain
    assert rho == pytest.approx(eps / abs(a - c) / fgain, rel=1e-6, abs=1e-13)
    gen = ResidualGenerator(Q, model, "test")
    fig = check_generator(gen, raise_error=False)
    assert fig["decoupling"] <= DEC_TOL  # the judge reads the leak as numpy does: not what refuses the row
    if not refused:
        assert not fig.get("failures") and fig["R_poles"] == [], fig
        return
    assert [complex(z) for z in fig["R_poles"]] == [pytest.approx(a, rel=1e-12)], fig
    msg = " ".join(fig["failures"])
    assert "R stability" in msg or "keeps the plant pole" in msg, msg
    assert "unstable" in msg and "residue" in msg and "δ_i" in msg, msg
    with pytest.raises(DesignError, match="R stability.*keeps the plant pole"):
        check_generator(ResidualGenerator(Q, model, "test"))


# ------------------------------------------------------------------ a row read alone and in a bank
def _bandpass(w0, zeta=0.3):
    """``ω0 s / (s² + 2ζω0 s + ω0²)``: peak ``1/(2ζ)`` at ``ω = ω0`` exactly."""
    return LTI(np.array([[0.0, 1.0], [-w0 ** 2, -2 * zeta * w0]]), np.array([[0.0], [1.0]]), np.array([[0.0, w0]]),
               np.zeros((1, 1)), 0.0)


def test_bank_member_reads_as_it_reads_alone():
    """Random seed 218's 16-row bank was refused for a row the same judge passed alone: one grid for the whole bank,
    built from every member's poles, sampled the row elsewhere (its excluded fault 1.18e-7 in the bank, 3.3e-8
    alone). Here two rows whose poles are nine decades apart (3e-3 and 1e6 rad/s) on the plant ``y0 = u/(s+1) + f1``,
    ``y1 = f2``: row 1 = F1·[1, 0, −(1−ε)/(s+1)] (R_u = ε F1/(s+1), R_f1 = F1), row 2 = F2·[0, 1, 0], F_i bandpasses.
    Each row's figures in the bank are its figures alone, to the last bit (one function of the row's data and the
    plant's), and they are numpy's peaks as the grid samples them: below the dense-grid peak, and above it by at
    most the grid's spacing — the row's own grid spans ~3e-5 … 1e2 rad/s (two decades beyond its pole scales) in
    120 log-spaced points, ratio ≤ 10^(6.5/120) = 1.133, so the peak ω0 lies within 6.4 % of a point, where the
    bandpass (ζ = 0.3) reads ``1/sqrt(1 + ((1.064 − 1/1.064)/0.6)²) = 0.979`` of its peak: bound 0.975. (The bank's
    one grid spanned 13 decades, ratio 1.28, and read row 1's fault gain at 0.95 of its peak.)"""
    from fmu_fdi import sensor_fault as sf
    from fmu_fdi.design.toolkit.postconditions import internal_figures
    from fmu_fdi.generator import ResidualBank

    model = FDIModel.from_matrices(np.array([[-1.0]]), np.array([[1.0]]), np.array([[1.0], [0.0]]),
                                   faults=[sf("f1", "y0"), sf("f2", "y1")])
    eps = 1e-8
    base1 = LTI(np.array([[-1.0]]), np.array([[0.0, 0.0, -(1 - eps)]]), np.array([[1.0]]), np.array([[1.0, 0.0, 0.0]]),
                0.0)
    base2 = LTI(np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((1, 0)), np.array([[0.0, 1.0, 0.0]]), 0.0)
    members = [ResidualGenerator(_bandpass(3e-3) @ base1, model, "row"), ResidualGenerator(_bandpass(1e6) @ base2,
                                                                                           model, "row")]
    bank = ResidualBank(members, "bank")
    in_bank = internal_figures(bank)
    # dense, and denser (0.1 % steps) within 12 % of the two peaks, which it holds exactly
    lam = 1j * np.concatenate([np.logspace(-6, 8, 2801)] + [w * np.logspace(-0.05, 0.05, 101) for w in (3e-3, 1e6)])
    for i, m in enumerate(members):
        alone = internal_figures(m)
        for k in ("u", "Q", "bound"):
            assert in_bank["peaks"][k][i] == alone["peaks"][k][0], (i, k, in_bank["peaks"][k][i], alone["peaks"][k][0])
        np.testing.assert_array_equal(in_bank["peaks"]["f"][i], alone["peaks"]["f"][0])
        np.testing.assert_array_equal(in_bank["cosine"][i], alone["cosine"][0])
        (ref,), _ = independent(m, lam)
        for k, v in (("u", alone["peaks"]["u"][0]), ("f1", alone["peaks"]["f"][0, 0]), ("f2", alone["peaks"]["f"][0, 1])):
            if ref[k] == 0:
                assert v <= 1e-15, (i, k, v)
            else:
                assert 0.975 * ref[k] <= v <= ref[k] * (1 + 1e-9), (i, k, v, ref[k])
