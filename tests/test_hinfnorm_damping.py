"""LTI.hinfnorm at very lightly damped modes: the peak to the certificate's accuracy, or a refusal naming the mode.

``lti.gain_crossings`` merged crossings closer than √eps (relative). A mode of damping ζ whose peak is δ above the
level crosses it at ``ω₀(1 ± ζ√(2δ))``, so the merge hid up to ``δ = eps/(8ζ²)`` above the level — more than the
certificate's ``2·HINF_RTOL`` for ζ < 4e-5. Found here: ζ = 1e-6 certified 2e-7 below the peak; ζ = 1e-7 no
certificate at all (30 steps, each step's lone merged crossing read a hair above its level); ζ = 1e-5 7.7e-8 low when
the climb starts on the resonance's shoulder; on mixed, ill-scaled realisations at ζ = 1e-7 2.5e-6 … 3e-5 low. Below
ζ ≈ eps/HINF_RTOL no double-precision reading near the mode is fixed to 1e-8 (``mixed``, seeds 0–3, the climb on
double readings: ζ = 1e-9 up to 1.3e-7 off, 1e-10 4e-7, 1e-11 1.2e-5, either sign; the old code 7.6e-3 … 42 % low):
those gains are now read with longdouble residuals (1.7e-10 at ζ = 1e-10), and where even that does not fix them
(ζ ≲ 1e-11) the norm is refused as a DesignError naming the mode.

The judge is independent of lti.py: the gain of the *stored* (double) realisation evaluated in 50-digit decimal
arithmetic (``decimal``, a real 2n×2n elimination of ``(λI − A)x = B``); the peak in closed form for a second-order
section beside a feedthrough (the stationary points of ``|G(jω)|² = N(x)/M(x)``, ``x = ω²``, quadratics in decimal),
else by a decimal scan of the resonance window refined around its best point. Discrete systems are read at
``z = (1 + jv)/(1 − jv)`` (every point of the unit circle, rational in v; ``θ = 2·atan v``).

Tolerance. ``hinfnorm`` claims ``2·HINF_RTOL = 2e-8`` (relative). Its gains are double-precision readings: near a
mode of damping ζ a reading is fixed only to ``ρ = eps·s_A/d`` (``s_A`` the largest pole modulus, d the mode's
distance to the boundary) — at most eps·2/1e-7 = 4.4e-9 where ρ ≤ rtol; nearer modes are read in longdouble, to
``eps + ext_eps·s_A/d ≤ 2.2e-9`` (ζ ≥ 1e-10, s_A/|λ| ≤ 2; lti._LightModes); the frequency's own rounding (eps·ω/2)
costs a Lorentzian top ``(eps/(2ζ))²/2 < 1e-11``. The decimal judge reads the exact binary values (not their repr,
half an ulp off: 1e-7 of the gain at ζ = 1e-10) and errs by 1e-50·κ, κ ≤ 1e16 (the elimination's condition at the
resonance, state scaling included). TOL = 2e-8 + 2·4.4e-9 < 3e-8; every miss found on the old code is 7.7e-8 or
more.
"""
from __future__ import annotations

from decimal import Decimal, localcontext

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import lti as lti_module
from fmu_fdi.errors import DesignError
from fmu_fdi.linalg import EPS
from fmu_fdi.lti import LTI, certified_peak, gain_crossings

TOL = 3e-8
#: the cases below ζ ≈ 2e-8 are read in longdouble (lti._LightModes); where it is double (Windows, ARM macOS; run
#: here under tests/test_double_host.py's simulated host) in double-double instead, to n²·eps²·s_A/d: every case here
#: is then read to TOL, the refusal cases too (test_a_peak_rounding_cannot_fix_is_refused_naming_the_mode)
EXT_EPS = float(np.finfo(np.longdouble).eps)
DOUBLE_HOST = EXT_EPS >= EPS
extended = pytest.mark.skipif(DOUBLE_HOST, reason="asserts the extended reading's accuracy (ext_eps/ζ = 1.1e-9 at "
                                                 "ζ = 1e-10); numpy's longdouble is double on this platform")
PREC = 50


