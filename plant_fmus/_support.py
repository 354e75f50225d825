"""Run-time support shared by the plant FMUs: variables with units, sensor and actuator
fault channels, seeded noise, an adaptive Runge-Kutta integrator (nonlinear plants) and the
exact step of a linear ODE with held inputs (linear plants).

This module is bundled into every plant FMU and may import only numpy and pythonfmu.
:func:`plant_fmus.build` copies it into each FMU under a plant-specific module name
(``<prefix>_support``): pythonfmu imports bundled modules by their bare name, so two
FMUs in one process that bundle a module of the same name would share whichever was
imported first (pythonfmu issue 228).

Conventions every plant follows (docs/plant_fmus.md):

- Communication step ``[t_k, t_k + h]``: the inputs set before ``do_step`` are held
  constant over the step (zero-order hold); a nonlinear ODE is integrated with :func:`dopri5`,
  a linear one ``x' = A x + B v`` exactly (:class:`ExactLinear`: no tolerance, one "ODE step"
  per communication step);
  the outputs at ``t_k + h`` are computed at the end of the step from the state and the
  inputs of that step and stay fixed until the next ``do_step``.
- Sensor ``y``: ``y_meas = stuck_value_y`` if ``stuck_y >= 0.5``, else
  ``gain_y * y_true + f_<sensor fault> + std_y * z`` with ``z ~ N(0, 1)``.
- Actuator ``u``: ``u_applied = stuck_value_u`` if ``stuck_u >= 0.5``, else
  ``gain_u * u_command + f_<actuator fault>``.
- Noise: one ``numpy.random.default_rng(seed)`` stream per instance; a fixed number of
  normal draws per step (none with noise off), so a run is reproducible bit by bit for a given
  seed and step sequence, whatever the std values.
- Per-step cost: what a step derives from the inputs (fault channels, noise stds, a plant's
  ``hold()``) is recomputed only after an input or parameter has changed; the vectors of a step
  are lists of floats, with one numpy product per step for a linear plant (small numpy
  operations cost ~1 us each, the FMI call itself a few us).
"""
from __future__ import annotations

import importlib
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
    The arithmetic is on lists of floats: for the few states of a plant it costs a fraction of
    the same sums on small numpy arrays (whose every operation has a fixed cost of ~1 us).

    Parameters
    ----------
    f : callable ``f(x) -> sequence of float`` (``x`` a list); the inputs are held constant over ``span``.
    x : initial state (sequence of float).
    span : length of the interval (> 0).
    rtol, atol : relative and absolute local error tolerances.
    h : first trial step (the proposal returned by the previous call); ``span`` if None.
    clip : optional ``(lo, hi)`` sequences; each accepted state is clipped to them
        (state limits such as an overflowing tank).
    max_steps : bound on accepted + rejected steps.

    Returns
    -------
    x_new (list of float), h_next, n_accepted
    """
    x = [float(v) for v in x]
    n = len(x)
    idx = range(n)
    t = 0.0
    h = span if h is None or not h > 0 else min(h, span)
    k1 = list(f(x))
    n_acc = 0
    (a21,), (a31, a32), (a41, a42, a43), (a51, a52, a53, a54), (a61, a62, a63, a64, a65), \
        (b1, _, b3, b4, b5, b6) = _A[1:]
    e1, _, e3, e4, e5, e6, e7 = _E
    for _ in range(max_steps):
        remaining = span - t
        if remaining <= 1e-12 * span:
            return x, h, n_acc
        step = min(h, remaining)
        k2 = f([x[i] + step * (a21 * k1[i]) for i in idx])
        k3 = f([x[i] + step * (a31 * k1[i] + a32 * k2[i]) for i in idx])
        k4 = f([x[i] + step * (a41 * k1[i] + a42 * k2[i] + a43 * k3[i]) for i in idx])
        k5 = f([x[i] + step * (a51 * k1[i] + a52 * k2[i] + a53 * k3[i] + a54 * k4[i]) for i in idx])
        k6 = f([x[i] + step * (a61 * k1[i] + a62 * k2[i] + a63 * k3[i] + a64 * k4[i] + a65 * k5[i]) for i in idx])
        x_new = [x[i] + step * (b1 * k1[i] + b3 * k3[i] + b4 * k4[i] + b5 * k5[i] + b6 * k6[i]) for i in idx]
        k7 = f(x_new)
        acc = 0.0
        for i in idx:
            err = step * (e1 * k1[i] + e3 * k3[i] + e4 * k4[i] + e5 * k5[i] + e6 * k6[i] + e7 * k7[i])
            acc += (err / (atol + rtol * max(abs(x[i]), abs(x_new[i])))) ** 2
        err = math.sqrt(acc / n)
        if not math.isfinite(err):
            raise FloatingPointError(f"non-finite derivative while integrating at state {x}")
        factor = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        if err <= 1.0:
            t += step
            if clip is not None:
                clipped = [min(max(v, lo), hi) for v, lo, hi in zip(x_new, clip[0], clip[1])]
                if clipped != x_new:
                    x_new, k7 = clipped, f(clipped)
            x, k1 = x_new, list(k7)
            n_acc += 1
            # A step shortened to hit the interval end says nothing about the next one.
            h = step * factor if step == h else max(h, step * factor)
        else:
            h = step * min(1.0, factor)
    raise RuntimeError(
        f"integrator took more than {max_steps} steps for one communication step of {span} s "
        f"(rtol={rtol}, atol={atol}): the step is too long for the dynamics or the state diverges"
    )


def phi1(A, h: float) -> np.ndarray:
    """``Psi = integral_0^h exp(A s) ds`` (= h phi_1(h A)), from the exponential of the augmented
    matrix ``[[A, I], [0, 0]] h`` whose upper right block it is (Van Loan 1978).

    The exponential: scaling and squaring with a Taylor polynomial, ``||M||_1 / 2^s <= 1/2`` and
    terms up to ``(1/2)^k / k! < 1e-18`` (k = 18), so the truncation is far below rounding
    (Moler & Van Loan, "Nineteen dubious ways", method 3; numpy only, as everything in an FMU).
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = A * h
    M[:n, n:] = np.eye(n) * h
    norm = float(np.max(np.sum(np.abs(M), axis=0)))
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    M = M / 2.0 ** s
    E = np.eye(2 * n)
    term = np.eye(2 * n)
    for k in range(1, 19):
        term = term @ M / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E[:n, n:]


