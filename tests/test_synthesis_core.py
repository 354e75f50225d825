"""The synthesis core (issue 17): properties any correct result must have, judged with numpy alone.

Every value here is computed from the matrices of the model and of the returned filter with
``numpy.linalg.solve`` (``Q(λ) = C_q (λI − A_q)⁻¹ B_q + D_q``, ``G(λ)`` likewise), never with the
package's analysis, internal-form or post-condition code.

1. Stable internal form: when the plant has an unstable or marginal pole that the decoupling leaves
   in ``R = Q·Ge`` (``Gf = [1/(s−1); 1/(s+2)]``: the null space is static, ``Q·Gf`` keeps +1), the
   returned filter's whole internal form is stable — R is analytic at the plant's pole — and Q is
   stable with the margin.
"""
import warnings

import numpy as np
import pytest

from fmu_fdi import DesignError, FDIModel, component_fault, nullspace_design, structured_bank


# ---------------------------------------------------------------- independent evaluation
def _tf_value(sys_mats, lam):
    """``C (λI − A)⁻¹ B + D`` from the bare matrices (numpy only)."""
    A, B, C, D = sys_mats
    if A.shape[0] == 0:
        return D.astype(complex)
    return C @ np.linalg.solve(lam * np.eye(A.shape[0]) - A, B.astype(complex)) + D


def _Q(gen):
    Q = gen.Q
    return Q.A, Q.B, Q.C, Q.D


def _Ge(model):
    """``[Gu Gd Gw Gf; I 0 0 0]`` as bare matrices, assembled here from the model's fields."""
    B = np.hstack([model.Bu, model.Bd, model.Bw, model.Bf])
    D = np.hstack([model.Du, model.Dd, model.Dw, model.Df])
    m, tot = model.nu, B.shape[1]
    low = np.zeros((m, tot))
    low[:, :m] = np.eye(m)
    return model.A, B, np.vstack([model.C, np.zeros((m, model.n))]), np.vstack([D, low])


def _R(gen, lam):
    return _tf_value(_Q(gen), lam) @ _tf_value(_Ge(gen.model), lam)


def _fault_cols(model):
    return slice(model.nu + model.nd + model.nw, model.nu + model.nd + model.nw + model.nf)


def _companion(den):
    """Controllable canonical realisation of ``1/den(λ)`` (den monic, highest power first)."""
    den = np.asarray(den, float)
    k = den.size - 1
    A = np.zeros((k, k))
    A[:-1, 1:] = np.eye(k - 1)
    A[-1, :] = -den[::-1][:-1]
    B = np.zeros((k, 1))
    B[-1, 0] = 1.0
    C = np.zeros((1, k))
    C[0, 0] = 1.0
    return A, B, C


def fault_only_model(dens, dt=0.0):
    """``y_i = f / den_i(λ)``: one fault, no u, d or w (the issue's examples)."""
    blocks = [_companion(d) for d in dens]
    n = sum(b[0].shape[0] for b in blocks)
    A = np.zeros((n, n))
    Bf = np.zeros((n, 1))
    C = np.zeros((len(dens), n))
    k = 0
    for i, (a, b, c) in enumerate(blocks):
        s = a.shape[0]
        A[k:k + s, k:k + s] = a
        Bf[k:k + s] = b
        C[i, k:k + s] = c
        k += s
    return FDIModel.from_matrices(A, np.zeros((n, 0)), C, dt=dt, faults=[component_fault("f", Bf)])


def _eig(gen):
    return np.linalg.eigvals(gen.Q.A) if gen.Q.n else np.zeros(0)


# a continuous pole p and its discrete analogue (dt = 0.1): unstable, at the boundary, undamped pair
CONTINUOUS = {
    "unstable": [[1, -1], [1, 2]],                 # [1/(s-1); 1/(s+2)]
    "integrator": [[1, 0], [1, 2]],                # [1/s; 1/(s+2)]
    "oscillator": [[1, 0, 4], [1, 2]],             # [1/(s^2+4); 1/(s+2)]
}
DISCRETE = {
    "unstable": [[1, -1.2], [1, -0.5]],            # [1/(z-1.2); 1/(z-0.5)]
    "integrator": [[1, -1], [1, -0.5]],            # [1/(z-1); ...]
    "oscillator": [[1, -2 * np.cos(0.3), 1], [1, -0.5]],  # poles e^{±0.3j} on the unit circle
}


