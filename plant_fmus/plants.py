"""The registry of benchmark plants: name -> :class:`~plant_fmus.registry.Plant`."""
from __future__ import annotations

from pathlib import Path

from .dr300 import PLANT as _DR300
from .dts200 import PLANT as _DTS200
from .lateral_aircraft import PLANT as _LATERAL
from .vtol import PLANT as _VTOL
from .wind_turbine import PLANT as _WIND

#: Every plant FMU this package builds, by name.
PLANTS = {p.name: p for p in (_DTS200, _DR300, _VTOL, _WIND, _LATERAL)}


def model_path(name: str, index: int = 0) -> Path:
    """Path of the plant's model file (``index`` selects one when a plant has several)."""
    try:
        files = PLANTS[name].model_files
    except KeyError:
        raise KeyError(f"unknown plant {name!r}; plants are {sorted(PLANTS)}") from None
    if not -len(files) <= index < len(files):
        raise IndexError(f"plant '{name}' has {len(files)} model file(s), no index {index}")
    return files[index]


def linear_models(name: str) -> list:
    """The plant's linear models (``FDIModel``), freshly computed from its parameters, in
    the order of ``PLANTS[name].model_files``."""
    return PLANTS[name].linear_models()


def write_model_files(names=None) -> list[Path]:
    """Recompute the model files of the given plants (default all) and write them."""
    written = []
    for name in names or PLANTS:
        for model, path in zip(linear_models(name), PLANTS[name].model_files):
            written.append(model.to_file(path))
    return written
