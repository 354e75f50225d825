"""Issues 22 and 20: FMU-state fuzz of the native diagnostic FMU (FMI 2.0 and 3.0) in a plain C host.

tests/hosts/native_state_fuzz.c mutates a serialized FMU state and steps the FMU K rows from
every mutated state the FMU accepts (docs/native-fmu.md, FMU state). Three kinds of mutation:
single bit flips, bytes set to 0x00 / 0xFF / 0x80 (several bits at once, a double's sign and
exponent at their extremes) and images cut short or extended. Two families of each:

- raw (what a disk, a network or a bad copy does): the image's checksum must refuse every one
  with a clean Error;
- resealed (the checksum recomputed after the mutation, as a host that edits states would):
  the runtime's own validation decides. Whatever it accepts must step in bounded time (no hang,
  no crash) and give outputs in their types' ranges; a mutation it accepts may change later
  outputs only in a value a valid state may hold (the measure printed is how many did).

A refused state must leave the instance as it was (the host steps it from there every 16th
refusal). Refusals are judged in the host's own process and only accepted states are stepped
in a child process. The default suite tries every raw mutation of a state of two designs and every
5th resealed one; the slow suite every mutation, raw and resealed, of every test design in FMI 2
and FMI 3.
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
FIELDS = ("tries", "refused", "step_error", "same", "different", "invalid", "hang", "crash", "intact_checks",
          "changed_by_refusal")
MODES = ("bits", "bytes", "sizes")


def _designs():
    out = dict(feature_designs())
    out.update(rls_designs())
    return out


_HOST_DIR = []  # the host, compiled once per test session


def _host(folder):
    import tempfile

    import fmpy

    if not _HOST_DIR:
        _HOST_DIR.append(tempfile.mkdtemp(prefix="fuzz_host_"))
    exe = Path(_HOST_DIR[0]) / "native_state_fuzz"
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


def fuzz(design, folder, version=2, stride=1, reseal=False, env_python=None, mode="bits"):
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
                           str(stride), "1" if reseal else "0", mode], capture_output=True, text=True, timeout=900,
                          env=env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", proc.stdout.splitlines()[-1])}


def _judge(name, raw, sealed):
    print(f"{name}: raw {raw}; resealed {sealed}")
    assert raw["tries"] > 0 and raw["refused"] == raw["tries"], raw  # the checksum catches every raw mutation
    for field in ("hang", "crash", "invalid"):  # bounded work and in-range outputs, whatever it accepts
        assert sealed[field] == 0, (field, sealed)
    assert sealed["refused"] > 0 and sealed["tries"] > 0 and sealed["bytes"] == raw["bytes"], sealed
    for tally in (raw, sealed):  # a refused state left the instance as it was, every time it was looked at
        assert tally["intact_checks"] > 0 and tally["changed_by_refusal"] == 0, tally


def _fuzz_all(design, folder, version, sealed_stride=1):
    """Every mutation raw (refused in the host's process: cheap) and every ``sealed_stride``-th resealed
    (each accepted one stepped in a child process)."""
    for mode in MODES:
        raw = fuzz(design, folder, version, 1, mode=mode)
        sealed = fuzz(design, folder, version, sealed_stride, reseal=True, mode=mode)
        _judge(f"{design['name']} FMI {version} {mode}", raw, sealed)
        if mode == "sizes":  # no image of another length fits the FMU, checksum or not
            assert sealed["refused"] == sealed["tries"], sealed


@pytest.mark.parametrize("name, version", [("rms_peak_ewrms_adaptive_structure", 3), ("rls_floor", 2)])
def test_state_mutations_sample(tmp_path, name, version):
    """Every bit flip, byte value and length of a state of two designs (LTI with four evaluator and
    threshold kinds, FMI 3; RLS, FMI 2) raw, and every 5th of them resealed (5 is prime to 8 and 3:
    every bit and byte position is reached)."""
    _fuzz_all(_designs()[name], tmp_path, version, sealed_stride=5)


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3])
def test_every_resealed_state_mutation_of_every_test_design(tmp_path, version):
    for name, design in _designs().items():
        _fuzz_all(design, tmp_path / name, version)


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
