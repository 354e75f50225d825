"""Build a pythonfmu FMU whose bundled Python code cannot clash with another FMU's.

pythonfmu 0.7.0 loads a slave by ``PyImport_ImportModule(<script stem>)`` after putting the
FMU's ``resources`` folder first on ``sys.path`` (``PySlaveInstance.cpp``). All FMUs in one
process share one interpreter and one ``sys.modules``: a second FMU whose script (or any
bundled module or package) has a name already imported gets the *first* FMU's code
(pythonfmu issue 228). So everything an FMU bundles lives under one name unique to it:

    resources/<bundle>.py                   three lines: import the slave class from the package
    resources/<bundle>_lib/__init__.py      (a package may not share the script's name: a
    resources/<bundle>_lib/slave_base.py     folder X/ shadows X.py on sys.path)
    resources/<bundle>_lib/slave_state.py   (both copied from fmu_fdi.fmu)
    resources/<bundle>_lib/<your modules>   (relative imports only)
    resources/pythonfmu/                                (bundled by pythonfmu itself)

The one name shared by all pythonfmu FMUs is ``pythonfmu``: the first copy imported in a
process (the host's own, or the first FMU's) serves every FMU. Our slaves use only
``Fmi2Slave``, the variable classes and the enums, which are the same across 0.7.x.
"""
from __future__ import annotations

import hashlib
import importlib
import re
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Mapping

from .model_description import patch_fmu

_HERE = Path(__file__).parent
#: modules copied into every bundle; they import only numpy, the stdlib and pythonfmu
BASE_MODULES = ("slave_base.py", "slave_state.py", "exit_guard.py")
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


# pythonfmu 0.7.0 (findClass in PySlaveInstance.cpp) imports this file as a module, then on
# every fmi2Instantiate executes it again into the module's namespace and Py_DECREFs that
# namespace dict although it only borrowed it. Each stray decrement eats a reference the
# module owns; after a few instantiations (or at interpreter finalisation, in a C host) the
# dict is freed while still in use: "module has no attribute ...", fmi2Instantiate returning
# NULL, or "free(): corrupted unsorted chunks" when the process exits. Every execution of the
# loader therefore parks one more reference to its own namespace in a list that lives as
# long as the interpreter, which exactly balances the stray decrement (the first import adds
# one reference more: the dict is never freed, a deliberate leak of one small dict). The
# class is defined here, with methods, for the same reason (functions hold their globals).
# Every instance also guards the host against pythonfmu 0.7's use-after-free of its global
# interpreter handle at process exit (see fmu_fdi.fmu.exit_guard): without it, whether the
# host aborts after its work is done depends on its heap layout.
_LOADER = '''"""Loader for pythonfmu (generated): the slave code lives in the package {lib}."""
import sys as _sys

# balance pythonfmu 0.7's stray Py_DECREF of this namespace (see fmu_fdi.fmu.packaging)
_sys.__dict__.setdefault("_fmu_fdi_namespaces", []).append(globals())

from {lib}.exit_guard import guard_slave as _guard_exit
from {lib}.{module} import {cls} as _Slave


class {cls}(_Slave):
    """The slave class pythonfmu instantiates (see fmu_fdi.fmu.packaging for why it is here)."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        _guard_exit(self, "{cls}")  # pythonfmu 0.7 frees its interpreter handle twice at exit

    def _loader_namespace(self):
        return globals()
'''


def unique_bundle_name(prefix: str, *parts: str) -> str:
    """``<prefix>_<10 hex digits>`` from a hash of ``parts`` (stable for equal content)."""
    h = hashlib.sha256("\0".join(parts).encode("utf-8")).hexdigest()[:10]
    return f"{re.sub(r'[^A-Za-z0-9_]', '_', prefix).lower()}_{h}"


def build_slave_fmu(
    modules: Mapping[str, str],
    slave: str,
    fmu_path: str | Path,
    *,
    bundle_name: str | None = None,
    data_files: Mapping[str, bytes] | None = None,
    **patch_options,
) -> Path:
    """Build a co-simulation FMU from slave source code and make its modelDescription valid.

    Parameters
    ----------
    modules : mapping
        File name inside the bundle package (``"standin.py"``) → Python source. Modules
        import each other and ``slave_base`` with relative imports (``from .slave_base import
        FdiSlave``).
    slave : str
        ``"module:ClassName"`` of the slave class, e.g. ``"standin:StandIn"``. The class name
        is the FMU's modelIdentifier (name of the shared library).
    fmu_path : path
        Where to write the .fmu.
    bundle_name : str, optional
        Name of the loader script (the package is ``<bundle_name>_lib``); must be unique
        among FMUs loaded into one process. Default: ``<classname>_<hash of the sources>``.
    data_files : mapping, optional
        Extra files for the bundle package (relative name → bytes), e.g. a design JSON.
    **patch_options
        Passed to :func:`fmu_fdi.fmu.model_description.patch_model_description`.
    """
    from pythonfmu import FmuBuilder  # the builder, not the FMU, needs pythonfmu here

    module, _, class_name = slave.partition(":")
    if not (_IDENT.match(module or "") and _IDENT.match(class_name or "")):
        raise ValueError(f"slave must be 'module:ClassName' with identifiers, got {slave!r}")
    if f"{module}.py" not in modules:
        raise ValueError(f"slave module {module!r} is not among modules {sorted(modules)}")
    sources = {name: (_HERE / name).read_text() for name in BASE_MODULES}
    sources.update(modules)
    if bundle_name is None:
        bundle_name = unique_bundle_name(class_name, *(f"{k}\n{v}" for k, v in sorted(sources.items())))
    if not _IDENT.match(bundle_name) or bundle_name == "pythonfmu":
        raise ValueError(f"bundle_name must be a Python identifier other than 'pythonfmu', got {bundle_name!r}")
    fmu_path = Path(fmu_path)
    fmu_path.parent.mkdir(parents=True, exist_ok=True)

    with tempfile.TemporaryDirectory(prefix="fmufdi_build_") as tmp:
        tmp = Path(tmp)
        lib = f"{bundle_name}_lib"
        pkg = tmp / lib
        pkg.mkdir()
        (pkg / "__init__.py").write_text(f'"""Code bundled in the FMU {class_name} (generated)."""\n')
        for name, text in sources.items():
            (pkg / name).write_text(text)
        for name, data in (data_files or {}).items():
            (pkg / name).write_bytes(data)
        script = tmp / f"{bundle_name}.py"
        script.write_text(_LOADER.format(lib=lib, module=module, cls=class_name))
        before = set(sys.modules)
        path_before = list(sys.path)
        try:
            built = FmuBuilder.build_FMU(script, dest=fmu_path, project_files=[pkg])
        finally:
            # the builder imports the script (and so the package) into this process and
            # leaves its folder on sys.path; undo both so later builds see fresh code
            for name in set(sys.modules) - before:
                if name in (bundle_name, lib) or name.startswith(lib + "."):
                    del sys.modules[name]
            sys.path[:] = path_before
            importlib.invalidate_caches()
    if Path(built) != fmu_path:
        shutil.move(built, fmu_path)
    patch_fmu(fmu_path, **patch_options)
    return fmu_path
