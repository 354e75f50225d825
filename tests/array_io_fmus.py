"""An FMI 3 FMU whose input and output are arrays, compiled from C99 with gcc -Wall -Wextra -Werror.

The plant (both interfaces: model exchange for ``fmu-fdi model``'s linearisation, co-simulation
for ``fmu-fdi simulate``)::

    x' = A x + B u,   y = C x + D u,   x, u, y of 2 elements each,

with the state ``x`` (value reference 1, ``<Dimension start="2"/>``), its derivative (2), the input
``u`` (3) and output ``y`` (4) sized by the structural parameter ``n`` (5, UInt64, fixed, start 2:
``<Dimension valueReference="5"/>``). ``tunable_dimension=True`` declares ``n`` tunable — a variable
dimension, which fmu-fdi refuses. ``x`` starts at the steady state of ``u``'s start value, so a
co-simulation with the start input stays at the operating point the linearisation trims to.

``doStep`` integrates with 50 classical Runge-Kutta sub-steps per communication step and the input
held: for the step 0.05 s used in the tests the local error is below (h/50)^5 |A|^5 / 120 ≈ 1e-17.
"""
from __future__ import annotations

import itertools
import shutil
import subprocess
import uuid
import zipfile
from pathlib import Path

import numpy as np

A = np.array([[-1.0, 0.5], [0.0, -2.0]])
B = np.array([[1.0, 0.0], [0.5, 1.0]])
C = np.array([[1.0, 0.0], [0.0, 1.0]])
D = np.array([[0.0, 0.0], [0.0, 0.2]])
U_START = np.array([1.0, 0.5])
X_START = np.linalg.solve(A, -B @ U_START)  # the steady state of the start input: [1.25, 0.5]
SUBSTEPS = 50

_serial = itertools.count()


def _c(M) -> str:
    return "{" + ", ".join(repr(float(v)) for v in np.ravel(M)) + "}"


