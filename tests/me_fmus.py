"""Model-exchange FMUs (FMI 2 and FMI 3) compiled from C on the fly, with analytic Jacobians.

Two plants, each with the same C core behind an FMI 2 and an FMI 3 glue:

- ``nonlinear`` (2 states, 2 inputs, 2 outputs): a tank feeding a second state,

      x1' = u1 - a sqrt(x1),   x2' = a sqrt(x1) - b x2^2 + c u2 x1,
      y1 = x2,                 y2 = x1 x2 + e u1,

  steady state for u1 > 0: x1 = (u1/a)^2, x2 = sqrt((u1 + c u2 x1)/b); none for u1 < 0.
- ``linear`` (3 states, 2 inputs, 2 outputs): x' = A x + B u, y = C x + D u.

The FMU provides directional derivatives (analytic) when built with ``directional=True``;
the binary is the same either way, only the model description's flag changes.
"""
from __future__ import annotations

import itertools
import math
import shutil
import subprocess
import uuid
import zipfile
from pathlib import Path

import numpy as np

_serial = itertools.count()

NONLINEAR = dict(
    nx=2, nu=2, ny=2, x_start=[1.0, 1.0], u_start=[1.0, 0.5],
    body=r"""
static const double a = 0.5, b = 0.2, c = 0.1, e = 0.3;
static void model(const double* x, const double* u, double* dx, double* y, double J[NX + NY][NX + NU]) {
    double s = sqrt(x[0] > 0 ? x[0] : 0.0);
    dx[0] = u[0] - a * s;
    dx[1] = a * s - b * x[1] * x[1] + c * u[1] * x[0];
    y[0] = x[1];
    y[1] = x[0] * x[1] + e * u[0];
    double ds = s > 0 ? 0.5 / s : 0.0;
    double Jl[NX + NY][NX + NU] = {
        {-a * ds, 0.0, 1.0, 0.0},
        {a * ds + c * u[1], -2.0 * b * x[1], 0.0, c * x[0]},
        {0.0, 1.0, 0.0, 0.0},
        {x[1], x[0], e, 0.0}};
    memcpy(J, Jl, sizeof Jl);
}
""")

A_LIN = [[-1.0, 0.5, 0.0], [0.0, -2.0, 1.0], [0.2, 0.0, -0.5]]
B_LIN = [[1.0, 0.0], [0.0, 2.0], [0.5, -1.0]]
C_LIN = [[1.0, 0.0, 1.0], [0.0, 3.0, 0.0]]
D_LIN = [[0.0, 0.1], [0.0, 0.0]]


def _c_matrix(M):
    return "{" + ", ".join("{" + ", ".join(repr(float(v)) for v in row) + "}" for row in M) + "}"


LINEAR = dict(
    nx=3, nu=2, ny=2, x_start=[0.0, 0.0, 0.0], u_start=[1.0, -1.0],
    body=r"""
static const double A[NX][NX] = %s, B[NX][NU] = %s, C[NY][NX] = %s, D[NY][NU] = %s;
static void model(const double* x, const double* u, double* dx, double* y, double J[NX + NY][NX + NU]) {
    for (int i = 0; i < NX; i++) {
        dx[i] = 0.0;
        for (int j = 0; j < NX; j++) { dx[i] += A[i][j] * x[j]; J[i][j] = A[i][j]; }
        for (int j = 0; j < NU; j++) { dx[i] += B[i][j] * u[j]; J[i][NX + j] = B[i][j]; }
    }
    for (int i = 0; i < NY; i++) {
        y[i] = 0.0;
        for (int j = 0; j < NX; j++) { y[i] += C[i][j] * x[j]; J[NX + i][j] = C[i][j]; }
        for (int j = 0; j < NU; j++) { y[i] += D[i][j] * u[j]; J[NX + i][NX + j] = D[i][j]; }
    }
}
""" % (_c_matrix(A_LIN), _c_matrix(B_LIN), _c_matrix(C_LIN), _c_matrix(D_LIN)))

PLANTS = {"nonlinear": NONLINEAR, "linear": LINEAR}


