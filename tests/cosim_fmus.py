"""Tiny FMUs for the co-simulation tests, built on the fly.

FMI 2 FMUs are pythonfmu slaves. pythonfmu imports each FMU's script under its module name, so
two different FMUs with the same module name clash in one process (pythonfmu issue 228): every
builder here gives its FMU a fresh module name.

The FMI 3 FMU is a C source compiled with gcc against the FMI 3 headers that fmpy ships.
"""
from __future__ import annotations

import itertools
import math
import shutil
import subprocess
import textwrap
import zipfile
from pathlib import Path

_serial = itertools.count()

PLANT = '''
import math
from pythonfmu import Fmi2Slave, Fmi2Causality, Fmi2Variability, Real


class {cls}(Fmi2Slave):
    """x' = -a x + b (u + f), y = x; integrated exactly for inputs held over the step."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 1.0
        self.f = 0.0
        self.a = 1.0
        self.b = 1.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("f", causality=Fmi2Causality.input))
        self.register_variable(Real("a", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("b", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, t, h):
        e = math.exp(-self.a * h)
        self.y = e * self.y + (1.0 - e) / self.a * self.b * (self.u + self.f)
        return True
'''

CONSUMER = '''
from pythonfmu import Fmi2Slave, Fmi2Causality, Real, Integer, Boolean


class {cls}(Fmi2Slave):
    """Samples its inputs in do_step: z = 2 y, acc += h y, w = u, count = steps, high = y > 0.5."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.y = 0.0
        self.u = 0.0
        self.z = 0.0
        self.acc = 0.0
        self.w = 0.0
        self.count = 0
        self.high = False
        self.register_variable(Real("y", causality=Fmi2Causality.input))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("z", causality=Fmi2Causality.output))
        self.register_variable(Real("acc", causality=Fmi2Causality.output))
        self.register_variable(Real("w", causality=Fmi2Causality.output))
        self.register_variable(Integer("count", causality=Fmi2Causality.output))
        self.register_variable(Boolean("high", causality=Fmi2Causality.output))

    def do_step(self, t, h):
        self.z = 2.0 * self.y
        self.acc = self.acc + h * self.y
        self.w = self.u
        self.count = self.count + 1
        self.high = self.y > 0.5
        return True
'''

FAILING = '''
from pythonfmu import Fmi2Slave, Fmi2Causality, Real


class {cls}(Fmi2Slave):
    """Counts time in y; from t >= {at} its do_step {how}."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.y = 0.0
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def exit_initialization_mode(self):
        if {at} < 0:
            raise RuntimeError("cannot initialise")

    def do_step(self, t, h):
        if t >= {at} - 1e-12:
            {action}
        self.y = t + h
        return True
'''


def _pythonfmu(tmp_path: Path, template: str, prefix: str, **fmt) -> Path:
    from fmu_fdi.fmu.packaging import installed_pythonfmu

    # a prefix no other test file uses: module names must be unique in the whole pytest process
    tag = f"cosimtest_{prefix}{next(_serial)}"
    cls = "".join(part.capitalize() for part in tag.split("_"))
    script = Path(tmp_path) / f"{tag}.py"
    script.write_text(template.format(cls=cls, **fmt))
    # the installed pythonfmu, not the binary-less copy a plant FMU run earlier in this
    # process put on sys.path (that one writes FMUs without binaries/)
    with installed_pythonfmu():
        from pythonfmu import FmuBuilder

        return FmuBuilder.build_FMU(script, dest=tmp_path, needsExecutionTool="false")


def build_plant(tmp_path) -> Path:
    """FMI 2 first-order plant: inputs u (start 1), f (start 0); tunable a, fixed b; output y."""
    return _pythonfmu(tmp_path, PLANT, "plant")


def build_consumer(tmp_path) -> Path:
    """FMI 2 stand-in for a diagnoser: inputs y, u; outputs z, acc, w, count, high."""
    return _pythonfmu(tmp_path, CONSUMER, "consumer")


