"""Residual evaluation at design time: evaluator specs and threshold design.

The per-sample logic lives in :mod:`fmu_fdi.runtime`; this package computes the
parameters (thresholds from uncertainty, statistics or data) that the runtime reads.

- :func:`analytic_threshold`: a fixed threshold for a false-alarm probability α of a
  Gaussian residual, from the generator's internal form and the noise covariance;
  :func:`residual_autocovariance` is the stationary autocovariance behind it.
- :func:`data_driven_threshold`: a fixed threshold for a false-alarm rate, with a stated
  confidence, from fault-free evaluation records; :func:`log_threshold` (``data:RATE``) falls
  back to :func:`gaussian_threshold`, a Gaussian fit of the residuals, when the log holds too
  few effective samples of the evaluation.
"""
from .analytic import analytic_threshold
from .covariance import residual_autocovariance
from .datadriven import ThresholdEstimate, data_driven_threshold
from .defaults import default_thresholds, fault_size_thresholds
from .gaussfit import gaussian_threshold, log_threshold
from .selector import ThresholdDesign, sensor_gain_plants, threshold_selector

__all__ = ["ThresholdDesign", "threshold_selector", "sensor_gain_plants", "fault_size_thresholds",
           "default_thresholds", "analytic_threshold", "residual_autocovariance", "data_driven_threshold", "ThresholdEstimate",
           "gaussian_threshold", "log_threshold"]
