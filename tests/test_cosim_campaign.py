"""Automated co-simulation test campaign (issue 5 §5): the five plant FMUs with every method that
applies, as diagnostic FMUs, co-simulated in Jacobi order (fmu_fdi.cosim) with noise on and
fixed seeds. The machinery and the derivations are in tests/campaign.py (threshold rule, the
α/β budget, the derived delays and isolation claims), the scenarios and fault sizes in
tests/campaign_plants.py; this module holds what is asserted and why.

Thresholds (tests/campaign.py): per residual group ``J_th = (1 + 1e-6) J_α + max J_mis``, J_α the
exact analytic rms threshold of the model's noise (Dw = diag(std): the FMU's levels) at the
per-sample false-alarm probability ``α = 5e-4 / (S · G)`` (S: every sample of every noisy run of
the subsystem, G: all its diagnosers' residual groups, Bonferroni; α in the results' headers), J_mis
the same evaluation of the scenario co-simulated noise-free (the DTS200's linearisation error,
the wind drive train's tau_r gust for the designs that do not decouple it, rounding elsewhere).
The noise adds to the residual and the rms is subadditive, so a fault-free run stays below J_th
at every sample and group with probability ≥ 1 − 5e-4 ≥ 99.9 %. RLS (no analytic law): the
upper 99 % confidence bound of the (1 − α) quantile from 10 fault-free runs with other seeds.

Targets: plants.md's for the wind turbine (10 Ts for faults 1–5, 8 Ts for 6, 600 Ts for 7, 5 Ts
for 8; unverified there, kept as documented); elsewhere derived from the design: the first
sample at which the noise-free evaluation of the fault run exceeds ``J_th + J_β`` (an alarm with
probability ≥ 1 − β, β = 5e-4 / (2 · methods · faults)), which the measured delay must not
exceed. Fault sizes (tests/campaign_plants.py, each with its reason): DTS200 in physical units
(1 cm level bias = 10 σ, pump −10 % of its flow, leak 0.05 cm² = a tenth of the outlet pipe,
20 % clogging); DR300 and VTOL sensor biases of 10 σ and actuator biases of the size of the
reference steps; the benchmark's own faults on the wind turbine; Varga's total loss of
effectiveness on the lateral aircraft.

Claims, per plant and method (probability that any of a subsystem's claims fails ≤ 1e-3):

- the noisy fault-free run, and every fault run before its onset, raises no alarm;
- every fault is detected no later than its derived delay; the pairs whose derivation finds no
  sure detection, or a delay beyond the published target, are exactly those listed in UNMET
  (with the evidence: their reach, in the results below);
- a bank (DOS, GOS, structured) isolates each fault of its kind: from the derived settling time
  on, or at least at the run's end, and never names another fault where the derivation
  excludes it; the pairs with neither claim are exactly those in UNISOLATED.

Applicability (hosted unless a reason is given; ``DesignError`` reasons are asserted below)

================  ==================================================================================
method            not applied, and why
================  ==================================================================================
parity            everywhere hosted (order N − 1, the evaluation window)
luenberger        everywhere hosted (poles at the plant's own)
kalman            DR300: DesignError, no stabilising Riccati solution — the load-torque integrator
                  (z = 1) is a mode the model's noise (sensor noise only) does not reach
uio               DTS200, VTOL, wind pitch, lateral aircraft: no unknown inputs (E = 0 gives H = 0:
                  the UIO is the Luenberger observer, asserted); DR300: DesignError, rank(E) = 1 = p,
                  no residual remains (the one sensor sees the load torque). Hosted: wind drive train
                  (E = tau_r, rank(C E) = rank(E) = 1)
fdf               needs state-entering faults (a Df column is a DesignError, asserted for the sensor
                  and converter faults): DTS200 leaks (3 of 8 state faults, p = 3), VTOL actuators,
                  wind pitch faults 6/7, wind drive train fault 9, lateral LOE; DR300: DesignError, the
                  load integrator is unobservable from the output the fault direction leaves
factorized        normalised coprime factors; DR300: DesignError, no stabilising Riccati solution (the
                  load integrator is unreachable from u; with pole placement it is the Luenberger row)
nullspace         DR300: DesignError, rank Gd = 1 = p (no residual decoupled from the load torque)
dos, gos          need ≥ 2 faults of a kind (DesignError): DR300 (one sensor, one actuator fault),
                  lateral (parametric faults only: a structured bank over the two LOE faults
                  instead); wind: sensor banks only (no actuator faults in the model files)
rls               suits SISO/MISO equations with coefficient (parametric) faults and persistent
                  excitation: hosted on wind pitch blades 2/3 (faults 6/7; two-tone references).
                  DTS200, DR300, VTOL: additive faults only (a bias moves no coefficient), DTS200
                  nonlinear too; wind drive train: tau_r sits in every equation error; lateral: the
                  LOE faults fit, but the held input steps do not excite (decorrelation length ≈ 200
                  samples: 30 effective samples in 10 calibration runs, too few for a tail fit)
================  ==================================================================================

Results of the seeds in tests/campaign_plants.py with the native plants (tests/campaign.py; the
VTOL's from the pythonfmu plant, before issue 17's judge refused its banks): ``measured/derived``
detection delay in plant steps after the onset (``-`` none; both include the plant's output latch and the Jacobi step, so
2 is the least), ``*`` a bank's isolation claim (settled or at the run's end), and for
every pair without a derived delay its reach max J_nf / (J_th + J_β): the smallest additive fault
detected surely is its size / reach. No diagnoser raised an alarm in any fault-free part.

dts200/tanks (Ts = 1 s, α = 4e-09): 1 sensor_h1, 2 sensor_h2, 3 sensor_h3, 4 pump_Q1, 5 pump_Q2, 6
    leak_T1, 7 leak_T2, 8 leak_T3, 9 clog_13, 10 clog_32, 11 clog_20
                       1       2       3       4       5       6       7       8       9      10      11
parity               5/9     6/9     6/9     -/-   20/33   11/15   11/16   10/16   16/23   15/22   10/15
luenberger          5/67    7/17    6/12     -/-   25/44   14/23   15/21   14/20   25/33   21/29   13/20
kalman               4/9    4/10     4/9   47/84   20/33   10/16   11/17   11/18   19/28   17/28   10/16
factorized          2/10    3/10     3/7     -/-    20/-    9/18   10/19    9/16   16/29   15/28   10/17
nullspace           5/13    7/18    6/13  68/100   27/55   14/19   14/21   15/22   51/80   15/24   15/22
fdf                 6/12    7/16    7/18   58/87   27/42   14/19   16/21   16/23   24/30   23/33   14/19
dos_sensor          3/6*    3/5*    3/5*   41/67   14/24    9/14    8/13    8/14   19/27   16/25    8/12
gos_sensor          4/9*   4/10*    3/8*   49/74   20/33   12/17   11/17   11/18   20/31   14/20   10/17
dos_actuator         3/6     3/6    13/-  42/72*   16/25   10/14    9/14   16/23   25/39   26/40    9/13
gos_actuator         3/6     3/6    13/-  42/72*   16/25   10/14    9/14   16/23   25/39   26/40    9/13
structured_leaks     2/5     3/5     2/5   34/76   15/25    8/13    9/13    7/13   16/24   15/24    8/13
reach: parity 4: 0.39, luenberger 4: 0.34, factorized 4: 0.36, factorized 5: 0.95, dos_actuator 3:
    0.82, gos_actuator 3: 0.82

dr300/motor (Ts = 0.01 s, α = 3e-07): 1 sensor_speed, 2 actuator_voltage
                       1       2
parity               -/-     -/-
luenberger           2/3    9/15
reach: parity 1: 0.23, parity 2: 0.00

vtol/aircraft (Ts = 0.01 s, α = 1e-08): 1 sensor_vh, 2 sensor_vv, 3 sensor_q, 4 sensor_y4, 5
    actuator_collective, 6 actuator_cyclic
                       1       2       3       4       5       6
parity               4/7     3/8     4/7     4/7    12/-    10/-
luenberger           5/-    4/59    5/12    5/14   13/23   13/18
kalman               2/6     2/6     2/6     2/6   10/15    7/13
factorized           2/4    2/10    3/10    3/10     -/-     -/-
nullspace           3/11     2/5    4/11  17/172   45/63   11/27
fdf                 8/17     9/-   10/49    8/34   19/30   16/24
dos_sensor           2/4     2/4     2/4     2/4   10/15    7/12
gos_sensor           3/9     2/4    2/5*    4/11    9/13    7/11
dos_actuator         2/4    13/-     -/-    11/-  20/41*  17/26*
gos_actuator         2/4    13/-     -/-    11/-  20/41*  17/26*
reach: parity 5: 0.74, parity 6: 0.99, luenberger 1: 0.89, factorized 5: 0.02, factorized 6: 0.02, fdf 2: 0.95, dos_actuator 2: 0.44,
    dos_actuator 3: 0.16, dos_actuator 4: 0.66, gos_actuator 2: 0.44, gos_actuator 3: 0.16, gos_actuator
    4: 0.66

wind_turbine/pitch (Ts = 0.01 s, α = 1e-08): 1 f1_beta_1_m1 (target 10), 2 f2_beta_2_m2 (target 10),
    3 f3_beta_3_m1 (target 10), 4 f6_pressure_drop (target 8), 5 f7_air_in_oil (target 600)
                       1       2       3       4       5
parity               3/5     4/6     2/3     -/-     -/-
luenberger           2/3     2/4     2/2   19/27     -/-
kalman               2/3     2/4     2/2   19/27     -/-
factorized           2/3     2/4     2/2     -/-     -/-
nullspace            2/4     3/6     2/2   19/27     -/-
fdf                 29/-     -/-     -/-     -/-     -/-
dos_sensor          2/2*    2/2*    2/2*   19/26     -/-
gos_sensor          2/3*     2/3    2/2*   21/36     -/-
rls                  -/-     -/-     -/-     -/-     -/-
reach: parity 4: 0.03, parity 5: 0.00, luenberger 5: 0.21, kalman 5: 0.21, factorized 4: 0.20,
    factorized 5: 0.03, nullspace 5: 0.18, fdf 1: 0.52, fdf 2: 0.17, fdf 3: 0.42, fdf 4: 0.01, fdf
    5: 0.00, dos_sensor 5: 0.22, gos_sensor 5: 0.15, rls 1: 0.00, rls 2: 0.00, rls 3: 0.01, rls 4:
    0.00, rls 5: 0.00
wind_turbine/drive (Ts = 0.01 s, α = 2e-08): 1 f4_omega_r_m1 (target 10), 2 f5_omega_m2 (target 10),
    3 f8_converter (target 5), 4 f9_efficiency
                       1       2       3       4
parity               5/6     2/2     -/-     -/-
luenberger           -/-     -/-     -/-     -/-
kalman               -/-     2/2     -/-     -/-
factorized           -/-     2/2     -/-     -/-
nullspace            -/-     -/-     -/-     -/-
uio                  -/-     -/-     -/-     -/-
fdf                  -/-     -/-     -/-     -/-
dos_sensor          4/5*     2/2     -/-     -/-
gos_sensor          3/5*     2/2     -/-     -/-
reach: parity 3: 0.15, parity 4: 0.02, luenberger 1: 0.14, luenberger 2: 0.15, luenberger 3: 0.01,
    luenberger 4: 0.00, kalman 1: 0.28, kalman 3: 0.17, kalman 4: 0.40, factorized 1: 0.28,
    factorized 3: 0.17, factorized 4: 0.40, nullspace 1: 0.03, nullspace 2: 0.21, nullspace 3: 0.20,
    nullspace 4: 0.00, uio 1: 0.14, uio 2: 0.18, uio 3: 0.09, uio 4: 0.00, fdf 1: 0.18, fdf 2: 0.13,
    fdf 3: 0.00, fdf 4: 0.01, dos_sensor 3: 0.00, dos_sensor 4: 0.02, gos_sensor 3: 0.00, gos_sensor
    4: 0.02

lateral_aircraft/aircraft (Ts = 0.01 s, α = 3e-08): 1 loe_u1, 2 loe_u2
                       1       2
parity              7/10   206/-
luenberger          29/-     -/-
kalman              5/10     -/-
factorized           -/-     -/-
nullspace            4/9     -/-
fdf                  -/-     -/-
structured_loe     7/10*     -/-
reach: parity 2: 0.34, luenberger 1: 0.81, luenberger 2: 0.21, kalman 2: 0.22, factorized 1: 0.02,
    factorized 2: 0.02, nullspace 2: 0.29, fdf 1: 0.44, fdf 2: 0.05, structured_loe 2: 0.30

Wall time: 77 s for this module on the 2-core development machine (designs, calibration runs and
derivations 44 s, noisy co-simulations 32 s), hence ``slow``; CI runs it.
"""
from __future__ import annotations