def assert_peak(G: LTI, peak: float, what: str, start=(1.0, np.inf), start_name: str = "from D"):
    """``hinfnorm`` and ``certified_peak`` from the candidate ``start`` (gain, frequency; rad/sample in discrete
    time) both return the peak to TOL, and the gain at their frequency is the peak to TOL (decimal)."""
    for how, call in (("hinfnorm", G.hinfnorm),
                      (start_name, lambda: certified_peak(G.A, G.B, G.C, G.D, bool(G.dt), *start))):
        g, f = call()
        f = f / G.dt if G.dt and how != "hinfnorm" else f
        assert_within(g, peak, f"{what} {how}")
        assert_within(decimal_gain(G, f), peak, f"{what} {how}: the gain at {f!r}")


# ------------------------------------------------------------------------------------------------ decimal judge
def _dec(x) -> Decimal:
    """The exact value of the double x (not its shortest repr: that differs by up to half an ulp, which near a mode of
    damping 1e-10 moves the gain by 1e-7)."""
    return Decimal(float(x))


def decimal_gain2(G: LTI, v) -> Decimal:
    """``|G(λ)|²`` of the stored SISO data in decimal: ``λ = jv`` (continuous) or ``(1 + jv)/(1 − jv)`` (discrete)."""
    n = G.n
    with localcontext() as ctx:
        ctx.prec = PREC
        A = [[_dec(a) for a in row] for row in G.A]
        v = v if isinstance(v, Decimal) else _dec(v)
        lr, li = ((1 - v * v) / (1 + v * v), 2 * v / (1 + v * v)) if G.dt else (Decimal(0), v)
        # (λI − A)(xr + j xi) = b as the real system [[lr I − A, −li I], [li I, lr I − A]] [xr; xi] = [b; 0]
        N = 2 * n
        M = [[Decimal(0)] * (N + 1) for _ in range(N)]
        for i in range(n):
            for k in range(n):
                M[i][k] = M[n + i][n + k] = (lr if i == k else 0) - A[i][k]
            M[i][n + i], M[n + i][i], M[i][N] = -li, li, _dec(G.B[i, 0])
        x = decimal_eliminate(M, N)[0]
        c = [_dec(a) for a in G.C[0]]
        gr = _dec(G.D[0, 0]) + sum(c[i] * x[i] for i in range(n))
        gi = sum(c[i] * x[n + i] for i in range(n))
        return gr * gr + gi * gi


def decimal_eliminate(M: list, N: int, cols: int = 1) -> list:
    """The solutions of ``M[:, :N] x = M[:, N + j]`` (rows of Decimals — or Fractions: then exact — the ``cols``
    right-hand sides after the N columns of the matrix), by Gaussian elimination with partial pivoting in the current
    decimal context (M is overwritten): a list of ``cols`` solution lists."""
    for col in range(N):
        piv = max(range(col, N), key=lambda r: abs(M[r][col]))
        M[col], M[piv] = M[piv], M[col]
        for r in range(col + 1, N):
            f = M[r][col] / M[col][col]
            if f:
                for k in range(col, N + cols):
                    M[r][k] -= f * M[col][k]
    out = []
    for j in range(cols):
        x = [Decimal(0)] * N
        for r in range(N - 1, -1, -1):
            x[r] = (M[r][N + j] - sum(M[r][k] * x[k] for k in range(r + 1, N))) / M[r][r]
        out.append(x)
    return out


def decimal_gain(G: LTI, w: float) -> float:
    """``|G|`` at the frequency w (rad/s) in decimal (discrete: v = tan(w·dt/2))."""
    v = np.tan(w * G.dt / 2) if G.dt else w
    with localcontext() as ctx:
        ctx.prec = PREC
        return float(decimal_gain2(G, v).sqrt())


def decimal_window_peak(G: LTI, centre: float, half: float, grid: int = 201, rounds: int = 9) -> float:
    """The largest ``|G|`` over ``v ∈ centre ± half`` (v as in decimal_gain2): a grid, then ``rounds`` grids of 41
    points on the best point's two neighbouring steps (each round shrinks the step 20×, from ``half/100`` to below
    ``half·1e-13``; at a top of width ≥ half/30 a point that close reads the gain low by less than 1e-20)."""
    with localcontext() as ctx:
        ctx.prec = PREC
        lo, hi = _dec(centre - half), _dec(centre + half)
        best, k = Decimal(-1), 0
        for r in range(rounds + 1):
            pts = [lo + (hi - lo) * i / (grid - 1) for i in range(grid)]
            vals = [decimal_gain2(G, p) for p in pts]
            k = max(range(grid), key=lambda i: vals[i])
            best = max(best, vals[k])
            lo, hi, grid = pts[max(k - 1, 0)], pts[min(k + 1, grid - 1)], 41
        return float(best.sqrt())