SOURCE = r"""
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

#define N 2
static const double A[N * N] = %(A)s, B[N * N] = %(B)s, C[N * N] = %(C)s, D[N * N] = %(D)s;
static const double X0[N] = %(X0)s, U0[N] = %(U0)s;

typedef struct { double t, x[N], u[N]; } Inst;

static void reset(Inst* p) { p->t = 0.0; memcpy(p->x, X0, sizeof p->x); memcpy(p->u, U0, sizeof p->u); }
static void deriv(const Inst* p, const double x[N], double dx[N]) {
    for (int i = 0; i < N; i++) {
        dx[i] = 0.0;
        for (int j = 0; j < N; j++) dx[i] += A[i * N + j] * x[j] + B[i * N + j] * p->u[j];
    }
}
static double out(const Inst* p, int i) {
    double y = 0.0;
    for (int j = 0; j < N; j++) y += C[i * N + j] * p->x[j] + D[i * N + j] * p->u[j];
    return y;
}
static Inst* make(fmi3String token) {
    if (strcmp(token, "%(token)s") != 0) return NULL;
    Inst* p = calloc(1, sizeof(Inst));
    if (p) reset(p);
    return p;
}

const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) { return fmi3OK; }
fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String res, fmi3Boolean vis,
        fmi3Boolean log, fmi3InstanceEnvironment env, fmi3LogMessageCallback cb) { return make(token); }
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
        fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean eventMode, fmi3Boolean earlyReturn,
        const fmi3ValueReference req[], size_t nreq, fmi3InstanceEnvironment env,
        fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback upd) { return make(token); }
void fmi3FreeInstance(fmi3Instance i) { free(i); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance i, fmi3Boolean tolDef, fmi3Float64 tol, fmi3Float64 start,
        fmi3Boolean stopDef, fmi3Float64 stop) { ((Inst*)i)->t = start; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3EnterEventMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3EnterStepMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance i) { reset(i); return fmi3OK; }

/* value references: 0 time, 1 x[2], 2 der(x)[2], 3 u[2], 4 y[2]; arrays serialised in order */
fmi3Status fmi3GetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    Inst* p = i;
    size_t at = 0;
    double dx[N];
    for (size_t k = 0; k < n; k++) {
        size_t need = vr[k] == 0 ? 1 : N;
        if (vr[k] > 4 || at + need > nv) return fmi3Error;
        if (vr[k] == 2) deriv(p, p->x, dx);
        for (size_t j = 0; j < need; j++, at++) {
            switch (vr[k]) {
            case 0: v[at] = p->t; break;
            case 1: v[at] = p->x[j]; break;
            case 2: v[at] = dx[j]; break;
            case 3: v[at] = p->u[j]; break;
            default: v[at] = out(p, (int)j); break;
            }
        }
    }
    return at == nv ? fmi3OK : fmi3Error;
}
fmi3Status fmi3SetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    Inst* p = i;
    size_t at = 0;
    for (size_t k = 0; k < n; k++) {
        if ((vr[k] != 1 && vr[k] != 3) || at + N > nv) return fmi3Error;
        for (size_t j = 0; j < N; j++, at++) (vr[k] == 1 ? p->x : p->u)[j] = v[at];
    }
    return at == nv ? fmi3OK : fmi3Error;
}
fmi3Status fmi3GetUInt64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3UInt64 v[], size_t nv) {
    for (size_t k = 0; k < n; k++) { if (vr[k] != 5 || k >= nv) return fmi3Error; v[k] = N; }
    return fmi3OK;
}
fmi3Status fmi3DoStep(fmi3Instance i, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet,
        fmi3Boolean* event, fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
    Inst* p = i;
    const double s = h / %(substeps)d;
    for (int m = 0; m < %(substeps)d; m++) {  /* classical Runge-Kutta, u held */
        double k1[N], k2[N], k3[N], k4[N], z[N];
        deriv(p, p->x, k1);
        for (int j = 0; j < N; j++) z[j] = p->x[j] + 0.5 * s * k1[j];
        deriv(p, z, k2);
        for (int j = 0; j < N; j++) z[j] = p->x[j] + 0.5 * s * k2[j];
        deriv(p, z, k3);
        for (int j = 0; j < N; j++) z[j] = p->x[j] + s * k3[j];
        deriv(p, z, k4);
        for (int j = 0; j < N; j++) p->x[j] += s / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    }
    p->t = t + h;
    *event = fmi3False; *terminate = fmi3False; *early = fmi3False; *last = p->t;
    return fmi3OK;
}
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance i, fmi3Boolean* more, fmi3Boolean* term, fmi3Boolean* nom,
        fmi3Boolean* val, fmi3Boolean* nextDef, fmi3Float64* next) {
    *more = fmi3False; *term = fmi3False; *nom = fmi3False; *val = fmi3False; *nextDef = fmi3False; *next = 0.0;
    return fmi3OK;
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance i, fmi3Boolean noSet, fmi3Boolean* ev, fmi3Boolean* term) {
    *ev = fmi3False; *term = fmi3False; return fmi3OK;
}
fmi3Status fmi3SetTime(fmi3Instance i, fmi3Float64 t) { ((Inst*)i)->t = t; return fmi3OK; }
fmi3Status fmi3SetContinuousStates(fmi3Instance i, const fmi3Float64 x[], size_t nx) {
    if (nx != N) return fmi3Error;
    memcpy(((Inst*)i)->x, x, sizeof(double) * N); return fmi3OK;
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance i, fmi3Float64 dx[], size_t nx) {
    if (nx != N) return fmi3Error;
    deriv(i, ((Inst*)i)->x, dx); return fmi3OK;
}
fmi3Status fmi3GetEventIndicators(fmi3Instance i, fmi3Float64 z[], size_t nz) { return nz == 0 ? fmi3OK : fmi3Error; }
fmi3Status fmi3GetContinuousStates(fmi3Instance i, fmi3Float64 x[], size_t nx) {
    if (nx != N) return fmi3Error;
    memcpy(x, ((Inst*)i)->x, sizeof(double) * N); return fmi3OK;
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance i, fmi3Float64 x[], size_t nx) {
    for (size_t k = 0; k < nx; k++) x[k] = 1.0;
    return fmi3OK;
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance i, size_t* n) { *n = 0; return fmi3OK; }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance i, size_t* n) { *n = N; return fmi3OK; }
"""