def build_failing(tmp_path, at: float, how: str) -> Path:
    """FMI 2 FMU whose do_step returns False (``how="discard"``) or raises (``"error"``) from
    ``at``; with ``at < 0`` its initialisation fails."""
    action = "return False" if how == "discard" else "raise RuntimeError('broken valve model')"
    return _pythonfmu(tmp_path, FAILING, "failing", at=repr(at), action=action,
                      how="returns False" if how == "discard" else "raises")


def plant_exact(h, n, a=1.0, b=1.0, u=None, x0=0.0):
    """Exact samples of x' = -a x + b u with u held over each step (u[k] on [t_k, t_k+1))."""
    u = [1.0] * n if u is None else u
    x = [x0]
    e = math.exp(-a * h)
    for k in range(n):
        x.append(e * x[-1] + (1.0 - e) / a * b * u[k])
    return x


# ---- FMI 3 -----------------------------------------------------------------------------------

FMI3_MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{mid}" instantiationToken="{{{token}}}">
  <CoSimulation modelIdentifier="{mid}" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="u" valueReference="1" causality="input" variability="continuous" start="1"/>
    <Float64 name="a" valueReference="2" causality="parameter" variability="tunable" start="1"/>
    <Float64 name="y" valueReference="3" causality="output" variability="continuous" initial="exact" start="0"/>
    <Int32 name="steps" valueReference="4" causality="output" variability="discrete" initial="exact" start="0"/>
    <Boolean name="positive" valueReference="5" causality="output" variability="discrete" initial="exact" start="false"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="3"/>
    <Output valueReference="4"/>
    <Output valueReference="5"/>
  </ModelStructure>
</fmiModelDescription>
"""

# The FMI 3 calls a co-simulation master makes of this FMU, implemented for real.
FMI3_SOURCE = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

typedef struct { double time, u, a, y; int steps; } Plant;

const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) { return fmi3OK; }

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
    fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean eventMode, fmi3Boolean earlyReturn,
    const fmi3ValueReference req[], size_t nreq, fmi3InstanceEnvironment env,
    fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback upd) {
    if (strcmp(token, "{TOKEN}") != 0) return NULL;
    Plant* p = calloc(1, sizeof(Plant));
    p->u = 1.0; p->a = 1.0;
    return p;
}
void fmi3FreeInstance(fmi3Instance i) { free(i); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance i, fmi3Boolean tolDef, fmi3Float64 tol,
    fmi3Float64 start, fmi3Boolean stopDef, fmi3Float64 stop) { ((Plant*)i)->time = start; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance i) { Plant* p = i; memset(p, 0, sizeof *p); p->u = 1.0; p->a = 1.0; return fmi3OK; }

fmi3Status fmi3GetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    Plant* p = i;
    for (size_t k = 0; k < n; k++) {
        switch (vr[k]) {
        case 0: v[k] = p->time; break;
        case 1: v[k] = p->u; break;
        case 2: v[k] = p->a; break;
        case 3: v[k] = p->y; break;
        default: return fmi3Error;
        }
    }
    return fmi3OK;
}
fmi3Status fmi3SetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    Plant* p = i;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 1) p->u = v[k];
        else if (vr[k] == 2) p->a = v[k];
        else return fmi3Error;
    }
    return fmi3OK;
}
fmi3Status fmi3GetInt32(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Int32 v[], size_t nv) {
    for (size_t k = 0; k < n; k++) { if (vr[k] != 4) return fmi3Error; v[k] = ((Plant*)i)->steps; }
    return fmi3OK;
}
fmi3Status fmi3GetBoolean(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Boolean v[], size_t nv) {
    for (size_t k = 0; k < n; k++) { if (vr[k] != 5) return fmi3Error; v[k] = ((Plant*)i)->y > 0; }
    return fmi3OK;
}
fmi3Status fmi3EnterStepMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3DoStep(fmi3Instance i, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet,
    fmi3Boolean* event, fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
    Plant* p = i;
    double e = exp(-p->a * h);  /* exact for u held over the step */
    p->y = e * p->y + (1.0 - e) / p->a * p->u;
    p->time = t + h;
    p->steps += 1;
    *event = fmi3False; *terminate = fmi3False; *early = fmi3False; *last = p->time;
    return fmi3OK;
}
"""

