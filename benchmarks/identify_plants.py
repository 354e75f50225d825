"""`fmu-fdi model` with default options on each shipped plant FMU, its noise on (issue 18, closing note).

Per plant: the experiment the automatic design chooses, the wall time and the CPU time of the
command (the machine may be loaded: CPU time is what the command itself costs), and the fit per
output against the noise floor (plain fit, the fit to the noise-free response, the floor a
perfect model would reach). The experiment is a function of the FMU and the options only
(fmu_fdi/identify/design.py: the budget is counted in samples), so it is the same on every run.

The wind turbine's drive train is the stiff case (138 s rotor mode, 28 rad/s shaft mode, 1/50 s
converter): slow pre-tests, a two-scale PRBS and the output-error refinement
(fmu_fdi/identify/design.py, output_error.py).

Run: ``python benchmarks/identify_plants.py [PLANT ...]``
"""
from __future__ import annotations

import resource
import subprocess
import sys
import tempfile
import time

import plant_fmus
from fmu_fdi import FDIModel

CASES = {  # plant FMU: (u, y, d, excite) as in tests/test_identify_design.py
    "dts200": ("dts200", ["Q1", "Q2"], ["h1", "h2", "h3"], [], []),
    "lateral_aircraft": ("lateral_aircraft", ["u1", "u2"], ["beta", "phi", "p", "r"], [], []),
    "vtol": ("vtol", ["collective", "cyclic"], ["vh", "vv", "q", "y4"], [], ["ref_collective", "ref_cyclic"]),
    "dr300": ("dr300", ["voltage"], ["speed"], ["load_torque"], ["speed_ref", "load_torque"]),
    "wind_pitch": ("wind_turbine", ["beta_ref_1", "beta_ref_2", "beta_ref_3"],
                   ["beta_1_m1", "beta_1_m2", "beta_2_m1", "beta_2_m2", "beta_3_m1", "beta_3_m2"], [], []),
    "wind_drive_train": ("wind_turbine", ["tau_g_ref"], ["omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2",
                                                          "tau_g_m"], ["tau_r"], []),
}


def main(names):
    out = tempfile.mkdtemp(prefix="identify_plants_")
    for name in names:
        fmu_name, u, y, d, excite = CASES[name]
        fmu = plant_fmus.build(fmu_name, out)
        model = f"{out}/{name}.toml"
        args = [sys.executable, "-m", "fmu_fdi", "model", str(fmu), "--inputs", *u, "--outputs", *y,
                "--sensor-faults", "all", "-o", model]
        if d:
            args += ["--disturbances", *d]
        if excite:
            args += ["--excite", *excite]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        run = subprocess.run(args, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        print(f"== {name}: wall {wall:.1f} s, CPU {cpu:.1f} s, exit {run.returncode}")
        print("\n".join(line for line in run.stdout.splitlines() if line.startswith(("experiment", "  "))))
        if run.returncode:
            print(run.stderr.strip().splitlines()[-1] if run.stderr.strip() else "")
            continue
        prov = FDIModel.from_file(model).provenance
        for j, n in enumerate(y):
            print(f"   {n}: fit {prov['fit_percent'][j]:.1f} %, noise-free {prov['fit_corrected_percent'][j]:.1f} %, "
                  f"floor {prov['floor_percent'][j]:.1f} %")


if __name__ == "__main__":
    main(sys.argv[1:] or list(CASES))
