"""Run-time support shared by the plant FMUs: variables with units, sensor and actuator
fault channels, seeded noise and an adaptive Runge-Kutta integrator.

This module is bundled into every plant FMU and may import only numpy and pythonfmu.
:func:`plant_fmus.build` copies it into each FMU under a plant-specific module name
(``<prefix>_support``): pythonfmu imports bundled modules by their bare name, so two
FMUs in one process that bundle a module of the same name would share whichever was
imported first (pythonfmu issue 228).

Conventions every plant follows (docs/plant_fmus.md):

- Communication step ``[t_k, t_k + h]``: the inputs set before ``do_step`` are held
  constant over the step (zero-order hold); the ODE is integrated with :func:`dopri5`;
  the outputs at ``t_k + h`` are computed at the end of the step from the state and the
  inputs of that step and stay fixed until the next ``do_step``.
- Sensor ``y``: ``y_meas = stuck_value_y`` if ``stuck_y >= 0.5``, else
  ``gain_y * y_true + f_<sensor fault> + std_y * z`` with ``z ~ N(0, 1)``.
- Actuator ``u``: ``u_applied = stuck_value_u`` if ``stuck_u >= 0.5``, else
  ``gain_u * u_command + f_<actuator fault>``.
- Noise: one ``numpy.random.default_rng(seed)`` stream per instance; a fixed number of
  normal draws per step, so a run is reproducible bit by bit for a given seed and step
  sequence, whatever the std values.
"""
from __future__ import annotations

import math
from xml.etree.ElementTree import Element, SubElement

import numpy as np
from pythonfmu import Boolean, Fmi2Causality, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

# Dormand-Prince 5(4) tableau (Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., Table II.5.2).
_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
# Error weights: 5th-order minus embedded 4th-order solution.
_E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)


def dopri5(f, x, span: float, rtol: float, atol: float, h: float | None = None,
           clip=None, max_steps: int = 100_000):
    """Integrate the autonomous ODE ``x' = f(x)`` over ``span`` with Dormand-Prince 5(4).

    Local error control per accepted step: ``rms(err_i / (atol + rtol max(|x_i|, |x_new_i|))) <= 1``,
    step factor ``0.9 err^(-1/5)`` limited to [0.2, 5] (Hairer et al., section II.4).

    Parameters
    ----------
    f : callable ``f(x) -> ndarray``; the inputs are held constant over ``span``.
    x : initial state.
    span : length of the interval (> 0).
    rtol, atol : relative and absolute local error tolerances.
    h : first trial step (the proposal returned by the previous call); ``span`` if None.
    clip : optional ``(lo, hi)`` arrays; each accepted state is clipped to them
        (state limits such as an overflowing tank).
    max_steps : bound on accepted + rejected steps.

    Returns
    -------
    x_new, h_next, n_accepted
    """
    x = np.array(x, dtype=float)
    t = 0.0
    h = span if h is None or not h > 0 else min(h, span)
    k1 = f(x)
    n_acc = 0
    for _ in range(max_steps):
        remaining = span - t
        if remaining <= 1e-12 * span:
            return x, h, n_acc
        step = min(h, remaining)
        k = [k1]
        for row in _A[1:6]:
            k.append(f(x + step * sum(a * kj for a, kj in zip(row, k) if a)))
        x_new = x + step * sum(a * kj for a, kj in zip(_A[6], k) if a)
        k7 = f(x_new)
        err_vec = step * (sum(e * kj for e, kj in zip(_E, k) if e) + _E[6] * k7)
        scale = atol + rtol * np.maximum(np.abs(x), np.abs(x_new))
        err = math.sqrt(float(np.mean((err_vec / scale) ** 2)))
        if not math.isfinite(err):
            raise FloatingPointError(f"non-finite derivative while integrating at state {x.tolist()}")
        factor = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        if err <= 1.0:
            t += step
            if clip is not None:
                clipped = np.clip(x_new, clip[0], clip[1])
                if np.any(clipped != x_new):
                    x_new, k7 = clipped, f(clipped)
            x, k1 = x_new, k7
            n_acc += 1
            # A step shortened to hit the interval end says nothing about the next one.
            h = step * factor if step == h else max(h, step * factor)
        else:
            h = step * min(1.0, factor)
    raise RuntimeError(
        f"integrator took more than {max_steps} steps for one communication step of {span} s "
        f"(rtol={rtol}, atol={atol}): the step is too long for the dynamics or the state diverges"
    )


class _RealWithUnit(Real):
    """pythonfmu ``Real`` that also writes the FMI ``unit`` attribute."""

    def __init__(self, name, unit: str = "", **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self) -> Element:
        node = super().to_xml()
        if self.unit:
            node.find("Real").set("unit", self.unit)
        return node


