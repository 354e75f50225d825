"""The five plant campaigns: scenario, methods, faults (see tests/test_cosim_campaign.py).

Common choices: each scenario starts at the operating point and varies its inputs as documented
below before the fault onset t_on (so the fault-free part holds the transients), and a fault run
lasts t_on + horizon (its derived delay, or its published target, plus margin). The evaluation
is an rms over N samples: 20 s on the DTS200 (the demo's), 0.1 s on the DR300, VTOL and lateral
aircraft, 0.05 s = half the benchmark's shortest sensor target on the wind turbine.
"""
from __future__ import annotations

import numpy as np

from campaign import Campaign, FaultCase, Subsystem
from fmu_fdi import (LTI, FDIModel, ResidualBank, ResidualGenerator, component_fault, dedicated_bank, factorized,
                     fault_detection_filter, generalized_bank, kalman, luenberger, nullspace_design, parity_space,
                     rls_estimator, structured_bank, unknown_input_observer)
from fmu_fdi.design.toolkit._basis import plant_pole_pool, spread_poles
from plant_fmus.dts200 import dts200_physics as dts
from plant_fmus.wind_turbine import windturbine_physics as wind

# Null-space designs and banks choose their combination for the largest fault-to-noise gap
# ('ignore' took the least-order rows as they came: the drive train's first DOS residual then
# had a noise gain 1e14 times its fault gain).
NOISE = "optimize"


def _step(t, t0, before, after):
    return np.where(t >= t0, after, before)


def at_plant_poles(design, real=lambda g: 0):
    """An observer design with its poles at the plant's own (stabilised) eigenvalues, spread from
    slow to fast — the library's default for the null-space filters (``pole_chooser``). The
    observers' own default is deadbeat-like, and a faster observer turns a step fault into a
    spike that dies away (DTS200: the default Luenberger residual keeps 1.6 % of a level-sensor
    bias). ``real(default design)`` leading poles must be real (the Beard–Jones detection
    spaces of order 1): a complex pole there, and a pair split by that boundary, become real
    poles of the same modulus."""
    def run(m):
        g0 = design(m, None)
        poles = list(spread_poles(plant_pole_pool(m.A, m.dt), len(g0.info["poles"])))
        k, i = real(g0), 0
        while i < k:  # conjugate pairs are adjacent in spread_poles' output
            i += 1 if poles[i].imag == 0 else 2
        return design(m, [complex(abs(z)) for z in poles[:i]] + poles[i:])
    return run


def normalised(design):
    """The design made on a normalised copy of the model and mapped back to the measured
    outputs: outputs in units of their noise std (y/σ: each sensor weighs by its own noise, so
    the rms of a residual vector is not ruled by the sensor with the largest unit — the wind
    turbine's torque, 90 Nm of noise, next to speeds in rad/s), and the state balanced by a
    diagonal similarity (SLICOT TB01ID; the drive train's states span 1e-3 rad to 3e4 Nm, and
    its plant-pole Luenberger observer placed in those coordinates passed the noise with a gain
    1e4 times that of the balanced design). Neither changes what a filter can do; the filter
    reads [y; u], so only the output scaling is undone:
    Q(λ) = Q_σ(λ) diag(1/σ, I)."""
    def run(m):
        sigma = np.array([np.linalg.norm(row) for row in m.Dw])
        S = np.diag(1.0 / sigma)
        G = m.augmented()
        _, scale = LTI(m.A, G.B[:m.n], S @ m.C, np.zeros((m.ny, G.m)), m.dt).balanced()
        T, Ti = np.diag(scale), np.diag(1.0 / scale)
        faults = [f if f.kind in ("sensor", "actuator") else
                  component_fault(f.name, Ti @ m.Bf[:, f.columns], S @ m.Df[:, f.columns], f.description)
                  for f in m.faults]
        ms = m._replace(A=Ti @ m.A @ T, Bu=Ti @ m.Bu, Bd=Ti @ m.Bd, Bw=Ti @ m.Bw, C=S @ m.C @ T, Du=S @ m.Du,
                        Dd=S @ m.Dd, Dw=S @ m.Dw, faults=faults, operating_point={"u": m.u0, "y": S @ m.y0})
        g = design(ms)
        M = np.diag(np.r_[1.0 / sigma, np.ones(m.nu)])
        if isinstance(g, ResidualBank):
            members = [ResidualGenerator(k.Q @ M, m, k.method, k.residual_names, k.groups, k.info) for k in g.members]
            return ResidualBank(members, g.method, g.info)
        return ResidualGenerator(g.Q @ M, m, g.method, g.residual_names, g.groups, g.info)
    return run


