"""Empty pythonfmu 0.7's global interpreter handle before the process exits (bundled into every FMU).

pythonfmu 0.7.0 (``PySlaveInstance.cpp``) keeps its interpreter handle in a global
``std::shared_ptr<PyState> pyState`` of the FMU's shared library. Two exit-time destructors
own it: the C++ destructor of the global, registered with ``__cxa_atexit`` and run by
``exit()`` first, and ``finalizePythonInterpreter()``, an ``__attribute__((destructor))`` run
later by ``_dl_fini``, which assigns ``nullptr`` to the already destroyed pointer. That
assignment decrements the use count inside the freed 128-byte control block (``lock xadd``
at offset 8): in a free heap chunk that word is the ``bk`` link of glibc's bins (or the tcache
key). The host then aborts in a later ``free``/``malloc`` of its own shutdown
("corrupted double-linked list", "free(): corrupted unsorted chunks") or not at all,
depending only on the heap layout: one more package in the environment (zipp) decides it.
valgrind shows the cause in every run: "Invalid read of size 4 at finalizePythonInterpreter
(from _dl_fini), block freed in __run_exit_handlers, allocated in pythonfmu::createInstance".

The remedy is pythonfmu's own: call ``finalizePythonInterpreter()`` once, while the handle
is alive and before the C++ exit handlers run. It empties the global (swap with an empty
pointer, then release), so both exit-time destructors find nothing to release. Python calls
``atexit`` callbacks from ``Py_FinalizeEx``:

* in a Python host (fmpy, libcosimpy, ...) before ``exit()``: pythonfmu did not start that
  interpreter, its ``PyState`` thread has long finished, releasing it only joins that thread;
* in a non-Python host, inside pythonfmu's own ``Py_Finalize``, which runs either from the
  host's call of ``finalizePythonInterpreter()`` (the global is already empty: nothing
  happens) or from the C++ destructor of the global, which has already decremented the use
  count to 0 before finalising: the call then leaves the global empty (so ``_dl_fini`` finds
  nothing) and decrements 0 to -1, which releases nothing twice.

The library is found among the FMU's own ``binaries/`` with ``RTLD_NOLOAD`` (only the copy
the host already loaded answers; the file identity is compared, not the path string) and
kept open until exit, so the callback can never outlive it even if the host unloads the
FMU. Windows has no ``RTLD_NOLOAD``, and there pythonfmu calls the function from
``DllMain`` before the C runtime destroys the global: nothing to do.
"""
from __future__ import annotations

import atexit
import ctypes
import glob
import os

#: real path of each guarded library → its handle (holding it keeps the library loaded)
_GUARDED: dict = {}


def guard_library(path) -> str | None:
    """Have ``finalizePythonInterpreter()`` of the already loaded library ``path`` run at
    interpreter exit, if it is a pythonfmu library (it exports that function).

    The library is looked up with ``RTLD_NOLOAD``: nothing is loaded that the host has not
    loaded itself. Idempotent per library. Returns the guarded library's real path, or None
    (not loaded, not a pythonfmu library, or a platform that needs no guard).
    """
    noload = getattr(os, "RTLD_NOLOAD", None)
    if noload is None:
        return None
    real = os.path.realpath(path)
    if real in _GUARDED:
        return real
    try:
        lib = ctypes.CDLL(str(path), mode=os.RTLD_NOW | noload)  # NULL unless this very file is loaded
        finalize = lib.finalizePythonInterpreter
    except (OSError, AttributeError):
        return None
    finalize.argtypes = []
    finalize.restype = None
    _GUARDED[real] = lib
    atexit.register(finalize)
    return real


def guard_interpreter_exit(resources: str, model_identifier: str) -> str | None:
    """:func:`guard_library` for this FMU's own loaded library, found next to its resources.

    Parameters
    ----------
    resources : str
        The instance's resources folder (``<unzipped FMU>/resources``).
    model_identifier : str
        Name of the FMU's shared library (without extension).

    Returns
    -------
    str or None
        Real path of the guarded library (also when an earlier instance guarded it), or None
        when no library of this FMU is loaded in the process, it lacks the function, or the
        platform needs no guard (no ``RTLD_NOLOAD``).
    """
    if getattr(os, "RTLD_NOLOAD", None) is None:
        return None
    root = os.path.dirname(os.path.normpath(resources))
    pattern = os.path.join(glob.escape(root), "binaries", "*", glob.escape(model_identifier) + ".*")
    for path in sorted(glob.glob(pattern)):
        guarded = guard_library(path)
        if guarded is not None:
            return guarded
    return None


def _unmarked(path: str) -> str:
    """A /proc/self/maps path without the " (deleted)" mark of a file removed since loading."""
    return path[:-len(" (deleted)")] if path.endswith(" (deleted)") else path


def guard_loaded_libraries() -> list:
    """:func:`guard_library` for every shared library this process has loaded from an FMU's
    ``binaries/`` folder (Linux: ``/proc/self/maps``): a host's safety net for pythonfmu FMUs
    that were not built by fmu-fdi and so do not guard themselves. Returns the guarded paths."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            fields = [line.split(None, 5) for line in fh]
    except OSError:
        return []
    marker = os.sep + "binaries" + os.sep
    paths = sorted({_unmarked(f[5].strip()) for f in fields if len(f) == 6 and marker in f[5]})
    return [g for g in map(guard_library, paths) if g is not None]


def guard_slave(slave, model_identifier: str) -> str | None:
    """:func:`guard_interpreter_exit` for a pythonfmu slave just constructed.

    Where the guard is needed but the library is not found, a warning goes to the FMI logger
    (category ``logStatusWarning``): the host may then abort at exit, after its work is done.
    """
    guarded = guard_interpreter_exit(slave.resources, model_identifier)
    if guarded is None and hasattr(os, "RTLD_NOLOAD"):
        from pythonfmu.enums import Fmi2Status

        slave.log(f"{model_identifier}: no loaded library binaries/*/{model_identifier}.* next to the resources "
                  f"folder {slave.resources}; pythonfmu 0.7 may corrupt the host's heap when the process exits",
                  Fmi2Status.warning, "logStatusWarning")
    return guarded
