"""DTS200 three-tank plant FMU (pythonfmu slave; numpy only at run time).

Nonlinear Torricelli dynamics of :mod:`dts200_physics`, integrated with the adaptive
Dormand-Prince 5(4) method of the bundled support module over each communication step.

Signals (names as in dts200.toml): inputs Q1, Q2 (pump flow commands, cm3/s); outputs
h1, h2, h3 (measured levels, cm). Faults: ``f_sensor_h<i>`` (cm), ``f_pump_Q<j>``
(cm3/s, additive on the delivered flow), ``f_leak_T<i>`` (equivalent leak area, cm2,
clipped to >= 0), ``f_clog_13/32/20`` (fraction of the pipe flow lost, clipped to [0, 1]),
plus gain and stuck channels per sensor and pump. Process noise ``std_w_Q<j>`` adds white
noise, held over each communication step, to the delivered pump flow. The delivered flow
is limited to [0, q_max].
"""
from pythonfmu import DefaultExperiment, Fmi2Slave

import dts200_physics as phys
from dts200_support import PlantSlave

_PROCESS_NOISE = tuple(f"std_w_{u}" for u in phys.U)
_LEAKS = tuple(f"f_{n}" for n in phys.LEAKS)
_CLOGS = tuple(f"f_{n}" for n in phys.CLOGS)
_PARAMS = tuple(phys.PARAMS)


class DTS200(PlantSlave, Fmi2Slave):
    description = "Three-tank system DTS200: nonlinear Torricelli dynamics, level sensor, pump, leak and clogging faults"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1000.0, step_size=phys.STEP)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        h0, q0 = phys.operating_point()
        units = phys.UNITS
        self.common_parameters()
        for key, text, unit in (("area", "tank cross-section", "cm2"), ("pipe_area", "pipe cross-section", "cm2"),
                                ("az1", "outflow coefficient T1->T3", ""), ("az2", "outflow coefficient T2->outlet", ""),
                                ("az3", "outflow coefficient T3->T2", ""), ("g", "gravity", "cm/s2"),
                                ("h_max", "tank height (overflow)", "cm"), ("q_max", "pump flow limit", "cm3/s")):
            self.parameter(key, phys.PARAMS[key], text, unit)
        for i, y in enumerate(phys.Y):
            self.parameter(f"{y}_start", h0[i], f"initial level of tank {i + 1}", "cm")
        self.actuators(phys.U, [units[u] for u in phys.U], phys.ACTUATOR_FAULTS,
                       ["flow of pump 1 into T1", "flow of pump 2 into T2"], starts=q0)
        for u in phys.U:
            self.parameter(f"std_w_{u}", 0.0, f"std of white noise on the delivered flow {u}", "cm3/s")
        self.sensors(phys.Y, [units[y] for y in phys.Y], phys.SENSOR_FAULTS, phys.NOISE_STD,
                     [f"level of tank {i + 1}" for i in range(3)])
        for i, name in enumerate(phys.LEAKS):
            self.real_input(f"f_{name}", 0.0, f"equivalent leak area of tank {i + 1} (>= 0)", "cm2")
        for name, pipe in zip(phys.CLOGS, ("T1->T3", "T3->T2", "T2->outlet")):
            self.real_input(f"f_{name}", 0.0, f"clogging of pipe {pipe}: fraction of flow lost, in [0, 1]")
        self.boolean_output("overflow", "a tank is at h_max and spilling")
        self.boolean_output("empty", "a tank level is below D_LAM = 0.01 cm (drained to the laminar film)")

    def _params(self):
        return dict(zip(_PARAMS, map(float, self._get(_PARAMS))))

    def initialize(self):
        p = self._params()
        for key in ("area", "pipe_area", "g", "h_max"):
            if not p[key] > 0:
                raise ValueError(f"parameter {key} must be > 0, got {p[key]}")
        self._x = [float(getattr(self, f"{y}_start")) for y in phys.Y]
        if min(self._x) < 0 or max(self._x) > p["h_max"]:
            raise ValueError(f"initial levels {self._x} must lie in [0, h_max={p['h_max']}]")
        self._publish(p)

    def hold(self):
        p = self._p = self._params()
        self._leak = [max(v, 0.0) for v in self._get(_LEAKS)]
        self._clog = [min(max(v, 0.0), 1.0) for v in self._get(_CLOGS)]
        self._clip = ([0.0] * 3, [p["h_max"]] * 3)
        self._q = self.actuate(self._get(phys.U))  # flows before process noise and limits
        self._rates = None  # (flows, h -> h'): the right-hand side for the last flows

    def advance(self, t, h):
        # plain floats throughout: three states and two pumps cost less in Python than in numpy
        p = self._p
        q_max = p["q_max"]
        q = [min(max(a + w, 0.0), q_max) for a, w in zip(self._q, self.process_noise(_PROCESS_NOISE))]
        if self._rates is None or self._rates[0] != q:
            self._rates = (q, phys.rates_function(q, p, self._leak, self._clog))
        self._x = self.integrate(self._rates[1], self._x, h, clip=self._clip)
        self._publish(p)

    def _publish(self, p):
        self.measure(self._x)
        self.overflow = any(x >= p["h_max"] for x in self._x)
        self.empty = any(x < phys.D_LAM for x in self._x)
