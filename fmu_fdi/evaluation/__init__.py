"""Residual evaluation at design time: evaluator specs and threshold design.

The per-sample logic lives in :mod:`fmu_fdi.runtime`; this package computes the
parameters (thresholds from uncertainty, statistics or data) that the runtime reads.
"""
from .defaults import fault_size_thresholds
from .selector import ThresholdDesign, sensor_gain_plants, threshold_selector

__all__ = ["ThresholdDesign", "threshold_selector", "sensor_gain_plants", "fault_size_thresholds"]
