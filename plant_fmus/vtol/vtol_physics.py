"""VTOL aircraft (Narendra & Tripathi 1973; COMPleib HE1) with a stabilising state
feedback (numpy only; bundled into the FMU).

States x = (horizontal velocity, vertical velocity, pitch rate, pitch angle); inputs
u = (collective pitch, longitudinal cyclic pitch); four sensors y = C x with
C = [[1,0,0,0], [0,1,0,0], [0,0,1,0], [0,1,1,1]]. The airspeed-dependent entries a32, a34
and b21 are uncertain: ``a32 (1 + delta_a32)`` etc., delta = 0 nominal, |delta| <= 0.1 the
documented default bound (**unverified**).

The open loop is unstable (eigenvalues 0.276 +- 0.258j, -0.233, -2.073). The FMU closes
the loop with the LQR state feedback u = -K x_hat + r, x_hat = C^-1 y_meas (C is
invertible), K minimising the integral of x'Qx + u'Ru with Q = I4, R = I2 for the nominal
plant. K was computed offline with scipy.linalg.solve_continuous_are (K = R^-1 B' P);
tests/test_plant_fmus.py recomputes it. Closed-loop poles -10.99, -0.717, -1.487 +- 0.338j;
sampled at h = 0.01 s the spectral radius of the sampled loop is 0.993 (stable for h up to
well beyond 0.1 s).
"""
import numpy as np

PREFIX = "vtol"
STEP = 0.01

A = np.array([[-0.0366, 0.0271, 0.0188, -0.4555],
              [0.0482, -1.01, 0.0024, -4.0208],
              [0.1002, 0.3681, -0.707, 1.42],
              [0.0, 0.0, 1.0, 0.0]])
B = np.array([[0.4422, 0.1761],
              [3.5446, -7.5922],
              [-5.52, 4.49],
              [0.0, 0.0]])
C = np.array([[1.0, 0.0, 0.0, 0.0],
              [0.0, 1.0, 0.0, 0.0],
              [0.0, 0.0, 1.0, 0.0],
              [0.0, 1.0, 1.0, 1.0]])
LQR_Q = np.eye(4)
LQR_R = np.eye(2)
#: LQR gain for (A, B, LQR_Q, LQR_R), computed offline (see the module docstring).
K = np.array([[0.9265980583247787, -0.01473996456202535, -0.9621624121321044, -1.386819391773749],
              [-0.02247765195723075, -0.8447507664432508, 0.18854771177973043, 0.7135346608114382]])
UNCERTAIN = ("delta_a32", "delta_a34", "delta_b21")
UNCERTAINTY_BOUND = 0.1  # documented default bound on |delta| (unverified)

U = ("collective", "cyclic")
Y = ("vh", "vv", "q", "y4")
SENSOR_TEXT = ("horizontal velocity", "vertical velocity", "pitch rate",
               "vertical velocity + pitch rate + pitch angle")
#: Sensor noise std: none published; our choice.
NOISE_STD = (0.01, 0.01, 0.01, 0.01)
SENSOR_FAULTS = tuple(f"sensor_{y}" for y in Y)
ACTUATOR_FAULTS = tuple(f"actuator_{u}" for u in U)


def plant_matrices(delta_a32=0.0, delta_a34=0.0, delta_b21=0.0):
    """``(A, B)`` with the uncertain entries scaled by ``1 + delta``."""
    a, b = A.copy(), B.copy()
    a[2, 1] *= 1.0 + delta_a32
    a[2, 3] *= 1.0 + delta_a34
    b[1, 0] *= 1.0 + delta_b21
    return a, b
