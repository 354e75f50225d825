"""Benchmark plant FMUs for fmu-fdi (FMI 2.0 co-simulation, built with pythonfmu).

Each plant ships a pythonfmu slave (numpy only at run time) with fault-injection inputs,
seeded process and measurement noise and disturbance inputs, plus the linear model file
(TOML, format fmu-fdi-model/1) that a diagnosis is designed from, computed from the plant
parameters. See docs/plant_fmus.md for the conventions and the per-plant signal tables.

>>> import plant_fmus
>>> sorted(plant_fmus.PLANTS)  # doctest: +SKIP
>>> fmu = plant_fmus.build("dts200", "out")  # doctest: +SKIP
"""
from .build import build, build_all
from .plants import PLANTS, linear_models, model_path, write_model_files
from .registry import FaultInput, Plant

__all__ = ["PLANTS", "Plant", "FaultInput", "build", "build_all", "model_path", "linear_models",
           "write_model_files"]
