"""Three-tank system DTS200 (AMIRA): parameters and Torricelli dynamics (numpy only).

Bundled into the DTS200 FMU and used by :mod:`plant_fmus.dts200` to linearise, so the
FMU and its model file share one set of equations and numbers.

Topology (S. X. Ding, *Model-based Fault Diagnosis Techniques*, 2008/2013): pump Q1 fills
T1, which drains through T3 into T2; pump Q2 fills T2, which drains to the outlet::

    A h1' = Q1 - Q13 - Qleak1
    A h2' = Q2 + Q32 - Q20 - Qleak2
    A h3' = Q13 - Q32 - Qleak3
    Q13 = (1 - c13) az1 s sqrt(2 g) r(h1 - h3)
    Q32 = (1 - c32) az3 s sqrt(2 g) r(h3 - h2)
    Q20 = (1 - c20) az2 s sqrt(2 g) r(h2)
    Qleak_i = theta_i sqrt(2 g) r(h_i)

with clogging factors ``c`` in [0, 1], equivalent leak areas ``theta_i >= 0`` (cm^2) and
``r(D) = sgn(D) sqrt(|D|)`` (Torricelli) for heads |D| >= D_LAM. Below D_LAM = 0.01 cm
(our choice) ``r`` is the odd cubic ``sqrt(D_LAM) (5/4 D/D_LAM - 1/4 (D/D_LAM)^3)``, which
joins the square root with a continuous slope (a laminar-like regime): with it the ODE is
Lipschitz, so a draining tank does not force the integrator into ever smaller steps near
an empty tank (sqrt has an infinite slope at 0). The operating point and the
linearisation lie far inside the Torricelli range.
Levels stay in ``[0, h_max]``: at ``h_max`` the tank overflows (inflow beyond the outflow
spills); a level never falls below 0.

Operating point: h1 = 41 cm and h2 = 32 cm as documented; h3 follows exactly from
Q13 = Q32, i.e. ``az1^2 (h1 - h3) = az3^2 (h3 - h2)``, giving h3 = 36.5989 cm (published,
rounded: 36.6 cm, where h3' would be -3.4e-5 cm/s), and the pump flows Q1 = Q13 =
21.3727 cm^3/s, Q2 = Q20 - Q32 = 53.7976 cm^3/s (published, rounded: 21.37, 53.80).
"""
import math

import numpy as np

PREFIX = "dts200"
STEP = 1.0  # s, the sample time of the DTS200 literature

#: Physical parameters (plants.md section 1). ``q_max`` is **unverified** (another source: 150).
PARAMS = {
    "area": 154.0,       # tank cross-section A, cm^2
    "pipe_area": 0.5,    # s13 = s32 = s20, cm^2
    "az1": 0.46,         # outflow coefficient T1 -> T3
    "az2": 0.60,         # outflow coefficient T2 -> outlet
    "az3": 0.45,         # outflow coefficient T3 -> T2
    "g": 981.0,          # cm/s^2
    "h_max": 62.0,       # cm, overflow above
    "q_max": 100.0,      # cm^3/s, pump limit (unverified)
}
H1_OP, H2_OP = 41.0, 32.0
D_LAM = 0.01  # cm, head below which the flow law is regularised (see the module docstring)

U = ("Q1", "Q2")
Y = ("h1", "h2", "h3")
UNITS = {"Q1": "cm3/s", "Q2": "cm3/s", "h1": "cm", "h2": "cm", "h3": "cm"}
#: Measurement noise std (plants.md: 0.1-0.2 cm typical; we take the lower end).
NOISE_STD = (0.1, 0.1, 0.1)
SENSOR_FAULTS = ("sensor_h1", "sensor_h2", "sensor_h3")
ACTUATOR_FAULTS = ("pump_Q1", "pump_Q2")
LEAKS = ("leak_T1", "leak_T2", "leak_T3")
CLOGS = ("clog_13", "clog_32", "clog_20")


def root(d: float) -> float:
    """``sgn(d) sqrt(|d|)``, regularised below the head D_LAM (module docstring)."""
    if abs(d) >= D_LAM:
        return math.copysign(math.sqrt(abs(d)), d)
    z = d / D_LAM
    return math.sqrt(D_LAM) * (1.25 * z - 0.25 * z ** 3)


def _coefficients(p, clog):
    """Flow per unit ``root`` of the three pipes, clogging included."""
    k = p["pipe_area"] * math.sqrt(2.0 * p["g"])
    return (1.0 - clog[0]) * p["az1"] * k, (1.0 - clog[1]) * p["az3"] * k, (1.0 - clog[2]) * p["az2"] * k


def flows(h, p=PARAMS, clog=(0.0, 0.0, 0.0)):
    """Pipe flows ``(Q13, Q32, Q20)`` in cm^3/s for levels ``h`` (cm)."""
    c13, c32, c20 = _coefficients(p, clog)
    h1, h2, h3 = float(h[0]), float(h[1]), float(h[2])
    return c13 * root(h1 - h3), c32 * root(h3 - h2), c20 * root(max(h2, 0.0))


def rates_function(q_in, p=PARAMS, leak=(0.0, 0.0, 0.0), clog=(0.0, 0.0, 0.0)):
    """``h -> h'`` (list of floats, cm/s) for inputs held over a step: pump flows ``q_in``
    (cm^3/s), leak areas, clogging; with the level limits. The inputs' constants are folded once,
    so the integrator's seven evaluations per step cost only the flows."""
    c13, c32, c20 = _coefficients(p, clog)
    s2g, area, h_max = math.sqrt(2.0 * p["g"]), p["area"], p["h_max"]
    q1, q2 = float(q_in[0]), float(q_in[1])
    k_leak = [lk * s2g for lk in leak]
    leaky = any(lk != 0.0 for lk in leak)

    def f(h):
        h1, h2, h3 = h
        q13, q32, q20 = c13 * root(h1 - h3), c32 * root(h3 - h2), c20 * root(max(h2, 0.0))
        out = [q1 - q13, q2 + q32 - q20, q13 - q32]
        for i, hi in enumerate(h):
            dh = (out[i] - k_leak[i] * root(max(hi, 0.0)) if leaky and k_leak[i] != 0.0 else out[i]) / area
            # A full tank spills what it cannot hold; an empty one has nothing left to lose.
            if (hi >= h_max and dh > 0.0) or (hi <= 0.0 and dh < 0.0):
                dh = 0.0
            out[i] = dh
        return out

    return f


def rates(h, q_in, p=PARAMS, leak=(0.0, 0.0, 0.0), clog=(0.0, 0.0, 0.0)) -> list:
    """Level rates ``h'`` (cm/s) for pump flows ``q_in`` (cm^3/s), with the level limits, as a
    list of floats (:func:`rates_function` evaluated once)."""
    return rates_function(q_in, p, leak, clog)(h)


def derivative(h, q_in, p=PARAMS, leak=(0.0, 0.0, 0.0), clog=(0.0, 0.0, 0.0)) -> np.ndarray:
    """:func:`rates` as an array."""
    return np.array(rates(h, q_in, p, leak, clog))


def operating_point(p=PARAMS, h1=H1_OP, h2=H2_OP):
    """Exact equilibrium ``(h, Q)`` with the given h1, h2 (see the module docstring)."""
    w1, w3 = p["az1"] ** 2, p["az3"] ** 2
    h = np.array([h1, h2, (w1 * h1 + w3 * h2) / (w1 + w3)])
    q13, q32, q20 = flows(h, p)
    return h, np.array([q13, q20 - q32])
