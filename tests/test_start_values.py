"""Start values a master may set before initialisation (issue 18): the one FMI 2/3 rule
(fmu_fdi/cosim/startvalues.py) as `fmu-fdi simulate --param`, co-simulations (what campaigns run) and
`fmu-fdi model --at` apply it; and units/declaredTypes carried from the plant FMU into the model file."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from fmu_fdi.cosim.startvalues import refusal

STATE_PLANT = '''
import math
from pythonfmu import Fmi2Slave, Fmi2Causality, Fmi2Initial, Fmi2Variability, Real


class {cls}(Fmi2Slave):
    """x' = -x + u with x an output whose start value a master may set (initial="exact", start 1);
    z = 2 x an output the FMU calculates (initial="calculated"), integrated exactly for u held."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.5
        self.x = 1.0
        self.z = 2.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact))
        self.register_variable(Real("z", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.calculated))

    def exit_initialization_mode(self):
        self.z = 2.0 * self.x

    def do_step(self, t, h):
        e = math.exp(-h)
        self.x = e * self.x + (1.0 - e) * self.u
        self.z = 2.0 * self.x
        return True
'''


@pytest.fixture(scope="module")
def state_plant(tmp_path_factory):
    from cosim_fmus import _pythonfmu

    return _pythonfmu(tmp_path_factory.mktemp("startvalues"), STATE_PLANT, "startvalue")


def _var(causality, variability, initial=None):
    return SimpleNamespace(causality=causality, variability=variability, initial=initial)


# FMI 2.0 sec. 2.2.7 / FMI 3.0 sec. 2.4.7: (causality, variability, initial as declared) -> settable before init
RULE = [
    (("parameter", "fixed", None), True), (("parameter", "tunable", "exact"), True),
    (("input", "continuous", None), True), (("input", "discrete", None), True),
    (("output", "continuous", "exact"), True), (("output", "discrete", "approx"), True),
    (("local", "continuous", "exact"), True), (("local", "fixed", "approx"), True),
    (("output", "continuous", None), False),        # default initial: calculated
    (("output", "continuous", "calculated"), False), (("local", "tunable", None), False),
    (("calculatedParameter", "fixed", None), False), (("calculatedParameter", "fixed", "approx"), False),
    (("output", "constant", "exact"), False), (("independent", "continuous", None), False),
    (("structuralParameter", "fixed", "exact"), False),
]


@pytest.mark.parametrize("attrs,settable", RULE)
def test_the_rule_follows_the_fmi_tables(attrs, settable):
    why = refusal(_var(*attrs))
    assert (why is None) == settable, (attrs, why)
    if not settable:
        assert why and "\n" not in why


def _cli(*args):
    """``fmu-fdi ARGS`` in this process (the same ``main`` a user's shell runs; no start-up cost)."""
    from test_cli_guidance import cli_here

    return cli_here(*args)


def test_simulate_sets_a_state_output_declared_exact(state_plant, tmp_path):
    """`--param plant.x=0.25` starts the state there (fmpy and fmusim accept it too): every row is the exact
    solution x(t) = u + (x0 - u) e^(-t) from x0 = 0.25, not from the FMU's start value 1."""
    out = tmp_path / "out.csv"
    r = _cli("simulate", "--plant", f"plant={state_plant}", "--stop", 1, "--step", 0.1, "--param", "plant.x=0.25",
             "-o", out)
    assert r.returncode == 0, r.stderr
    rows = np.genfromtxt(out, delimiter=",", names=True, deletechars="")
    t = rows["time"]
    assert np.allclose(rows["plant.x"], 0.5 + (0.25 - 0.5) * np.exp(-t), rtol=0, atol=1e-12)
    assert math.isclose(rows["plant.z"][0], 0.5, abs_tol=1e-12)  # computed by the FMU from the set start


def test_simulate_refuses_a_calculated_output_in_one_line(state_plant, tmp_path):
    r = _cli("simulate", "--plant", f"plant={state_plant}", "--stop", 1, "--step", 0.1, "--param", "plant.z=1",
             "-o", tmp_path / "out.csv")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    line, = r.stderr.strip().splitlines()
    assert "plant.z" in line and 'initial="calculated"' in line and "cannot be set before initialisation" in line
    assert not (tmp_path / "out.csv").exists() or (tmp_path / "out.csv").stat().st_size == 0


def test_cosimulation_as_campaigns_run_it_takes_the_start_value(state_plant):
    """Campaigns hand their [parameters] to CoSimulation (campaign/spec.py check and execute.py): the same rule."""
    from fmu_fdi.cosim import CoSimulation, CoSimulationError

    res = CoSimulation({"plant": state_plant}, None, None, step=0.5, stop=1.0, parameters={"plant.x": 0.5}).run()
    assert np.allclose(res["plant.x"], 0.5, rtol=0, atol=1e-12)  # started at the equilibrium u = 0.5: stays
    with pytest.raises(CoSimulationError, match='initial="calculated"'):
        CoSimulation({"plant": state_plant}, None, None, step=0.5, stop=1.0, parameters={"plant.z": 0.5})


def test_model_at_takes_a_start_value_and_refuses_what_fmi_does_not_allow(state_plant):
    """`fmu-fdi model --at x=0.5`: the plant starts at its operating point (x = u = 0.5, recorded among the values
    set); `--at z=1` is refused by the same rule before any experiment runs."""
    from fmu_fdi.identify import IdentificationError, model_from_fmu
    from fmu_fdi.identify.experiment import Excitation

    with pytest.raises(IdentificationError, match='--at z: cannot be set before initialisation.*initial="calculated"'):
        model_from_fmu(state_plant, inputs=["u"], outputs=["x"], at={"z": 1.0})
    with pytest.raises(IdentificationError, match="no variable 'nope'"):
        model_from_fmu(state_plant, inputs=["u"], outputs=["x"], at={"nope": 1.0})
    m = model_from_fmu(state_plant, inputs=["u"], outputs=["x"], at={"x": 0.5}, ts=0.1,
                       excitation=Excitation(signal="prbs", period=5, amplitude=0.2, samples=400, settle=2.0))
    assert "x=0.5" in m.provenance["parameters"]
    # the identified first-order plant: pole -1, gain 1 (x' = -x + u), exactly for this noise-free plant
    assert np.allclose(np.linalg.eigvals(m.A), [-1.0], atol=1e-6)
    assert math.isclose(float(m.lti("u").dcgain()[0, 0]), 1.0, abs_tol=1e-6)


# ---- units and declaredTypes in the model file ---------------------------------------------------------------

MD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="typed" guid="{0}">
  <CoSimulation modelIdentifier="typed"/>
  <UnitDefinitions><Unit name="rad"/><Unit name="N.m"/></UnitDefinitions>
  <TypeDefinitions>
    <SimpleType name="Modelica.Units.SI.Angle"><Real quantity="Angle" unit="rad"/></SimpleType>
    <SimpleType name="Modelica.Units.SI.Torque"><Real quantity="Torque" unit="N.m"/></SimpleType>
  </TypeDefinitions>
  <ModelVariables>
    <ScalarVariable name="tau" valueReference="0" causality="input" variability="continuous">
      <Real declaredType="Modelica.Units.SI.Torque" start="0"/></ScalarVariable>
    <ScalarVariable name="phi" valueReference="1" causality="output" variability="continuous">
      <Real declaredType="Modelica.Units.SI.Angle" unit="rad"/></ScalarVariable>
    <ScalarVariable name="w" valueReference="2" causality="output" variability="continuous">
      <Real unit="rad/s"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="3" causality="output" variability="continuous">
      <Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2"/><Unknown index="3"/><Unknown index="4"/></Outputs></ModelStructure>
</fmiModelDescription>
"""


def test_units_and_declared_types_come_from_the_model_description(tmp_path):
    from fmpy import read_model_description

    from fmu_fdi.identify.fmu_model import _signal_types

    path = tmp_path / "modelDescription.xml"
    path.write_text(MD)
    units, types = _signal_types(read_model_description(str(path), validate=False), ["tau", "phi", "w", "n"])
    assert units == {"tau": "N.m", "phi": "rad", "w": "rad/s"}  # tau's unit is its declared type's
    assert types == {"tau": "Modelica.Units.SI.Torque", "phi": "Modelica.Units.SI.Angle"}


@pytest.mark.parametrize("suffix,sidecar", [(".toml", False), (".json", False), (".toml", True)])
def test_declared_types_round_trip_and_old_files_load(tmp_path, suffix, sidecar):
    from fmu_fdi import FDIModel
    from fmu_fdi.faults import ModelError

    m = FDIModel([[-1.0]], [[1.0]], [[1.0], [2.0]], u_names=["tau"], y_names=["phi", "x1"],
                 units={"tau": "N.m", "phi": "rad", "x1": "m"},
                 declared_types={"tau": "Modelica.Units.SI.Torque", "x1": "Modelica.Units.SI.Length"})
    back = FDIModel.from_file(m.to_file(tmp_path / f"m{suffix}", sidecar=sidecar))
    assert back.units == m.units and back.declared_types == m.declared_types
    assert back.discretize(0.1).declared_types == m.declared_types  # transformations keep them
    assert back.labels(["tau", "phi"]) == ["tau [N.m: Modelica.Units.SI.Torque]", "phi [rad]"]
    old = tmp_path / "old.toml"  # a file written before declared types existed
    old.write_text('format = "fmu-fdi-model/1"\n[signals]\nu = ["u"]\ny = ["y"]\n[units]\ny = "cm"\n'
                   '[matrices]\nA = [[-1.0]]\nBu = [[1.0]]\nC = [[1.0]]\n')
    legacy = FDIModel.from_file(old)
    assert legacy.declared_types == {} and legacy.units == {"y": "cm"} and legacy.labels(["u", "y"]) == ["u", "y [cm]"]
    with pytest.raises(ModelError, match="declared_types given for unknown signal 'q'"):
        FDIModel([[-1.0]], [[1.0]], [[1.0]], declared_types={"q": "T"})
    bad = tmp_path / "bad.toml"
    bad.write_text(old.read_text() + "[declared_types]\ny = 3\n")
    with pytest.raises(ModelError, match="declared_types.y"):
        FDIModel.from_file(bad)
