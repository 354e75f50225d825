"""The published example plants of ../shared/reference/acceptance.md, built from their
transfer functions. Numbers are re-entered from Varga (2017) and Chen & Patton (1999)."""
import control as ct
import numpy as np

from fmu_fdi import FDIModel, actuator_fault, sensor_fault

s = ct.tf("s")


def tfm(rows, inputs, outputs=None):
    """Transfer matrix from nested lists of SISO transfer functions (0 allowed)."""
    rows = [[x if isinstance(x, ct.TransferFunction) else ct.tf([float(x)], [1.0], 0) for x in row] for row in rows]
    G = ct.combine_tf(rows)
    outputs = outputs or [f"y{i + 1}" for i in range(len(rows))]
    return ct.tf(G.num, G.den, inputs=inputs, outputs=outputs)


GU = [(s + 1) / (s + 2), (s + 2) / (s + 3)]


def a1_system():
    """A1: Gf = [Gu I2] as a fault-to-output system (3 fault columns)."""
    return tfm([[GU[0], 1, 0], [GU[1], 0, 1]], ["fa", "fs1", "fs2"])


def a2_system():
    """A2: Gf = [s/(s+1) 0; (s²+4)/(s+3)² 1]."""
    return tfm([[s / (s + 1), 0], [(s**2 + 4) / (s + 3) ** 2, 1]], ["f1", "f2"])


def ex5_2():
    G = tfm([[GU[0], 1 / (s + 2), (s + 1) / (s + 2), 0], [GU[1], 0, 0, 1]], ["u", "d", "f1", "f2"])
    return FDIModel.from_control(G, u=["u"], d=["d"], f=["f1", "f2"], name="ex5_2")


def ex5_3():
    G = tfm([[GU[0], (s - 1) / (s + 2)], [GU[1], 0]], ["u", "d"])
    return FDIModel.from_control(G, u=["u"], d=["d"], faults=[actuator_fault("fa", "u"), sensor_fault("fs2", "y2")],
                                 name="ex5_3")


def ex5_4():
    G = tfm([[(s + 1) / (s - 2), (s - 1) / (s + 2)], [(s + 2) / (s - 3), 0]], ["u", "d"])
    return FDIModel.from_control(G, u=["u"], d=["d"], faults=[actuator_fault("fa", "u"), sensor_fault("fs2", "y2")],
                                 name="ex5_4")


def a4_model():
    """A4 (and A5b): Ex 5.3 plant, Gw = [(s-1)/(s+2); 0], Gf = [Gu I2]."""
    G = tfm([[GU[0], (s - 1) / (s + 2)], [GU[1], 0]], ["u", "w"])
    return FDIModel.from_control(G, u=["u"], w=["w"], name="a4", faults=[
        actuator_fault("fa", "u"), sensor_fault("fs1", "y1"), sensor_fault("fs2", "y2")])


def a5a_model():
    """A5(a): Gu of Ex 5.2, Gw = [1/(s+2); 0], Gf = [(s+1)/(s+2) 0; 0 1]."""
    G = tfm([[GU[0], 1 / (s + 2), (s + 1) / (s + 2), 0], [GU[1], 0, 0, 1]], ["u", "w", "f1", "f2"])
    return FDIModel.from_control(G, u=["u"], w=["w"], f=["f1", "f2"], name="a5a")


def a6_model():
    """A6 (Chen & Patton UIO example): B = E = [-1; 0; 0]."""
    A = np.array([[-1.0, 1, 0], [-1, 0, 0], [0, -1, -1]])
    B = np.array([[-1.0], [0], [0]])
    C = np.array([[1.0, 0, 0], [0, 0, 1]])
    return FDIModel.from_matrices(A, B, C, Bd=B, u_names=["u"], y_names=["y1", "y2"], d_names=["d"],
                                  faults=[sensor_fault("s1", "y1"), sensor_fault("s2", "y2")], name="a6")


def three_tank_like(dt=0.0, leak=True) -> FDIModel:
    """A linearised three-tank (coupled first-order tanks), 3 sensors, 2 pumps, 1 leak d."""
    a = 0.0158
    A = np.array([[-a, 0, a], [0, -0.0227, 0.0151], [a, 0.0151, -0.0309]])
    B = np.array([[1, 0], [0, 1], [0, 0]]) / 154
    model = FDIModel.from_matrices(A, B, np.eye(3), Bd=[[0], [0], [-0.01]] if leak else None,
                                   u_names=["Q1", "Q2"], y_names=["h1", "h2", "h3"],
                                   d_names=["leak3"] if leak else [], faults=[
                                       sensor_fault("s1", "h1"), sensor_fault("s2", "h2"), sensor_fault("s3", "h3"),
                                       actuator_fault("p1", "Q1"), actuator_fault("p2", "Q2")], name="tanks")
    return model.discretize(dt) if dt else model