def methods(window, banks=(), fdf=None, uio=False):
    """The designs a model gets (window: the rms evaluation's N). Parity: order N − 1 (the parity
    window is the evaluation window: a low-order relation on a finely sampled plant is a
    differencing filter that sees a constant fault only as (I − A^s) f), the ny relations of best
    fault sensitivity; observers: poles at the plant's (:func:`at_plant_poles`); Kalman: the
    model's noise w (unit variance, Dw = diag(std)), no extra measurement noise (Rv = 0);
    factorised: the normalised coprime factorisation (pole placement with the identity
    post-filter would repeat the Luenberger row); null-space designs and banks: see NOISE."""
    out = {
        "parity": lambda m: parity_space(m, window - 1, rdim=m.ny),
        "luenberger": at_plant_poles(luenberger),
        "kalman": lambda m: kalman(m, Qw=1.0, Rv=0.0),
        "factorized": lambda m: factorized(m, normalized=True),
        "nullspace": lambda m: nullspace_design(m, noise=NOISE),
    }
    if uio:
        out["uio"] = at_plant_poles(unknown_input_observer)
    if fdf:
        out["fdf"] = at_plant_poles(lambda m, poles: fault_detection_filter(m, poles, faults=list(fdf)),
                                    real=lambda g: sum(g.info["detection_orders"].values()))
    for kind in banks:
        out[f"dos_{kind}"] = lambda m, k=kind: dedicated_bank(m, k, noise=NOISE)
        out[f"gos_{kind}"] = lambda m, k=kind: generalized_bank(m, k, noise=NOISE)
    return {name: normalised(d) for name, d in out.items()}


def subsystem(name, index, designs):
    """Banks keep one evaluation group per member (the isolation reads them); RLS one per output."""
    return Subsystem(name, index, designs, tuple(k for k in designs if k.startswith(("dos", "gos", "structured"))),
                     tuple(k for k in designs if k == "rls"))


def pitch_rls(m):
    """RLS on blades 2 and 3 (faults 6 and 7 change their coefficients): the blocks of the pitch
    model from beta_ref_2, beta_ref_3 to beta_2_m1, beta_3_m1, each output's MISO equation of
    order 2 (the other blade's b coefficients are 0), the 0.2° sensor noise as its floor."""
    i = [2, 3, 4, 5]
    sub = FDIModel.from_matrices(m.A[np.ix_(i, i)], m.Bu[np.ix_(i, [1, 2])], m.C[np.ix_([2, 4], i)], dt=m.dt,
                                 u_names=["beta_ref_2", "beta_ref_3"], y_names=["beta_2_m1", "beta_3_m1"],
                                 units={n: "deg" for n in ("beta_ref_2", "beta_ref_3", "beta_2_m1", "beta_3_m1")},
                                 name="pitch_blades_2_3")
    return rls_estimator(sub, noise_std=0.2)


def structured(faults):
    """A structured bank with S = I over the given faults (each residual sees one of them)."""
    return normalised(lambda m: structured_bank(m, np.eye(len(faults), dtype=int), faults=list(faults),
                                                    noise=NOISE))


def fault(key, sub, var, value, model_fault, size, horizon, target=None, kind="abrupt"):
    return FaultCase(key, sub, ((kind, var, value),), (model_fault,), size, horizon, target)


# ------------------------------------------------------------------------- DTS200
DTS_H, DTS_Q = dts.operating_point()
DTS_LEAKS = ("leak_T1", "leak_T2", "leak_T3")


def dts_inputs(t):
    """The demo's pump schedule, earlier: Q1 +10 % from 100 s, Q2 −10 % from 200 s."""
    return {"Q1": _step(t, 100.0, DTS_Q[0], 1.1 * DTS_Q[0]), "Q2": _step(t, 200.0, DTS_Q[1], 0.9 * DTS_Q[1])}