def _bad_poles(model):
    eig = np.linalg.eigvals(model.A)
    return eig[np.abs(eig) >= 1 - 1e-9] if model.dt else eig[eig.real >= -1e-9]


def _assert_R_analytic_at(gen, poles):
    """R = Q·Ge has no pole at each of ``poles``: approaching p from inside the stability region by
    δ ≈ 1e-5 and 1e-7 (relative; off round numbers, where designs put poles), a pole of residue ρ
    would grow |R| by the ratio of the δs (100); an analytic R changes by |R'|·δ ≤ 1e-5·|R'|. 1.5
    separates the two with room for |R'| up to 1e4·|R| (a zero of R next to p).
    The rounding of an exact cancellation (a decoupled column, ~1e-12 of |Q||Ge| — which itself grows
    like 1/δ) is allowed on top: 1e-10·max(|Q(λ)|, |Q|_peak)·|Ge_f(λ)| at the inner point — the row's peak gain on
    the boundary (200 points), not only |Q(λ)|: the rounding of Q's values is that of its terms, and where the stable
    factor M put several zeros next to p (tiny seed 45's bank row: three moved poles 1.35 … 1.42) |Q(λ)| is far
    below them (a residue 1.4e-16 of the unit fault gain read as a pole)."""
    fc = _fault_cols(gen.model)
    dt = gen.model.dt
    sweep = np.exp(1j * np.linspace(0.0, np.pi, 200)) if dt else 1j * np.concatenate([[0.0], np.logspace(-3, 3, 199)])
    qpeak = max(np.linalg.norm(_tf_value(_Q(gen), z), 2) for z in sweep)
    for p in poles:
        steps = [1.237e-5, 1.237e-7]
        vals = []
        for d in steps:
            lam = p * (1 - d) if gen.model.dt else p - d * max(1.0, abs(p))
            Qv, Gv = _tf_value(_Q(gen), lam), _tf_value(_Ge(gen.model), lam)[:, fc]
            vals.append(np.linalg.norm(Qv @ Gv, 2))
        floor = 1e-10 * max(np.linalg.norm(Qv, 2), qpeak) * np.linalg.norm(Gv, 2)
        assert np.isfinite(vals).all()
        assert vals[1] <= 1.5 * vals[0] + floor, f"R has a pole at {p}: |R| {vals[0]:.3g} -> {vals[1]:.3g}"


def _assert_fault_visible(gen):
    """The fault gain is far from rounding: the largest |R_f| on a frequency sweep is at least 1e-3
    of |Q_y|·|G_f| there (the residual is normalised to a unit peak, so this is an absolute floor too)."""
    model = gen.model
    om = np.logspace(-3, np.log10(np.pi / model.dt) if model.dt else 3, 200)
    lam = np.exp(1j * om * model.dt) if model.dt else 1j * om
    best = 0.0
    for l in lam:
        try:
            R = _R(gen, l)[:, _fault_cols(model)]
        except np.linalg.LinAlgError:
            continue
        best = max(best, np.linalg.norm(R, 2))
    assert best > 1e-3


@pytest.mark.parametrize("dt, name", [(0.0, k) for k in CONTINUOUS] + [(0.1, k) for k in DISCRETE])
def test_internal_form_is_stable_for_unstable_and_marginal_fault_poles(dt, name):
    model = fault_only_model((DISCRETE if dt else CONTINUOUS)[name], dt)
    bad = _bad_poles(model)
    assert bad.size  # the example has what it is named for
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gen = nullspace_design(model)
    eig = _eig(gen)
    # default margin just inside the boundary (sqrt(eps)); the moved poles sit far inside
    assert (np.all(np.abs(eig) < 1 - 1e-8) if dt else np.all(eig.real < -1e-8))
    _assert_R_analytic_at(gen, bad)
    _assert_fault_visible(gen)
    assert gen.info["internal_form"]["moved"] >= 1