class ExactLinear:
    """Exact step of ``x' = A x + B v`` with ``v`` held over the step, and the outputs ``y = C x``
    at its end:

        x_{k+1} = x_k + Psi(h) (A x_k + B v_k),   y_{k+1} = C x_{k+1},

    ``Psi(h) = integral_0^h exp(A s) ds`` (:func:`phi1`). Both are one product with the matrix
    ``W(h) = [[P], [C + C P_x, C P_u]]``, ``P = Psi(h) [A, B] = [P_x, P_u]``, applied to
    ``z = (x_k, v_k)``: ``W z = (x_{k+1} - x_k, y_{k+1})``. The state is advanced by the increment
    ``P z``, not as ``exp(A h) x + Psi B v``: at an equilibrium the increment is zero up to
    rounding, so the state does not drift (two large, nearly cancelling terms would). ``W`` is
    cached per ``h`` (a plant steps with one ``h``; the cache keeps the last ``size``).
    The vectors are lists of floats: one numpy product per step, no other array operation.
    """

    def __init__(self, A, B, C, size: int = 8):
        self.A, self.B, self.C = (np.asarray(M, dtype=float) for M in (A, B, C))
        self.n = self.A.shape[0]
        self.size = size
        self._W = {}
        self._h, self._product = None, None

    def matrix(self, h: float) -> np.ndarray:
        """``W(h)`` (see the class docstring)."""
        W = self._W.get(h)
        if W is None:
            if len(self._W) >= self.size:
                self._W.pop(next(iter(self._W)))
            P = phi1(self.A, h) @ np.hstack([self.A, self.B])
            CP = self.C @ P
            CP[:, :self.n] += self.C
            W = self._W[h] = np.vstack([P, CP])
        return W

    def step(self, x: list, v: list, h: float):
        """``(x_{k+1}, y_{k+1})`` as lists from ``x_k`` and ``v_k`` (lists)."""
        if h != self._h:
            self._h, self._product = h, self.matrix(h).dot  # the bound method: half the cost of @
        w = self._product(np.array(x + v)).tolist()
        n = self.n
        return [a + b for a, b in zip(x, w[:n])], w[n:]


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


def _guard_exit(slave) -> None:
    """Guard the host against pythonfmu 0.7's exit-time use-after-free (see the bundled
    ``<prefix>_exit_guard`` module, fmu_fdi/fmu/exit_guard.py); outside an FMU (no bundled
    guard next to this module) there is nothing to guard."""
    if not __name__.endswith("_support") or "." in __name__:
        return
    guard = importlib.import_module(__name__[:-len("_support")] + "_exit_guard")
    guard.guard_slave(slave, type(slave).__name__)