def section_peak(d: float, k: float, wn: float, zeta: float) -> tuple[float, float]:
    """Closed form: ``G(s) = d + k·wn²/(s² + 2ζ·wn·s + wn²)`` has ``|G(jω)|² = N(x)/M(x)``, ``x = ω²``,
    ``N = (d(wn² − x) + k·wn²)² + 4d²ζ²wn²x``, ``M = (wn² − x)² + 4ζ²wn²x``; the peak is the largest of N/M at the
    positive roots of the quadratic ``N'M − NM'`` (its cubic terms cancel) and at x → ∞ (d²). (peak, ω_peak)."""
    with localcontext() as ctx:
        ctx.prec = PREC
        d, k, wn, z = (_dec(a) for a in (d, k, wn, zeta))
        w2 = wn * wn
        c = 4 * z * z * w2
        e = (d + k) * w2
        N = [d * d, -2 * d * e + d * d * c, e * e]
        M = [Decimal(1), -2 * w2 + c, w2 * w2]
        a2 = 2 * N[0] * M[1] + N[1] * M[0] - 2 * N[1] - N[0] * M[1]
        a1 = 2 * N[0] * M[2] - 2 * N[2]
        a0 = N[1] * M[2] - N[2] * M[1]
        disc = a1 * a1 - 4 * a2 * a0
        xs = [(-a1 + s * disc.sqrt()) / (2 * a2) for s in (1, -1)] if disc >= 0 else []
        xs = [x for x in xs if x > 0]
        ratio = lambda x: (N[0] * x * x + N[1] * x + N[2]) / (M[0] * x * x + M[1] * x + M[2])  # noqa: E731
        top = max(xs, key=ratio)
        assert ratio(top) > N[0], "the resonance is the peak of every case here"
        return float(ratio(top).sqrt()), float(top.sqrt())


def section(d: float, k: float, wn: float, zeta: float, T=None) -> LTI:
    """The second-order section beside a feedthrough (section_peak), states optionally changed by T."""
    A = np.array([[0.0, 1.0], [-wn ** 2, -2 * zeta * wn]])
    B, C = np.array([[0.0], [1.0]]), np.array([[k * wn ** 2, 0.0]])
    if T is not None:
        A, B, C = np.linalg.solve(T, A @ T), np.linalg.solve(T, B), C @ T
    return LTI(A, B, C, np.array([[d]]))


def light(zeta: float, wn: float, T=None) -> LTI:
    """Feedthrough 1 and a resonance of residue 0.7·2ζ: the peak ≈ 1.41 at ωn, beside ‖D‖ = 1 at ω → ∞."""
    return section(1.0, 1.4 * zeta, wn, zeta, T)


def tustin(G: LTI, T: float) -> LTI:
    """Bilinear image s = (2/T)(z − 1)/(z + 1) (numpy); its own stored data is what the judge reads."""
    a = 2.0 / T
    Mi = np.linalg.inv(a * np.eye(G.n) - G.A)
    return LTI((a * np.eye(G.n) + G.A) @ Mi, np.sqrt(2 * a) * Mi @ G.B, np.sqrt(2 * a) * G.C @ Mi,
               G.D + G.C @ Mi @ G.B, T)


def assert_within(got: float, peak: float, what: str):
    assert abs(got - peak) <= TOL * peak, f"{what}: {got!r} where the peak is {peak!r} ({(got - peak) / peak:+.2e})"


# ------------------------------------------------------------------------------------------------ continuous
CASES = [(z, wn) for z in (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10) for wn in (1.0, 37.0)]


@pytest.mark.parametrize("zeta,wn", CASES)
def test_a_light_resonance_beside_the_feedthrough(zeta, wn):
    """From AB13DD's candidate and from ‖D‖ at ω = ∞ (a first level that is not the resonance), companion form
    and states scaled over six decades: the closed-form peak, and the gain at the returned frequency."""
    peak, _ = section_peak(1.0, 1.4 * zeta, wn, zeta)
    for T in (None, np.diag([1e-3, 1e3])):
        assert_peak(light(zeta, wn, T), peak, f"zeta {zeta} wn {wn}")


