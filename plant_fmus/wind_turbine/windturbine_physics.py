"""Wind-turbine FDI benchmark, linear subsystems: three pitch systems, drive train and
converter (Odgaard, Stoustrup & Kinnaert 2009/2013). numpy only; bundled into the FMU.

Pitch system of blade i, beta in deg::

    beta_i'' = -2 zeta wn beta_i' - wn^2 beta_i + wn^2 beta_ref_i,   wn = 11.11 rad/s, zeta = 0.6

Benchmark faults 6 (hydraulic pressure drop: wn 5.73, zeta 0.45) and 7 (air in oil: wn 3.42,
zeta 0.9) blend the coefficients with a fault level theta in [0, 1]::

    wn^2(theta)    = wn^2 + theta_p (wn_p^2 - wn^2) + theta_a (wn_a^2 - wn^2)
    2 zeta wn(theta) = 2 zeta wn + theta_p (2 zeta_p wn_p - 2 zeta wn) + theta_a (2 zeta_a wn_a - 2 zeta wn)

(the benchmark ramps fault 7 in and out over 30 s: theta_a from 0 to 1 and back).

Drive train x = (omega_r, omega_g, theta_delta) with rotor torque tau_r (aerodynamic, the
unknown input) and generator torque tau_g::

    J_r omega_r' = -(B_dt + B_r) omega_r + B_dt/N_g omega_g - K_dt theta_delta + tau_r
    J_g omega_g' = eta_dt B_dt/N_g omega_r - (eta_dt B_dt/N_g^2 + B_g) omega_g
                   + eta_dt K_dt/N_g theta_delta - tau_g
    theta_delta' = omega_r - omega_g / N_g

Converter: tau_g' = alpha_gc (tau_g_ref - tau_g); the torque acting on the generator and
measured is tau_g + offset (benchmark fault 8, 100 Nm). Sensors: two per pitch angle, two
for omega_r, two for omega_g, one for tau_g (noise std 0.2 deg, 0.004*2*pi rad/s,
0.05 rad/s, 90 Nm). The converter efficiency eta_gc = 0.98 only scales the electrical
power, which these subsystems do not output.

Operating point (**our choice**, not from the benchmark): omega_r = 1.6 rad/s,
tau_g = 3.0e4 Nm, beta = 0 deg; omega_g, theta_delta and tau_r follow from the steady
state: omega_g = N_g omega_r, K_dt theta_delta = tau_r - B_r omega_r,
tau_r = N_g (tau_g + B_g N_g omega_r) / eta_dt + B_r omega_r.
"""
import numpy as np

PREFIX = "windturbine"
STEP = 0.01  # s, the benchmark sample time Ts

PARAMS = {
    "omega_n": 11.11, "zeta": 0.6,
    "omega_n_pressure_drop": 5.73, "zeta_pressure_drop": 0.45,
    "omega_n_air_in_oil": 3.42, "zeta_air_in_oil": 0.9,
    "B_dt": 775.49, "B_r": 7.11, "B_g": 45.6, "N_g": 95.0, "K_dt": 2.7e9, "eta_dt": 0.97,
    "J_g": 390.0, "J_r": 55e6, "alpha_gc": 50.0,
}
OMEGA_R_OP = 1.6
TAU_G_OP = 3.0e4
BETA_OP = 0.0

BLADES = (1, 2, 3)
PITCH_U = tuple(f"beta_ref_{i}" for i in BLADES)
PITCH_Y = tuple(f"beta_{i}_m{j}" for i in BLADES for j in (1, 2))
DT_U = ("tau_g_ref",)
DT_D = ("tau_r",)
DT_Y = ("omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2", "tau_g_m")
UNITS = {**{n: "deg" for n in PITCH_U + PITCH_Y}, "tau_g_ref": "Nm", "tau_r": "Nm", "tau_g_m": "Nm",
         **{n: "rad/s" for n in DT_Y[:4]}}
NOISE_STD = {**{y: 0.2 for y in PITCH_Y}, "omega_r_m1": 0.004 * 2 * np.pi, "omega_r_m2": 0.004 * 2 * np.pi,
             "omega_g_m1": 0.05, "omega_g_m2": 0.05, "tau_g_m": 90.0}
PITCH_FAULT_KINDS = ("pressure_drop", "air_in_oil")


def pitch_coefficients(p, theta_pressure_drop=0.0, theta_air_in_oil=0.0):
    """``(wn^2, 2 zeta wn)`` of one pitch system at the given fault levels."""
    w2, c = p["omega_n"] ** 2, 2 * p["zeta"] * p["omega_n"]
    for kind, theta in zip(PITCH_FAULT_KINDS, (theta_pressure_drop, theta_air_in_oil)):
        wf = p[f"omega_n_{kind}"]
        w2 += theta * (wf ** 2 - p["omega_n"] ** 2)
        c += theta * (2 * p[f"zeta_{kind}"] * wf - 2 * p["zeta"] * p["omega_n"])
    return w2, c


def pitch_matrices(p=PARAMS, theta_pressure_drop=(0.0,) * 3, theta_air_in_oil=(0.0,) * 3):
    """``(A, B, C)`` of the three pitch systems, x = (beta_1, beta_1', ..., beta_3'), u = beta_ref."""
    A, B, C = np.zeros((6, 6)), np.zeros((6, 3)), np.zeros((6, 6))
    for i in range(3):
        w2, c = pitch_coefficients(p, theta_pressure_drop[i], theta_air_in_oil[i])
        A[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[0.0, 1.0], [-w2, -c]]
        B[2 * i + 1, i] = w2
        C[2 * i, 2 * i] = C[2 * i + 1, 2 * i] = 1.0
    return A, B, C


def drive_train_matrices(p=PARAMS, d_eta=0.0):
    """``(A, Bu, Bd, C)`` of drive train + converter, x = (omega_r, omega_g, theta_delta, tau_g),
    u = tau_g_ref, d = tau_r, y = DT_Y; ``d_eta`` is the change of eta_dt (fault 9)."""
    Bdt, Br, Bg, Ng, K, Jg, Jr = (p[k] for k in ("B_dt", "B_r", "B_g", "N_g", "K_dt", "J_g", "J_r"))
    eta = p["eta_dt"] + d_eta
    A = np.array([[-(Bdt + Br) / Jr, Bdt / (Ng * Jr), -K / Jr, 0.0],
                  [eta * Bdt / (Ng * Jg), -(eta * Bdt / Ng ** 2 + Bg) / Jg, eta * K / (Ng * Jg), -1.0 / Jg],
                  [1.0, -1.0 / Ng, 0.0, 0.0],
                  [0.0, 0.0, 0.0, -p["alpha_gc"]]])
    Bu = np.array([[0.0], [0.0], [0.0], [p["alpha_gc"]]])
    Bd = np.array([[1.0 / Jr], [0.0], [0.0], [0.0]])
    C = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 1.0]])
    return A, Bu, Bd, C


def operating_point(p=PARAMS, omega_r=OMEGA_R_OP, tau_g=TAU_G_OP):
    """Steady state of the drive train: ``(x0, tau_r0)`` with x0 = (omega_r, omega_g, theta_delta, tau_g)."""
    tau_r = p["N_g"] * (tau_g + p["B_g"] * p["N_g"] * omega_r) / p["eta_dt"] + p["B_r"] * omega_r
    x0 = np.array([omega_r, p["N_g"] * omega_r, (tau_r - p["B_r"] * omega_r) / p["K_dt"], tau_g])
    return x0, tau_r