class PlantSlave:
    """Mixin for the plant slaves (deliberately not an ``Fmi2Slave`` subclass, so each
    FMU's slave module holds exactly one ``Fmi2Slave`` subclass for pythonfmu to find).

    A plant class derives from ``(PlantSlave, Fmi2Slave)``, declares its variables in
    ``__init__`` with the helpers below and implements ``initialize()`` (state at the
    start time, first outputs), ``advance(t, h)`` (one communication step) and, for what it
    derives from its inputs and tunable parameters, ``hold()`` (run before the first step and
    after any change of a variable; ``advance`` reads what it held).
    Exceptions never reach the host (pythonfmu would turn them into fmi2Fatal): they are
    logged with ``Fmi2Status.error`` and ``do_step`` returns False, which pythonfmu
    reports as fmi2Discard; every later step fails the same way.
    """

    # ------------------------------------------------------------ declaration
    def _declare(self, cls, name, start, causality, variability, description, unit="", initial=None):
        if not hasattr(self, "_units"):  # the first declaration: set-up of the instance
            self._units, self._real_inputs = [], []
            self._failed = None
            _guard_exit(self)
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
        self.parameter("rtol", rtol, "relative local error tolerance of the Dormand-Prince 5(4) integrator "
                                     "(nonlinear plants; a linear plant is integrated exactly)")
        self.parameter("atol", atol, "absolute local error tolerance of the integrator (state units; "
                                     "nonlinear plants)")
        self._declare(Integer, "ode_steps", 0, Fmi2Causality.output, Fmi2Variability.discrete,
                      "accepted integrator steps since the start (bounds the global integration error; "
                      "a linear plant counts one exact step per communication step)")

    def sensors(self, names, units, fault_names, stds, descriptions):
        """Measured outputs with their fault channels and noise std parameters."""
        self._sensor_names = tuple(names)
        for y, unit, fault, std, text in zip(names, units, fault_names, stds, descriptions):
            self.real_output(y, f"measured {text}", unit)
            self.real_input(f"f_{fault}", 0.0, f"additive fault on sensor {y} (model fault '{fault}')", unit)
            self.real_input(f"gain_{y}", 1.0, f"gain of sensor {y} (gain fault: != 1)")
            self.real_input(f"stuck_{y}", 0.0, f">= 0.5: sensor {y} stuck at stuck_value_{y}")
            self.real_input(f"stuck_value_{y}", 0.0, f"value sensor {y} is stuck at", unit)
            self.parameter(f"std_{y}", std, f"standard deviation of the white noise on sensor {y}", unit)
        self._sensor_faults = tuple(f"f_{fault}" for fault in fault_names)
        self._sensor_fields = tuple(tuple(f"{p}{y}" for y in names) for p in ("gain_", "std_", "stuck_", "stuck_value_"))

    def actuators(self, names, units, fault_names, descriptions, inputs=True, starts=None):
        """Actuators: the command is an input (``inputs``) or an output set by a controller."""
        self._actuator_names = tuple(names)
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
        self._actuator_faults = tuple(f"f_{fault}" for fault in fault_names)
        self._actuator_fields = tuple(tuple(f"{p}{u}" for u in names) for p in ("gain_", "stuck_", "stuck_value_"))

    def _values(self, names) -> np.ndarray:
        return np.array(self._get(names), dtype=float)

    def _get(self, names) -> tuple:
        """The current values of ``names`` (a tuple of variable names) as a tuple: the variables
        live in the instance dict, and one C-level map over it is what keeps a step cheap."""
        try:
            return tuple(map(self.__dict__.__getitem__, names))
        except KeyError:  # a name that is a property or class attribute
            return tuple([getattr(self, n) for n in names])

    # ------------------------------------------------ held inputs (per-step constants)
    # Inputs change only through the FMI setters (and fmi2SetFMUstate): ``set_real`` marks the
    # instance when a value actually changes, and the next step checks the inputs and refreshes
    # what it derives from them (fault channels, noise stds, the plant's ``hold()``). A step with
    # unchanged inputs (the common case: a master writes every input at every step) does none
    # of that work.

    def _refresh(self):
        """Check the inputs and recompute everything held (after any change of a variable)."""
        self._check_inputs()
        self._refresh_channels()
        self.hold()
        self._changed = False

    def _refresh_channels(self):
        """Sensor channels ``(gain, fault, std, stuck, stuck value)``, actuator channels
        ``(gain, fault, stuck, stuck value)``, process-noise stds."""
        get = self._get
        if hasattr(self, "_sensor_names"):
            gain, std, stuck, value = self._sensor_fields
            std = get(std) if self.noise_enable else (0.0,) * len(std)
            self._sensor_channels = tuple(zip(get(gain), get(self._sensor_faults), std,
                                              [s >= 0.5 for s in get(stuck)], get(value)))
        if hasattr(self, "_actuator_names"):
            gain, stuck, value = self._actuator_fields
            self._actuator_channels = tuple(zip(get(gain), get(self._actuator_faults),
                                                [s >= 0.5 for s in get(stuck)], get(value)))
        self._noise_stds = {}

    def hold(self):
        """Plant hook: recompute what the plant derives from its inputs and tunable parameters
        (called before the first step and before any step that follows a change of them)."""

    def _normals(self, n: int) -> list:
        """The next ``n`` standard normal draws of the instance's stream. Drawn in blocks: a
        ``Generator`` fills an array draw by draw, so a block is the same sequence as draws
        of any other sizes in the same order (the stream is reproducible bit by bit)."""
        i = self._z_next
        j = i + n
        if j > len(self._z_block):
            self._z_block = self._z_block[i:] + self._rng.standard_normal(max(1024, n)).tolist()
            i, j = 0, n
        self._z_next = j
        return self._z_block[i:j]

    # ---------------------------------------------------------- fault channels
    def measure(self, y_true) -> list:
        """Measured outputs from the true ones (floats); draws one normal per sensor; sets the outputs."""
        channels = self._sensor_channels
        z = self._normals(len(channels)) if self.noise_enable else (0.0,) * len(channels)
        y = [value if stuck else g * yt + f + sd * zz
             for yt, zz, (g, f, sd, stuck, value) in zip(y_true, z, channels)]
        self.__dict__.update(zip(self._sensor_names, y))
        return y

    def actuate(self, u_command) -> list:
        """Input applied to the plant from the command (floats; see the module docstring)."""
        return [value if stuck else g * u + f for u, (g, f, stuck, value) in zip(u_command, self._actuator_channels)]

    def process_noise(self, std_names) -> list:
        """One normal draw per process-noise channel, scaled by its std (held over the step)."""
        stds = self._noise_stds.get(std_names)
        if stds is None:
            stds = self._noise_stds[std_names] = tuple(map(float, self._get(std_names)))
        if not self.noise_enable:
            return [0.0] * len(std_names)
        return [s * z for s, z in zip(stds, self._normals(len(std_names)))]

    def integrate(self, f, x, h, clip=None):
        """:func:`dopri5` over one communication step, remembering the step-size proposal."""
        x, self._h_ode, n_accepted = dopri5(f, x, h, self.rtol, self.atol, self._h_ode, clip)
        self.ode_steps += n_accepted
        return x

    def step_linear(self, system: ExactLinear, x: list, v: list, h: float):
        """One exact step of a linear plant (:class:`ExactLinear`); counts as one ODE step.
        Returns ``(x_{k+1}, y_{k+1})`` as lists."""
        self.ode_steps += 1
        return system.step(x, v, h)

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
            self._rng = np.random.default_rng(int(self.seed))
            self._z_block, self._z_next = [], 0
            self._h_ode, self.ode_steps = None, 0
            self._real_names = {vr: v.name for vr, v in self.vars.items()
                                if isinstance(v, Real) and v.name in self.__dict__}
            self._real_settable = {vr: name for vr, name in self._real_names.items()
                                   if self.vars[vr].setter is not None}
            self._check_inputs()
            self._refresh_channels()
            self.initialize()
            self._changed = True  # the first step refreshes all, hold() included
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
            if self._changed:
                self._refresh()
            self.advance(current_time, step_size)
            return True
        except Exception as exc:  # noqa: BLE001 - nothing may reach the host
            self._failed = f"step at t={current_time} failed: {type(exc).__name__}: {exc}"
            self.log(self._failed, Fmi2Status.error)
            return False

    def _check_inputs(self):
        values = self._get(self._real_inputs)
        if not math.isfinite(sum(values)):  # one sum: non-finite iff an input is (or it overflows)
            bad = [(n, v) for n, v in zip(self._real_inputs, values) if not math.isfinite(v)]
            if bad:
                raise ValueError(f"input {bad[0][0]} is {bad[0][1]}; inputs must be finite")

    def get_real(self, vrs):
        """pythonfmu's ``get_real`` (same values, same errors), with the Real variables read
        from the instance dict by one map instead of a getter call per variable."""
        try:
            return list(map(float, map(self.__dict__.__getitem__, map(self._real_names.__getitem__, vrs))))
        except (KeyError, AttributeError, TypeError):  # not a Real variable, or before initialisation
            return super().get_real(vrs)

    def set_real(self, vrs, values):
        """pythonfmu's ``set_real`` (same effect, same errors), noting whether a value changed:
        the next step then checks the inputs and refreshes what is held (see ``_refresh``)."""
        names, d = getattr(self, "_real_settable", None), self.__dict__
        if names is None or len(vrs) != len(values) or not all(map(names.__contains__, vrs)):
            self._changed = True
            return super().set_real(vrs, values)
        for vr, value in zip(vrs, values):
            name = names[vr]
            if d[name] != value:  # a NaN always differs: it is then checked
                self._changed = True
            d[name] = value

    def set_integer(self, vrs, values):
        self._changed = True
        return super().set_integer(vrs, values)

    def set_boolean(self, vrs, values):
        self._changed = True
        return super().set_boolean(vrs, values)

    def _set_fmu_state(self, state):
        self._changed = True
        return super()._set_fmu_state(state)

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
