"""From a plant FMU to a linear model: linearisation, excitation experiments and subspace identification.

This package only *produces* models (nothing else in fmu_fdi imports it):

- :func:`linearise` — a model-exchange FMU (FMI 2 or 3) at an operating point, trimmed to a
  steady state when asked; Jacobians from the FMU's directional derivatives or central
  differences (:mod:`.linearise`).
- :func:`run_experiment` — excitation (multisine or PRBS) of a co-simulation FMU through
  :class:`fmu_fdi.cosim.CoSimulation` (:mod:`.experiment`).
- :func:`moesp` — PO-MOESP subspace identification with order selection (:mod:`.subspace`).
- :func:`~.closed_loop.identify_closed_loop` — a plant in its own loop (model inputs that are FMU
  outputs) from its references: the joint input-output method, then the plant by inversion
  (:mod:`.closed_loop`).
- :func:`validate` — fit (NRMSE %) per output on an independent run, poles, PNG (:mod:`.validation`).
- :func:`innovation_noise`, :func:`measurement_noise` — opt-in noise models (w unit white) of an
  identified model: Kalman innovation form or output-error covariance (:mod:`.noise`).
- :func:`model_from_fmu` — the door (``fmu_fdi.model_from_fmu``, ``fmu-fdi model``): a model at one
  operating point (:mod:`.fmu_model`) or a model set over several (:func:`model_set_from_fmu`,
  :mod:`.envelope`).
"""
from .errors import IdentificationError
from .experiment import Excitation, run_experiment
from .envelope import model_from_fmu, model_set_from_fmu
from .linearise import Linearisation, linearise
from .noise import NoiseModel, innovation_noise, measurement_noise
from .subspace import SubspaceModel, moesp
from .validation import ValidationReport, validate

__all__ = ["IdentificationError", "Excitation", "run_experiment", "model_from_fmu", "model_set_from_fmu", "Linearisation", "linearise",
           "NoiseModel", "innovation_noise", "measurement_noise",
           "SubspaceModel", "moesp", "ValidationReport", "validate"]