def analytic(name, x, u):
    """(f, g, J) of the plant at (x, u) computed in Python, J = [A B; C D]."""
    x, u = np.asarray(x, float), np.asarray(u, float)
    if name == "linear":
        A, B, C, D = (np.array(M) for M in (A_LIN, B_LIN, C_LIN, D_LIN))
        return A @ x + B @ u, C @ x + D @ u, np.block([[A, B], [C, D]])
    a, b, c, e = 0.5, 0.2, 0.1, 0.3
    s = math.sqrt(x[0])
    f = np.array([u[0] - a * s, a * s - b * x[1] ** 2 + c * u[1] * x[0]])
    g = np.array([x[1], x[0] * x[1] + e * u[0]])
    J = np.array([[-a / (2 * s), 0, 1, 0], [a / (2 * s) + c * u[1], -2 * b * x[1], 0, c * x[0]],
                  [0, 1, 0, 0], [x[1], x[0], e, 0]])
    return f, g, J


def equilibrium(name, u):
    """The analytic steady state for inputs u."""
    u = np.asarray(u, float)
    if name == "linear":
        return -np.linalg.solve(np.array(A_LIN), np.array(B_LIN) @ u)
    x1 = (u[0] / 0.5) ** 2
    return np.array([x1, math.sqrt((u[0] + 0.1 * u[1] * x1) / 0.2)])


