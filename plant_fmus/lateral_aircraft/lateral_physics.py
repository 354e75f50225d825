"""Lateral aircraft dynamics with loss-of-effectiveness (LOE) actuator faults
(A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, Examples 6.1 and 6.2).
numpy only; bundled into the FMU.

    x' = A x + Bu Gamma u + Bw w,   y = C x + Dw w,   Gamma = diag(1 - gamma_1, 1 - gamma_2)

gamma_j in [0, 1] (Varga: {0, 0.5, 1} each, nine models). Example 6.1 measures the whole
state (C = I4, no noise); Example 6.2 adds process noise on every state (Bw = I) and
measurement noise. We keep C = I4 (radians; Example 6.2 reports two outputs in degrees,
C = (180/pi) I_{2,4}). State names are our reading of the matrices (sideslip beta, bank
angle phi with phi' = p + 0.0067 r, roll rate p, yaw rate r); the example does not name
them, nor the two inputs.

The open loop is stable (eigenvalues -5.237, -0.541 +- 4.078j, -0.0110: a slow spiral
mode), so no feedback is added.
"""
import numpy as np

PREFIX = "lateral"
STEP = 0.01

A = np.array([[-0.4492, 0.046, 0.0053, -0.9926],
              [0.0, 0.0, 1.0, 0.0067],
              [-50.8436, 0.0, -5.2184, 0.722],
              [16.4148, 0.0, 0.0026, -0.6627]])
BU = np.array([[0.0004, 0.0011],
               [0.0, 0.0],
               [-1.4161, 0.2621],
               [-0.0633, -0.1205]])
C = np.eye(4)

U = ("u1", "u2")
Y = ("beta", "phi", "p", "r")
UNITS = {"beta": "rad", "phi": "rad", "p": "rad/s", "r": "rad/s"}
SENSOR_TEXT = ("sideslip angle", "bank angle", "roll rate", "yaw rate")
#: Noise std, our choice (none published): process noise on each state derivative
#: (held over each communication step; Example 6.2: Bw = I) and measurement noise.
PROCESS_NOISE_STD = (0.01, 0.01, 0.01, 0.01)
NOISE_STD = (1e-3, 1e-3, 1e-3, 1e-3)
LOE_FAULTS = ("loe_u1", "loe_u2")
SENSOR_FAULTS = tuple(f"sensor_{y}" for y in Y)
ACTUATOR_FAULTS = tuple(f"actuator_{u}" for u in U)