def shoulder(zeta: float, wn: float, below: float) -> float:
    """The frequency above the peak where the section's gain is ``peak·(1 − below)`` (closed form, decimal)."""
    peak, _ = section_peak(1.0, 1.4 * zeta, wn, zeta)
    with localcontext() as ctx:
        ctx.prec = PREC
        d, k, w2, z = Decimal(1), _dec(1.4 * zeta), _dec(wn) ** 2, _dec(zeta)
        c, e, g2 = 4 * z * z * w2, (d + k) * w2, (_dec(peak) * (1 - _dec(below))) ** 2
        # N(x) − g²M(x) = 0 (section_peak's N, M)
        q = [d * d - g2, -2 * d * e + d * d * c - g2 * (-2 * w2 + c), e * e - g2 * w2 * w2]
        disc = (q[1] * q[1] - 4 * q[0] * q[2]).sqrt()
        return float(max((-q[1] + disc) / (2 * q[0]), (-q[1] - disc) / (2 * q[0])).sqrt())


@pytest.mark.parametrize("zeta", [1e-5, 1e-6])
def test_the_climb_from_the_resonance_shoulder(zeta):
    """A candidate on the resonance's flank, 1e-7 below its top: the first level's two crossings are ζ·√(2e-7)·ωn
    (1e-8 relative at ζ = 1e-5) apart — the old merge took them for one and certified 1e-7 low."""
    wn = 1.0
    G = light(zeta, wn)
    peak, _ = section_peak(1.0, 1.4 * zeta, wn, zeta)
    w = shoulder(zeta, wn, 1e-7)
    g, f = certified_peak(G.A, G.B, G.C, G.D, False, decimal_gain(G, w), w)
    assert_within(g, peak, f"zeta {zeta} from the shoulder {w!r}")
    assert_within(decimal_gain(G, f), peak, f"zeta {zeta}: the gain at {f!r}")


def test_crossings_closer_than_sqrt_eps_are_both_kept():
    """ζ = 1e-6 at the level peak·(1 − 1e-8): the two closed-form crossings are 2ζ√(2e-8) = 2.8e-10 apart
    (relative), far below the old √eps merge; both are returned, and the gain midway between the returned
    crossings there (decimal) is above the level — the certificate's next step reads it."""
    zeta, wn = 1e-6, 1.0
    G = light(zeta, wn)
    peak, wp = section_peak(1.0, 1.4 * zeta, wn, zeta)
    level = peak * (1 - 1e-8)
    got = gain_crossings(G.A, G.B, G.C, G.D, False, level)
    near = got[np.abs(got - wp) <= 10 * zeta * wn]
    assert near.size >= 2, (got, wp)
    assert decimal_gain(G, 0.5 * (near.min() + near.max())) > level, (near, wp)


# ------------------------------------------------------------------------------------------------ discrete
@pytest.mark.parametrize("zeta", [1e-5, 1e-6, 1e-7, 1e-9, 1e-10])
def test_a_light_resonance_in_discrete_time(zeta):
    """The Tustin image (T = 0.5) of the section at ωn = 1: its stored data's peak by a decimal scan of the
    resonance window (v = tan(θ/2) within ±30 times the pole's distance to the circle, mapped), from AB13DD's
    candidate and from the Nyquist frequency."""
    G = tustin(light(zeta, 1.0), 0.5)
    assert_peak(G, discrete_peak(G), f"discrete zeta {zeta}", start=(1.0, np.pi), start_name="from Nyquist")


def discrete_peak(G: LTI) -> float:
    """The peak of a Tustin-imaged section by a decimal scan of the resonance window (v = tan(θ/2) within ±30
    times the pole's distance to the circle, mapped)."""
    lam = np.linalg.eigvals(G.A)[0]
    v0, dv = np.tan(abs(np.angle(lam)) / 2), 30 * (1 - abs(lam)) * (1 + np.tan(abs(np.angle(lam)) / 2) ** 2) / 2
    return decimal_window_peak(G, v0, dv)


# ------------------------------------------------------------------------------------------------ several modes
def mixed(zeta: float, seed: int, close: bool) -> LTI:
    """A mode of damping ζ at ωn = 1 with residue 1.6ζ, a second one (``close``: at 1 + 3ζ, damping ζ, residue
    0.8ζ; else at 2 rad/s, damping 0.3, residue 0.1), D = 1; states mixed by an orthogonal matrix and scaled over
    six decades (seeded)."""
    rng = np.random.default_rng(seed)
    w2, z2, r2 = (1 + 3 * zeta, zeta, 0.8 * zeta) if close else (2.0, 0.3, 0.1)
    blocks = [np.array([[-z * w, w * np.sqrt(1 - z * z)], [-w * np.sqrt(1 - z * z), -z * w]])
              for z, w in ((zeta, 1.0), (z2, w2))]
    A = sla.block_diag(*blocks)
    B = np.array([[0.0], [2 * 1.6 * zeta], [0.0], [2 * r2 * w2]])
    C = np.array([[1.0, 0.0, 1.0, 0.0]])
    T = np.linalg.qr(rng.standard_normal((4, 4)))[0] * 10 ** rng.uniform(-3, 3, 4)
    return LTI(np.linalg.solve(T, A @ T), np.linalg.solve(T, B), C @ T, np.array([[1.0]]))


