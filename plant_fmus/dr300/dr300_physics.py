"""DC motor DR300 with its PI speed controller (Ding 2013): parameters and a state-space
realisation of the published transfer functions (numpy only; bundled into the FMU).

    Gu(s) = k_u / ((1 + T1 s)(1 + T2 s)(1 + T3 s))    voltage -> speed
    Gd(s) = -k_d / (s (1 + T3 s))                      load torque -> speed
    Gc(s) = k_c (1 + T1 s) / s = Kp + Ki / s,  Kp = k_c T1, Ki = k_c    (PI controller)

Realisation (minimal, order 4; the lag T3 that Gu and Gd share is the last stage)::

    x1' = (k_u V - x1) / T1
    x2' = (x1 - x2) / T2
    x3' = -k_d tau_L
    x4' = (x2 + x3 - x4) / T3,      speed = x4

Note: Gd integrates and Gu does not, so a constant load torque is compensated by a ramping
voltage (x2 ramps against x3); this is a property of the published model.
The PI controller runs at the communication step h (sampled at the communication points,
zero-order hold): ``e_k = r_k - y_k``, ``V_k = Kp e_k + Ki xi_k``, ``xi_{k+1} = xi_k + h e_k``.
"""
import numpy as np

PREFIX = "dr300"
STEP = 0.01  # s; none published, plants.md calls 0.01 s a reasonable choice

PARAMS = {"k_u": 8.75, "T1": 1.225, "T2": 0.03, "T3": 0.005, "k_d": 31.07, "k_c": 1.6}

U = ("voltage",)        # controller output = the model's known input
Y = ("speed",)
D = ("load_torque",)
UNITS = {"voltage": "V"}   # speed and torque units are not stated in our reference
#: Speed-sensor noise std: none published; our choice.
NOISE_STD = (0.01,)
SENSOR_FAULTS = ("sensor_speed",)
ACTUATOR_FAULTS = ("actuator_voltage",)


def matrices(p=PARAMS):
    """``(A, Bu, Bd, C)`` of the realisation in the module docstring."""
    T1, T2, T3 = p["T1"], p["T2"], p["T3"]
    A = np.array([[-1 / T1, 0.0, 0.0, 0.0],
                  [1 / T2, -1 / T2, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 0.0],
                  [0.0, 1 / T3, 1 / T3, -1 / T3]])
    Bu = np.array([[p["k_u"] / T1], [0.0], [0.0], [0.0]])
    Bd = np.array([[0.0], [0.0], [-p["k_d"]], [0.0]])
    C = np.array([[0.0, 0.0, 0.0, 1.0]])
    return A, Bu, Bd, C


def pi_gains(p=PARAMS):
    """``(Kp, Ki)`` of Gc(s) = k_c (1 + T1 s)/s."""
    return p["k_c"] * p["T1"], p["k_c"]
