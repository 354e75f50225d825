"""How tests/data/varga_cs1.json and varga_cs2.json were made (run once; not imported by the tests).

Source: FaultDetectionTools.jl (A. Varga, MIT licence), Examples/cs1data.jld2 and
Examples/cs2data.jld2 at commit 76ec594 of github.com/andreasvarga/FaultDetectionTools.jl — the data
of the case studies CS1 (flight actuator faults) and CS2 (air-data sensor faults) of Varga, "Solving
Fault Diagnosis Problems", Springer 2017, ch. 8. The JLD2 files are HDF5; each DescriptorStateSpace
is a compound record (A, E, B, C, D, Ts) whose matrices are object references, E = I (UniformScaling)
and Ts = 0 (continuous). Julia stores column-major, so every matrix is transposed on reading.

Needs h5py (only for this conversion): python tests/data/varga_cs_from_jld2.py CS1.jld2 CS2.jld2
"""
import json
import sys
from pathlib import Path

import h5py
import numpy as np

HERE = Path(__file__).resolve().parent
SOURCE = ("FaultDetectionTools.jl (github.com/andreasvarga/FaultDetectionTools.jl, commit 76ec594), "
          "Examples/{}: data of Varga (2017), 'Solving Fault Diagnosis Problems', ch. 8. Converted by "
          "tests/data/varga_cs_from_jld2.py (h5py; Julia column-major arrays transposed). "
          "Descriptor E = I, Ts = 0 (continuous) for every system.")


def _system(f, rec) -> dict:
    out = {}
    for k in "ABCD":
        M = np.asarray(f[rec[k]][()], float).T  # Julia column-major -> row-major
        out[k] = M.tolist()
    assert float(rec["Ts"]) == 0.0
    return out


def convert(cs1: str, cs2: str) -> None:
    with h5py.File(cs1, "r") as f:
        data = {"source": SOURCE.format("cs1data.jld2"),
                "SYSACM": [_system(f, f[r][()]) for r in f["SYSACM"][()]],
                "ACT": _system(f, f["ACT"][()]),
                "K": np.asarray(f["K"][()], float).T.tolist()}
    (HERE / "varga_cs1.json").write_text(json.dumps(data, separators=(",", ":")))
    with h5py.File(cs2, "r") as f:
        data = {"source": SOURCE.format("cs2data.jld2"),
                "SYSACSM": [_system(f, f[r][()]) for r in f["SYSACSM"][()]],
                "massi": np.asarray(f["massi"][()], float).ravel().tolist()}
    (HERE / "varga_cs2.json").write_text(json.dumps(data, separators=(",", ":")))


if __name__ == "__main__":
    convert(*sys.argv[1:3])
