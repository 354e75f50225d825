"""Wall time of ``fmu_fdi.model_from_fmu`` (what ``fmu-fdi model`` runs) per benchmark plant FMU (issue 9).

Each identification runs two experiments (identification and validation) of 200 settling +
2000 recorded steps through fmu_fdi.cosim, PO-MOESP and the validation. It is printed next to
the baseline measured in the same run: one bare co-simulation of the plant alone over the same
number of steps with constant inputs; the ratio is the cost of identification beyond running
the plant. Target: DTS200 under 30 s. Also prints the validation fit per output.

Run: ``python benchmarks/identify_speed.py [PLANT ...]``
"""
from __future__ import annotations

import sys
import tempfile
import time

import plant_fmus
from fmu_fdi.cosim import CoSimulation
from fmu_fdi.identify import Excitation, model_from_fmu

CASES = {  # plant: (u, y, d, excite, amplitudes), noise off (a simulation model lets you)
    "dts200": (["Q1", "Q2"], ["h1", "h2", "h3"], [], None, None),
    "dr300": (["voltage"], ["speed"], ["load_torque"], ["speed_ref", "load_torque"],
              {"speed_ref": 1.0, "load_torque": 0.1}),
    "vtol": (["collective", "cyclic"], ["vh", "vv", "q", "y4"], [], ["ref_collective", "ref_cyclic"],
             {"ref_collective": 1.0, "ref_cyclic": 1.0}),
    "lateral_aircraft": (["u1", "u2"], ["beta", "phi", "p", "r"], [], None, {"u1": 0.01, "u2": 0.01}),
    "wind_turbine": (["tau_g_ref"], ["omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2", "tau_g_m"], ["tau_r"],
                     None, None),
}


def main(names):
    out = tempfile.mkdtemp(prefix="identify_speed_")
    print(f"{'plant':<18}{'identify (s)':>13}{'baseline (s)':>14}{'ratio':>7}  fit per output (%)")
    for name in names:
        u, y, d, excite, amp = CASES[name]
        fmu = plant_fmus.build(name, out)
        step = plant_fmus.PLANTS[name].step
        t0 = time.perf_counter()
        CoSimulation({"plant": fmu}, None, step=step, stop=2 * 2200 * step,
                     parameters={"plant.noise_enable": False}).run()
        base = time.perf_counter() - t0
        t0 = time.perf_counter()
        m = model_from_fmu(fmu, u, y, d, at={"noise_enable": False}, excite=excite,
                           excitation=Excitation(amplitude=amp))
        ident = time.perf_counter() - t0
        fit = " ".join(f"{f:.2f}" for f in m.provenance["fit_percent"])
        print(f"{name:<18}{ident:>13.2f}{base:>14.2f}{ident / base:>7.2f}  {fit}  (order {m.n})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or list(CASES)))