import numpy as np
import pytest

import campaign_plants as cp
from campaign import model_of, run_campaign, summary
from fmu_fdi import (DesignError, dedicated_bank, factorized, fault_detection_filter, generalized_bank,
                     kalman, luenberger, nullspace_design, unknown_input_observer)
from fmu_fdi.testing import assert_detected, assert_no_false_alarm

PLANTS = list(cp.CAMPAIGNS)
RUN_PLANTS = PLANTS
METHODS = ("parity", "luenberger", "kalman", "uio", "fdf", "factorized", "nullspace", "dos", "gos", "rls")

# (plant, subsystem, method) not hosted -> reason (the table above)
NOT_APPLICABLE = {
    ("dts200", "tanks", "uio"): "no unknown inputs",
    ("dts200", "tanks", "rls"): "additive faults, nonlinear plant",
    ("dr300", "motor", "kalman"): "DesignError",
    ("dr300", "motor", "uio"): "DesignError",
    ("dr300", "motor", "fdf"): "DesignError",
    ("dr300", "motor", "factorized"): "DesignError",
    ("dr300", "motor", "nullspace"): "DesignError",
    ("dr300", "motor", "dos"): "DesignError",
    ("dr300", "motor", "gos"): "DesignError",
    ("dr300", "motor", "rls"): "additive faults",
    ("vtol", "aircraft", "uio"): "no unknown inputs",
    ("vtol", "aircraft", "rls"): "additive faults",
    ("wind_turbine", "pitch", "uio"): "no unknown inputs",
    ("wind_turbine", "drive", "rls"): "tau_r in the equation error",
    ("lateral_aircraft", "aircraft", "uio"): "no unknown inputs",
    ("lateral_aircraft", "aircraft", "dos"): "DesignError",
    ("lateral_aircraft", "aircraft", "gos"): "DesignError",
    ("lateral_aircraft", "aircraft", "rls"): "inputs not persistently exciting",
}