def judged_peak(G: LTI, zeta: float) -> float:
    """The decimal scan of 1 ± 40ζ (both close modes inside), checked to be the peak: a numpy grid over
    0 … 100 rad/s outside the window and ‖D‖ stay below 0.9 of it."""
    peak = decimal_window_peak(G, 1.0, 40 * zeta, grid=401)
    w = np.r_[np.linspace(0, 1 - 40 * zeta, 3000), np.linspace(1 + 40 * zeta, 100, 3000)]
    X = np.linalg.solve(1j * w[:, None, None] * np.eye(G.n) - G.A, np.broadcast_to(G.B.astype(complex),
                                                                                    (w.size,) + G.B.shape))
    assert np.abs(G.C @ X + G.D).max() < 0.9 * peak and abs(G.D[0, 0]) < 0.9 * peak
    return peak


@pytest.mark.parametrize("zeta,seed,close", [(1e-6, 0, True), (1e-6, 1, True), (1e-7, 2, True),
                                             (1e-6, 3, False), (1e-7, 4, False), (1e-7, 5, False),
                                             (1e-9, 6, True), (1e-9, 7, False), (1e-10, 1, False), (1e-10, 3, False)])
def test_close_and_ill_scaled_modes(zeta, seed, close):
    G = mixed(zeta, seed, close)
    assert_peak(G, judged_peak(G, zeta), f"zeta {zeta} seed {seed} close {close}")


# ------------------------------------------------------------------------------------------------ refusals
@pytest.mark.parametrize("G,what,zeta", [(light(1e-12, 1.0), "section 1e-12", 1e-12),
                                         (mixed(1e-11, 0, False), "mixed 1e-11", 1e-11),
                                         (mixed(1e-12, 1, False), "mixed 1e-12", 1e-12),
                                         (tustin(light(1e-12, 1.0), 0.5), "discrete 1e-12", 1e-12)],
                         ids=lambda x: x if isinstance(x, str) else "")
def test_a_peak_rounding_cannot_fix_is_refused_naming_the_mode(G, what, zeta):
    """ζ = 1e-11, 1e-12: even an extended-precision reading near the mode is fixed only to ext_eps·s_A/d ≥ 1e-8,
    or its refinement does not converge (the mixed realisations): a DesignError naming the mode. (The old code
    returned figures 0.4 … 0.8 % low on ``mixed`` at ζ = 1e-11.) Where longdouble is double, the readings are
    double-double (n²·eps²·s_A/d ≤ 2e-18 here): those peaks are read, to TOL of the decimal judge's."""
    if DOUBLE_HOST:
        peak = (discrete_peak(G) if G.dt else section_peak(1.0, 1.4 * zeta, 1.0, zeta)[0] if G.n == 2
                else judged_peak(G, zeta))
        assert_peak(G, peak, what, start=(1.0, np.pi) if G.dt else (1.0, np.inf))
        return
    with pytest.raises(DesignError, match=r"not computable to 1\.0e-08.*at the mode λ.*pole on the boundary"):
        G.hinfnorm()


def test_a_light_mode_below_the_peak_is_not_refused():
    """A mode of damping 1e-10 whose resonance (≈ 0.5 above D = 1) stays far below a broad peak of 4.2 (a
    first-order lag of DC gain 3.2 in parallel): the certified peak is the lag's, |1 + 3.2| at ω = 0 (closed form;
    the light mode adds 0.5e-10·… there), not refused."""
    light_mode = section(1.0, 1e-10, 1.0, 1e-10)
    lag = LTI(np.array([[-1.0]]), np.array([[1.0]]), np.array([[3.2]]), np.zeros((1, 1)))
    G = light_mode + lag
    g, f = G.hinfnorm()
    assert_within(g, decimal_gain(G, 0.0), "the lag's peak")
    assert decimal_gain(G, 1.0) < 0.9 * g


