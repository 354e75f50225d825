"""LTI.hinfnorm returns the peak gain, not a local one (issue 17; approximate audit seed 176).

SLICOT AB13DD — main's whole ``hinfnorm`` — returns a value it has not certified: on a resonance beside a
feedthrough of about the same size it returns ``‖D‖`` (a point where the gain crosses it), on ill-scaled
realisations a value below the peak. ``hinfnorm`` now checks the value against the Hamiltonian (symplectic)
pencil and climbs to the peak (``lti.certified_peak``). Every figure here is judged by numpy alone: the gain
``σ_max(C(λI − A)⁻¹B + D)`` by dense solves on a grid, refined at its top — or, for the resonance, the stationary
points of ``|G(jω)|²`` in closed form.

Tolerance. ``hinfnorm`` promises a value within ``2·HINF_RTOL = 2e-8`` of the peak (the peak is at most HINF_RTOL
above an attained gain, the value within HINF_RTOL of that gain).
numpy's refined peak: a 4001-point grid, then 8 rounds of 21 points on the two grid steps around each of the six
largest values, shrinking the step 10× a round — the step ends below 1e-8 of the first, and at a quadratic top
the gain read is low by (step/width)²·peak, far below 1e-12 for the damping ≥ 1e-3 here; the rounding of a
dense solve is eps·κ(λI − A) ≲ 1e-16·1e6 (states scaled over at most eight decades, the solve's error relative
to the gain, not to κ(T)). Their sum is below 3e-8; ``TOL = 1e-7`` leaves a factor of three and still fails any
local peak (AB13DD's misses below are 1e-6 … 30 % low).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import lti as lti_module
from fmu_fdi.errors import DesignError
from fmu_fdi.lti import LTI

TOL = 1e-7


# ------------------------------------------------------------------------------------------------ numpy judge
def numpy_gains(G: LTI, w: np.ndarray) -> np.ndarray:
    """``σ_max(C(λI − A)⁻¹B + D)`` at ``λ = jω`` (``e^{jω·dt}``), dense numpy solves."""
    lam = np.exp(1j * w * G.dt) if G.dt else 1j * w
    X = np.linalg.solve(lam[:, None, None] * np.eye(G.n) - G.A,
                        np.broadcast_to(G.B.astype(complex), (w.size,) + G.B.shape))
    return np.linalg.norm(G.C @ X + G.D, 2, axis=(1, 2))


def numpy_peak(G: LTI) -> float:
    """The refined peak of the grid (module docstring), with ``‖D‖`` (ω → ∞) in continuous time."""
    ev = np.linalg.eigvals(G.A)
    if G.dt:
        w = np.unique(np.r_[np.linspace(0.0, np.pi, 4001), np.abs(np.angle(ev))]) / G.dt
    else:
        w = np.unique(np.r_[0.0, np.logspace(-3, 4, 4001), np.abs(ev.imag), np.abs(ev)])
    v = numpy_gains(G, w)
    best = v.max()
    for k in np.argsort(v)[-6:]:
        lo, hi = w[max(k - 1, 0)], w[min(k + 1, w.size - 1)]
        for _ in range(8):
            ww = np.linspace(lo, hi, 21)
            vv = numpy_gains(G, ww)
            j = int(np.argmax(vv))
            best = max(best, vv[j])
            lo, hi = ww[max(j - 1, 0)], ww[min(j + 1, 20)]
    return float(best) if G.dt else max(float(best), float(np.linalg.norm(G.D, 2)))


def main_hinfnorm(G: LTI) -> float:
    """main's ``hinfnorm`` before the certificate: AB13DD's value as returned."""
    import slycot

    return float(slycot.ab13dd("D" if G.dt else "C", "I", "N", "D", G.n, G.m, G.p, G.A.copy(), np.eye(G.n),
                               G.B.copy(), G.C.copy(), G.D.copy())[0])


def assert_is_the_peak(G: LTI, what: str):
    g, f = G.hinfnorm()
    peak = numpy_peak(G)
    assert abs(g - peak) <= TOL * peak, f"{what}: hinfnorm {g!r} where numpy's refined peak is {peak!r}"
    attained = float(np.linalg.norm(G.D, 2)) if np.isinf(f) else float(numpy_gains(G, np.array([f]))[0])
    assert abs(attained - g) <= TOL * peak, f"{what}: the gain at the returned frequency {f} is {attained!r}, not {g!r}"


# ------------------------------------------------------------------------------------------------ a constructed case
#: G(s) = (s² + 2s + 60)/(s² + 4s + 100): 0.6 at ω = 0, 1 at ω → ∞, a resonance of 1.3498 at 11.55 rad/s
RESONANCE = LTI(np.array([[0.0, 1.0], [-100.0, -4.0]]), np.array([[0.0], [1.0]]), np.array([[-40.0, -2.0]]),
                np.array([[1.0]]))


def resonance_peak() -> float:
    """``|G(jω)|² = N(x)/M(x)``, ``x = ω²``, ``N = x² − 116x + 3600``, ``M = x² − 184x + 10000``: the peak is the
    largest of N/M at the positive stationary points (roots of N'M − NM') and at x = 0 and x → ∞ (value 1)."""
    N, M = np.array([1.0, -116.0, 3600.0]), np.array([1.0, -184.0, 10000.0])
    stat = np.roots(np.polysub(np.polymul(np.polyder(N), M), np.polymul(N, np.polyder(M))))
    xs = np.r_[0.0, stat[(np.abs(stat.imag) == 0) & (stat.real > 0)].real]
    return float(np.sqrt(max(1.0, np.max(np.polyval(N, xs) / np.polyval(M, xs)))))


def test_a_resonance_beside_the_feedthrough_is_the_peak():
    peak = resonance_peak()  # 1.3497844603…
    # the case is one AB13DD gets wrong: it returns ‖D‖ = 1 (where the gain crosses 1, 9.70 rad/s)
    assert main_hinfnorm(RESONANCE) < 1.0 + 1e-6 < peak
    g, f = RESONANCE.hinfnorm()
    assert abs(g - peak) <= TOL * peak, (g, peak)
    s = 1j * f
    assert abs(abs((s * s + 2 * s + 60) / (s * s + 4 * s + 100)) - g) <= TOL * peak, (f, g)


@pytest.mark.parametrize("scale", [1e-3, 0.1, 1e2, 1e4])
def test_the_resonance_on_other_time_scales_and_state_coordinates(scale):
    """G(s/scale)·1 with the states scaled over 4 decades (T = diag(1e-2, 1e2)): same peak, at 11.55·scale."""
    T = np.diag([1e-2, 1e2])
    G = RESONANCE
    Gs = LTI(np.linalg.solve(T, G.A * scale @ T), np.linalg.solve(T, G.B * scale), G.C @ T, G.D)
    g, f = Gs.hinfnorm()
    peak = resonance_peak()
    assert abs(g - peak) <= TOL * peak, (scale, g, peak)
    assert abs(f / scale - 11.5484801) <= 1e-4 * 11.55, (scale, f)


def test_an_uncertified_peak_is_refused_with_its_figures(monkeypatch):
    """One Bruinsma–Steinbuch step is not enough to climb from AB13DD's 1.0 to the resonance: refused, with the
    bound reached, never the local value."""
    monkeypatch.setattr(lti_module, "HINF_MAXIT", 1)
    with pytest.raises(DesignError, match=r"not certified in 1 Bruinsma-Steinbuch steps.*AB13DD's candidate 1"):
        RESONANCE.hinfnorm()



def tustin(G: LTI, T: float) -> LTI:
    """The bilinear map s = (2/T)(z − 1)/(z + 1) of G (numpy): G_d(e^{jθ}) = G(jω), θ = 2·atan(ωT/2)."""
    a = 2.0 / T
    Mi = np.linalg.inv(a * np.eye(G.n) - G.A)
    return LTI((a * np.eye(G.n) + G.A) @ Mi, np.sqrt(2 * a) * Mi @ G.B, np.sqrt(2 * a) * G.C @ Mi,
               G.D + G.C @ Mi @ G.B, T)


@pytest.mark.parametrize("level", [0.8, 1.2, 1.3497])
def test_gain_crossings_are_the_closed_form_ones(level):
    """|G(jω)| = level ⇔ N(x) − level²·M(x) = 0, x = ω² (resonance_peak's N, M): the pencil's frequencies
    (continuous; and the Tustin image, discrete, at θ = 2·atan(ωT/2)) are these roots. Relative error: a simple
    crossing's eigenvalue is accurate to κ·eps; at 1.3497 the two crossings are 2e-2 apart (κ ~ 1e3), so 1e-9."""
    N, M = np.array([1.0, -116.0, 3600.0]), np.array([1.0, -184.0, 10000.0])
    x = np.roots(N - level ** 2 * M)
    x = np.sort(x[(np.abs(x.imag) == 0) & (x.real > 0)].real)
    exact = np.sqrt(x)
    G = RESONANCE
    got = lti_module.gain_crossings(G.A, G.B, G.C, G.D, False, level)
    assert got.size == exact.size and np.allclose(got, exact, rtol=1e-9, atol=0), (got, exact)
    T = 0.05
    Gd = tustin(G, T)
    got = lti_module.gain_crossings(Gd.A, Gd.B, Gd.C, Gd.D, True, level)
    theta = 2 * np.arctan(exact * T / 2)
    assert got.size == theta.size and np.allclose(got, theta, rtol=1e-9, atol=0), (got, theta)


# ------------------------------------------------------------------------------------------------ random systems
def modal_system(seed: int, discrete: bool, order: int | None = None) -> LTI:
    """n 2–16 (or ``order``) stable modes (damping 1e-3 … 1, frequencies 0.1 … 100 rad/s; discrete: e^{A·h}), m, p
    1–3, states mixed by an orthogonal matrix and scaled over four decades, D of size 0.1 … 10 (zero in one case of
    five)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 17)) if order is None else (rng.integers(2, 17), order)[1]
    m, p = (int(k) for k in rng.integers(1, 4, 2))
    blocks, size = [], 0
    while size < n:
        zeta, w = 10 ** rng.uniform(-3, 0), 10 ** rng.uniform(-1, 2)
        if rng.random() < 0.7 and size + 2 <= n:
            wd = w * np.sqrt(1 - zeta ** 2)
            blocks.append(np.array([[-zeta * w, wd], [-wd, -zeta * w]]))
        else:
            blocks.append(np.array([[-w]]))
        size += len(blocks[-1])
    A = sla.block_diag(*blocks)
    if discrete:
        A = sla.expm(A * 0.1 / 10 ** rng.uniform(0, 1.5))
    T = np.linalg.qr(rng.standard_normal((n, n)))[0] * 10 ** rng.uniform(-2, 2, n)
    A = np.linalg.solve(T, A @ T)
    B = np.linalg.solve(T, rng.standard_normal((n, m)))
    C = rng.standard_normal((p, n)) @ T
    D = rng.standard_normal((p, m)) * 10 ** rng.uniform(-1, 1) * (rng.random() < 0.8)
    return LTI(A, B, C, D, 0.5 if discrete else 0.0)


def dense_system(seed: int, discrete: bool) -> LTI:
    """A dense random A shifted (scaled) to be stable with margin 1e-3 … 1, states scaled over eight (continuous)
    or six (discrete) decades; SISO continuous with D 0.5 … 5 times the largest DC gain, discrete m, p 1–2 with a
    random D — the families where AB13DD's value was found low."""
    rng = np.random.default_rng(seed)
    if discrete:
        n, m, p = (int(k) for k in (rng.integers(3, 12), rng.integers(1, 3), rng.integers(1, 3)))
        A = rng.standard_normal((n, n))
        A = A / (np.abs(np.linalg.eigvals(A)).max() * (1 + 10 ** rng.uniform(-3, -0.5)))
        B, C = rng.standard_normal((n, m)), rng.standard_normal((p, n))
        D = rng.standard_normal((p, m)) * rng.uniform(0, 5)
        T = np.diag(10 ** rng.uniform(-3, 3, n))
    else:
        n = int(rng.integers(4, 12))
        A = rng.standard_normal((n, n))
        A = A - (np.linalg.eigvals(A).real.max() + 10 ** rng.uniform(-3, 0)) * np.eye(n)
        B, C = rng.standard_normal((n, 1)), rng.standard_normal((1, n))
        D = np.array([[rng.uniform(0.5, 5) * np.abs(C @ np.linalg.solve(-A, B)).max()]])
        T = np.diag(10 ** rng.uniform(-4, 4, n))
    return LTI(np.linalg.solve(T, A @ T), np.linalg.solve(T, B), C @ T, D, 1.0 if discrete else 0.0)


#: seeds of the families where main's AB13DD value is below numpy's peak by more than TOL (relative shortfall):
#: modal continuous 81 (n 2: 0.3137 for 0.3671), dense continuous 0 (2.633 for 3.423), 46, 55, 66, 75, 96
#: (1e-6 … 8e-3), dense discrete 130, 152, 165, 183, 188, 371 (2e-6 … 1.6e-5). (Dense discrete 4, in CASES, fails
#: main the other way: AB13DD's value is 1.6e-6 above numpy's peak — not attained.)
AB13DD_LOW = [("modal", False, 81), ("dense", False, 0), ("dense", False, 46), ("dense", False, 55),
              ("dense", False, 66), ("dense", False, 75), ("dense", False, 96), ("dense", True, 130),
              ("dense", True, 152), ("dense", True, 165), ("dense", True, 183), ("dense", True, 188),
              ("dense", True, 371)]
FAMILIES = {"modal": modal_system, "dense": dense_system}
CASES = AB13DD_LOW + [("modal", d, s) for d in (False, True) for s in range(12)] + \
        [("dense", d, s) for d in (False, True) for s in range(1, 5)]


@pytest.mark.parametrize("family,discrete,seed", CASES)
def test_random_systems_norm_is_numpys_refined_peak(family, discrete, seed):
    G = FAMILIES[family](seed, discrete)
    assert_is_the_peak(G, f"{family} {'discrete' if discrete else 'continuous'} seed {seed} (n {G.n})")


def test_the_listed_seeds_are_ones_main_gets_wrong():
    """The random test has teeth: on each AB13DD_LOW seed main's hinfnorm is below numpy's peak by more than TOL
    (if a SLICOT update mends some, this list and the comment above it are to be updated)."""
    short = {}
    for family, discrete, seed in AB13DD_LOW:
        G = FAMILIES[family](seed, discrete)
        peak = numpy_peak(G)
        short[(family, discrete, seed)] = (peak - main_hinfnorm(G)) / peak
    assert all(v > TOL for v in short.values()), short


# ------------------------------------------------------------------------------------------------ semantics kept
@pytest.mark.parametrize("G", [LTI(np.zeros((1, 1)), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1))),
                               LTI(np.array([[0.0, 2.0], [-2.0, 0.0]]), np.ones((2, 1)), np.ones((1, 2)),
                                   np.zeros((1, 1))),
                               LTI(np.ones((1, 1)), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)), 0.1)],
                         ids=["integrator", "oscillator", "discrete-integrator"])
def test_a_pole_on_the_boundary_gives_inf(G):
    assert G.hinfnorm() == (float("inf"), 0.0)


def test_static_and_empty_systems():
    D = np.array([[3.0, 4.0]])
    assert LTI.static(D).hinfnorm() == (5.0, float("inf"))
    assert LTI.static(np.zeros((0, 2))).hinfnorm() == (0.0, 0.0)