# plant -> method -> faults whose target the derivation does not meet (no sure detection, or a
# derived delay beyond the published target). The evidence, reach = max J_nf / (J_th + J_β),
# is in the results table; the reasons:
UNMET = {
    "dts200": {
        # the order-19 relations of largest steady-state fault-to-noise ratio (before: of the best fault
        # sensitivity condition, which on a plant sampled 20-400 times faster than its time constants
        # kept relations that see a constant fault as (I − A^s) f: reach 0.08-0.76 for every fault)
        "parity": {"pump_Q1"},                      # reach 0.39, like luenberger's and factorized's
        "luenberger": {"pump_Q1"},                  # reach 0.34: the smallest fault (2 cm³/s into the slow tank 1)
        "factorized": {"pump_Q1", "pump_Q2"},       # reach 0.36, 0.95: its Riccati poles pass steps of u quickly
        "dos_actuator": {"sensor_h3"},              # reach 0.82: a don't-care fault of the actuator bank
        "gos_actuator": {"sensor_h3"},
    },
    "dr300": {"parity": {"sensor_speed", "actuator_voltage"}},  # robust relation (d not decoupled): reach 0.23, 0.00
    "vtol": {
        "parity": {"actuator_collective", "actuator_cyclic"},  # reach 0.74, 0.99 (the sensors: 0.04-0.08 s)
        "luenberger": {"sensor_vh"},                # reach 0.89
        "factorized": {"actuator_collective", "actuator_cyclic"},  # reach 0.02: the factors' fast poles
        "fdf": {"sensor_vv"},                       # reach 0.95 (sensor faults have no direction in the filter)
        "dos_actuator": {"sensor_vv", "sensor_q", "sensor_y4"},    # don't-care faults of the actuator bank
        "gos_actuator": {"sensor_vv", "sensor_q", "sensor_y4"},
    },
    "wind_turbine": {
        # published targets (plants.md, unverified): f6 within 8 Ts is met by nobody — the best derived delay
        # is 0.26 s (DOS), measured 0.16-0.19 s: the pressure drop moves beta_2 by a fraction of a degree per
        # period of the pitch activity, against 0.2° of sensor noise; f7 (6 s): reach ≤ 0.22 at θ = 0.27 after
        # 8 s of the 30 s ramp; f8 (5 Ts): 100 Nm is 1.1 σ of the torque sensor, reach ≤ 0.20; f9: reach
        # ≤ 0.40, its effect (a torque imbalance on the drive train) looks like the tau_r gust
        # parity: the ny relations of largest steady-state fault-to-noise ratio (before: the fault
        # sensitivity condition of the basis as the rank decisions left it, which moved with the
        # scaling rho of the parity data — rho 2 -> 1 took f1, f3 from 0.10, 0.06 s to 0.14 s);
        # now f1, f2, f3 in 0.05, 0.06, 0.03 s and f4 in 0.06 s
        "parity": {"f6_pressure_drop", "f7_air_in_oil", "f8_converter", "f9_efficiency"},
        "luenberger": {"f6_pressure_drop", "f7_air_in_oil", "f4_omega_r_m1", "f5_omega_m2", "f8_converter",
                       "f9_efficiency"},  # drive train: placement at the plant's poles passes the noise x 600
        "kalman": {"f6_pressure_drop", "f7_air_in_oil", "f4_omega_r_m1", "f8_converter", "f9_efficiency"},
        "factorized": {"f6_pressure_drop", "f7_air_in_oil", "f4_omega_r_m1", "f8_converter", "f9_efficiency"},
        "nullspace": {"f6_pressure_drop", "f7_air_in_oil", "f4_omega_r_m1", "f5_omega_m2", "f8_converter",
                      "f9_efficiency"},  # one residual for all faults: reach 0.03 for f4, 0.21 for f5
        "fdf": {"f1_beta_1_m1", "f2_beta_2_m2", "f3_beta_3_m1", "f6_pressure_drop", "f7_air_in_oil",
                "f4_omega_r_m1", "f5_omega_m2", "f8_converter", "f9_efficiency"},  # noise gains 9x (pitch), 5000x
        "uio": {"f4_omega_r_m1", "f5_omega_m2", "f8_converter", "f9_efficiency"},  # plant-pole UIO: noise x 400
        "dos_sensor": {"f6_pressure_drop", "f7_air_in_oil", "f8_converter", "f9_efficiency"},
        "gos_sensor": {"f6_pressure_drop", "f7_air_in_oil", "f8_converter", "f9_efficiency"},
        # per-parameter residuals (θ̂_i − θ0_i)/σ̂_θi: a1 moves from −1.864 to the faulty −1.946 within 1 s,
        # but y[k−1], y[k−2] are collinear at 100 Hz and σ̂_θ of a1 alone is large: reach 0.00 for 6 and 7
        "rls": {"f1_beta_1_m1", "f2_beta_2_m2", "f3_beta_3_m1", "f6_pressure_drop", "f7_air_in_oil"},
    },
    "lateral_aircraft": {
        # the u2 channel (|Bu[:, 2]| = 0.29 against 1.42 for u1) under the process noise: even a total loss at
        # 0.2 rad reaches at most 0.30 (structured bank); u1: see the table
        "parity": {"loe_u2"},                       # reach 0.34; u1 in 0.10 s since the fault-to-noise choice
        "luenberger": {"loe_u1", "loe_u2"},
        "kalman": {"loe_u2"},
        "factorized": {"loe_u1", "loe_u2"},
        "nullspace": {"loe_u2"},
        "fdf": {"loe_u1", "loe_u2"},
        "structured_loe": {"loe_u2"},
    },
}

