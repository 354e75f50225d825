"""A small state-space toolkit: the LTI object every design returns and analysis reads.

``LTI(A, B, C, D, dt)`` is ``x' = A x + B v, r = C x + D v`` in continuous time
(``dt == 0``) or ``x[k+1] = A x[k] + B v[k]`` in discrete time (``dt > 0``).
Products, stacking, minimal realisation (SLICOT TB01PD, orthogonal staircase),
H-infinity norms (SLICOT AB13DD, certified on the Hamiltonian pencil) and exact zero-order-hold
discretisation live here so that design code never hand-rolls them twice.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
import scipy.linalg as sla

from .freqresp import dense_values, eigenvalues, hessenberg_form
from .errors import DesignError
from .linalg import EPS, is_finite, shifted_hessenberg_solve


#: Relative accuracy of :meth:`LTI.hinfnorm`: the peak is at most ``(1 + HINF_RTOL)`` times an attained gain γ_lo
#: and the value returned is within HINF_RTOL of γ_lo (so within 2·HINF_RTOL of the peak). The figures built on norms
#: (gaps, thresholds, matching errors) are compared at 1e-3 and looser; 1e-8 keeps AB13DD's own accuracy (its
#: tolerance 1e-10) within reach of one certifying eigenproblem.
HINF_RTOL = 1e-8
#: An eigenvalue ``λ`` of the gain-crossing pencil ``M − λN`` (:func:`gain_crossings`) counts as on the frequency
#: axis (unit circle) when its distance to it is at most ``ON_AXIS·(‖M‖_F + |λ|·‖N‖_F)``. QZ returns the exact
#: eigenvalues of ``(M + E, N + F)`` with ``‖E‖ ≲ eps‖M‖``, ``‖F‖ ≲ eps‖N‖``: a simple crossing eigenvalue of
#: condition κ moves by ``κ·eps·(‖M‖ + |λ|‖N‖)``, and the double eigenvalue of a level that touches a peak (the
#: worst case: two crossings merging) splits by ``√eps·(‖M‖ + |λ|‖N‖)`` — so the threshold is √eps relative to the
#: pencil's size, with a factor 10 for the dimension-dependent constants. Too generous costs nothing but points:
#: an eigenvalue taken for a crossing is only a frequency where the gain is evaluated, and the certificate compares
#: evaluated gains; too strict would miss a crossing and return a local peak.
ON_AXIS = 10.0 * np.sqrt(EPS)
#: Bruinsma–Steinbuch steps before :func:`certified_peak` gives up (it converges quadratically: 2–4 in practice)
HINF_MAXIT = 30


def _as2d(X, shape_if_empty: tuple[int, int], name: str) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.size == 0:
        return np.zeros(shape_if_empty)
    if X.ndim == 0:
        return X.reshape(1, 1)
    if X.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix, got shape {X.shape}")
    return X


@dataclass(frozen=True, eq=False)
class LTI:
    """Linear time-invariant system in state-space form.

    Parameters
    ----------
    A, B, C, D : array_like
        State-space matrices of shapes (n, n), (n, m), (p, n), (p, m).
    dt : float
        0 for continuous time, the sample time for discrete time.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float = 0.0

    # numpy must defer to LTI for ``ndarray @ LTI`` (constant pre-multiplication)
    __array_ufunc__ = None

    def __post_init__(self):
        D = np.asarray(self.D, dtype=float)
        if D.ndim == 0:
            D = D.reshape(1, 1)
        if D.ndim != 2:
            raise ValueError(f"D must be a 2-D matrix, got shape {D.shape}")
        p, m = D.shape
        A = _as2d(self.A, (0, 0), "A")
        n = A.shape[0]
        B = _as2d(self.B, (n, m), "B")
        C = _as2d(self.C, (p, n), "C")
        if A.shape != (n, n) or B.shape != (n, m) or C.shape != (p, n):
            raise ValueError(
                f"inconsistent state-space shapes: A {A.shape}, B {B.shape}, C {C.shape}, D {D.shape}"
            )
        if not is_finite(A, B, C, D):
            raise ValueError("state-space matrices contain NaN or Inf")
        dt = float(self.dt)
        if not np.isfinite(dt) or dt < 0:
            raise ValueError(f"dt must be 0 (continuous) or a positive sample time, got {self.dt!r}")
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "B", B)
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "D", D)
        object.__setattr__(self, "dt", dt)

    # ------------------------------------------------------------------ basics
    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    @property
    def p(self) -> int:
        return self.C.shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        return self.p, self.m

    @property
    def is_discrete(self) -> bool:
        return self.dt > 0

    @classmethod
    def static(cls, D, dt: float = 0.0) -> "LTI":
        D = np.atleast_2d(np.asarray(D, dtype=float))
        return cls(np.zeros((0, 0)), np.zeros((0, D.shape[1])), np.zeros((D.shape[0], 0)), D, dt)

    @classmethod
    def zero(cls, p: int, m: int, dt: float = 0.0) -> "LTI":
        return cls.static(np.zeros((p, m)), dt)

    def __repr__(self) -> str:
        kind = f"discrete, dt={self.dt:g}" if self.is_discrete else "continuous"
        return f"LTI(n={self.n}, inputs={self.m}, outputs={self.p}, {kind})"

    def __getitem__(self, idx) -> "LTI":
        rows, cols = idx if isinstance(idx, tuple) else (idx, slice(None))
        rows = _index(rows, self.p)
        cols = _index(cols, self.m)
        return LTI(self.A, self.B[:, cols], self.C[rows, :], self.D[np.ix_(rows, cols)], self.dt)

    # ----------------------------------------------------------- evaluation
    def evalfr(self, lam: complex) -> np.ndarray:
        """Transfer matrix ``C (lam I - A)^{-1} B + D`` at one complex point."""
        if self.n == 0:
            return self.D.astype(complex)
        X = np.linalg.solve(lam * np.eye(self.n) - self.A, self.B.astype(complex))
        return self.C @ X + self.D

    def freq_points(self, omega) -> np.ndarray:
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        if self.is_discrete:
            return np.exp(1j * omega * self.dt)
        return 1j * omega

    def freqresp(self, omega) -> np.ndarray:
        """Frequency response at real frequencies ``omega`` (rad/s): shape (len, p, m).

        ``omega = inf`` gives D in continuous time.
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        out = np.empty((omega.size, self.p, self.m), dtype=complex)
        finite = np.ones(omega.size, bool) if self.is_discrete else np.isfinite(omega)
        out[~finite] = self.D
        if np.any(finite):
            out[finite] = self.values(self.freq_points(omega[finite]), where="frequencies")
        return out

    def values(self, lams, where: str = "points") -> np.ndarray:
        """Transfer matrix ``C (lam I - A)^{-1} B + D`` at complex points: shape (len, p, m).

        One Hessenberg reduction ``A = Z H Zᵀ`` serves every point, each then an O(n²)
        structured solve (:func:`fmu_fdi.linalg.shifted_hessenberg_solve`; Laub 1981) instead
        of a dense O(n³) one. Points where ``lam I - A`` is singular to working precision
        (reciprocal condition below eps, as LAPACK's dense solvers warn) are reported in one
        :class:`scipy.linalg.LinAlgWarning` with their count; an exactly singular point raises
        :class:`numpy.linalg.LinAlgError`.
        """
        lams = np.atleast_1d(np.asarray(lams, dtype=complex))
        out = np.empty((lams.size, self.p, self.m), dtype=complex)
        if self.n == 0 or lams.size == 0:
            out[:] = self.D
            return out
        H, Z = sla.hessenberg(self.A, calc_q=True)
        Bh = Z.T @ self.B
        Ch = self.C @ Z
        near = []
        for k, lam in enumerate(lams):
            X, rcond = shifted_hessenberg_solve(H, lam, Bh)
            out[k] = Ch @ X + self.D
            if rcond < EPS:
                near.append((lam, rcond))
        if near:
            warnings.warn(f"frequency response of an order-{self.n} realisation: at {len(near)} of {lams.size} "
                          f"{where} lam I - A is singular to working precision (a pole on or next to the "
                          f"frequency axis, e.g. one a non-minimal realisation cancels); the values there are "
                          f"unreliable (first: lam = {near[0][0]:.6g}, reciprocal condition {near[0][1]:.3g})",
                          sla.LinAlgWarning, stacklevel=3)
        return out

    def dcgain(self) -> np.ndarray:
        return self.freqresp([0.0])[0].real

    def poles(self) -> np.ndarray:
        return eigenvalues(self.A) if self.n else np.zeros(0, complex)  # once per content of A (freqresp)

    def is_stable(self, margin: float = 0.0) -> bool:
        """All poles in Re < -margin (continuous) or |z| < 1 - margin (discrete)."""
        p = self.poles()
        if p.size == 0:
            return True
        if self.is_discrete:
            return bool(np.all(np.abs(p) < 1.0 - margin))
        return bool(np.all(p.real < -margin))

    # -------------------------------------------------------- interconnection
    def _check_dt(self, other: "LTI"):
        if abs(self.dt - other.dt) > 1e-12 * max(1.0, self.dt):
            raise ValueError(f"cannot connect systems with sample times {self.dt} and {other.dt}")

    def __matmul__(self, other: "LTI") -> "LTI":
        """Series connection ``self(λ) · other(λ)`` (other acts first)."""
        if isinstance(other, np.ndarray):
            return LTI(self.A, self.B @ other, self.C, self.D @ other, self.dt)
        self._check_dt(other)
        if self.m != other.p:
            raise ValueError(f"series connection: {self.m} inputs vs {other.p} outputs")
        n1, n2 = self.n, other.n
        A = np.block([[other.A, np.zeros((n2, n1))], [self.B @ other.C, self.A]])
        B = np.vstack([other.B, self.B @ other.D])
        C = np.hstack([self.D @ other.C, self.C])
        return LTI(A, B, C, self.D @ other.D, self.dt)

    def __rmatmul__(self, other) -> "LTI":
        other = np.asarray(other, dtype=float)
        return LTI(self.A, self.B, other @ self.C, other @ self.D, self.dt)

    def __mul__(self, k) -> "LTI":
        k = float(k)
        return LTI(self.A, self.B, k * self.C, k * self.D, self.dt)

    __rmul__ = __mul__

    def __neg__(self) -> "LTI":
        return self * -1.0

    def __add__(self, other: "LTI") -> "LTI":
        if isinstance(other, (int, float, np.ndarray)):
            other = LTI.static(np.broadcast_to(np.asarray(other, float), self.shape), self.dt)
        self._check_dt(other)
        if self.shape != other.shape:
            raise ValueError(f"cannot add systems of shapes {self.shape} and {other.shape}")
        return LTI(
            sla.block_diag(self.A, other.A),
            np.vstack([self.B, other.B]),
            np.hstack([self.C, other.C]),
            self.D + other.D,
            self.dt,
        )

    def __sub__(self, other: "LTI") -> "LTI":
        return self + (-other)

    def transpose(self) -> "LTI":
        return LTI(self.A.T, self.C.T, self.B.T, self.D.T, self.dt)

    # --------------------------------------------------------- realisation
    def minreal(self, tol: float | None = None, job: str = "M", equil: str = "S") -> "LTI":
        """Minimal (or controllable 'C' / observable 'O') realisation by SLICOT TB01PD.

        The orthogonal staircase keeps the computation backward stable; ``tol`` is the
        rank tolerance of the staircase (SLICOT's default ``n*n*eps*||[A B; C 0]||`` when
        None or ≤ 0, so an ``atol`` of 0 can be passed as it is). A static system is returned as it is. The triplet is balanced first (SLICOT TB01ID, ``equil="S"``): without it the
        rank decisions failed on badly scaled rows, e.g. the sampled row of three identical
        pitch systems kept two unobservable states. ``equil="N"`` skips the balancing (the
        decisions are then those of the coordinates given, as :func:`.model.minimal_realisation`
        wants).
        """
        n, m, p = self.n, self.m, self.p
        if n == 0:
            return self
        if m == 0 and job in "MC" or p == 0 and job in "MO":
            return LTI.static(self.D, self.dt)
        import slycot

        mp = max(m, p, 1)
        B = np.zeros((n, mp))
        B[:, :m] = self.B
        C = np.zeros((mp, n))
        C[:p, :] = self.C
        A = self.A.copy()
        if equil == "S":
            # TB01PD's own balancing (TB01ID, MAXRED = 100) done first, then TB01PD without it: the same
            # numbers bit for bit, but slycot's TB01PD with equil='S' and tol > 1 dies in LAPACK (DORMQR
            # "parameter 5 illegal", then a segmentation fault) — a tolerance that large means rank 0.
            _, A, B, C = slycot.tb01id(n, mp, mp, 100.0, A, B, C, job="A")[:4]
        Ar, Br, Cr, nr = slycot.tb01pd(n, m, p, A, B, C, job=job, equil="N", tol=0.0 if tol is None else tol)
        return LTI(Ar[:nr, :nr], Br[:nr, :m], Cr[:p, :nr], self.D, self.dt)

    def to_discrete(self, Ts: float) -> "LTI":
        """Exact zero-order-hold discretisation: ``Ad = e^{A Ts}``, ``Bd = ∫ e^{A t} dt B``."""
        if self.is_discrete:
            raise ValueError("system is already discrete")
        Ts = float(Ts)
        if not np.isfinite(Ts) or Ts <= 0:
            raise ValueError(f"sample time must be positive, got {Ts!r}")
        n, m = self.n, self.m
        M = np.zeros((n + m, n + m))
        M[:n, :n] = self.A * Ts
        M[:n, n:] = self.B * Ts
        E = sla.expm(M)
        return LTI(E[:n, :n], E[:n, n:], self.C, self.D, Ts)

    def balanced(self) -> tuple["LTI", np.ndarray]:
        """Diagonal-similarity balancing of ``[A B; C 0]`` (SLICOT TB01ID): returns (sys, scale).

        The state is ``x_bal = diag(scale)^{-1} x``.
        """
        n, m, p = self.n, self.m, self.p
        if n == 0 or m == 0 or p == 0:
            return self, np.ones(n)
        import slycot

        _, A, B, C, scale = slycot.tb01id(n, m, p, 0.0, self.A.copy(), self.B.copy(), self.C.copy(), job="A")
        return LTI(A, B, C, self.D, self.dt), np.asarray(scale)

    def balanced_truncation(self, order: int | None = None, tol: float = 0.0,
                            equil: str = "N") -> tuple["LTI", np.ndarray]:
        """Balance-and-truncate reduction of a stable system (SLICOT AB09AD, square-root method): ``(reduced,
        hsv)``, the Hankel singular values ``hsv`` and the system truncated to ``order`` states (None: those
        above ``tol``; the error is at most twice the sum of the dropped values). ``equil='S'`` scales the
        realisation first. SLICOT's note that the order asked exceeds the minimal one is silenced; its
        refusals (e.g. a mode too close to the boundary) raise ``slycot.exceptions.SlycotError``."""
        import warnings

        import slycot

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            nr, A, B, C, hsv = slycot.ab09ad("D" if self.dt else "C", "B", equil, self.n, self.m, self.p,
                                             self.A.copy(), self.B.copy(), self.C.copy(), nr=order, tol=tol)
        return LTI(A[:nr, :nr], B[:nr, :self.m], C[:self.p, :nr], self.D, self.dt), np.asarray(hsv)

    # ---------------------------------------------------------------- norms
    def hinfnorm(self, rtol: float = HINF_RTOL) -> tuple[float, float]:
        """L-infinity norm ``γ = sup_ω σ_max(G(jω))`` (``G(e^{jωT})`` in discrete time) and a frequency
        (rad/s) where it is attained — the H-infinity norm for stable systems.

        SLICOT AB13DD (Bruinsma–Steinbuch, with a structure-preserving Hamiltonian eigensolver) gives a
        first value; what it returns is checked, never trusted: ``σ_max`` evaluated at its frequency (and
        at ω = 0, ∞ or the Nyquist frequency) is an attained lower bound ``γ_lo``, and
        :func:`certified_peak` proves ``γ ≤ γ_lo·(1 + rtol)`` with the Hamiltonian pencil — or, where
        the pencil shows that the gain crosses that level, climbs to the higher peak by the
        Boyd–Balakrishnan / Bruinsma–Steinbuch iteration. AB13DD alone returns a local peak on
        some realisations (approximate audit seed 176, an order-77 minimal fault slice: 0.835288 at
        6.38 rad/s, where the gain is 1.011848 at 11.95 rad/s).

        The peak is at most ``rtol`` (relative) above an attained gain ``γ_lo``, and the value returned is within
        ``rtol`` of ``γ_lo`` (AB13DD's own figure where it is, else ``γ_lo``): within ``2·rtol`` of the peak;
        a realisation whose peak cannot be certified raises :class:`~fmu_fdi.errors.DesignError`, and so does one
        whose peak may lie at a mode so lightly damped (``ζ ≲ 1e-11`` on x86; where longdouble is double the
        readings are double-double, ``ζ ≲ 2.4e-21·(1 + n/650)·s_A/|λ|``: far below the boundary-pole cut) that even
        extended-precision readings do not fix the gain there to ``rtol`` (:class:`_LightModes`).
        Returns ``(inf, freq)`` for a pole on the stability boundary (``0.0``: the frequency is not
        located).
        """
        if self.m == 0 or self.p == 0:
            return 0.0, 0.0
        if self.n == 0 or not np.any(self.B) or not np.any(self.C):
            return float(np.linalg.norm(self.D, 2)), float("inf")
        import slycot

        dico = "D" if self.is_discrete else "C"
        poles = self.poles()
        boundary = np.abs(np.abs(poles) - 1.0) if self.is_discrete else np.abs(poles.real)
        scale = max(1.0, float(np.max(np.abs(poles))))
        if np.any(boundary < 1e3 * EPS * scale):
            return float("inf"), 0.0
        g, f = slycot.ab13dd(dico, "I", "N", "D", self.n, self.m, self.p, self.A.copy(),
                             np.eye(self.n), self.B.copy(), self.C.copy(), self.D.copy())
        g, f = certified_peak(self.A, self.B, self.C, self.D, self.is_discrete, float(g), float(f), rtol)
        if self.is_discrete and np.isfinite(f):
            f = f / self.dt
        return g, f

    def h2norm(self) -> float:
        """H2 norm (system must be stable; D must be 0 in continuous time)."""
        if self.m == 0 or self.p == 0:
            return 0.0
        if self.is_discrete:
            if self.n == 0:
                return float(np.linalg.norm(self.D))
            P = sla.solve_discrete_lyapunov(self.A, self.B @ self.B.T)
            return float(np.sqrt(np.trace(self.C @ P @ self.C.T + self.D @ self.D.T)))
        if np.any(self.D):
            return float("inf")
        if self.n == 0:
            return 0.0
        P = sla.solve_continuous_lyapunov(self.A, -self.B @ self.B.T)
        return float(np.sqrt(max(np.trace(self.C @ P @ self.C.T), 0.0)))

    def scale_of(self) -> float:
        """A size of the data used for relative tolerances: ``||[A B; C D]||_F``."""
        return float(np.sqrt(sum(np.sum(X * X) for X in (self.A, self.B, self.C, self.D))))

    # --------------------------------------------------------------- python-control
    def to_control(self):
        import control

        return control.ss(self.A, self.B, self.C, self.D, self.dt if self.is_discrete else 0)

    @classmethod
    def from_control(cls, sys) -> "LTI":
        import control

        if isinstance(sys, control.TransferFunction):
            sys = control.tf2ss(sys)
        if not isinstance(sys, control.StateSpace):
            raise TypeError(f"expected a python-control StateSpace or TransferFunction, got {type(sys).__name__}")
        dt = sys.dt
        if dt is True:
            raise ValueError("discrete system with unspecified sample time (dt=True): give a numeric dt")
        return cls(sys.A, sys.B, sys.C, sys.D, float(dt or 0.0))


# ------------------------------------------------------------------- H-infinity norm certificate
def peak_gains(A, B, C, D, discrete: bool, freqs) -> np.ndarray:
    """``σ_max(G(λ))`` at ``λ = jω`` (continuous; ``ω = inf`` reads D) or ``λ = e^{jω}`` (discrete, ω in
    rad/sample), ``G(λ) = C(λI − A)⁻¹B + D`` by :func:`.freqresp.dense_values` (one LU solve per point)."""
    freqs = np.atleast_1d(np.asarray(freqs, dtype=float))
    out = np.empty(freqs.size)
    fin = np.ones(freqs.size, bool) if discrete else np.isfinite(freqs)
    if not np.all(fin):
        out[~fin] = np.linalg.svd(D, compute_uv=False)[0]
    if np.any(fin):
        G = dense_values(A, B, C, D, np.exp(1j * freqs[fin]) if discrete else 1j * freqs[fin])
        if not np.all(np.isfinite(G)):  # λI − A exactly singular at a point: a pole on the axis to rounding
            raise DesignError(f"H-infinity norm of an order-{A.shape[0]} realisation: λI − A is singular at one of "
                              f"the frequencies {freqs[fin]} (a pole on the stability boundary to rounding)")
        out[fin] = np.linalg.svd(G, compute_uv=False)[:, 0]
    return out


def gain_crossings(A, B, C, D, discrete: bool, gamma: float) -> np.ndarray:
    """The frequencies (rad/s; rad/sample in discrete time), sorted, in [0, ∞) or [0, π], where a singular value
    of ``G`` may equal ``gamma`` (``gamma > σ_max(D)``, no pole on the boundary): the eigenvalues on the axis
    (unit circle) of the pencil ``M − λN`` (Hamiltonian / symplectic pencil in extended form, no inverse of
    ``D'D − γ²I``; Bruinsma & Steinbuch, Syst. Control Lett. 14, 1990; Benner, Sima & Voigt, IEEE TAC 57, 2012)::

        continuous:  M = [A 0 B 0; 0 Aᵀ 0 Cᵀ; C 0 D −I; 0 Bᵀ −I Dᵀ],  N = diag(I, −I, 0, 0)
        discrete:    M = [A 0 B 0; 0 I 0 0;  C 0 D −I; 0 Bᵀ −I Dᵀ],  N = [I 0 0 0; 0 Aᵀ 0 Cᵀ; 0; 0]

    on ``G/γ`` (B and D divided by γ, then TB01ID-balanced), rows from ``λx = Ax + Bu``, ``−λz = Aᵀz + Cᵀv``
    (``z = λ(Aᵀz + Cᵀv)``), ``Cx + Du = v``, ``Bᵀz + Dᵀv = u``: ``G(λ)u = v``, ``G(λ)ᴴv = u`` at ``λ = jω``
    (``e^{jω}``), so ``γ`` is a singular value of ``G`` there. On the axis means within ``ON_AXIS`` of it."""
    import slycot

    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    _, A, Bs, Cs = slycot.tb01id(n, m, p, 0.0, A.copy(), B / gamma, C.copy(), job="A")[:4]
    Ds = D / gamma
    x, z, u, v = slice(0, n), slice(n, 2 * n), slice(2 * n, 2 * n + m), slice(2 * n + m, 2 * n + m + p)
    M, N = np.zeros((2, 2 * n + m + p, 2 * n + m + p))
    M[x, x], M[x, u] = A, Bs  # λx = Ax + Bu
    M[v, x], M[v, u], M[v, v] = Cs, Ds, -np.eye(p)  # Cx + Du = v
    M[u, z], M[u, v], M[u, u] = Bs.T, Ds.T, -np.eye(m)  # Bᵀz + Dᵀv = u
    N[x, x] = np.eye(n)
    if discrete:  # z = λ(Aᵀz + Cᵀv)
        M[z, z], N[z, z], N[z, v] = np.eye(n), A.T, Cs.T
    else:  # −λz = Aᵀz + Cᵀv
        M[z, z], M[z, v], N[z, z] = A.T, Cs.T, -np.eye(n)
    alpha, beta = sla.eigvals(M, N, homogeneous_eigvals=True)
    keep = beta != 0
    lam = alpha[keep] / beta[keep]
    # one of each conjugate pair: the real pencil's ±jω (e^{±jθ}) are one crossing, read as two values an ulp apart
    # (each member is its own alpha/beta); the mirror λ, −λ̄ (1/λ̄) of a near-double crossing stays, both in Im ≥ 0
    lam = lam[lam.imag >= 0]
    size = ON_AXIS * (np.linalg.norm(M) + np.abs(lam) * np.linalg.norm(N))
    if discrete:
        w = np.sort(np.abs(np.angle(lam[np.abs(np.abs(lam) - 1.0) <= size])))
    else:
        w = np.sort(np.abs(lam[np.abs(lam.real) <= size].imag))
    # Every other candidate is kept (only exact repeats are dropped): two true crossings can lie closer than any
    # relative gap one would merge at — a mode of damping ζ whose peak is δ above the level crosses it at
    # ω₀(1 ± ζ√(2δ)), so a merge at √eps (relative) hid δ up to eps/(8ζ²), above 2·HINF_RTOL for ζ < 4e-5
    # (ζ = 1e-6: the certificate stopped 2e-7 below the peak; 1e-7: no certificate in 30 steps, each step's lone
    # merged crossing read a hair above its level). A near-repeat costs one evaluation point and puts a midpoint
    # between the two, where the peak is.
    return np.unique(w)


def certified_peak(A, B, C, D, discrete: bool, gamma: float, freq: float,
                   rtol: float = HINF_RTOL) -> tuple[float, float]:
    """The peak gain of ``G = C(λI − A)⁻¹B + D`` (no pole on the boundary) to relative accuracy ``rtol``, from a
    candidate ``(gamma, freq)`` (AB13DD's; freq in rad/sample in discrete time, ``inf``: D): ``(γ, ω)``.

    The candidate is a claim: ``γ_lo``, the largest ``σ_max`` evaluated at ``freq``, 0 and ∞ (π), is attained. At the
    level ``γ_c = γ_lo·(1 + rtol)`` :func:`gain_crossings` gives every frequency where a singular value equals
    ``γ_c``; between two consecutive ones ``σ_max − γ_c`` keeps its sign (it is continuous and vanishes only
    there) and it is negative at the ends (``γ_lo`` bounds the gain at 0 and ∞), so if the gain at every
    midpoint is at most ``γ_c`` the peak is ``≤ γ_c`` — certified. Otherwise the largest midpoint gain is the new
    ``γ_lo`` and the step repeats (Boyd & Balakrishnan, Math. Control Signals Systems 3, 1990; Bruinsma &
    Steinbuch 1990: quadratic convergence). Returns the candidate itself when it lies in ``[γ_lo·(1 − rtol), γ_c]``
    (the common case: AB13DD's figures unchanged, also where they differ from the evaluated gain by rounding),
    else the attained ``γ_lo`` and its frequency: either way within ``2·rtol`` (relative) of the peak.
    Raises :class:`~fmu_fdi.errors.DesignError` after ``HINF_MAXIT`` steps without a certificate, or where the peak
    may lie at a mode whose gain rounding does not fix to ``rtol`` (:class:`_LightModes`, which also reads
    the gains near very lightly damped modes in extended precision)."""
    top = np.pi if discrete else np.inf
    light = _LightModes(A, B, C, D, discrete, rtol)
    pts = np.array([freq if np.isfinite(freq) or not discrete else np.pi, 0.0, top])
    vals = light.gains(pts)
    k = int(np.argmax(vals))
    lo, wlo = float(vals[k]), float(pts[k])
    # a level below which the gain counts as zero: eps times the gain's own scale at high frequency
    floor = EPS * (float(np.linalg.norm(D))
                   + float(np.linalg.norm(C) * np.linalg.norm(B)) / max(float(np.linalg.norm(A)), EPS))
    for _ in range(HINF_MAXIT):
        level = max(lo * (1.0 + rtol), floor)
        cross = gain_crossings(A, B, C, D, discrete, level)
        if cross.size == 0:
            break
        mids = 0.5 * (cross[:-1] + cross[1:])  # discrete: arithmetic; continuous: geometric between positive ends
        if not discrete:
            mids = np.where(cross[:-1] > 0, np.sqrt(cross[:-1] * cross[1:]), mids)
        pts = np.r_[cross, mids]
        vals = light.gains(pts)
        k = int(np.argmax(vals))
        if vals[k] > lo:
            lo, wlo = float(vals[k]), float(pts[k])
        if vals[k] <= level:
            break
    else:
        raise DesignError(f"H-infinity norm of an order-{A.shape[0]} realisation not certified in {HINF_MAXIT} "
                          f"Bruinsma-Steinbuch steps: the gain reaches {lo:.6g} (at {wlo:.6g}) and still crosses "
                          f"{lo * (1 + rtol):.6g} (AB13DD's candidate {gamma:.6g} at {freq:.6g})")
    lo, wlo = light.settle(lo, wlo)
    if lo * (1.0 - rtol) <= gamma <= max(lo * (1.0 + rtol), floor):
        return gamma, freq  # AB13DD's own figure, within rtol of the attained γ_lo (rounding apart: main's figures)
    return lo, wlo


#: machine epsilon of numpy's longdouble (x87 80-bit on x86: 1.08e-19; where it is double, EPS, and the extended
#: readings of :class:`_LightModes` are plain ones)
EXT_EPS = float(np.finfo(np.longdouble).eps)


class _LightModes:
    """Gains near modes so lightly damped that double precision does not fix them to ``rtol``, read with
    extended-precision residuals; and the refusal where even those do not.

    Near a pole λ the gain holds ``r/(s − λ)``; a backward-stable double evaluation (an LU solve of ``sI − A``)
    moves λ by about ``eps·s_A`` (``s_A``: the largest pole modulus; discrete: 1, the unit circle), which changes the
    gain near the mode by up to ``ρ = eps·s_A/d`` relative, ``d`` the pole's distance to the boundary (``|Re λ|``,
    discrete ``1 − |λ|``): ``eps/ζ`` at the resonance of an isolated mode of damping ζ. Modes with ``ρ > rtol``
    (ζ ≲ 2.2e-8·s_A/|λ| at rtol = 1e-8) are *light*; a system without them is read exactly as before. Every gain
    the certificate reads within ``1.5·R``, ``R = max(10·d, eps·s_A/rtol)``, of a light pole (where a double
    reading may be off by more than rtol) is read again: the LU of ``sI − A`` rounded to double, then three
    refinement steps whose residual ``B − (sI − A)X`` is formed in longdouble from the stored data and the point
    ``s`` itself in longdouble (``jω``; ``cos ω + j sin ω``, on the circle to longdouble's rounding, not double's —
    a point off the circle by eps moves the gain near the mode by eps/d), on the realisation scaled by powers of 2
    (TB01ID's factors rounded: exact, the same transfer function to the last bit). Where longdouble is double
    (Windows, ARM macOS) the points are read in double-double instead (:func:`_double_double_gains`: error-free
    transformations, ``ext_eps`` = :func:`residual_unit` ``≈ (1968 + 3n)·u²``; in discrete time at the rational point
    ``(1 − v² + 2jv)/(1 + v²)``, ``v = tan(ω/2)``, on the circle to ~u²). Each step divides the error by
    ``κ·eps ≤ ρ ≪ 1``; it ends at ``eps + ρ_x``, ``ρ_x = ext_eps·s_A/d``. Measured (tests/test_hinfnorm_damping
    ``mixed``, seeds 0–3, against a 50-digit evaluation of the stored data), worst relative error with double
    readings only → with these: ζ = 1e-8 1.2e-8 → 1.3e-12, 1e-9 1.3e-7 → 3.5e-11, 1e-10 4.0e-7 → 1.7e-10; 1e-11
    1.2e-5 → refused (main, AB13DD and merged crossings: 7.8e-3, 7.6e-3, 25 %, 42 % low). In double-double on a
    simulated double-longdouble host (tests/test_double_host.py's patch), the sections, ``mixed`` cases and
    Tustin images at ζ = 1e-8 … 1e-12: worst 1.45e-9 (ζ = 1e-12, ωn = 37), none refused.

    :meth:`settle` then scans each light mode's resonance with these readings — 81 points over ``Im λ ± 10d``
    (``arg λ``), five rounds of 21 points on the best point's two neighbouring steps (the step ends at ``d/4e5``:
    a Lorentzian top read ``(step/d)²/2 < 1e-11`` low) — so that a top the pencil's double-precision crossings
    located badly is read at its height; beyond ``10d`` the mode's term is below a tenth of its peak. A mode whose
    ``ρ_x`` still exceeds ``rtol`` (ζ ≲ 1e-11·s_A/|λ| on x86; where longdouble is double, read in double-double,
    ζ ≲ 2.4e-21·(1 + n/650)·s_A/|λ|) and whose scanned gains widened by ``ρ_x`` reach the peak is refused with a
    :class:`~fmu_fdi.errors.DesignError` naming it — for the working precision it is a pole on the boundary —
    instead of a figure off by up to ``ρ_x``; so is such a mode
    beside which the peak itself was read (a reading over-read by ``ρ_x`` there can exceed the scan's best by more
    than rtol). (Modes with ``d < 1e3·eps·max(1, s_A)`` are boundary poles: :meth:`LTI.hinfnorm` returns ``inf``
    before.) A reading whose refinement does not converge to ``rtol/10`` is refused the same way — except beside a
    mode with ``ρ_x > rtol``, whose readings are known only to ``ρ_x`` and are decided by :meth:`settle` as above:
    where longdouble is double (Windows, ARM macOS), before the double-double readings, ``ρ_x = ρ`` for every light
    mode and that rule refused light modes far below the peak (tests/test_hinfnorm_damping.py: ζ = 1e-10, the gain
    there 0.8 of the peak)."""

    def __init__(self, A, B, C, D, discrete: bool, rtol: float):
        self.A, self.B, self.C, self.D, self.discrete, self.rtol = A, B, C, D, discrete, rtol
        poles = eigenvalues(A) if A.shape[0] else np.zeros(0, complex)
        if discrete:
            dist, self.size, where = np.abs(1.0 - np.abs(poles)), 1.0, np.abs(np.angle(poles))
        else:
            dist = np.abs(poles.real)
            self.size, where = (float(np.max(np.abs(poles))) if poles.size else 0.0), np.abs(poles.imag)
        with np.errstate(divide="ignore"):
            light = np.flatnonzero(EPS * self.size / dist > rtol)
        light = light[poles[light].imag >= 0]  # one of each conjugate pair: both have one resonance on [0, ∞)
        light = light[np.argsort(where[light], kind="stable")]
        self.poles, self.dist, self.where = poles[light], dist[light], where[light]
        self.radius = np.maximum(10.0 * self.dist, EPS * self.size / rtol)
        with np.errstate(divide="ignore"):  # what an extended reading near each mode is fixed to
            self.rho_x = _ext_eps(A.shape[0]) * self.size / self.dist
        self.balanced = (A, B, C)
        if self.poles.size and B.shape[1] and C.shape[0]:
            import slycot

            # TB01ID's scaling rounded to powers of 2, applied here: exact, so the same transfer function to the last
            # bit (TB01ID's own factors are powers of 10 — a realisation rounded once, which near a mode of damping ζ
            # moves the gain by eps/ζ), and sI − A without most of the state scaling's condition
            n, m, p = A.shape[0], B.shape[1], C.shape[0]
            t = slycot.tb01id(n, m, p, 0.0, A.copy(), B.copy(), C.copy(), job="A")[4]
            t = np.exp2(np.round(np.log2(np.asarray(t, float))))
            self.balanced = (A / t[:, None] * t[None, :], B / t[:, None], C * t[None, :])

    def _points(self, w):
        return np.exp(1j * w) if self.discrete else 1j * w

    def gains(self, freqs) -> np.ndarray:
        """``σ_max(G)`` at the frequencies, by :func:`peak_gains`, read again in extended precision near light poles."""
        freqs = np.atleast_1d(np.asarray(freqs, dtype=float))
        out = peak_gains(self.A, self.B, self.C, self.D, self.discrete, freqs)
        if self.poles.size:
            fin = np.isfinite(freqs)
            close = np.zeros((freqs.size, self.poles.size), bool)
            close[fin] = np.abs(self._points(freqs[fin])[:, None] - self.poles[None, :]) <= 1.5 * self.radius[None, :]
            near = np.any(close, axis=1)
            if np.any(near):
                at = freqs[near]
                out[near], moved = _extended_gains(*self.balanced, self.D, self.discrete, at)
                # a point near a mode whose extended reading is fixed only to rho_x > rtol need not converge to
                # rtol/10: its reading is known to rho_x, and settle() refuses the mode if it may be the peak (on x86
                # ζ ≲ 1e-11; in double-double, where longdouble is double, none). Elsewhere non-convergence is refused.
                loose = np.any(close[near] & (self.rho_x > self.rtol)[None, :], axis=1)
                bad = np.where(loose, 0.0, moved)
                if np.any(bad > 0.1 * self.rtol):
                    i = int(np.argmax(bad))
                    k = int(np.argmin(np.abs(self._points(at[i:i + 1]) - self.poles)))
                    self._refuse(k, out[near][i], at[i], f"the extended-precision reading there did not converge "
                                                         f"(its last step moved the gain by {moved[i]:.3g})")
        return out

    def _refuse(self, k: int, gain: float, w: float, why: str):
        kind = "1 - |λ|" if self.discrete else "|Re λ|/|λ|"
        raise DesignError(
            f"H-infinity norm of an order-{self.A.shape[0]} realisation not computable to {self.rtol:.1e}: the gain "
            f"{gain:.9g} at {w:.9g} is at the mode λ = {self.poles[k]:.9g} ({kind} = "
            f"{self.dist[k] / (1.0 if self.discrete else abs(self.poles[k])):.3g}) and {why}: for the working "
            f"precision the mode is a pole on the boundary")

    def settle(self, lo: float, wlo: float) -> tuple[float, float]:
        """The peak with every light mode's resonance scanned (class docstring); refuses a mode no reading fixes."""
        for k in range(self.poles.size):
            d = self.dist[k]
            w = self.where[k] + d * np.linspace(-10.0, 10.0, 81)
            best, wbest = -np.inf, self.where[k]
            for _ in range(6):
                w = w[(w >= 0.0) & (w <= np.pi)] if self.discrete else w[w >= 0.0]
                g = self.gains(w)
                j = int(np.argmax(g))
                if g[j] > best:
                    best, wbest = float(g[j]), float(w[j])
                step = w[1] - w[0] if w.size > 1 else d
                w = w[j] + step * np.linspace(-1.0, 1.0, 21)
            rho_x = self.rho_x[k]
            if rho_x > self.rtol and best * (1.0 + rho_x) >= max(lo, best) * (1.0 - self.rtol):
                self._refuse(k, best, wbest, f"may be the peak ({max(lo, best):.9g}), read by extended precision "
                                             f"only to {rho_x:.3g} relative (ext_eps·{self.size:.3g}/{d:.3g})")
            if best > lo:
                lo, wlo = best, wbest
        # the peak itself read beside such a mode is that mode's reading, fixed only to its rho_x: even where the
        # scan's best stays below it (a reading over-read by rho_x, the scan's under-read), it is no figure to rtol
        if np.isfinite(wlo):
            at = np.abs(self._points(np.array([wlo]))[0] - self.poles) <= 1.5 * self.radius
            for k in np.flatnonzero(at & (self.rho_x > self.rtol)):
                self._refuse(int(k), lo, wlo, f"is where the peak was read, by extended precision only to "
                                              f"{self.rho_x[k]:.3g} relative (ext_eps·{self.size:.3g}/"
                                              f"{self.dist[k]:.3g})")
        return lo, wlo


def _extended_gains(A, B, C, D, discrete: bool, freqs) -> tuple[np.ndarray, np.ndarray]:
    """``σ_max(C(sI − A)⁻¹B + D)`` at ``s = jω`` (``e^{jω}``) with the solve refined against a longdouble residual
    (:class:`_LightModes`; give a balanced realisation): the LU of ``sI − A`` rounded to double, three steps
    ``X += (sI − A)⁻¹(B − (sI − A)X)`` with the residual and ``C X + D`` in longdouble, ``s`` in longdouble. The
    steps contract by ``κ·eps`` down to a floor ``κ·ext_eps``. Returns the gains and, per point, how much the last
    step moved ``C X`` relative to the gain (the caller refuses a reading it moved by more than ``rtol/10``)."""
    if DOUBLE_DOUBLE:
        return _double_double_gains(A, B, C, D, discrete, freqs)
    ld, cld = np.longdouble, np.clongdouble
    Al, Bl, Cl, Dl = A.astype(ld), B.astype(ld), C.astype(ld), D.astype(ld)
    out, moved = np.empty(freqs.size), np.empty(freqs.size)
    for i, w in enumerate(np.asarray(freqs, float)):
        wl = ld(w)
        s = (np.cos(wl) + cld(1j) * np.sin(wl)) if discrete else cld(1j) * wl
        M = s * np.eye(A.shape[0], dtype=cld) - Al
        lu = sla.lu_factor(M.astype(complex), check_finite=False)
        X = sla.lu_solve(lu, B.astype(complex), check_finite=False).astype(cld)
        for _ in range(3):
            dX = sla.lu_solve(lu, (Bl - M @ X).astype(complex), check_finite=False)
            X = X + dX
        G = (Cl @ X + Dl).astype(complex)
        out[i] = np.linalg.svd(G, compute_uv=False)[0]
        moved[i] = float(np.linalg.norm((Cl @ dX.astype(cld)).astype(complex))) / max(out[i], np.finfo(float).tiny)
    return out, moved


# ------------------------------------------------------------------------------ double-double residuals
# Accuracy beyond double on every host, whatever numpy's longdouble is (the x87 80-bit format on x86 Linux; plain
# double on Windows and ARM macOS), from error-free transformations:
# ``two_sum(a, b) = (s, e)`` with ``s = fl(a + b)`` and ``a + b = s + e`` exactly (Knuth, TAOCP vol. 2, §4.2.2);
# ``two_prod(a, b) = (p, e)`` with ``p = fl(a·b)`` and ``a·b = p + e`` exactly (Dekker, "A floating-point technique for
# extending the available precision", Numer. Math. 18, 1971: Veltkamp's split by ``2^27 + 1``; exact barring overflow of
# ``(2^27 + 1)·a``, i.e. for ``|a| < 1e300``, and underflow of the partial products). :func:`dot2` is Ogita, Rump &
# Oishi's Dot2 ("Accurate sum and dot product", SIAM J. Sci. Comput. 26(6), 2005, Alg. 5.3) with the sums taken
# pairwise: every error term is kept, and only the error terms are summed in plain double, so ``|hi + lo − A·X| ≤
# (n + 2⌈log₂ n⌉)·u²·|A||X|`` to first order (``u = eps/2``): as if computed in twice the working precision.

#: Veltkamp's splitting constant 2^27 + 1 (binary64: a 53-bit significand split into two 26-bit halves)
_SPLITTER = 134217729.0


def two_sum(a, b):
    """``(s, e)``: ``s = fl(a + b)``, ``e = a + b − s`` exactly (Knuth's branch-free TwoSum)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def two_prod(a, b):
    """``(p, e)``: ``p = fl(a·b)``, ``e = a·b − p`` exactly (Dekker's TwoProduct with Veltkamp's split)."""
    p = a * b
    c = _SPLITTER * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLITTER * b
    bh = c - (c - b)
    bl = b - bh
    return p, al * bl - (((p - ah * bh) - al * bh) - ah * bl)


def dot2(A: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A·X`` (real, (r, n) by (n, c)) as an unevaluated sum ``hi + lo`` accurate to ``(n + 2⌈log₂ n⌉)·u²·|A||X|``
    (the section's comment): every product split exactly by :func:`two_prod`, the products summed pairwise by
    :func:`two_sum` (⌈log₂ n⌉ vector steps), the exact errors of both gathered in ``lo`` by plain sums."""
    A, X = np.asarray(A, float), np.asarray(X, float)
    P, E = two_prod(A[:, :, None], X[None, :, :])  # (r, n, c)
    lo = E.sum(axis=1)
    if not P.shape[1]:
        return np.zeros((A.shape[0], X.shape[1])), lo
    while P.shape[1] > 1:
        if P.shape[1] % 2:
            P = np.concatenate([P, np.zeros((P.shape[0], 1, P.shape[2]))], axis=1)
        P, q = two_sum(P[:, 0::2], P[:, 1::2])
        lo = lo + q.sum(axis=1)
    return P[:, 0], lo


#: :func:`sliced_dot`: the most slices of each factor before the rest is left to :func:`dot2` (6 slices of β ≥ 21 bits:
#: the entries within 2^-73 of their row's (column's) largest are split exactly; a smaller one is rare)
SLICES = 6


def _slices(M: np.ndarray, axis: int, beta: int) -> tuple[list, np.ndarray]:
    """``M = Σ_s M_s + R`` exactly: ``M_s`` the entries of the remainder rounded to multiples of ``w_s = 2^(e + 1 −
    s·β)``, ``e`` per row (``axis = 1``) or column (``axis = 0``) with ``max|M| < 2^e`` — so ``M_s/w_s`` are integers of
    magnitude ≤ 2^(β−1) (Ozaki, Ogita, Oishi & Rump, "Error-free transformations of matrix multiplication by using
    fast routines of matrix multiplication", Numer. Algorithms 59, 2012); at most :data:`SLICES`, fewer where the
    remainder R vanishes. Scaling by powers of 2 and rounding to an integer are exact; so is each difference."""
    e = np.frexp(np.max(np.abs(M), axis=axis, keepdims=True))[1]
    out, R = [], np.array(M, float)
    for s in range(1, SLICES + 1):
        if not R.any():
            break
        sh = e + 1 - s * beta
        S = np.ldexp(np.rint(np.ldexp(R, -sh)), sh)
        out.append(S)
        R = R - S
    return out, R


def sliced_dot(A: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A·X`` (real, ``(r, n)`` by ``(n, c)``) as an unevaluated sum ``hi + lo`` from matrix products in double (BLAS)
    that are exact: A split by rows and X by columns (:func:`_slices`, ``β = ⌊(55 − ⌈log₂(n·S)⌉)/2⌋``, S =
    :data:`SLICES`), so each product ``A_s X_t`` is ``w_s,i·w_t,j`` times a sum of n integer products each ≤
    ``2^(2β−2)`` — every partial sum an integer below 2^53 times that power of 2, exact in any order (FMA or not),
    and the products of equal ``s + t`` (one unit) add exactly too (≤ S of them). The remainders (entries below
    ``2^-(Sβ − 53)`` of their row's or column's largest) by :func:`dot2` on the rows/columns where they are not zero:
    ``A·X = Σ_g G_g + R_A·X + (A − R_A)·R_X``, the ≤ 2S − 1 group sums ``G_g`` exact and the two Dot2 pairs summed by
    Sum2 (:func:`compensated_sum`, m terms, ``γ_{m−1}²`` of their absolute sum; Ogita, Rump & Oishi 2005, Prop. 4.5).
    Each entry's slices have ``Σ_s |A_s| ≤ 3(1 + 2^(2−β))|a|`` (the first ≤ 2|a|, the rest within half a unit of the
    first's), so the sum's terms are ``≤ 10·|A||X|`` and the error

        ``|hi + lo − A·X| ≤ (10·(m − 1)² + 2n + 4⌈log₂ n⌉)·u²·|A||X|``, ``m ≤ 2S + 3`` (first order, ``u = eps/2``).

    Where the data's exponents leave the safe range (any |entry| ≥ 2^400, or a row's or column's largest below
    2^-300: the units ``w_s,i·w_t,j ≥ 2^(e_i + e_j + 2 − 2Sβ)`` must stay ≥ 2^-1074, the subnormal step, for the
    sums to be exact) or an entry is not finite, :func:`dot2` on everything."""
    A, X = np.asarray(A, float), np.asarray(X, float)
    r, n = A.shape
    c = X.shape[1]
    if not n or not r or not c:
        return np.zeros((r, c)), np.zeros((r, c))
    scales = np.concatenate([np.max(np.abs(A), axis=1), np.max(np.abs(X), axis=0)])
    big, nonzero = float(np.max(scales)), scales[scales > 0]
    if not (np.isfinite(big) and big < 2.0 ** 400 and (not nonzero.size or float(np.min(nonzero)) > 2.0 ** -300)):
        return _dot2_blocked(A, X)
    beta = (55 - int(np.ceil(np.log2(n * SLICES)))) // 2
    As, RA = _slices(A, 1, beta)
    Xs, RX = _slices(X, 0, beta)
    groups = {}
    for s, As_ in enumerate(As):
        for t, Xt in enumerate(Xs):
            P = As_ @ Xt
            groups[s + t] = groups[s + t] + P if s + t in groups else P
    terms = [groups[g] for g in sorted(groups)]
    for L, R in ((RA, X), (A - RA, RX)):  # R_A·X over A's columns with a remainder; (A − R_A)·R_X over X's rows
        lo_rows = np.flatnonzero(np.any(L != 0, axis=0)) if R is X else np.flatnonzero(np.any(R != 0, axis=1))
        if lo_rows.size:
            terms.extend(_dot2_blocked(L[:, lo_rows], R[lo_rows]))
    if not terms:
        return np.zeros((r, c)), np.zeros((r, c))
    return compensated_sum(terms)


def times_dd(N: np.ndarray, Mh: np.ndarray, Ml: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``N·(Mh + Ml)`` (``N`` double, ``Mh + Ml`` double-double, real) as ``hi + lo``: :func:`dot2` on the high part,
    the low part's product (relative size u) in double, the three summed by :func:`compensated_sum`; error
    ``≲ (n + 2⌈log₂ n⌉ + 1)·u²·|N||M|``."""
    h, lo = dot2(N, Mh)
    return compensated_sum([h, lo, np.asarray(N, float) @ Ml])


def dd_times(Mh: np.ndarray, Ml: np.ndarray, N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Mh + Ml)·N`` as ``hi + lo`` (:func:`times_dd` from the right)."""
    h, lo = dot2(Mh, N)
    return compensated_sum([h, lo, Ml @ np.asarray(N, float)])


def compensated_sum(terms) -> tuple[np.ndarray, np.ndarray]:
    """``Σ terms`` (equal-shaped arrays) as ``hi + lo``: Sum2 (Ogita, Rump & Oishi Alg. 4.4), ``|hi + lo − Σ| ≤
    γ_k²·Σ|terms|`` for k terms."""
    terms = list(terms)
    hi, lo = np.array(terms[0], float), np.zeros(np.shape(terms[0]))
    for t in terms[1:]:
        hi, q = two_sum(hi, t)
        lo = lo + q
    return hi, lo


def dd_add(ah, al, bh, bl) -> tuple[np.ndarray, np.ndarray]:
    """``(ah + al) + (bh + bl)`` as ``(hi, lo)``: :func:`two_sum` of the high parts (componentwise on complex arrays),
    the low parts in double, renormalised (``|lo| ≤ u·|hi|`` per real part)."""
    s, e = two_sum(ah, bh)
    return two_sum(s, e + (al + bl))


def _cplx(re: np.ndarray, im: np.ndarray) -> np.ndarray:
    """``re + j·im`` exactly (no complex multiplication)."""
    z = np.empty(np.shape(re), complex)
    z.real, z.imag = re, im
    return z


#: the most products one :func:`dot2` call holds in :func:`sliced_dot`'s remainders (its ``(r, n, columns)``
#: temporaries): 2^18 (2 MB each) — measured at n = 29, 87, 125 with 144–250 points of 10 columns: batches of 2^20 or
#: more products are slower (memory traffic), 2^16 … 2^18 the fastest
DD_BATCH = 2 ** 18
#: the most entries of X one :func:`sliced_dot` call of :func:`stack_times_dd` slices (each slice a copy): 2^20
DD_COLUMNS = 2 ** 20


def _dot2_blocked(A: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`dot2` in column blocks of at most :data:`DD_BATCH` products (the same numbers: each column on its own)."""
    width = max(1, DD_BATCH // max(A.shape[0] * A.shape[1], 1))
    if X.shape[1] <= width:
        return dot2(A, X)
    parts = [dot2(A, X[:, j:j + width]) for j in range(0, X.shape[1], width)]
    return np.concatenate([p[0] for p in parts], axis=1), np.concatenate([p[1] for p in parts], axis=1)


def stack_times_dd(M: np.ndarray, Xh: np.ndarray, Xl=None) -> tuple[np.ndarray, np.ndarray]:
    """``M·(X_h[k] + X_l[k])`` for every k of a stack of complex double-double matrices (``(K, n, c)``; ``X_l`` None:
    zero), M real ``(r, n)``: ``(hi, lo)``, each ``(K, r, c)``. The columns of all points side by side (real and
    imaginary parts apart), in blocks of at most :data:`DD_COLUMNS` entries: the high part by :func:`sliced_dot`
    (exact BLAS products), the low part's product in double, the three summed by Sum2 — error ``≤ (10(m − 1)² + 3n
    + 4⌈log₂ n⌉ + 2)·u²·|M||X|`` to first order (:func:`sliced_dot`'s, ``m ≤ 2·SLICES + 3``; ``γ_n·|M||X_l| ≤
    n·u²·|M||X|`` for the low part; Sum2's ``≤ 2u²``). Batching changes no rounding: a column's slices are scaled by
    its own exponent, and what the other columns add to its sums (a slice or remainder row it does not need) are
    exact zeros."""
    M = np.asarray(M, float)
    K, n, c = Xh.shape
    r = M.shape[0]

    def columns(X):  # (n, K·2c): point k's real parts in columns 2ck … 2ck + c − 1, its imaginary parts after them
        return np.concatenate([X.real, X.imag], axis=2).transpose(1, 0, 2).reshape(n, 2 * K * c)

    H, L = columns(Xh), None if Xl is None else columns(Xl)
    hi, lo = np.empty((r, H.shape[1])), np.empty((r, H.shape[1]))
    width = max(1, DD_COLUMNS // max(n, 1))
    for j in range(0, H.shape[1], width):
        h, e = sliced_dot(M, H[:, j:j + width])
        low = [] if L is None else [M @ L[:, j:j + width]]
        hi[:, j:j + width], lo[:, j:j + width] = compensated_sum([h, e, *low])
    hi, lo = (v.reshape(r, K, 2 * c).transpose(1, 0, 2) for v in (hi, lo))
    return _cplx(hi[..., :c], hi[..., c:]), _cplx(lo[..., :c], lo[..., c:])


@dataclass(frozen=True)
class RationalPoints:
    """Points ``λ_k = (a_k + j·b_k)/q_k`` held exactly: ``a = ah + al`` and ``q = qh + ql`` double-double, ``b`` double
    (arrays of one length K). :meth:`of` takes complex doubles (``a = Re λ``, ``b = Im λ``, ``q = 1``: exact);
    :meth:`on_circle` the points ``e^{jω}`` as ``(1 − v² + 2jv)/(1 + v²)``, ``v = tan(ω/2)`` — ``v² = p + e`` exactly
    (TwoProduct), ``a`` and ``q`` from it by TwoSum with one rounding of the two error terms' sum, so ``|a² + b² − q²|
    ≲ 8u²·q²``: on the unit circle to ~u² (a point off it by eps moved the gain near a mode at distance d by eps/d),
    at ``2·atan(v)``, within an ulp of ω."""

    ah: np.ndarray
    al: np.ndarray
    b: np.ndarray
    qh: np.ndarray
    ql: np.ndarray

    @classmethod
    def of(cls, lam) -> "RationalPoints":
        lam = np.atleast_1d(np.asarray(lam, complex))
        zero = np.zeros(lam.size)
        return cls(lam.real.copy(), zero, lam.imag.copy(), np.ones(lam.size), zero)

    @classmethod
    def on_circle(cls, w) -> "RationalPoints":
        v = np.tan(np.atleast_1d(np.asarray(w, float)) / 2.0)
        p, e = two_prod(v, v)
        qh, ql = two_sum(1.0, p)
        ah, al = two_sum(1.0, -p)
        return cls(ah, al - e, 2.0 * v, qh, ql + e)

    def __len__(self) -> int:
        return self.b.size

    def __getitem__(self, idx) -> "RationalPoints":
        return RationalPoints(self.ah[idx], self.al[idx], self.b[idx], self.qh[idx], self.ql[idx])

    def rounded(self) -> np.ndarray:
        """The points in complex double (to factor ``λI − A`` in double)."""
        return (self.ah + 1j * self.b) / self.qh


def shifted_solvers(A: np.ndarray, lam, hessenberg: bool = True) -> list:
    """Per point λ_k a function ``R ↦ (λ_k I − A)^{-1} R`` in double (complex), None where the factorisation meets an
    exactly zero pivot. ``hessenberg``: the LU with partial pivoting of ``λI − H``, ``A = U H Uᵀ`` the Hessenberg form
    of :func:`.freqresp.hessenberg_form` (one reduction, then O(n²) per point: LAPACK zgbtrf on the band with one
    subdiagonal); else the dense LU with partial pivoting of ``λI − A`` (zgetrf, O(n³) per point)."""
    A = np.asarray(A, float)
    n = A.shape[0]
    out = []
    if not hessenberg:
        getrf, getrs = sla.get_lapack_funcs(("getrf", "getrs"), (np.zeros(1, complex),))
        for lk in np.asarray(lam, complex):
            lu, piv, info = getrf(lk * np.eye(n) - A)
            out.append(None if info != 0 else (lambda R, lu=lu, piv=piv: getrs(lu, piv, R)[0]))
        return out
    H, U = hessenberg_form(A)
    low, up = min(1, n - 1), n - 1
    i, j = np.triu_indices(n, -low)
    band = np.zeros((2 * low + up + 1, n), complex, order="F")
    band[low + up + i - j, j] = -np.asarray(H, float)[i, j]
    gbtrf, gbtrs = sla.get_lapack_funcs(("gbtrf", "gbtrs"), (band,))
    Ut = np.ascontiguousarray(U.T)
    for lk in np.asarray(lam, complex):
        ab = band.copy(order="F")
        ab[low + up] += lk
        lu, piv, info = gbtrf(ab, low, up)
        out.append(None if info != 0 else
                   (lambda R, lu=lu, piv=piv: U @ gbtrs(lu, low, up, np.asarray(Ut @ R, complex), piv)[0]))
    return out


def residual_unit(n: int) -> float:
    """``c_n·u²``, the relative error of :func:`refine_dd`'s residual at order n (its docstring):
    ``(10·(2·SLICES + 2)² + 3n + 4⌈log₂ n⌉ + 8)·u²`` (``u = eps/2``)."""
    return (10 * (2 * SLICES + 2) ** 2 + 3 * n + 4 * int(np.ceil(np.log2(max(n, 1)))) + 8) * (EPS / 2) ** 2


def refine_dd(A: np.ndarray, points: RationalPoints, Rh: np.ndarray, Rl, X: np.ndarray, solvers,
              steps: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Iterative refinement in double-double of ``(λ_k I − A) X_k = R_k`` at every point of ``points`` at once:
    ``steps`` steps ``X += (λI − A)^{-1} r`` from ``X`` (double, ``(K, n, c)`` complex), the residual r formed in
    double-double for all points together, each correction solved in double by the point's ``solvers[k]`` (e.g. of
    :func:`shifted_solvers`; None: the point's results are NaN). ``R = R_h + R_l`` is a complex double-double
    right-hand side (``R_l`` None: zero), A real. Returns ``(X_h, X_l, D)``: the iterate as an unevaluated sum
    (``|X_l| ≤ u·|X_h|``) and the last correction D (how far the last step moved).

    **The residual.** With ``λ = (a + jb)/q`` exact (:class:`RationalPoints`) and ``x = x_h + x_l`` it is formed times
    q, ``q·r = q·R + q·Ax − (a + jb)·x`` (real part ``qR_r + q(Ax)_r − a·x_r + b·x_i``, imaginary ``qR_i + q(Ax)_i −
    a·x_i − b·x_r``): ``Ax`` by :func:`stack_times_dd` (exact BLAS products over the columns of every point at once,
    :func:`sliced_dot`), the products
    of the scalars' high parts with the high parts by :func:`two_prod` (exact), the terms of relative size u (low
    parts) in double, the four high terms of each part by Sum2 (:func:`compensated_sum`); then rounded to double
    and divided by q for the correction. Its error, to first order (``u = eps/2``)::

        |q·r̂ − q·r| ≤ c_n·u²·(|q|·|R| + |a + jb|·|x| + |q|·|A||x|),   c_n = 10(m − 1)² + 3n + 4⌈log₂ n⌉ + 8

    (:func:`residual_unit`: ``c_n·u²``) — :func:`stack_times_dd`'s ``(10(m − 1)² + 3n + 4⌈log₂ n⌉ + 2)·u²`` on
    ``|A||x|`` (``m ≤ 2·SLICES + 3`` = 15: c_n ≤ 1968 + 3n + 4⌈log₂ n⌉), Sum2's ``γ_4²`` on the four high terms, and
    the low terms' products and sums (each within ``u²`` of its term, the dropped products of two low parts too):
    at most ``c_n·u²`` times ``|R| + |λI − A||x|`` relative to r (``|λ| = |a + jb|/|q|``).

    **What it guarantees.** Refinement with a solver whose error contracts (``c·u·‖ |(λI − A)^{-1}|·|ΔM| ‖ ≪ 1``, ΔM
    the solver's backward error) converges, each step dividing the error by that factor, to the solution of the
    stored system to the residual's precision (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed.,
    ch. 12): after enough steps ``|X − X_true| ≲ |(λI − A)^{-1}|·c_n·u²·(|R| + |λI − A||X|)``. The
    routine does not measure the contraction: its callers charge the reading
    (:func:`fmu_fdi.design.toolkit.postconditions._dd_refined_values` at ``REFINED_UNIT``; :class:`_LightModes` by the
    last step's move). Per column the arithmetic is that of one point alone: batching changes no rounding."""
    K, n, c = Rh.shape
    Rl = np.zeros((K, n, c), complex) if Rl is None else Rl
    qh, ql, ah, al, b = (np.asarray(v, float)[:, None, None] for v in (points.qh, points.ql, points.ah, points.al,
                                                                          points.b))
    xh, xl = np.array(X, complex), np.zeros((K, n, c), complex)
    xh[np.array([s is None for s in solvers], bool)] = np.nan
    d = np.zeros((K, n, c), complex)

    def part(R, Rlo, t, tlo, x, xlo, y, ylo, sign):  # a part of q·r (docstring), rounded to double
        p1, e1 = two_prod(qh, R)
        p2, e2 = two_prod(qh, t)
        p3, e3 = two_prod(ah, x)
        p4, e4 = two_prod(b, y)
        s, q = compensated_sum([p1, p2, -p3, sign * p4])
        low = (q + e1 + e2 - e3 + sign * e4 + (qh * Rlo + ql * R) + (qh * tlo + ql * t) - (ah * xlo + al * x)
               + sign * (b * ylo))
        return s + low

    q = qh + ql
    for _ in range(steps):
        th, tl = stack_times_dd(A, xh, xl)
        r = _cplx(part(Rh.real, Rl.real, th.real, tl.real, xh.real, xl.real, xh.imag, xl.imag, 1.0) / q,
                  part(Rh.imag, Rl.imag, th.imag, tl.imag, xh.imag, xl.imag, xh.real, xl.real, -1.0) / q)
        for k, solve in enumerate(solvers):
            if solve is not None:
                d[k] = solve(r[k])
        xh, xl = dd_add(xh, xl, d, 0.0)
    return xh, xl, d


#: the most entries the factorisations of one block of points of :func:`dd_refined_solves` hold: 2^21 (32 MB complex;
#: order 125: 130 points a block)
DD_FACTOR_ENTRIES = 2 ** 21


def dd_refined_solves(A: np.ndarray, points: RationalPoints, Rh: np.ndarray, Rl=None, steps: int = 3,
                      hessenberg: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(λ_k I − A)^{-1}(R_h[k] + R_l[k])`` at every point (``Rh``, ``Rl``: ``(K, n, c)`` complex; ``Rl`` None: zero)
    in double-double: each point's ``λI − A`` factored in double (:func:`shifted_solvers`), the first solve in double,
    then :func:`refine_dd` (its docstring: what it guarantees) — in blocks of points whose factorisations hold at
    most :data:`DD_FACTOR_ENTRIES` entries. Returns ``(X_h, X_l, D)`` as :func:`refine_dd`; NaN at a point where
    ``λI − A`` is exactly singular."""
    K, n, c = Rh.shape
    if n == 0 or K == 0:
        return tuple(np.zeros((K, n, c), complex) for _ in range(3))
    Xh, Xl, D = (np.full((K, n, c), np.nan, complex) for _ in range(3))
    lam = points.rounded()
    block = max(1, DD_FACTOR_ENTRIES // (n * (n + 2)))
    for s in range(0, K, block):
        idx = slice(s, min(K, s + block))
        solvers = shifted_solvers(A, lam[idx], hessenberg)
        X0 = np.stack([np.full((n, c), np.nan, complex) if f is None else f(np.asarray(R, complex))
                       for f, R in zip(solvers, Rh[idx])])
        Xh[idx], Xl[idx], D[idx] = refine_dd(A, points[idx], Rh[idx], None if Rl is None else Rl[idx], X0, solvers,
                                             steps)
    return Xh, Xl, D


#: whether :func:`_extended_gains` reads in double-double (:func:`dot2` and the other error-free transformations
#: above) instead of longdouble: where longdouble is double (Windows, ARM macOS)
DOUBLE_DOUBLE = EXT_EPS >= EPS


def _ext_eps(n: int) -> float:
    """The relative precision of :func:`_extended_gains`' residual — longdouble's eps, or in double-double
    (:data:`DOUBLE_DOUBLE`) :func:`refine_dd`'s residual, :func:`residual_unit` (``≤ (1968 + 3n + 4⌈log₂ n⌉)·u²``)."""
    return residual_unit(n) if DOUBLE_DOUBLE else EXT_EPS


def _double_double_gains(A, B, C, D, discrete: bool, freqs) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_extended_gains` with the residual and the iterate in double-double: :func:`dd_refined_solves` (the dense
    LU of ``sI − A`` in double, three steps, the residual of all points at once) at the exact points of
    :class:`RationalPoints` — continuous ``s = jω`` (``a = 0``, ``b = ω``, ``q = 1``), discrete ``(1 − v² + 2jv)/(1 +
    v²)``, ``v = tan(ω/2)``, on the unit circle to ~u²; ``C X + D`` by :func:`stack_times_dd` and Sum2. Each step
    contracts by ``κ·eps`` to the residual's floor ``~c_n·u²·q·(|B| + |sI − A||X|)`` (:func:`residual_unit`) — below
    longdouble's on x86. ``moved``: the last correction's ``‖C dX‖`` relative to the gain."""
    freqs = np.asarray(freqs, float)
    K = freqs.size
    pts = RationalPoints.on_circle(freqs) if discrete else RationalPoints.of(1j * freqs)
    Bs = np.broadcast_to(np.asarray(B, float).astype(complex), (K,) + B.shape)
    Xh, Xl, dX = dd_refined_solves(A, pts, Bs, None, steps=3, hessenberg=False)
    Gh, Gl = stack_times_dd(C, Xh, Xl)
    Dk = np.broadcast_to(np.asarray(D, float), Gh.shape)
    G = _cplx(sum(compensated_sum([Dk, Gh.real, Gl.real])), sum(compensated_sum([Gh.imag, Gl.imag])))
    out = np.linalg.svd(G, compute_uv=False)[:, 0]
    moved = np.linalg.norm(np.asarray(C, float) @ dX, axis=(1, 2)) / np.maximum(out, np.finfo(float).tiny)
    return out, moved


def structurally_observed(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Indices (in order) of the states of ``(A, C)`` with a path to the output through the exact
    non-zero pattern: ``C[:, j] ≠ 0``, or ``A[i, j] ≠ 0`` for an observed state i. The other states are
    unobservable whatever the values (no rank decision, no tolerance): removing them keeps the transfer
    function and, where none is removed, the realisation."""
    n = A.shape[0]
    seen = np.any(C != 0, axis=0) if C.size else np.zeros(n, bool)
    frontier = seen.copy()
    nz = A != 0
    while frontier.any():
        new = np.any(nz[frontier, :], axis=0) & ~seen
        seen |= new
        frontier = new
    return np.flatnonzero(seen)


def _index(idx, size: int) -> np.ndarray:
    if isinstance(idx, slice):
        return np.arange(size)[idx]
    idx = np.atleast_1d(np.asarray(idx))
    if idx.dtype == bool:
        return np.flatnonzero(idx)
    return idx.astype(int)


def hstack(systems: Sequence[LTI]) -> LTI:
    """``[G1 G2 ...]``: shared outputs, concatenated inputs (block-diagonal states)."""
    systems = list(systems)
    dt = systems[0].dt
    p = systems[0].p
    for s in systems:
        systems[0]._check_dt(s)
        if s.p != p:
            raise ValueError("hstack: all systems need the same number of outputs")
    return LTI(
        sla.block_diag(*[s.A for s in systems]) if any(s.n for s in systems) else np.zeros((0, 0)),
        sla.block_diag(*[s.B for s in systems]),
        np.hstack([s.C for s in systems]),
        np.hstack([s.D for s in systems]),
        dt,
    )


def vstack(systems: Sequence[LTI]) -> LTI:
    """``[G1; G2; ...]``: shared inputs, concatenated outputs."""
    systems = list(systems)
    m = systems[0].m
    for s in systems:
        systems[0]._check_dt(s)
        if s.m != m:
            raise ValueError("vstack: all systems need the same number of inputs")
    return LTI(
        sla.block_diag(*[s.A for s in systems]) if any(s.n for s in systems) else np.zeros((0, 0)),
        np.vstack([s.B for s in systems]),
        sla.block_diag(*[s.C for s in systems]),
        np.vstack([s.D for s in systems]),
        systems[0].dt,
    )


def blockdiag(systems: Iterable[LTI]) -> LTI:
    systems = list(systems)
    for s in systems:
        systems[0]._check_dt(s)
    return LTI(
        sla.block_diag(*[s.A for s in systems]),
        sla.block_diag(*[s.B for s in systems]),
        sla.block_diag(*[s.C for s in systems]),
        sla.block_diag(*[s.D for s in systems]),
        systems[0].dt,
    )


def _pole_scales(poles, dt: float) -> np.ndarray:
    p = np.asarray(poles, complex)
    p = p[np.abs(p) > 0]
    return np.abs(np.log(p)) / dt if dt else np.abs(p)


def frequency_grid(systems: Sequence[LTI], num: int = 400, extra=(), poles=()) -> np.ndarray:
    """Log-spaced frequencies (rad/s) spanning two decades beyond every pole scale, plus 0.

    ``poles`` adds further pole locations (in the systems' domain). For discrete systems
    the grid stops at the Nyquist frequency.
    """
    dt = next((s.dt for s in systems if s.dt), 0.0)
    mags = np.concatenate([_pole_scales(s.poles(), s.dt) for s in systems] + [_pole_scales(poles, dt)])
    mags = mags[np.isfinite(mags) & (mags > 0)]
    lo = mags.min() / 100 if mags.size else 1e-3
    hi = mags.max() * 100 if mags.size else 1e3
    if dt > 0:
        hi = min(hi, np.pi / dt)
        lo = min(lo, hi / 1e4)
    grid = np.concatenate([[0.0], np.logspace(np.log10(lo), np.log10(hi), num), np.asarray(extra, float)])
    if dt > 0:
        grid = np.append(grid, np.pi / dt)
    return np.unique(grid)