DTS200 = Campaign(
    plant="dts200", t_on=300.0, inputs=dts_inputs, evaluation={"kind": "rms", "window": 20}, seed=500,
    subsystems=[subsystem("tanks", 0, {**methods(20, ("sensor", "actuator"), fdf=DTS_LEAKS),
                                       "structured_leaks": structured(DTS_LEAKS)})],
    faults=[
        *[fault(f"sensor_h{i}", "tanks", f"f_sensor_h{i}", 1.0, f"sensor_h{i}",
                "+1 cm level-sensor bias (10 σ of the 0.1 cm noise; 2.5 % of the 41 cm level)", 300.0)
          for i in (1, 2, 3)],
        fault("pump_Q1", "tanks", "f_pump_Q1", -2.0, "pump_Q1",
              "pump 1 delivers 2 cm³/s less (≈ 10 % of its 21.4 cm³/s operating flow)", 300.0),
        fault("pump_Q2", "tanks", "f_pump_Q2", -5.0, "pump_Q2",
              "pump 2 delivers 5 cm³/s less (≈ 10 % of its 53.8 cm³/s operating flow)", 300.0),
        *[fault(f"leak_T{i}", "tanks", f"f_leak_T{i}", 0.05, f"leak_T{i}",
                "leak of 0.05 cm² (a tenth of the 0.5 cm² outlet pipe)", 300.0) for i in (1, 2, 3)],
        *[fault(f"clog_{p}", "tanks", f"f_clog_{p}", 0.2, f"clog_{p}", "pipe clogged: 20 % of its flow lost", 300.0)
          for p in ("13", "32", "20")],
    ],
)


# -------------------------------------------------------------------------- DR300
def dr_inputs(t):
    """Speed reference step 0 → 1 at 0.2 s; load torque at its operating value 0 (with one
    sensor no residual can be decoupled from it: see the UIO and null-space rows)."""
    return {"speed_ref": _step(t, 0.2, 0.0, 1.0), "load_torque": np.zeros_like(t)}


DR300 = Campaign(
    plant="dr300", t_on=1.0, inputs=dr_inputs, evaluation={"kind": "rms", "window": 10}, seed=600,
    subsystems=[subsystem("motor", 0, {k: v for k, v in methods(10).items() if k in ("parity", "luenberger")})],
    faults=[
        fault("sensor_speed", "motor", "f_sensor_speed", 0.1, "sensor_speed",
              "speed-sensor bias 0.1 (10 σ of the 0.01 noise; a tenth of the reference step)", 2.0),
        fault("actuator_voltage", "motor", "f_actuator_voltage", 0.1, "actuator_voltage",
              "voltage bias 0.1 V (the reference step needs 1/8.75 = 0.114 V at steady state)", 2.0),
    ],
)


# --------------------------------------------------------------------------- VTOL
def vtol_inputs(t):
    """Reference steps of the plant tests: collective +0.1 at 0.5 s, cyclic −0.1 at 1 s."""
    return {"ref_collective": _step(t, 0.5, 0.0, 0.1), "ref_cyclic": _step(t, 1.0, 0.0, -0.1)}


VTOL_SENSORS = ("vh", "vv", "q", "y4")
VTOL = Campaign(
    plant="vtol", t_on=2.0, inputs=vtol_inputs, evaluation={"kind": "rms", "window": 10}, seed=700,
    subsystems=[subsystem("aircraft", 0, methods(10, ("sensor", "actuator"),
                                                 fdf=("actuator_collective", "actuator_cyclic")))],
    faults=[
        *[fault(f"sensor_{y}", "aircraft", f"f_sensor_{y}", 0.1, f"sensor_{y}",
                "sensor bias 0.1 (10 σ of the 0.01 noise)", 2.0) for y in VTOL_SENSORS],
        *[fault(f"actuator_{u}", "aircraft", f"f_actuator_{u}", 0.1, f"actuator_{u}",
                "actuator bias 0.1 (the size of the reference steps)", 2.0) for u in ("collective", "cyclic")],
    ],
)


# ------------------------------------------------------------------- wind turbine
WIND_X0, WIND_TAU_R0 = wind.operating_point()
WIND_TS = wind.STEP
WIND_BETA = (10.0, 10.0, 5.0)


def wind_inputs(t):
    """Pitch references 10°, 10°, 5° (above rated wind; our choice: the stuck values 5° and 10° of
    faults 1 and 3 then differ from the true angle, and the gain 1.2 of fault 2 shows) with pitch
    activity: 2° at 0.5 Hz plus 1° at 1.5 Hz (phases 0, 120°, 240°; two frequencies excite the four
    coefficients of a second-order blade, which RLS needs); converter reference +1 kNm at 0.5 s;
    rotor torque +2 % at 1 s (a gust: the unknown input)."""
    out = {f"beta_ref_{i + 1}": b + 2.0 * np.sin(np.pi * t + 2 * np.pi * i / 3)
           + np.sin(3 * np.pi * t + 2 * np.pi * i / 3) for i, b in enumerate(WIND_BETA)}
    out["tau_g_ref"] = _step(t, 0.5, WIND_X0[3], WIND_X0[3] + 1000.0)
    out["tau_r"] = _step(t, 1.0, WIND_TAU_R0, 1.02 * WIND_TAU_R0)
    return out


