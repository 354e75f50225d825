"""Issue 22: FMU-state fuzz of the native diagnostic FMU (FMI 2.0 and 3.0) in a plain C host.

tests/hosts/native_state_fuzz.c flips single bits of a serialized FMU state, one per child
process, and steps the FMU K rows from the flipped state (docs/native-fmu.md, FMU state). Two
families:

- raw flips (what a disk, a network or a bad copy does): the image's checksum must refuse
  every one of them with a clean Error;
- resealed flips (the checksum recomputed after the flip, as a host that edits states would):
  the runtime's own validation decides. Whatever it accepts must step in bounded time (no hang,
  no crash) and give outputs in their types' ranges; a flip it accepts may change later
  outputs only in a value a valid state may hold (the measure printed is how many did).

The slow suite flips every bit of a state of each test design; the default suite every 61st
bit of two designs.
"""
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmu_fdi import build_fmu
from native_designs import feature_designs, rls_designs
from native_scenario import make_scenario

HERE = Path(__file__).parent / "hosts"
CC = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
ROWS = 120
FIELDS = ("tries", "refused", "step_error", "same", "different", "invalid", "hang", "crash")


def _designs():
    out = dict(feature_designs())
    out.update(rls_designs())
    return out


def _host(folder):
    import fmpy

    exe = Path(folder) / "native_state_fuzz"
    if not exe.exists():
        subprocess.run([CC, "-std=c99", "-O1", "-g", "-Wall", "-Wextra", "-Werror", "-pedantic",
                        f"-I{Path(fmpy.__file__).parent / 'c-code'}", str(HERE / "native_state_fuzz.c"),
                        "-o", str(exe), "-ldl", "-lm"], check=True, capture_output=True, timeout=120)
    return exe


def _rows_csv(design, path):
    """ROWS calls of the conformance scenario at Ts (NaN bursts and overflowing samples included)."""
    ops = [op for op in make_scenario(design, np.random.default_rng(22), ROWS) if op[0] == "step"]
    Ts = float(design["generator"]["dt"])
    lines = ["time," + ",".join(design["signals"]["u"] + design["signals"]["y"])]
    lines += [",".join(repr(float(x)) for x in [k * Ts, *op[1], *op[2]]) for k, op in enumerate(ops)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def fuzz(design, folder, version=2, stride=1, reseal=False, env_python=None):
    """Build the FMU, run the fuzz host; returns the tally (dict of FIELDS and bytes)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fmu = folder / f"{design['name']}_{version}.fmu"
    if not fmu.exists():
        if env_python is None:
            build_fmu(design, fmu, target="native", fmi_version=version)
        else:  # another source tree (the measurement before the fix)
            import json

            (folder / "d.json").write_text(json.dumps(design), encoding="utf-8")
            subprocess.run([sys.executable, "-m", "fmu_fdi", "build", str(folder / "d.json"), "-o", str(fmu),
                            "--target", "native", "--fmi", str(version)], check=True, capture_output=True,
                           env=dict(os.environ, PYTHONPATH=env_python), timeout=300, cwd=folder)
    unzip = folder / f"u_{design['name']}_{version}"
    if not unzip.exists():
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(unzip)
    plain = design["members"][0] if "members" in design else design  # a scheduled design: member 1's signals
    csv = folder / f"{design['name']}.csv"
    _rows_csv(plain, csv)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD"))}
    proc = subprocess.run([str(_host(folder)), str(version), str(unzip), str(csv),
                           repr(float(plain["generator"]["dt"])), str(len(design.get("faults", []))),
                           str(stride), "1" if reseal else "0"], capture_output=True, text=True, timeout=900, env=env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", proc.stdout.splitlines()[-1])}


def _judge(name, raw, sealed):
    print(f"{name}: raw {raw}; resealed {sealed}")
    assert raw["tries"] > 0 and raw["refused"] == raw["tries"], raw  # the checksum catches every raw flip
    for field in ("hang", "crash", "invalid"):  # bounded work and in-range outputs, whatever it accepts
        assert sealed[field] == 0, (field, sealed)
    assert sealed["refused"] > 0 and sealed["tries"] == raw["tries"], sealed


@pytest.mark.parametrize("name, version", [("rms_peak_ewrms_adaptive_structure", 3), ("rls_floor", 2)])
def test_state_bit_flips_sample(tmp_path, name, version):
    design = _designs()[name]
    raw = fuzz(design, tmp_path, version, stride=61)
    sealed = fuzz(design, tmp_path, version, stride=61, reseal=True)
    _judge(name, raw, sealed)


@pytest.mark.slow
def test_every_state_bit_flip_of_every_test_design(tmp_path):
    for name, design in _designs().items():
        for version in ((2, 3) if name == "rms_peak_ewrms_adaptive_structure" else (2,)):
            raw = fuzz(design, tmp_path / name, version)
            sealed = fuzz(design, tmp_path / name, version, reseal=True)
            _judge(f"{name} FMI {version}", raw, sealed)


if __name__ == "__main__":  # the measurement: python tests/test_native_state_fuzz.py [SOURCE_TREE] [STRIDE]
    import tempfile

    tree = (sys.argv[1] if len(sys.argv) > 1 else "") or None
    stride = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    with tempfile.TemporaryDirectory() as tmp:
        total = dict.fromkeys(FIELDS, 0)
        totals = {False: dict(total), True: dict(total)}
        for name, design in _designs().items():
            for reseal in (False, True):
                t = fuzz(design, Path(tmp) / name, 2, stride, reseal, env_python=tree)
                print(name, "resealed" if reseal else "raw", t, flush=True)
                for k in FIELDS:
                    totals[reseal][k] += t[k]
        print("raw", totals[False])
        print("resealed", totals[True])
