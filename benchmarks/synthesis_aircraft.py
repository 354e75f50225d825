"""Design time of the full achievable structured bank on the real-size aircraft loop
(lateral aircraft + actuators in series + dynamic controller; 20 rows x 6 faults).
Prints the time against a baseline measured in the same run: one nullspace_design
detection filter on the same model. Run: python benchmarks/synthesis_aircraft.py
"""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_fdi import nullspace_design, structured_bank  # noqa: E402
from fmu_fdi.design.problems.achievable import achievable_structure  # noqa: E402
from synthesis_models import aircraft_loop  # noqa: E402

model = aircraft_loop()
t0 = time.perf_counter()
nullspace_design(model)
base = time.perf_counter() - t0
t0 = time.perf_counter()
S = achievable_structure(model)
bank = structured_bank(model, S, FDtol=1e-5)
t = time.perf_counter() - t0
print(f"aircraft loop n={model.n}: bank {S.shape[0]}x{S.shape[1]} order {bank.Q.n} in {t:.2f} s "
      f"({t / base:.1f}x one detection filter, {base:.2f} s); postconditions {bank.info['postconditions']}")