# plant -> bank -> faults of its kind with neither a settled nor a final isolation claim
UNISOLATED = {
    "dts200": {
        "dos_actuator": {"pump_Q2"}, "gos_actuator": {"pump_Q2"},  # the nonlinear plant leaks into the other
        "structured_leaks": {"leak_T1", "leak_T2", "leak_T3"},     # residuals beyond the fault-free mismatch
    },
    # the sensor residuals overshoot and settle below the detection level (DC gain): detected, then
    # isolated on most samples (measured), not surely on every one
    "vtol": {"dos_sensor": {"sensor_vh", "sensor_vv", "sensor_q", "sensor_y4"},
             "gos_sensor": {"sensor_vh", "sensor_vv", "sensor_y4"}},
    "wind_turbine": {"gos_sensor": {"f2_beta_2_m2"}},  # the gain fault's signal 0.2 beta varies with the pitch
    "lateral_aircraft": {"structured_loe": {"loe_u2"}},  # not detected either (UNMET)
}

_CAMPAIGNS: dict = {}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """``campaign(plant)`` runs a plant's campaign once per session (module-scoped cache); a
    campaign that fails (the xfail VTOL) fails once and raises the same error in every test."""
    def get(plant):
        if plant not in _CAMPAIGNS:
            try:
                _CAMPAIGNS[plant] = run_campaign(cp.CAMPAIGNS[plant], tmp_path_factory.mktemp(plant))
            except Exception as exc:
                _CAMPAIGNS[plant] = exc
                raise
            print(f"\n{summary(cp.CAMPAIGNS[plant], _CAMPAIGNS[plant])}\n{_CAMPAIGNS[plant]['seconds']}")
        if isinstance(_CAMPAIGNS[plant], Exception):
            raise _CAMPAIGNS[plant]
        return _CAMPAIGNS[plant]
    return get