# value references: x 0..nx-1, der(x) nx..2nx-1, u 2nx.., y 2nx+nu..
CORE = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "%(header)s"
#define NX %(nx)d
#define NU %(nu)d
#define NY %(ny)d
%(body)s
typedef struct { double t, x[NX], u[NU], dx[NX], y[NY], J[NX + NY][NX + NU]; } Inst;
static const double X_START[NX] = %(x_start)s, U_START[NU] = %(u_start)s;
static void reset(Inst* p) { memset(p, 0, sizeof *p); memcpy(p->x, X_START, sizeof p->x); memcpy(p->u, U_START, sizeof p->u); }
static void update(Inst* p) { model(p->x, p->u, p->dx, p->y, p->J); }
static int get1(Inst* p, unsigned vr, double* v) {
    update(p);
    if (vr < NX) *v = p->x[vr];
    else if (vr < 2 * NX) *v = p->dx[vr - NX];
    else if (vr < 2 * NX + NU) *v = p->u[vr - 2 * NX];
    else if (vr < 2 * NX + NU + NY) *v = p->y[vr - 2 * NX - NU];
    else return 1;
    return 0;
}
static int set1(Inst* p, unsigned vr, double v) {
    if (vr < NX) p->x[vr] = v;
    else if (vr >= 2 * NX && vr < 2 * NX + NU) p->u[vr - 2 * NX] = v;
    else return 1;
    return 0;
}
/* row of an unknown (der or output) and column of a known (state or input) in J */
static int row_of(unsigned vr) { if (vr >= NX && vr < 2 * NX) return vr - NX; if (vr >= 2 * NX + NU && vr < 2 * NX + NU + NY) return NX + vr - 2 * NX - NU; return -1; }
static int col_of(unsigned vr) { if (vr < NX) return vr; if (vr >= 2 * NX && vr < 2 * NX + NU) return NX + vr - 2 * NX; return -1; }
static int ddir(Inst* p, const unsigned* unk, size_t nu, const unsigned* kn, size_t nk, const double* seed, double* out) {
    update(p);
    for (size_t i = 0; i < nu; i++) {
        int r = row_of(unk[i]);
        if (r < 0) return 1;
        out[i] = 0.0;
        for (size_t j = 0; j < nk; j++) { int c = col_of(kn[j]); if (c < 0) return 1; out[i] += p->J[r][c] * seed[j]; }
    }
    return 0;
}
"""

GLUE2 = r"""
const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* f, fmi2Boolean vis, fmi2Boolean log) {
    if (type != fmi2ModelExchange || strcmp(guid, "%(token)s") != 0) return NULL;
    Inst* p = calloc(1, sizeof(Inst));
    if (p) reset(p);
    return p;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start, fmi2Boolean stopDef, fmi2Real stop) { ((Inst*)c)->t = start; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { reset(c); return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    for (size_t k = 0; k < n; k++) if (get1(c, vr[k], &v[k])) return fmi2Error;
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    for (size_t k = 0; k < n; k++) if (set1(c, vr[k], v[k])) return fmi2Error;
    return fmi2OK;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unk[], size_t nu,
        const fmi2ValueReference kn[], size_t nk, const fmi2Real seed[], fmi2Real out[]) {
    return ddir(c, unk, nu, kn, nk, seed, out) ? fmi2Error : fmi2OK;
}
fmi2Status fmi2EnterEventMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* e) {
    e->newDiscreteStatesNeeded = fmi2False; e->terminateSimulation = fmi2False;
    e->nominalsOfContinuousStatesChanged = fmi2False; e->valuesOfContinuousStatesChanged = fmi2False;
    e->nextEventTimeDefined = fmi2False; e->nextEventTime = 0.0;
    return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSet, fmi2Boolean* ev, fmi2Boolean* term) {
    *ev = fmi2False; *term = fmi2False; return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Inst*)c)->t = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    if (nx != NX) return fmi2Error;
    memcpy(((Inst*)c)->x, x, sizeof(double) * NX); return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    if (nx != NX) return fmi2Error;
    update(c); memcpy(dx, ((Inst*)c)->dx, sizeof(double) * NX); return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) { return nz == 0 ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    if (nx != NX) return fmi2Error;
    memcpy(x, ((Inst*)c)->x, sizeof(double) * NX); return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    for (size_t i = 0; i < nx; i++) x[i] = 1.0;
    return fmi2OK;
}
"""
UNUSED2 = """fmi2GetInteger fmi2GetBoolean fmi2GetString fmi2SetInteger fmi2SetBoolean fmi2SetString
fmi2GetFMUstate fmi2SetFMUstate fmi2FreeFMUstate fmi2SerializedFMUstateSize fmi2SerializeFMUstate
fmi2DeSerializeFMUstate fmi2SetRealInputDerivatives fmi2GetRealOutputDerivatives fmi2DoStep
fmi2CancelStep fmi2GetStatus fmi2GetRealStatus fmi2GetIntegerStatus fmi2GetBooleanStatus
fmi2GetStringStatus""".split()

GLUE3 = r"""
const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) { return fmi3OK; }
fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String res, fmi3Boolean vis,
        fmi3Boolean log, fmi3InstanceEnvironment env, fmi3LogMessageCallback cb) {
    if (strcmp(token, "%(token)s") != 0) return NULL;
    Inst* p = calloc(1, sizeof(Inst));
    if (p) reset(p);
    return p;
}
void fmi3FreeInstance(fmi3Instance i) { free(i); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance i, fmi3Boolean tolDef, fmi3Float64 tol, fmi3Float64 start,
        fmi3Boolean stopDef, fmi3Float64 stop) { ((Inst*)i)->t = start; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3EnterEventMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance i) { reset(i); return fmi3OK; }
