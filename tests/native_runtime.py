"""The native runtime without FMI: compile fmu_fdi/native/c + an emitted design into a shared
library and drive it through ctypes (the conformance suite's direct channel to the C code)."""
import ctypes
import os
import shutil
import subprocess
from pathlib import Path

from fmu_fdi.native import C_DIR, RUNTIME_SOURCES
from fmu_fdi.native.emit import emit_design_c

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2"]


def compile_runtime(design: dict, folder, extra=()) -> Path:
    """Write design_data.c into ``folder`` and build the runtime as a shared library."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "design_data.c").write_text(emit_design_c(design), encoding="utf-8")
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    srcs = [str(C_DIR / s) for s in RUNTIME_SOURCES] + [str(folder / "design_data.c")]
    out = folder / "libfdi.so"
    subprocess.run([cc, *CFLAGS, *extra, f"-I{C_DIR}", *srcs, "-shared", "-fPIC", "-o", str(out), "-lm"],
                   check=True, capture_output=True, text=True)
    return out


class CRuntime:
    """ctypes view of one fdi_runtime instance (fdi_runtime.h)."""

    def __init__(self, lib_path):
        lib = self.lib = ctypes.CDLL(str(lib_path))
        self.design = ctypes.addressof(ctypes.c_char.in_dll(lib, "FDI_DESIGN"))
        for name, res, args in [
                ("fdi_n_u", ctypes.c_size_t, [ctypes.c_void_p]), ("fdi_n_y", ctypes.c_size_t, [ctypes.c_void_p]),
                ("fdi_n_outputs", ctypes.c_size_t, [ctypes.c_void_p]),
                ("fdi_runtime_size", ctypes.c_size_t, [ctypes.c_void_p]),
                ("fdi_runtime_init", ctypes.c_int, [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t]),
                ("fdi_runtime_reset", None, [ctypes.c_void_p]),
                ("fdi_runtime_advance", ctypes.c_int, [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double),
                                                       ctypes.POINTER(ctypes.c_double), ctypes.c_double,
                                                       ctypes.c_char_p, ctypes.c_size_t]),
                ("fdi_runtime_outputs", ctypes.POINTER(ctypes.c_double), [ctypes.c_void_p]),
                ("fdi_runtime_set_threshold_scale", ctypes.c_int, [ctypes.c_void_p, ctypes.c_double,
                                                                   ctypes.c_char_p, ctypes.c_size_t]),
                ("fdi_runtime_threshold_scale", ctypes.c_double, [ctypes.c_void_p]),
                ("fdi_runtime_state_size", ctypes.c_size_t, [ctypes.c_void_p]),
                ("fdi_runtime_get_state", None, [ctypes.c_void_p, ctypes.c_char_p]),
                ("fdi_runtime_set_state", ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t,
                                                         ctypes.c_char_p, ctypes.c_size_t])]:
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
        self.nu, self.ny = lib.fdi_n_u(self.design), lib.fdi_n_y(self.design)
        self.n_out = lib.fdi_n_outputs(self.design)
        self.size = lib.fdi_runtime_size(self.design)
        self.block = ctypes.create_string_buffer(self.size)
        assert lib.fdi_runtime_init(self.block, self.design, self.size) == 0
        self.why = ctypes.create_string_buffer(512)
        self.u = (ctypes.c_double * max(self.nu, 1))()
        self.y = (ctypes.c_double * max(self.ny, 1))()

    def advance(self, u, y, h):
        """Returns (status, outputs list, reason)."""
        for i, x in enumerate(u):
            self.u[i] = x
        for i, x in enumerate(y):
            self.y[i] = x
        st = self.lib.fdi_runtime_advance(self.block, self.u, self.y, h, self.why, 512)
        out = self.lib.fdi_runtime_outputs(self.block)
        return st, out[:self.n_out], self.why.value.decode()

    def reset(self):
        self.lib.fdi_runtime_reset(self.block)

    def set_threshold_scale(self, s):
        return self.lib.fdi_runtime_set_threshold_scale(self.block, s, self.why, 512)

    def threshold_scale(self) -> float:
        return self.lib.fdi_runtime_threshold_scale(self.block)

    def get_state(self) -> bytes:
        n = self.lib.fdi_runtime_state_size(self.block)
        buf = ctypes.create_string_buffer(n)
        self.lib.fdi_runtime_get_state(self.block, buf)
        return buf.raw

    def set_state(self, img: bytes):
        st = self.lib.fdi_runtime_set_state(self.block, img, len(img), self.why, 512)
        return st, self.why.value.decode()


def c_outputs(lib_path, ops):
    """Run conformance operations (tests/native_scenario.py) on the runtime through ctypes."""
    rt = CRuntime(lib_path)
    saved, out = {}, []
    for op in ops:
        if op[0] == "step":
            st, vals, why = rt.advance(op[1], op[2], op[3])
            assert st in (0, 1), why
            out.append("discard" if st == 1 else vals)
        elif op[0] == "save":
            saved[op[1]] = rt.get_state()
        elif op[0] == "restore":
            st, why = rt.set_state(saved[op[1]])
            assert st == 0, why
        elif op[0] == "reset":
            rt.reset()
        elif op[0] == "scale":
            assert rt.set_threshold_scale(float(op[1])) == 0
    return out