# fmpy resolves every FMI 3 symbol when it loads a library, whether or not it calls it. These
# are never called for this FMU; they live in a separate file without the FMI header (whose
# prototypes they do not repeat) and answer fmi3Error if they ever were.
FMI3_UNUSED = """
fmi3InstantiateModelExchange fmi3InstantiateScheduledExecution fmi3EnterEventMode
fmi3GetFloat32 fmi3GetInt8 fmi3GetUInt8 fmi3GetInt16 fmi3GetUInt16 fmi3GetUInt32 fmi3GetInt64
fmi3GetUInt64 fmi3GetString fmi3GetBinary fmi3GetClock fmi3SetFloat32 fmi3SetInt8 fmi3SetUInt8
fmi3SetInt16 fmi3SetUInt16 fmi3SetInt32 fmi3SetUInt32 fmi3SetInt64 fmi3SetUInt64 fmi3SetBoolean
fmi3SetString fmi3SetBinary fmi3SetClock fmi3GetNumberOfVariableDependencies
fmi3GetVariableDependencies fmi3GetFMUState fmi3SetFMUState fmi3FreeFMUState
fmi3SerializedFMUStateSize fmi3SerializeFMUState fmi3DeserializeFMUState
fmi3GetDirectionalDerivative fmi3GetAdjointDerivative fmi3EnterConfigurationMode
fmi3ExitConfigurationMode fmi3GetIntervalDecimal fmi3GetIntervalFraction fmi3GetShiftDecimal
fmi3GetShiftFraction fmi3SetIntervalDecimal fmi3SetIntervalFraction fmi3SetShiftDecimal
fmi3SetShiftFraction fmi3EvaluateDiscreteStates fmi3UpdateDiscreteStates
fmi3EnterContinuousTimeMode fmi3CompletedIntegratorStep fmi3SetTime fmi3SetContinuousStates
fmi3GetContinuousStateDerivatives fmi3GetEventIndicators fmi3GetContinuousStates
fmi3GetNominalsOfContinuousStates fmi3GetNumberOfEventIndicators
fmi3GetNumberOfContinuousStates fmi3GetOutputDerivatives fmi3ActivateModelPartition
""".split()


def fmi3_headers() -> Path | None:
    """The folder of fmpy's FMI 3 C headers, if present."""
    import fmpy

    folder = Path(fmpy.__file__).parent / "c-code"
    return folder if (folder / "fmi3Functions.h").is_file() else None


def build_fmi3_plant(tmp_path) -> Path:
    """Compile the FMI 3 first-order plant (x' = -a x + u, y = x) into an .fmu with gcc."""
    import fmpy

    tmp_path = Path(tmp_path)
    mid = f"fmi3plant{next(_serial)}"
    token = "3b1f0c4e-fd10-4a55-9e2a-" + f"{next(_serial):012d}"
    work = tmp_path / mid
    (work / "src").mkdir(parents=True)
    (work / "src" / "model.c").write_text(FMI3_SOURCE.replace("{TOKEN}", "{" + token + "}"))
    stubs = "\n".join(f"int {name}(void) {{ return 3; }}" for name in FMI3_UNUSED)
    (work / "src" / "unused.c").write_text(stubs + "\n")
    binary = work / "binaries" / fmpy.platform_tuple / f"{mid}.so"
    binary.parent.mkdir(parents=True)
    subprocess.run([shutil.which("gcc") or "gcc", "-shared", "-fPIC", "-O2", "-I", str(fmi3_headers()),
                    str(work / "src" / "model.c"), str(work / "src" / "unused.c"), "-lm", "-o", str(binary)],
                   check=True, capture_output=True, text=True)
    (work / "modelDescription.xml").write_text(
        textwrap.dedent(FMI3_MODEL_DESCRIPTION).format(mid=mid, token=token))
    fmu = tmp_path / f"{mid}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        for path in sorted(work.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(work).as_posix())
    return fmu