fmi3Status fmi3GetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    for (size_t k = 0; k < n; k++) if (get1(i, vr[k], &v[k])) return fmi3Error;
    return fmi3OK;
}
fmi3Status fmi3SetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    for (size_t k = 0; k < n; k++) if (set1(i, vr[k], v[k])) return fmi3Error;
    return fmi3OK;
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance i, const fmi3ValueReference unk[], size_t nu,
        const fmi3ValueReference kn[], size_t nk, const fmi3Float64 seed[], size_t ns, fmi3Float64 out[], size_t no) {
    if (ns != nk || no != nu) return fmi3Error;
    return ddir(i, unk, nu, kn, nk, seed, out) ? fmi3Error : fmi3OK;
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
    if (nx != NX) return fmi3Error;
    memcpy(((Inst*)i)->x, x, sizeof(double) * NX); return fmi3OK;
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance i, fmi3Float64 dx[], size_t nx) {
    if (nx != NX) return fmi3Error;
    update(i); memcpy(dx, ((Inst*)i)->dx, sizeof(double) * NX); return fmi3OK;
}
fmi3Status fmi3GetEventIndicators(fmi3Instance i, fmi3Float64 z[], size_t nz) { return nz == 0 ? fmi3OK : fmi3Error; }
fmi3Status fmi3GetContinuousStates(fmi3Instance i, fmi3Float64 x[], size_t nx) {
    if (nx != NX) return fmi3Error;
    memcpy(x, ((Inst*)i)->x, sizeof(double) * NX); return fmi3OK;
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance i, fmi3Float64 x[], size_t nx) {
    for (size_t k = 0; k < nx; k++) x[k] = 1.0;
    return fmi3OK;
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance i, size_t* n) { *n = 0; return fmi3OK; }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance i, size_t* n) { *n = NX; return fmi3OK; }
"""
UNUSED3 = """fmi3InstantiateCoSimulation fmi3InstantiateScheduledExecution fmi3GetFloat32 fmi3GetInt8
fmi3GetUInt8 fmi3GetInt16 fmi3GetUInt16 fmi3GetInt32 fmi3GetUInt32 fmi3GetInt64 fmi3GetUInt64
fmi3GetBoolean fmi3GetString fmi3GetBinary fmi3GetClock fmi3SetFloat32 fmi3SetInt8 fmi3SetUInt8
fmi3SetInt16 fmi3SetUInt16 fmi3SetInt32 fmi3SetUInt32 fmi3SetInt64 fmi3SetUInt64 fmi3SetBoolean
fmi3SetString fmi3SetBinary fmi3SetClock fmi3GetNumberOfVariableDependencies
fmi3GetVariableDependencies fmi3GetFMUState fmi3SetFMUState fmi3FreeFMUState
fmi3SerializedFMUStateSize fmi3SerializeFMUState fmi3DeserializeFMUState fmi3GetAdjointDerivative
fmi3EnterConfigurationMode fmi3ExitConfigurationMode fmi3GetIntervalDecimal fmi3GetIntervalFraction
fmi3GetShiftDecimal fmi3GetShiftFraction fmi3SetIntervalDecimal fmi3SetIntervalFraction
fmi3SetShiftDecimal fmi3SetShiftFraction fmi3EvaluateDiscreteStates fmi3EnterStepMode fmi3DoStep
fmi3GetOutputDerivatives fmi3ActivateModelPartition""".split()


def _variables2(p):
    nx, nu, ny = p["nx"], p["nu"], p["ny"]
    rows = []
    for i in range(nx):
        rows.append(f'<ScalarVariable name="x{i + 1}" valueReference="{i}" causality="local" '
                    f'variability="continuous" initial="exact"><Real start="{p["x_start"][i]}"/></ScalarVariable>')
    for i in range(nx):
        rows.append(f'<ScalarVariable name="der(x{i + 1})" valueReference="{nx + i}" causality="local" '
                    f'variability="continuous" initial="calculated"><Real derivative="{i + 1}"/></ScalarVariable>')
    for i in range(nu):
        rows.append(f'<ScalarVariable name="u{i + 1}" valueReference="{2 * nx + i}" causality="input" '
                    f'variability="continuous"><Real start="{p["u_start"][i]}"/></ScalarVariable>')
    for i in range(ny):
        rows.append(f'<ScalarVariable name="y{i + 1}" valueReference="{2 * nx + nu + i}" causality="output" '
                    f'variability="continuous" initial="calculated"><Real/></ScalarVariable>')
    idx_y = [2 * nx + nu + i + 1 for i in range(ny)]
    idx_d = [nx + i + 1 for i in range(nx)]
    struct = ("<Outputs>" + "".join(f'<Unknown index="{k}"/>' for k in idx_y) + "</Outputs>"
              + "<Derivatives>" + "".join(f'<Unknown index="{k}"/>' for k in idx_d) + "</Derivatives>"
              + "<InitialUnknowns>" + "".join(f'<Unknown index="{k}"/>' for k in idx_d + idx_y)
              + "</InitialUnknowns>")
    return "\n".join(rows), struct


def _variables3(p):
    nx, nu, ny = p["nx"], p["nu"], p["ny"]
    rows = ['<Float64 name="time" valueReference="999" causality="independent" variability="continuous"/>']
    for i in range(nx):
        rows.append(f'<Float64 name="x{i + 1}" valueReference="{i}" causality="local" variability="continuous" '
                    f'initial="exact" start="{p["x_start"][i]}"/>')
    for i in range(nx):
        rows.append(f'<Float64 name="der(x{i + 1})" valueReference="{nx + i}" causality="local" '
                    f'variability="continuous" derivative="{i}"/>')
    for i in range(nu):
        rows.append(f'<Float64 name="u{i + 1}" valueReference="{2 * nx + i}" causality="input" '
                    f'variability="continuous" start="{p["u_start"][i]}"/>')
    for i in range(ny):
        rows.append(f'<Float64 name="y{i + 1}" valueReference="{2 * nx + nu + i}" causality="output" '
                    f'variability="continuous"/>')
    vr_y = [2 * nx + nu + i for i in range(ny)]
    vr_d = [nx + i for i in range(nx)]
    struct = ("".join(f'<Output valueReference="{k}"/>' for k in vr_y)
              + "".join(f'<ContinuousStateDerivative valueReference="{k}"/>' for k in vr_d)
              + "".join(f'<InitialUnknown valueReference="{k}"/>' for k in vr_d + vr_y))
    return "\n".join(rows), struct


def build_me_fmu(tmp_path, plant: str, fmi: int, directional: bool = True) -> Path:
    """Compile plant ``plant`` ('nonlinear' or 'linear') as an FMI ``fmi`` (2 or 3) model-exchange FMU."""
    import fmpy

    p = PLANTS[plant]
    mid = f"me{fmi}{plant}{next(_serial)}"
    token = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, mid)) + "}"
    work = Path(tmp_path) / mid
    (work / "sources").mkdir(parents=True)
    fmt = dict(p, header=f"fmi{fmi}Functions.h", token=token,
               x_start="{" + ", ".join(map(repr, map(float, p["x_start"]))) + "}",
               u_start="{" + ", ".join(map(repr, map(float, p["u_start"]))) + "}")
    source = CORE % fmt + (GLUE2 if fmi == 2 else GLUE3) % fmt
    (work / "sources" / "model.c").write_text(source)
    stubs = "\n".join(f"int {name}(void) {{ return 3; }}" for name in (UNUSED2 if fmi == 2 else UNUSED3))
    (work / "sources" / "unused.c").write_text(stubs + "\n")
    folder = fmpy.platform if fmi == 2 else fmpy.platform_tuple
    binary = work / "binaries" / folder / f"{mid}.so"
    binary.parent.mkdir(parents=True)
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([shutil.which("gcc") or "gcc", "-std=c99", "-shared", "-fPIC", "-O2", "-Wall", "-Wextra",
                    "-Werror", "-Wno-unused-parameter", "-I", str(headers), str(work / "sources" / "model.c"),
                    str(work / "sources" / "unused.c"), "-lm", "-o", str(binary)],
                   check=True, capture_output=True, text=True)
    if fmi == 2:
        variables, struct = _variables2(p)
        flag = f' providesDirectionalDerivative="{str(directional).lower()}"'
        xml = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" modelName="{mid}" '
               f'guid="{token}" numberOfEventIndicators="0">\n<ModelExchange modelIdentifier="{mid}"{flag}/>\n'
               f'<ModelVariables>\n{variables}\n</ModelVariables>\n<ModelStructure>{struct}</ModelStructure>\n'
               f'</fmiModelDescription>\n')
    else:
        variables, struct = _variables3(p)
        flag = f' providesDirectionalDerivatives="{str(directional).lower()}"'
        xml = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" modelName="{mid}" '
               f'instantiationToken="{token}">\n<ModelExchange modelIdentifier="{mid}"{flag}/>\n'
               f'<ModelVariables>\n{variables}\n</ModelVariables>\n<ModelStructure>{struct}</ModelStructure>\n'
               f'</fmiModelDescription>\n')
    (work / "modelDescription.xml").write_text(xml)
    fmu = Path(tmp_path) / f"{mid}{'' if directional else '_nodd'}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        for path in sorted(work.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(work).as_posix())
    return fmu
