"""The native runtime in a plain C host (tests/native_runtime_driver.c), under AddressSanitizer
and UndefinedBehaviorSanitizer, and under valgrind: no invalid access, no leak, no undefined
behaviour, through random calls with NaN/Inf and overflowing samples, every kind of step,
resets, roll-backs and hostile state images (which must be refused leaving the instance as
it was). The driver itself asserts bit-identical outputs of two instances (reentrancy)."""
import shutil
import subprocess

import pytest

from fmu_fdi.native import C_DIR, RUNTIME_SOURCES
from fmu_fdi.native.emit import emit_design_c
from native_designs import feature_designs, rls_designs

DRIVER = C_DIR.parent.parent.parent / "tests" / "native_runtime_driver.c"
WARN = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]


def _cc():
    return shutil.which("cc") or shutil.which("gcc")


def _build(design, folder, flags):
    (folder / "design_data.c").write_text(emit_design_c(design), encoding="utf-8")
    exe = folder / "driver"
    srcs = [str(C_DIR / s) for s in RUNTIME_SOURCES] + [str(folder / "design_data.c"), str(DRIVER)]
    subprocess.run([_cc(), *WARN, *flags, f"-I{C_DIR}", *srcs, "-o", str(exe), "-lm"], check=True,
                   capture_output=True, text=True)
    return exe


@pytest.fixture(scope="module")
def designs():
    d = feature_designs()
    return {"continuous_odd_steps": d["rms_peak_ewrms_adaptive_structure"],
            "statistical": d["chi2_cusum_glr_none"], "majorant_direction": d["narendra_norm_majorant_direction"],
            "rls": rls_designs()["rls_floor"]}


@pytest.mark.skipif(_cc() is None, reason="no C compiler")
@pytest.mark.parametrize("name", ["continuous_odd_steps", "statistical", "majorant_direction", "rls"])
def test_runtime_clean_under_address_and_undefined_sanitizers(name, designs, tmp_path):
    flags = ["-g", "-O1", "-fno-omit-frame-pointer", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    try:
        exe = _build(designs[name], tmp_path, flags)
    except subprocess.CalledProcessError as exc:
        if "sanitize" in exc.stderr or "asan" in exc.stderr:
            pytest.skip(f"the compiler has no AddressSanitizer here: {exc.stderr[-200:]}")
        raise
    proc = subprocess.run([str(exe), "4000", "11"], capture_output=True, text=True, timeout=120,
                          env={"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0", "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "runtime error" not in proc.stderr and "Sanitizer" not in proc.stderr, proc.stderr[-3000:]
    assert "hostile states refused" in proc.stdout


@pytest.mark.skipif(shutil.which("valgrind") is None or _cc() is None, reason="no valgrind or no C compiler")
def test_runtime_clean_under_valgrind(designs, tmp_path):
    exe = _build(designs["continuous_odd_steps"], tmp_path, ["-g", "-O2"])
    proc = subprocess.run(["valgrind", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=all",
                           "-q", str(exe), "800", "5"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]


@pytest.mark.skipif(shutil.which("nm") is None or _cc() is None, reason="no nm or no C compiler")
def test_runtime_has_no_global_mutable_state(tmp_path):
    """No object of the runtime defines writable data (data or bss symbols): every instance
    lives in its own block, so any number of instances can run in any threads."""
    objs = []
    for src in RUNTIME_SOURCES:
        obj = tmp_path / (src + ".o")
        subprocess.run([_cc(), *WARN, "-O2", "-fPIC", "-c", str(C_DIR / src), "-o", str(obj)], check=True,
                       capture_output=True, text=True)
        objs.append(str(obj))
    syms = subprocess.run(["nm", *objs], check=True, capture_output=True, text=True).stdout.splitlines()
    writable = [s for s in syms if len(s.split()) == 3 and s.split()[1] in "DdBbCGgSs"]
    assert not writable, writable
