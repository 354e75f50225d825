"""Build the plant FMUs with pythonfmu."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from .plants import PLANTS


def build(name: str, out_dir) -> Path:
    """Build the plant FMU ``name`` into ``out_dir``; returns ``out_dir/<name>.fmu``.

    The slave, the shared support module (copied as ``<prefix>_support.py``), the
    plant's numpy-only helpers and its model files are staged in a temporary folder and
    handed to ``pythonfmu.builder.FmuBuilder.build_FMU``; the model files end up in the
    FMU's ``resources/``.
    """
    from fmu_fdi.fmu.packaging import installed_pythonfmu, isolated_imports

    try:
        plant = PLANTS[name]
    except KeyError:
        raise KeyError(f"unknown plant {name!r}; plants are {sorted(PLANTS)}") from None
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"plant_{name}_") as tmp:
        stage = Path(tmp)
        script = stage / plant.slave.name
        shutil.copy2(plant.slave, script)
        project = []
        for source, bundled in plant.bundle():
            shutil.copy2(source, stage / bundled)
            project.append(stage / bundled)
        for model_file in plant.model_files:
            shutil.copy2(model_file, stage / model_file.name)
            project.append(stage / model_file.name)
        modules = [script.stem] + [p.stem for p in project if p.suffix == ".py"]
        # fresh imports of the slave's modules (a plant FMU that ran in this process left
        # them bound to its own pythonfmu copy) and the installed pythonfmu; restored after
        with isolated_imports(*modules), installed_pythonfmu():
            from pythonfmu.builder import FmuBuilder

            return Path(FmuBuilder.build_FMU(script, dest=out_dir / f"{name}.fmu", project_files=project))


def build_all(out_dir) -> list[Path]:
    """Build every plant of :data:`PLANTS` into ``out_dir``."""
    return [build(name, out_dir) for name in PLANTS]
