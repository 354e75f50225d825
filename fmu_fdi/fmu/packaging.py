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

The *builder* is another matter: it copies the FMI wrapper libraries (``binaries/``) from
the folder of the ``pythonfmu`` it was imported from, and the copy a pythonfmu FMU bundles
in its ``resources/`` has none. Once such an FMU ran in this process, ``import pythonfmu``
finds that copy, and a build would silently write an FMU without binaries.
:func:`installed_pythonfmu` therefore imports the *installed* distribution for the build,
and :func:`check_fmu_archive` checks every archive before it is reported as written. The
archive is written to a temporary file next to the destination and renamed over it, so a
failed build never leaves a half-written FMU or destroys the previous one.
"""
from __future__ import annotations

import hashlib
import importlib
import os
import re
import shutil
import sys
import tempfile
import zipfile
from contextlib import contextmanager
from pathlib import Path
from typing import Mapping, Sequence
from xml.etree import ElementTree as ET

from ..errors import BuildError
from ..outpath import check_output_path, write_atomically
from .model_description import patch_fmu

#: permissions of a written FMU: readable by everyone, like any other build artefact
FMU_MODE = 0o644

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


@contextmanager
def installed_pythonfmu():
    """Make ``import pythonfmu`` give the installed distribution for the duration of the block.

    A pythonfmu FMU that ran in this process put its ``resources/`` folder, with a stripped
    ``pythonfmu`` copy (no wrapper binaries), first on ``sys.path`` and in ``sys.modules``.
    The block sees the package from the distribution's own folder; afterwards ``sys.path``
    and ``sys.modules`` are as before, so FMUs already loaded keep the copy they use.

    Yields
    ------
    Path
        The folder of the installed ``pythonfmu`` package.

    Raises
    ------
    BuildError
        pythonfmu is not installed.
    """
    from importlib import metadata

    try:
        root = Path(metadata.distribution("pythonfmu").locate_file("")).resolve()
    except metadata.PackageNotFoundError:
        raise BuildError("pythonfmu is not installed in this Python; pip install 'pythonfmu>=0.7,<0.8'") from None
    package = root / "pythonfmu"

    current = sys.modules.get("pythonfmu")
    if current is not None and Path(current.__file__).resolve().parent == package:
        yield package
        return
    with isolated_imports("pythonfmu"):
        sys.path.insert(0, str(root))
        importlib.invalidate_caches()
        import pythonfmu

        if Path(pythonfmu.__file__).resolve().parent != package:
            raise BuildError(f"could not import the installed pythonfmu from {package} "
                             f"(got {pythonfmu.__file__})")
        yield package


@contextmanager
def isolated_imports(*names: str):
    """Let a build import the modules ``names`` (and their submodules) afresh, then put
    ``sys.modules`` and ``sys.path`` back as they were.

    An FMU that ran in this process left its slave module under the same name in
    ``sys.modules``, bound to that FMU's pythonfmu copy: the builder would find that stale
    class instead of the one it is building (``No child class of Fmi2Slave``). The running
    FMU keeps its module: it is restored after the build.
    """
    def ours(mod):
        return any(mod == n or mod.startswith(n + ".") for n in names)

    saved = {n: m for n, m in sys.modules.items() if ours(n)}
    path_before = list(sys.path)
    for name in saved:
        del sys.modules[name]
    try:
        yield
    finally:
        for name in [n for n in sys.modules if ours(n)]:
            del sys.modules[name]
        sys.modules.update(saved)
        sys.path[:] = path_before
        importlib.invalidate_caches()


def this_platform() -> tuple[str, str]:
    """``(binaries folder, shared library extension)`` of this machine, as FMI 2.0 names them."""
    import fmpy

    return fmpy.platform, fmpy.sharedLibraryExtension


def check_fmu_archive(fmu_path, resources: Sequence[str] = ()) -> list[str]:
    """Check that an FMU archive can be loaded here; return the platforms it has binaries for.

    Checked: the file is a zip archive with a parseable ``modelDescription.xml`` naming a
    ``CoSimulation`` ``modelIdentifier``; ``binaries/<platform>/<modelIdentifier><ext>`` is
    there for this machine's platform, and every ``binaries/<platform>/`` folder holds that
    library; every name in ``resources`` is a member under ``resources/``.

    Raises
    ------
    BuildError
        Naming the first condition that failed.
    """
    name = Path(fmu_path).name
    try:
        with zipfile.ZipFile(fmu_path) as zf:
            members = set(zf.namelist())
            bad = zf.testzip()
            if bad is not None:
                raise BuildError(f"{name}: archive member {bad} is corrupt")
            if "modelDescription.xml" not in members:
                raise BuildError(f"{name}: the archive has no modelDescription.xml")
            root = ET.fromstring(zf.read("modelDescription.xml"))
    except (zipfile.BadZipFile, OSError) as exc:
        raise BuildError(f"{name}: not a readable FMU archive ({exc})") from None
    except ET.ParseError as exc:
        raise BuildError(f"{name}: modelDescription.xml does not parse ({exc})") from None
    cs = root.find("CoSimulation")
    mid = cs.get("modelIdentifier") if cs is not None else None
    if not mid:
        raise BuildError(f"{name}: modelDescription.xml declares no CoSimulation modelIdentifier")
    platform, ext = this_platform()
    folders = sorted({m.split("/")[1] for m in members if m.startswith("binaries/") and m.count("/") >= 2})
    if f"binaries/{platform}/{mid}{ext}" not in members:
        raise BuildError(f"{name}: no binaries/{platform}/{mid}{ext} for this platform (binaries for: "
                         f"{', '.join(folders) or 'none'}); the pythonfmu used has no wrapper library for "
                         f"{platform}")
    empty = [p for p in folders if not any(m.startswith(f"binaries/{p}/{mid}.") for m in members)]
    if empty:
        raise BuildError(f"{name}: binaries/{', '.join(empty)} hold no library named {mid}")
    missing = [r for r in resources if f"resources/{r}" not in members]
    if missing:
        raise BuildError(f"{name}: resources {missing} are missing from the archive")
    return folders


def checked_destination(fmu_path) -> Path:
    """``fmu_path`` as a Path once an FMU can be written there (its folder is created).

    Raises
    ------
    BuildError
        The name does not end in ``.fmu``, names a folder, or its folder cannot be created
        or written (see :func:`fmu_fdi.outpath.check_output_path`).
    """
    return check_output_path(fmu_path, (".fmu",), "FMU", error=BuildError)


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
    fmu_path = checked_destination(fmu_path)
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
        staged = tmp / "out" / fmu_path.name
        staged.parent.mkdir()
        # the builder imports the script (and so the package) into this process and leaves
        # its folder on sys.path: both are undone, and an FMU of this bundle that ran here
        # keeps its modules
        with isolated_imports(bundle_name, lib), installed_pythonfmu():
            from pythonfmu import FmuBuilder

            FmuBuilder.build_FMU(script, dest=staged, project_files=[pkg])
        resources = [f"{bundle_name}.py", f"{lib}/__init__.py"] + [f"{lib}/{n}" for n in sources]
        resources += [f"{lib}/{n}" for n in (data_files or {})]
        platforms = check_fmu_archive(staged, resources)
        if "model_description" in patch_options and patch_options["model_description"] is not None:
            patch_options["model_description"] += f" (binaries: {', '.join(platforms)})"
        patch_fmu(staged, **patch_options)
        check_fmu_archive(staged, resources)
        _replace(staged, fmu_path)  # write_atomically gives the renamed file FMU_MODE
    return fmu_path


def _replace(src: Path, dst: Path):
    """Move ``src`` onto ``dst`` atomically: copy next to ``dst``, then rename over it."""
    def fill(part: Path):
        with open(part, "wb") as out, open(src, "rb") as inp:
            shutil.copyfileobj(inp, out, 1 << 20)
            out.flush()
            os.fsync(out.fileno())

    write_atomically(dst, fill, FMU_MODE)