def results(campaign, plant):
    """(fault case, method name, MethodResult) for every fault run of the plant."""
    c = cp.CAMPAIGNS[plant]
    out = campaign(plant)["methods"]
    return [(f, name, r) for f in c.faults for name, r in out[f.subsystem].items()]


# --------------------------------------------------------------------------- the campaign
@pytest.mark.slow
@pytest.mark.parametrize("plant", RUN_PLANTS)
def test_fault_free_runs_raise_no_alarm(campaign, plant):
    for sub in campaign(plant)["methods"].values():
        for name, r in sub.items():
            free = r.measured["fault-free"]
            assert_no_false_alarm(free["record"], diagnoser=free["instance"])
    for f, name, r in results(campaign, plant):
        m = r.measured[f.key]  # up to the onset sample: with Jacobi order its diagnosis reads y before the fault
        assert_no_false_alarm(m["record"], until=cp.CAMPAIGNS[plant].t_on, diagnoser=m["instance"])


@pytest.mark.slow
@pytest.mark.parametrize("plant", RUN_PLANTS)
def test_faults_detected_within_their_targets(campaign, plant):
    unmet = {}
    for f, name, r in results(campaign, plant):
        derived, m = r.derived[f.key]["delay"], r.measured[f.key]
        if np.isfinite(derived):
            # derived: the first sure sample (+ the Jacobi step); 1e-9 s absorbs the time grid's rounding
            assert_detected(m["record"], onset=cp.CAMPAIGNS[plant].t_on, within=derived + 1e-9,
                            diagnoser=m["instance"])
        target = derived if f.target is None else f.target
        if not derived <= target + 1e-9 or not np.isfinite(derived):
            unmet.setdefault(name, set()).add(f.key)
    assert unmet == {m: set(fs) for m, fs in UNMET.get(plant, {}).items()}