@pytest.mark.parametrize("name", list(CONTINUOUS))
def test_sdeg_places_the_moved_poles(name):
    """With sdeg = -3 every moved pole lies at Re ≤ -3 (mirrored about sdeg; no given poles), and
    with keep_stable_poles=False so does the plant's stable pole -2 that R carries."""
    model = fault_only_model(CONTINUOUS[name])
    gen = nullspace_design(model, sdeg=-3.0)
    assert np.all(_eig(gen).real <= -3.0 + 1e-9)
    _assert_R_analytic_at(gen, _bad_poles(model))
    gen2 = nullspace_design(model, sdeg=-3.0, keep_stable_poles=False)
    assert np.all(_eig(gen2).real <= -3.0 + 1e-9)
    # R's poles are Q's and the plant's: the plant pole -2 must now be cancelled in R as well
    _assert_R_analytic_at(gen2, np.array([-2.0]))


def test_decoupling_kept_when_the_plant_pole_is_moved():
    """u enters a stable mode only, the fault an unstable one: Q decouples u exactly (R_u = 0 at
    every point, to rounding 1e-12 of |Q||Ge|) and R_f is analytic at +1."""
    A = np.diag([1.0, -2.0])
    Bu = np.array([[0.0], [1.0]])
    C = np.eye(2)
    model = FDIModel.from_matrices(A, Bu, C, faults=[component_fault("f", np.array([[1.0], [0.0]]))])
    gen = nullspace_design(model)
    _assert_R_analytic_at(gen, np.array([1.0]))
    for w in (0.0, 0.3, 1.0, 7.0):
        Qv, Gv = _tf_value(_Q(gen), 1j * w), _tf_value(_Ge(model), 1j * w)
        Ru = (Qv @ Gv)[:, :1]
        assert np.linalg.norm(Ru) <= 1e-12 * np.linalg.norm(Qv) * np.linalg.norm(Gv)


def test_bank_rows_have_stable_internal_forms():
    """A structured bank on a plant with an unstable and an integrating mode: each row decouples
    the fault its structure excludes and keeps no plant pole outside the stability region."""
    A = np.diag([1.0, 0.0, -2.0])
    C = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 0.0]])
    faults = [component_fault("f1", np.array([[1.0], [0.0], [0.0]])),
              component_fault("f2", np.array([[0.0], [1.0], [0.0]]))]
    model = FDIModel.from_matrices(A, np.zeros((3, 0)), C, faults=faults)
    bank = structured_bank(model, np.eye(2, dtype=int))
    for i, g in enumerate(bank.members):
        gen_i = type("G", (), {"Q": g.Q, "model": model})()
        _assert_R_analytic_at(gen_i, np.array([1.0, 0.0]))
        assert np.all(np.linalg.eigvals(g.Q.A).real < 0) if g.Q.n else True
        for w in (0.1, 1.0, 5.0):
            R = _tf_value(_Q(g), 1j * w) @ _tf_value(_Ge(model), 1j * w)
            Rf = R[:, _fault_cols(model)]
            excluded = 1 - i  # row i sees fault i only
            assert abs(Rf[0, excluded]) <= 1e-10 * np.linalg.norm(R)


def test_given_poles_outside_the_margin_are_refused():
    model = fault_only_model(CONTINUOUS["unstable"])
    with pytest.raises(DesignError, match="stability margin smarg = -5"):
        nullspace_design(model, poles=[-3.0], smarg=-5.0)


# ------------------------------------------------------------------ 2. refusals, never crashes
def _fault_noise_model(den_f, den_w, dt=0.0):
    """One output ``y = f/den_f + w/den_w`` (the issue's crash examples)."""
    af, bf, cf = _companion(den_f)
    aw, bw, cw = _companion(den_w)
    nf_, nw_ = af.shape[0], aw.shape[0]
    A = np.block([[af, np.zeros((nf_, nw_))], [np.zeros((nw_, nf_)), aw]])
    Bf = np.vstack([bf, np.zeros((nw_, 1))])
    Bw = np.vstack([np.zeros((nf_, 1)), bw])
    return FDIModel.from_matrices(A, np.zeros((nf_ + nw_, 0)), np.hstack([cf, cw]), Bw=Bw, dt=dt,
                                  faults=[component_fault("f", Bf)])


def test_integrator_and_oscillator_faults_design():
    """``Gf = [1/s; 1/(s²+4)]`` (a ValueError before): designed, R analytic at 0 and ±2j."""
    model = fault_only_model([[1, 0], [1, 0, 4]])
    gen = nullspace_design(model)
    assert np.all(_eig(gen).real < 0)
    _assert_R_analytic_at(gen, np.array([0.0, 2j, -2j]))
    _assert_fault_visible(gen)


