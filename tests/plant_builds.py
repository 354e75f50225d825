"""The benchmark plant FMUs, built once per test process for every module that only runs them.

A pythonfmu plant build costs a few seconds (the first in a process imports pythonfmu's builder),
a native one a C compilation; the campaign, the native-plant conformance tests and the CLI tests
ran the same builds again module by module. The FMUs here are read-only: a test that changes an
FMU, or is about building one (plant_fmus.build, build_native, ``plants build``), builds its own.
The folder is removed when the process exits.
"""
from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from pathlib import Path


@functools.cache
def _folder() -> Path:
    folder = Path(tempfile.mkdtemp(prefix="fmu_fdi_test_plants_"))
    atexit.register(shutil.rmtree, folder, True)
    return folder


@functools.cache
def python_plant(name: str) -> Path:
    """The pythonfmu plant FMU ``name`` (plant_fmus.build), built once."""
    import plant_fmus

    return plant_fmus.build(name, _folder() / "pythonfmu")


@functools.cache
def native_plant(name: str, fmi_version: int = 2) -> Path:
    """The native C plant FMU ``name`` (plant_fmus.native_build.build_native, FMI 2.0 or 3.0) with
    the variables of :func:`python_plant` ``(name)``, built once."""
    from plant_fmus.native_build import build_native

    return build_native(name, _folder() / f"native_fmi{fmi_version}", reference=python_plant(name),
                        fmi_version=fmi_version)