@pytest.mark.slow
@pytest.mark.parametrize("plant", RUN_PLANTS)
def test_banks_isolate_the_injected_fault(campaign, plant):
    unisolated = {}
    for f, name, r in results(campaign, plant):
        d = r.derived[f.key]
        if "settled" not in d:
            continue
        iso, t = r.measured[f.key]["isolated"], r.measured[f.key]["t"]
        if np.isfinite(d["settled"]):
            assert np.all(iso[t >= d["settled"] - 1e-9] == d["fault"]), (name, f.key)
        if d["final"]:
            assert iso[-1] == d["fault"], (name, f.key)
        if d["clean"]:  # 0 none, -1 unknown/several, else a fault: only the injected one
            assert set(iso.tolist()) <= {0, -1, d["fault"]}, (name, f.key, set(iso.tolist()))
        if not (np.isfinite(d["settled"]) or d["final"]):
            unisolated.setdefault(name, set()).add(f.key)
    assert unisolated == {m: set(fs) for m, fs in UNISOLATED.get(plant, {}).items()}


# ------------------------------------------------------------------------- applicability
@pytest.mark.parametrize("plant", PLANTS)
def test_every_method_is_hosted_or_has_a_reason(plant):
    for sub in cp.CAMPAIGNS[plant].subsystems:
        hosted = {name.split("_")[0] for name in sub.methods}
        for method in METHODS:
            assert (method in hosted) != ((plant, sub.name, method) in NOT_APPLICABLE), (plant, sub.name, method)