class PlantSlave:
    """Mixin for the plant slaves (deliberately not an ``Fmi2Slave`` subclass, so each
    FMU's slave module holds exactly one ``Fmi2Slave`` subclass for pythonfmu to find).

    A plant class derives from ``(PlantSlave, Fmi2Slave)``, declares its variables in
    ``__init__`` with the helpers below and implements ``initialize()`` (state at the
    start time, first outputs) and ``advance(t, h)`` (one communication step).
    Exceptions never reach the host (pythonfmu would turn them into fmi2Fatal): they are
    logged with ``Fmi2Status.error`` and ``do_step`` returns False, which pythonfmu
    reports as fmi2Discard; every later step fails the same way.
    """

    # ------------------------------------------------------------ declaration
    def _declare(self, cls, name, start, causality, variability, description, unit="", initial=None):
        if not hasattr(self, "_units"):
            self._units, self._real_inputs = [], []
            self._failed = None
        setattr(self, name, start)
        kwargs = dict(causality=causality, variability=variability, description=description)
        if initial is not None:
            kwargs["initial"] = initial
        if cls is Real:
            var = _RealWithUnit(name, unit=unit, **kwargs)
            if unit and unit not in self._units:
                self._units.append(unit)
        else:
            var = cls(name, **kwargs)
        self.register_variable(var)
        if cls is Real and causality == Fmi2Causality.input:
            self._real_inputs.append(name)

    def parameter(self, name, start, description, unit="", tunable=False):
        """Real parameter (fixed unless ``tunable``)."""
        self._declare(Real, name, float(start), Fmi2Causality.parameter,
                      Fmi2Variability.tunable if tunable else Fmi2Variability.fixed, description, unit)

    def real_input(self, name, start, description, unit=""):
        self._declare(Real, name, float(start), Fmi2Causality.input, Fmi2Variability.continuous,
                      description, unit)

    def real_output(self, name, description, unit=""):
        self._declare(Real, name, 0.0, Fmi2Causality.output, Fmi2Variability.continuous, description, unit)

    def boolean_output(self, name, description):
        self._declare(Boolean, name, False, Fmi2Causality.output, Fmi2Variability.discrete, description)

    def common_parameters(self, rtol=1e-8, atol=1e-10):
        """``seed``, ``noise_enable`` and the integrator tolerances ``rtol``, ``atol``."""
        self._declare(Integer, "seed", 0, Fmi2Causality.parameter, Fmi2Variability.fixed,
                      "seed of the noise generator (numpy PCG64), >= 0")
        self._declare(Boolean, "noise_enable", True, Fmi2Causality.parameter, Fmi2Variability.fixed,
                      "false: all noise off, whatever the std parameters")
        self.parameter("rtol", rtol, "relative local error tolerance of the Dormand-Prince 5(4) integrator")
        self.parameter("atol", atol, "absolute local error tolerance of the integrator (state units)")
        self._declare(Integer, "ode_steps", 0, Fmi2Causality.output, Fmi2Variability.discrete,
                      "accepted integrator steps since the start (bounds the global integration error)")

    def sensors(self, names, units, fault_names, stds, descriptions):
        """Measured outputs with their fault channels and noise std parameters."""
        self._sensor_names = list(names)
        for y, unit, fault, std, text in zip(names, units, fault_names, stds, descriptions):
            self.real_output(y, f"measured {text}", unit)
            self.real_input(f"f_{fault}", 0.0, f"additive fault on sensor {y} (model fault '{fault}')", unit)
            self.real_input(f"gain_{y}", 1.0, f"gain of sensor {y} (gain fault: != 1)")
            self.real_input(f"stuck_{y}", 0.0, f">= 0.5: sensor {y} stuck at stuck_value_{y}")
            self.real_input(f"stuck_value_{y}", 0.0, f"value sensor {y} is stuck at", unit)
            self.parameter(f"std_{y}", std, f"standard deviation of the white noise on sensor {y}", unit)
        self._sensor_faults = [f"f_{fault}" for fault in fault_names]

    def actuators(self, names, units, fault_names, descriptions, inputs=True, starts=None):
        """Actuators: the command is an input (``inputs``) or an output set by a controller."""
        self._actuator_names = list(names)
        starts = starts if starts is not None else [0.0] * len(names)
        for u, unit, fault, text, start in zip(names, units, fault_names, descriptions, starts):
            if inputs:
                self.real_input(u, start, f"command: {text}", unit)
            else:
                self.real_output(u, f"controller command (model input): {text}", unit)
            self.real_input(f"f_{fault}", 0.0, f"additive fault on actuator {u} (model fault '{fault}')", unit)
            self.real_input(f"gain_{u}", 1.0, f"effectiveness of actuator {u} (gain fault: != 1)")
            self.real_input(f"stuck_{u}", 0.0, f">= 0.5: actuator {u} stuck at stuck_value_{u}")
            self.real_input(f"stuck_value_{u}", 0.0, f"value actuator {u} is stuck at", unit)
        self._actuator_faults = [f"f_{fault}" for fault in fault_names]

    def _values(self, names) -> np.ndarray:
        return np.array([getattr(self, n) for n in names], dtype=float)

    # ---------------------------------------------------------- fault channels
    def measure(self, y_true) -> np.ndarray:
        """Measured outputs from the true ones; draws one normal per sensor; sets the outputs."""
        names = self._sensor_names
        z = self._rng.standard_normal(len(names))
        std = self._values([f"std_{y}" for y in names]) if self.noise_enable else np.zeros(len(names))
        gain = self._values([f"gain_{y}" for y in names])
        y = gain * np.asarray(y_true, float) + self._values(self._sensor_faults) + std * z
        stuck = self._values([f"stuck_{y}" for y in names]) >= 0.5
        y = np.where(stuck, self._values([f"stuck_value_{y}" for y in names]), y)
        for nm, val in zip(names, y):
            setattr(self, nm, float(val))
        return y

    def actuate(self, u_command) -> np.ndarray:
        """Input applied to the plant from the command (see the module docstring)."""
        names = self._actuator_names
        u = self._values([f"gain_{n}" for n in names]) * np.asarray(u_command, float) \
            + self._values(self._actuator_faults)
        stuck = self._values([f"stuck_{n}" for n in names]) >= 0.5
        return np.where(stuck, self._values([f"stuck_value_{n}" for n in names]), u)

    def process_noise(self, std_names) -> np.ndarray:
        """One normal draw per process-noise channel, scaled by its std (held over the step)."""
        z = self._rng.standard_normal(len(std_names))
        return self._values(std_names) * z if self.noise_enable else np.zeros(len(std_names))

    def integrate(self, f, x, h, clip=None):
        """:func:`dopri5` over one communication step, remembering the step-size proposal."""
        x, self._h_ode, n_accepted = dopri5(f, x, h, self.rtol, self.atol, self._h_ode, clip)
        self.ode_steps += n_accepted
        return x

    # ---------------------------------------------------------------- FMI side
    def exit_initialization_mode(self):
        try:
            for name in ("rtol", "atol"):
                if not getattr(self, name) > 0:
                    raise ValueError(f"parameter {name} must be > 0, got {getattr(self, name)}")
            if int(self.seed) < 0:
                raise ValueError(f"parameter seed must be >= 0, got {self.seed}")
            for var in self.vars.values():
                if var.name.startswith("std_") and not getattr(self, var.name) >= 0:
                    raise ValueError(f"parameter {var.name} must be >= 0, got {getattr(self, var.name)}")
            self._check_inputs()
            self._rng = np.random.default_rng(int(self.seed))
            self._h_ode, self.ode_steps = None, 0
            self.initialize()
            self._failed = None
        except Exception as exc:  # noqa: BLE001 - nothing may reach the host
            self._failed = f"initialisation failed: {type(exc).__name__}: {exc}"
            self.log(self._failed, Fmi2Status.error)

    def do_step(self, current_time, step_size):
        if self._failed:
            self.log(f"cannot step: {self._failed}", Fmi2Status.error)
            return False
        try:
            if not step_size > 0:
                raise ValueError(f"communication step must be > 0, got {step_size}")
            self._check_inputs()
            self.advance(current_time, step_size)
            return True
        except Exception as exc:  # noqa: BLE001 - nothing may reach the host
            self._failed = f"step at t={current_time} failed: {type(exc).__name__}: {exc}"
            self.log(self._failed, Fmi2Status.error)
            return False

    def _check_inputs(self):
        for name in self._real_inputs:
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"input {name} is {value}; inputs must be finite")

    def to_xml(self, model_options=None) -> Element:
        """Model description with ``<UnitDefinitions>`` for the units the variables use and
        the ``<InitialUnknowns>`` FMI 2.0 requires (every output is computed at
        initialisation), both of which pythonfmu leaves out."""
        root = super().to_xml(model_options or {})
        structure = root.find("ModelStructure")
        outputs = structure.find("Outputs")
        if outputs is not None:
            initial = SubElement(structure, "InitialUnknowns")
            for unknown in outputs:
                initial.append(Element("Unknown", {"index": unknown.get("index")}))
        if self._units:
            units = Element("UnitDefinitions")
            for unit in self._units:
                units.append(Element("Unit", {"name": unit}))
            root.insert(1, units)  # schema order: CoSimulation, UnitDefinitions, ..., ModelVariables
        return root