@pytest.mark.parametrize("den_f, den_w, dt", [([1, 0], [1, 2], 0.0), ([1, 0], [1, 0, 4], 0.0),
                                              ([1, -1], [1, -0.5], 0.1), ([1, -1], [1, -2 * np.cos(0.3), 1], 0.1)])
def test_marginal_fault_with_noise_is_not_a_zero_filter(den_f, den_w, dt):
    """``Gf = 1/s`` with ``Gw = 1/(s+2)`` or ``1/(s²+4)`` (a LinAlgError / a returned Q = 3e-33
    before): a nonzero stable filter whose fault response has no pole at 0. Q not zero: its peak
    over a sweep is above 1e-3 (rows are normalised to unit peak fault gain, and |Gf| ≥ 1e-3 on it).
    Discrete analogues: ``1/(z−1)`` with ``1/(z−0.5)`` or poles e^{±0.3j}."""
    model = _fault_noise_model(den_f, den_w, dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gen = nullspace_design(model)
    eig = _eig(gen)
    assert np.all(np.abs(eig) < 1) if dt else np.all(eig.real < 0)
    _assert_R_analytic_at(gen, np.array([1.0 if dt else 0.0]))
    om = np.linspace(1e-3, np.pi / dt, 61) if dt else np.logspace(-3, 3, 61)
    peak = max(np.linalg.norm(_tf_value(_Q(gen), np.exp(1j * w * dt) if dt else 1j * w), 2) for w in om)
    assert peak > 1e-3
    _assert_fault_visible(gen)


def tiny_model(seed):
    """A seeded tiny model: n in 0..4 with eigenvalues at the origin (z = 1), on the axis (the unit
    circle), unstable or stable, an orthogonal change of coordinates half the time; 1-3 outputs,
    0-2 known inputs, 0-1 unknown and noise inputs, 1-2 faults; continuous for even seeds,
    dt = 0.1 for odd ones."""
    rng = np.random.default_rng(seed)
    dt = 0.0 if seed % 2 == 0 else 0.1
    n = int(rng.integers(0, 5))
    kinds = rng.choice(["origin", "axis", "unstable", "stable"], size=n)
    A = np.zeros((n, n))
    i = 0
    while i < n:
        if kinds[i] == "axis" and i + 1 < n:
            w = rng.uniform(0.5, 3.0)
            c, s = (np.cos(w * dt), np.sin(w * dt)) if dt else (0.0, w)
            A[i:i + 2, i:i + 2] = [[c, s], [-s, c]]
            i += 2
            continue
        if dt:
            A[i, i] = {"origin": 1.0, "axis": -1.0, "unstable": 1 + rng.uniform(0.05, 0.5),
                       "stable": rng.uniform(-0.8, 0.9)}[kinds[i]]
        else:
            A[i, i] = {"origin": 0.0, "axis": 0.0, "unstable": rng.uniform(0.2, 2.0),
                       "stable": -rng.uniform(0.2, 3.0)}[kinds[i]]
        i += 1
    if n > 1 and rng.random() < 0.5:
        T, _ = np.linalg.qr(rng.standard_normal((n, n)))
        A = T @ A @ T.T
    p, mu, md, mw, nf = (int(rng.integers(1, 4)), int(rng.integers(0, 3)), int(rng.integers(0, 2)),
                         int(rng.integers(0, 2)), int(rng.integers(1, 3)))

    def mat(r, c, pz=0.3):
        M = rng.standard_normal((r, c))
        M[rng.random((r, c)) < pz] = 0.0
        return M

    Bu, Bd, Bw, C = mat(n, mu), mat(n, md), mat(n, mw), mat(p, n)
    Du, Dd, Dw = mat(p, mu, 0.7), mat(p, md, 0.7), mat(p, mw, 0.6)
    faults = []
    for j in range(nf):
        Bf, Df = mat(n, 1), mat(p, 1, 0.6)
        if not np.any(Bf) and not np.any(Df):
            Df[0, 0] = 1.0
        faults.append(component_fault(f"f{j}", Bf, Df))
    return FDIModel.from_matrices(A, Bu, C, Du, Bd=Bd, Dd=Dd, Bw=Bw, Dw=Dw, faults=faults, dt=dt)


def _assert_contract(gen, model, decoupled_cols):
    """Independent judge of a returned design: Q stable; ``R = Q·Ge`` zero on the decoupled columns
    at sample points (relative 1e-7 of |Q||Ge| there: exact rows of these order ≤ 4 models leak
    ~1e-13, dec_tol is 1e-6 of the peaks); R analytic at every plant pole outside the stability region."""
    eig = _eig(gen)
    assert (np.all(np.abs(eig) < 1) if model.dt else np.all(eig.real < 0))
    for w in (0.37, 1.3, 2.9):
        lam = np.exp(1j * w * model.dt) if model.dt else 1j * w
        try:
            Qv, Gv = _tf_value(_Q(gen), lam), _tf_value(_Ge(model), lam)
        except np.linalg.LinAlgError:
            continue
        R = Qv @ Gv
        if decoupled_cols.size:
            assert np.linalg.norm(R[:, decoupled_cols]) <= 1e-7 * np.linalg.norm(Qv) * np.linalg.norm(Gv)
    _assert_R_analytic_at(gen, _bad_poles(model))


@pytest.mark.parametrize("seed", range(48))
def test_tiny_models_design_or_refuse(seed):
    """Fuzz over tiny models: a design meeting the contract or a DesignError — never another
    exception (a ValueError, LinAlgError, ...)."""
    model = tiny_model(seed)
    ud = np.arange(model.nu + model.nd)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            gen = nullspace_design(model)
        except DesignError:
            gen = None
        if gen is not None:
            _assert_contract(gen, model, ud)
        if model.nf == 2:
            try:
                bank = structured_bank(model, np.eye(2, dtype=int))
            except DesignError:
                return
            fcols = np.arange(model.nu + model.nd + model.nw, model.nu + model.nd + model.nw + 2)
            for i, g in enumerate(bank.members):
                gi = type("G", (), {"Q": g.Q, "model": model})()
                _assert_contract(gi, model, np.r_[ud, fcols[1 - i]])


# ------------------------------------------------------------------ 3. static plants (n = 0)
STATIC_D = np.array([[1.0, 0.5], [0.0, 1.0], [2.0, 1.0]])


def _static_models():
    import control
    from fmu_fdi import actuator_fault, sensor_fault

    faults = [sensor_fault("s0", "y0"), sensor_fault("s1", "y1"), actuator_fault("a0", "u0")]
    yield FDIModel.from_matrices(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((3, 0)), STATIC_D, faults=faults)
    yield FDIModel.from_matrices([], [], [], STATIC_D, faults=faults, dt=0.1)
    io = {"inputs": ["u0", "u1"], "outputs": ["y0", "y1", "y2"]}
    yield FDIModel.from_control(control.ss([], [], [], STATIC_D, **io), faults=faults)
    num = [[[v] for v in row] for row in STATIC_D]
    yield FDIModel.from_control(control.tf(num, [[[1.0]] * 2] * 3, **io), faults=faults)


@pytest.mark.parametrize("k", range(4))
def test_static_plant_builds_and_designs(k):
    """n = 0 (empty A; python-control static ss/tf): the model keeps its 3 outputs and 2 inputs, and
    nullspace_design, the dedicated bank and parity_space return static filters with
    ``Q_y Du + Q_u = 0`` (u decoupled, 1e-12 of |Q|) that see their faults."""
    from fmu_fdi.design.problems.parity import parity_space

    model = list(_static_models())[k]
    assert (model.n, model.ny, model.nu) == (0, 3, 2)
    Ge = np.vstack([STATIC_D, np.eye(2)])  # [Du; I] from the data, not from the model

    def check(Q, faults_seen):
        assert Q.n == 0
        assert np.linalg.norm(Q.D @ Ge) <= 1e-12 * np.linalg.norm(Q.D)
        Df = np.vstack([model.Df, np.zeros((2, model.nf))])
        gains = np.abs(Q.D @ Df)
        for j in faults_seen:
            assert gains[:, j].max() > 1e-3 * np.linalg.norm(Q.D)

    check(nullspace_design(model).Q, range(3))
    bank = structured_bank(model, np.eye(2, dtype=int), faults=["s0", "s1"])
    for i, g in enumerate(bank.members):
        check(g.Q, [i])
        other = 1 - i
        assert abs((g.Q.D @ np.vstack([model.Df, np.zeros((2, 3))]))[0, other]) <= 1e-12 * np.linalg.norm(g.Q.D)
    par = parity_space(model, Ts=None if model.dt else 0.1)
    assert par.Q.D.shape[1] == 5 and np.linalg.norm(par.Q.D @ Ge) <= 1e-12 * np.linalg.norm(par.Q.D)


def test_static_model_file_round_trip(tmp_path):
    from fmu_fdi import component_fault as cf

    model = FDIModel.from_matrices(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((3, 0)), STATIC_D,
                                   faults=[cf("c", np.zeros((0, 1)), [[1.0], [0.0], [1.0]])])
    path = model.to_file(tmp_path / "static.json")
    back = FDIModel.from_file(path)
    assert (back.n, back.ny, back.nu) == (0, 3, 2)
    assert np.array_equal(back.Du, STATIC_D) and np.array_equal(back.Df, [[1.0], [0.0], [1.0]])


# ------------------------------------------------------------------ 4. the state-space core first
def _auto_cases():
    from published import three_tank_like
    from synthesis_models import random_model  # tests/ is on the path (conftest.py)
    from test_synthesis_published import xiong_saif_2

    return {**{f"random{s}": (lambda s=s: random_model(s)) for s in (1, 6, 7, 8)},
            "tanks": three_tank_like, "xiong_saif_2": xiong_saif_2}


@pytest.mark.parametrize("name", ["random1", "random6", "random7", "random8", "tanks", "xiong_saif_2"])
def test_auto_prefers_the_pencil_core_at_least_order(name):
    """On seeded random models (n 16-29, state scalings over decades) and two published ones whose least
    order needs two basis rows of index 1 combined over one denominator, basis='auto' returns the
    state-space (pencil) row, of the same order as the least-order polynomial row, decoupling u and d
    *pointwise* to 1e-11 of |Q||Ge| (orthogonal reductions: ~1e-14 seen; the polynomial rows of these
    models leak up to 1e-9 pointwise)."""
    model = _auto_cases()[name]()
    polys = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto = nullspace_design(model)
        # the cross-check's own search for an accurate parity basis (the explicit choice has no retry)
        for tol in (None, 1e-15, 1e-9):
            try:
                polys.append(nullspace_design(model, basis="polynomial", tol=tol))
            except DesignError:
                pass
    assert auto.info["basis"] == "pencil"
    # least order: no exact row has order below the smallest left minimal index (predictable degree
    # property), and no polynomial row that passes the judge (random7: none does) is of lower order
    assert auto.Q.n == min(auto.info["left_minimal_indices"]) or name in ("tanks", "xiong_saif_2")
    assert all(auto.Q.n <= p.Q.n for p in polys)
    ud = np.arange(model.nu + model.nd)
    om = np.linspace(1e-3, np.pi / model.dt, 97) if model.dt else np.logspace(-3, 3, 97)
    worst = 0.0
    for w in om:
        lam = np.exp(1j * w * model.dt) if model.dt else 1j * w
        Qv, Gv = _tf_value(_Q(auto), lam), _tf_value(_Ge(model), lam)[:, ud]
        worst = max(worst, np.linalg.norm(Qv @ Gv) / (np.linalg.norm(Qv) * np.linalg.norm(Gv, 2)))
    assert worst <= 1e-11


def test_boeing747_detection_of_every_fault_is_designed():
    """Varga's Boeing 747 (5 faults): the polynomial row puts fault f5 at relative gain 1e-4 = FDtol
    exactly and was refused; the pencil row at order 1 sees every fault with a relative gain
    ``max_ω |R_fj| / (|Q_y||Gf_j|)`` (numpy, 200 points) well above FDtol, and decouples u."""
    from test_synthesis_published import boeing747

    model = boeing747()
    gen = nullspace_design(model)
    assert gen.Q.n == 1 and gen.info["basis"] == "pencil"
    p, fc = model.ny, _fault_cols(model)
    gains = np.zeros(model.nf)
    for w in np.logspace(-4, 2, 200):
        Qv, Gv = _tf_value(_Q(gen), 1j * w), _tf_value(_Ge(model), 1j * w)
        R = Qv @ Gv
        assert np.linalg.norm(R[:, :model.nu]) <= 1e-10 * np.linalg.norm(Qv) * np.linalg.norm(Gv[:, :model.nu], 2)
        for j in range(model.nf):
            col = fc.start + j
            gains[j] = max(gains[j], abs(R[0, col]) / (np.linalg.norm(Qv[:, :p]) * np.linalg.norm(Gv[:p, col])))
    assert np.all(gains > 1e-3), gains


def test_moved_mode_is_the_plants_own_pole():
    """Random seed 149's row [1 0 0 1 1] (tests/test_synthesis_random.py; discrete, n = 25): the component
    fault's z = 1 sits 5.1e-3 from the plant pole 0.9949, and the decoupling row's Q (order 24) has a pole at
    0.999. The stable factorisation must cancel R_fc's pole at the plant's z = 1 itself: the moved pole is the
    plant's eigenvalue (numpy's, on the model's own A) to rounding, and Q ← M·Q has the zero ``Q(1)·Ge v = 0``
    in the mode's direction v. Read here with numpy: ``||Q(1) Ge v|| / (max_θ ||Q(e^{jθ})|| ||Ge v||)``. A zero
    computed to rounding leaves ~N·eps·cond of the Q evaluation (measured 8.5e-15); the zero the series
    realisation gave (z = 1 read as 1 − 1.85e-10 there) left 6.0e-10. 1e-12 lies between."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from test_synthesis_random import random_case

    model = random_case(149).with_disturbances(["fs2", "fa1"])
    gen = nullspace_design(model)
    ev, V = np.linalg.eig(model.A)
    j = int(np.argmin(np.abs(ev - 1.0)))
    moved = np.asarray(gen.info["internal_form"]["moved_poles"])
    assert moved.size == 1 and abs(moved[0] - ev[j]) <= 1e-12
    gv = _Ge(model)[2] @ V[:, j]  # Ge's output direction of the mode
    A, B, C, D = _Q(gen)
    q1 = _tf_value((A, B, C, D), 1.0)
    peak = max(np.linalg.norm(_tf_value((A, B, C, D), np.exp(1j * w)), 2) for w in np.linspace(1e-3, np.pi, 2000))
    assert np.linalg.norm(q1 @ gv) <= 1e-12 * peak * np.linalg.norm(gv)


def test_moved_mode_is_the_judges_mode():
    """One plant-mode table (design/toolkit/plant_modes.py): the factoriser moves the plant mode the judge then
    tests, to the last bit. Random seed 3's bank row [1 1 0 1 1] (discrete, n = 10, unstable z = e^0.1 in Gfc):
    with the factoriser balancing only Ge's w and f columns and the judge all of Ge, M's zero sat at
    1.1051709180756502 and the judge's p at …464; the row's slope turned the 3.8e-15 into a residue 3.3e-13 of
    the unit fault gain, 2.3 times the judge's rounding bound δ_i, and the achievable row was refused as keeping an
    unstable pole of R. Read here with numpy: the moved pole is the table's, and the returned row's zero at the
    plant's own pole (numpy's eigenvalue of the model's A) leaves ``||Q(p) Ge v|| / (max_θ ||Q(e^{jθ})|| ||Ge v||)``
    at rounding — N·eps·cond of the evaluation (N = 19): 1e-12 as in the test above (measured 3.8e-16; with the
    two balancings 1.3e-14)."""
    import sys
    from pathlib import Path

    from fmu_fdi.design.toolkit.plant_modes import boundary_mode_table

    sys.path.insert(0, str(Path(__file__).parent))
    from test_synthesis_random import random_case

    model = random_case(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bank = structured_bank(model, [[1, 1, 0, 1, 1]])
    member = bank.members[0]
    moved = np.asarray(member.info["internal_form"]["moved_poles"])
    table = boundary_mode_table(model)["poles"]
    assert moved.size == 1 and np.min(np.abs(table - moved[0])) == 0.0  # the same floating-point number
    assert bank.info["postconditions"]["R_poles"] == []
    ev, V = np.linalg.eig(model.A)
    j = int(np.argmax(np.abs(ev)))
    assert abs(ev[j] - np.exp(0.1)) <= 1e-12
    gv = _Ge(model)[2] @ V[:, j]
    A, B, C, D = _Q(member)
    q = _tf_value((A, B, C, D), ev[j])
    peak = max(np.linalg.norm(_tf_value((A, B, C, D), np.exp(1j * w)), 2) for w in np.linspace(1e-3, np.pi, 2000))
    assert np.linalg.norm(q @ gv) <= 1e-12 * peak * np.linalg.norm(gv)