def _model(plant, index=0):
    return model_of(cp.CAMPAIGNS[plant], cp.CAMPAIGNS[plant].subsystems[index])


@pytest.mark.parametrize("plant, index, design, message", [
    ("dr300", 0, lambda m: kalman(m, Qw=1.0, Rv=0.0), "no stabilising solution"),
    ("dr300", 0, lambda m: unknown_input_observer(m), r"no residual remains: rank\(E\) = 1 ≥ 1 outputs"),
    ("dr300", 0, lambda m: fault_detection_filter(m, faults=["actuator_voltage"]), "not detectable"),
    ("dr300", 0, lambda m: factorized(m, normalized=True), "no stabilising solution"),
    ("dr300", 0, lambda m: nullspace_design(m), r"span every output direction \(normal rank of Gd = 1"),
    ("dr300", 0, lambda m: dedicated_bank(m, "sensor"), "needs at least two sensor faults"),
    ("dr300", 0, lambda m: generalized_bank(m, "actuator"), "needs at least two actuator faults"),
    ("lateral_aircraft", 0, lambda m: dedicated_bank(m, "sensor"), "needs at least two sensor faults"),
    ("lateral_aircraft", 0, lambda m: generalized_bank(m, "actuator"), "needs at least two actuator faults"),
    ("wind_turbine", 0, lambda m: dedicated_bank(m, "actuator"), "needs at least two actuator faults"),
    ("wind_turbine", 1, lambda m: fault_detection_filter(m, faults=["converter_offset"]), "acts on the measurements"),
    ("dts200", 0, lambda m: fault_detection_filter(m), "'sensor_h1' acts on the measurements"),
])
def test_not_applicable_designs_raise_the_documented_error(plant, index, design, message):
    with pytest.raises(DesignError, match=message):
        design(_model(plant, index))


@pytest.mark.parametrize("plant, index", [("dts200", 0), ("vtol", 0), ("wind_turbine", 0), ("lateral_aircraft", 0)])
def test_uio_without_unknown_inputs_is_the_luenberger_observer(plant, index):
    # E = 0: H = 0, T = I, F = A − K1 C, so the UIO with the same poles is the output observer
    m = _model(plant, index)
    uio = unknown_input_observer(m)
    assert uio.info["rank_E"] == 0 and not np.any(uio.info["H"])
    obs = luenberger(m, uio.info["poles"])
    # both place the same poles on the same pair with the same algorithm: equal to rounding
    np.testing.assert_allclose(uio.Q.D, obs.Q.D, atol=1e-12)
    np.testing.assert_allclose(np.sort_complex(uio.Q.poles()), np.sort_complex(obs.Q.poles()), atol=1e-9)
    assert np.allclose(uio.info["K"], obs.info["gain"], atol=1e-9 * max(1.0, np.abs(obs.info["gain"]).max()))