# resolved by fmpy when it loads the library, never called here; without the FMI header, answering fmi3Error
UNUSED = """fmi3InstantiateScheduledExecution fmi3GetFloat32 fmi3GetInt8 fmi3GetUInt8 fmi3GetInt16
fmi3GetUInt16 fmi3GetInt32 fmi3GetUInt32 fmi3GetInt64 fmi3GetBoolean fmi3GetString fmi3GetBinary fmi3GetClock
fmi3SetFloat32 fmi3SetInt8 fmi3SetUInt8 fmi3SetInt16 fmi3SetUInt16 fmi3SetInt32 fmi3SetUInt32 fmi3SetInt64
fmi3SetUInt64 fmi3SetBoolean fmi3SetString fmi3SetBinary fmi3SetClock fmi3GetNumberOfVariableDependencies
fmi3GetVariableDependencies fmi3GetFMUState fmi3SetFMUState fmi3FreeFMUState fmi3SerializedFMUStateSize
fmi3SerializeFMUState fmi3DeserializeFMUState fmi3GetDirectionalDerivative fmi3GetAdjointDerivative
fmi3EnterConfigurationMode fmi3ExitConfigurationMode fmi3GetIntervalDecimal fmi3GetIntervalFraction
fmi3GetShiftDecimal fmi3GetShiftFraction fmi3SetIntervalDecimal fmi3SetIntervalFraction fmi3SetShiftDecimal
fmi3SetShiftFraction fmi3EvaluateDiscreteStates fmi3GetOutputDerivatives fmi3ActivateModelPartition""".split()


def build_array_io_fmu(tmp_path, tunable_dimension: bool = False) -> Path:
    """Compile the plant of the module docstring into an FMI 3 FMU (ME + CS); returns its path."""
    import fmpy

    mid = f"arrio{next(_serial)}"
    token = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, mid)) + "}"
    work = Path(tmp_path) / mid
    (work / "sources").mkdir(parents=True)
    (work / "sources" / "model.c").write_text(SOURCE % dict(A=_c(A), B=_c(B), C=_c(C), D=_c(D), X0=_c(X_START),
                                                             U0=_c(U_START), token=token, substeps=SUBSTEPS))
    (work / "sources" / "unused.c").write_text("\n".join(f"int {name}(void) {{ return 3; }}" for name in UNUSED) + "\n")
    binary = work / "binaries" / fmpy.platform_tuple / f"{mid}.so"
    binary.parent.mkdir(parents=True)
    subprocess.run([shutil.which("gcc") or "gcc", "-std=c99", "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Werror",
                    "-Wno-unused-parameter", "-I", str(Path(fmpy.__file__).parent / "c-code"),
                    str(work / "sources" / "model.c"), str(work / "sources" / "unused.c"), "-o", str(binary)],
                   check=True, capture_output=True, text=True)
    xs, us = " ".join(map(repr, X_START.tolist())), " ".join(map(repr, U_START.tolist()))
    variability = "tunable" if tunable_dimension else "fixed"
    (work / "modelDescription.xml").write_text(f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{mid}" instantiationToken="{token}" variableNamingConvention="structured">
  <ModelExchange modelIdentifier="{mid}"/>
  <CoSimulation modelIdentifier="{mid}" canHandleVariableCommunicationStepSize="true"/>
  <UnitDefinitions><Unit name="m"/><Unit name="N"/></UnitDefinitions>
  <TypeDefinitions>
    <Float64Type name="Force" quantity="Force" unit="N"/>
    <Float64Type name="Position" quantity="Length" unit="m"/>
  </TypeDefinitions>
  <DefaultExperiment startTime="0" stopTime="10" stepSize="0.05"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="x" valueReference="1" causality="local" variability="continuous" initial="exact" start="{xs}"><Dimension start="2"/></Float64>
    <Float64 name="der(x)" valueReference="2" causality="local" variability="continuous" derivative="1"><Dimension start="2"/></Float64>
    <Float64 name="u" valueReference="3" causality="input" variability="continuous" declaredType="Force" start="{us}"><Dimension valueReference="5"/></Float64>
    <Float64 name="y" valueReference="4" causality="output" variability="continuous" declaredType="Position"><Dimension valueReference="5"/></Float64>
    <UInt64 name="n" valueReference="5" causality="structuralParameter" variability="{variability}" start="2"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="4"/>
    <ContinuousStateDerivative valueReference="2"/>
    <InitialUnknown valueReference="4"/>
    <InitialUnknown valueReference="2"/>
  </ModelStructure>
</fmiModelDescription>
""")
    fmu = Path(tmp_path) / f"{mid}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        for path in sorted(work.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(work).as_posix())
    return fmu