@extended
def test_refusal_threshold_is_the_stated_accuracy():
    """ζ = 1e-10 at ωn = 1: extended readings fix the gain to ext_eps/ζ = 1.1e-9 — certified at rtol 1e-8 (to the
    closed-form peak), refused at rtol 1e-10."""
    G = light(1e-10, 1.0)
    peak, _ = section_peak(1.0, 1.4e-10, 1.0, 1e-10)
    assert_within(G.hinfnorm()[0], peak, "rtol 1e-8")
    with pytest.raises(DesignError, match="not computable to 1.0e-10"):
        G.hinfnorm(rtol=1e-10)
    assert lti_module.HINF_RTOL == 1e-8


# ------------------------------------------------------------------------------------------------ a random family
def light_family(seed: int) -> tuple[LTI, list]:
    """1–3 modes of damping 1e-7 … 1e-4 at 0.1 … 100 rad/s (half of them within 1–5 widths of the previous one), 0–2
    broad modes, residues ~ζ (resonances of size O(1)), D 0.5 … 2, states mixed by an orthogonal matrix and scaled
    over four decades; (system, [(ζ, ωn)])."""
    rng = np.random.default_rng(seed)
    blocks, lights = [], []
    for _ in range(int(rng.integers(1, 4))):
        z, w = 10 ** rng.uniform(-7, -4), 10 ** rng.uniform(-1, 2)
        if lights and rng.random() < 0.5:
            w = lights[-1][1] * (1 + rng.uniform(1, 5) * lights[-1][0])
        lights.append((z, w))
        blocks.append(np.array([[-z * w, w * np.sqrt(1 - z * z)], [-w * np.sqrt(1 - z * z), -z * w]]))
    for _ in range(int(rng.integers(0, 3))):
        z, w = rng.uniform(0.1, 1), 10 ** rng.uniform(-1, 2)
        blocks.append(np.array([[-z * w, w], [-w, -z * w]]))
    A = sla.block_diag(*blocks)
    n = A.shape[0]
    B, C = rng.standard_normal((n, 1)), rng.standard_normal((1, n))
    for i, (z, w) in enumerate(lights):
        B[2 * i:2 * i + 2] *= 2 * z * rng.uniform(0.3, 3)
    D = np.array([[rng.uniform(0.5, 2.0)]])
    T = np.linalg.qr(rng.standard_normal((n, n)))[0] * 10 ** rng.uniform(-2, 2, n)
    return LTI(np.linalg.solve(T, A @ T), np.linalg.solve(T, B), C @ T, D), lights


def numpy_grid_peak(G: LTI) -> float:
    """The broad part: a dense numpy grid (0 … 1e4 rad/s, 4001 log points) refined 8 rounds around its best five
    points (the broad modes' tops have damping ≥ 0.1: read to 1e-12) and ‖D‖."""
    def gains(w):
        X = np.linalg.solve(1j * w[:, None, None] * np.eye(G.n) - G.A,
                            np.broadcast_to(G.B.astype(complex), (w.size,) + G.B.shape))
        return np.abs(G.C @ X + G.D)[:, 0, 0]
    w = np.r_[0.0, np.logspace(-3, 4, 4001)]
    v = gains(w)
    best = max(float(v.max()), abs(G.D[0, 0]))
    for k in np.argsort(v)[-5:]:
        lo, hi = w[max(k - 1, 0)], w[min(k + 1, w.size - 1)]
        for _ in range(8):
            ww = np.linspace(lo, hi, 21)
            vv = gains(ww)
            j = int(np.argmax(vv))
            best = max(best, float(vv[j]))
            lo, hi = ww[max(j - 1, 0)], ww[min(j + 1, 20)]
    return best


@pytest.mark.parametrize("seed", [2, 12, 25, 30, 34])
def test_a_random_family_of_light_modes(seed):
    """The peak is the largest of the decimal scans of every light mode's window (±40ζωn) and numpy's grid peak (a
    light mode's top escapes a grid; its window is read in decimal). Seeds 25 and 30: the old code 1.1e-7 and
    9.8e-7 low. Seeds 0–39 were run once (with test_hinfnorm_certified.numpy_peak for the broad part): all within
    1.1e-8, none refused; the old code 2 misses (these two)."""
    G, lights = light_family(seed)
    peak = max([decimal_window_peak(G, w, 40 * z * w, grid=101, rounds=7) for z, w in lights] + [numpy_grid_peak(G)])
    g, f = G.hinfnorm()
    assert_within(g, peak, f"light family seed {seed}")
    assert_within(decimal_gain(G, f), peak, f"light family seed {seed}: the gain at {f!r}")