def _stuck(key, sensor, value, number):
    return FaultCase(key, "pitch" if sensor.startswith("beta") else "drive",
                     (("abrupt", f"stuck_{sensor}", 1.0), ("abrupt", f"stuck_value_{sensor}", value)),
                     (f"sensor_{sensor}",), f"benchmark fault {number}: {sensor} stuck at {value}", 1.0, 10 * WIND_TS)


WIND = Campaign(
    plant="wind_turbine", t_on=2.0, inputs=wind_inputs, evaluation={"kind": "rms", "window": 5}, seed=800,
    subsystems=[
        subsystem("pitch", 0, {**methods(5, ("sensor",), fdf=("pitch_2_pressure_drop", "pitch_3_air_in_oil")),
                               "rls": pitch_rls}),
        subsystem("drive", 1, methods(5, ("sensor",), fdf=("drive_train_efficiency",), uio=True)),
    ],
    faults=[
        _stuck("f1_beta_1_m1", "beta_1_m1", 5.0, 1),
        FaultCase("f2_beta_2_m2", "pitch", (("abrupt", "gain_beta_2_m2", 0.2),), ("sensor_beta_2_m2",),
                  "benchmark fault 2: beta_2_m2 gain 1.2", 1.0, 10 * WIND_TS),
        _stuck("f3_beta_3_m1", "beta_3_m1", 10.0, 3),
        _stuck("f4_omega_r_m1", "omega_r_m1", 1.4, 4),
        FaultCase("f5_omega_m2", "drive", (("abrupt", "gain_omega_r_m2", 0.1), ("abrupt", "gain_omega_g_m2", -0.1)),
                  ("sensor_omega_r_m2", "sensor_omega_g_m2"), "benchmark fault 5: omega_r_m2 gain 1.1, "
                  "omega_g_m2 gain 0.9", 1.0, 10 * WIND_TS),
        fault("f6_pressure_drop", "pitch", "f_pitch_2_pressure_drop", 1.0, "pitch_2_pressure_drop",
              "benchmark fault 6: pitch 2 hydraulic pressure drop (theta = 1)", 1.0, 8 * WIND_TS),
        FaultCase("f7_air_in_oil", "pitch", (("incipient", "f_pitch_3_air_in_oil", 1.0, 30.0),),
                  ("pitch_3_air_in_oil",), "benchmark fault 7: pitch 3 air in oil, 30 s ramp in", 8.0,
                  600 * WIND_TS),
        fault("f8_converter", "drive", "f_converter_offset", 100.0, "converter_offset",
              "benchmark fault 8: converter torque offset 100 Nm", 1.0, 5 * WIND_TS),
        fault("f9_efficiency", "drive", "f_drive_train_efficiency", -0.05, "drive_train_efficiency",
              "benchmark fault 9: eta_dt 0.97 -> 0.92", 3.0),
    ],
)


# --------------------------------------------------------------- lateral aircraft
LOE = ("loe_u1", "loe_u2")


def lateral_inputs(t):
    """Surface deflections 0.2 rad from 0.5 s (u1) and −0.2 rad from 1 s (u2), then held: a loss
    of effectiveness shows only while its input is nonzero, in proportion to it."""
    return {"u1": _step(t, 0.5, 0.0, 0.2), "u2": _step(t, 1.0, 0.0, -0.2)}


LATERAL = Campaign(
    plant="lateral_aircraft", t_on=3.0, inputs=lateral_inputs, evaluation={"kind": "rms", "window": 10}, seed=900,
    subsystems=[subsystem("aircraft", 0, {**methods(10, fdf=LOE), "structured_loe": structured(LOE)})],
    faults=[fault(f, "aircraft", f"f_{f}", 1.0, f, f"total loss of effectiveness of u{j + 1} (Varga's gamma = 1)",
                  3.0) for j, f in enumerate(LOE)],
)

CAMPAIGNS = {c.plant: c for c in (DTS200, DR300, VTOL, WIND, LATERAL)}
