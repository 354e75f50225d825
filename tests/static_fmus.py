"""Third-party-like FMI 3 co-simulation FMUs compiled from C with gcc: static plants (order 0).

``build_static_fmu(tmp_path, K, offset)``: outputs ``y_i = Σ_j K_ij u_j + offset_i + σ n_i``
(``n`` white, unit normal from a seeded xorshift64* generator and Box–Muller, a fresh draw per
step), computed in ``fmi3DoStep`` from the inputs held over the step. Parameters ``sigma``
(default 0.01) and Int32 ``seed``; a discrete-variability Int32 input ``mode`` that adds
``mode`` to the first output (held at its start value 1 by an experiment). ``K = [[1]]`` with
no offset is a pure feedthrough ``y = u``.
"""
from __future__ import annotations

import itertools
import shutil
import subprocess
import zipfile
from pathlib import Path

from cosim_fmus import FMI3_UNUSED, fmi3_headers

_serial = itertools.count()

SOURCE = r"""
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

#define NU %(nu)d
#define NY %(ny)d
static const double K[NY][NU] = %(K)s;
static const double OFFSET[NY] = %(offset)s;

typedef struct { double time, u[NU], y[NY], sigma; int32_t seed, mode; uint64_t rng; int seeded; } Plant;

static double uniform(Plant* p) {       /* xorshift64*, in (0, 1) */
    p->rng ^= p->rng >> 12; p->rng ^= p->rng << 25; p->rng ^= p->rng >> 27;
    return ((double)((p->rng * 2685821657736338717ULL) >> 11) + 0.5) / 9007199254740992.0;
}
static double normal(Plant* p) { return sqrt(-2.0 * log(uniform(p))) * cos(6.283185307179586 * uniform(p)); }
static void outputs(Plant* p, int noisy) {
    for (int i = 0; i < NY; i++) {
        double v = OFFSET[i] + (i == 0 ? p->mode : 0);
        for (int j = 0; j < NU; j++) v += K[i][j] * p->u[j];
        p->y[i] = v + (noisy ? p->sigma * normal(p) : 0.0);
    }
}
static void defaults(Plant* p) { memset(p, 0, sizeof *p); p->sigma = 0.01; p->mode = 1; }

const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) { return fmi3OK; }
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
    fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean eventMode, fmi3Boolean earlyReturn,
    const fmi3ValueReference req[], size_t nreq, fmi3InstanceEnvironment env,
    fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback upd) {
    if (strcmp(token, "{TOKEN}") != 0) return NULL;
    Plant* p = malloc(sizeof(Plant));
    if (p) defaults(p);
    return p;
}
void fmi3FreeInstance(fmi3Instance i) { free(i); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance i, fmi3Boolean tolDef, fmi3Float64 tol,
    fmi3Float64 start, fmi3Boolean stopDef, fmi3Float64 stop) { ((Plant*)i)->time = start; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance i) {
    Plant* p = i;
    p->rng = 0x9E3779B97F4A7C15ULL ^ ((uint64_t)(uint32_t)p->seed * 0xBF58476D1CE4E5B9ULL);
    if (!p->rng) p->rng = 1;
    outputs(p, 1);
    return fmi3OK;
}
fmi3Status fmi3Terminate(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance i) { defaults(i); return fmi3OK; }

/* value references: 0 time, 1..NU inputs u, NU+1..NU+NY outputs y, 100 sigma, 101 seed, 102 mode */
fmi3Status fmi3GetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    Plant* p = i;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 0) v[k] = p->time;
        else if (vr[k] >= 1 && vr[k] <= NU) v[k] = p->u[vr[k] - 1];
        else if (vr[k] > NU && vr[k] <= NU + NY) v[k] = p->y[vr[k] - NU - 1];
        else if (vr[k] == 100) v[k] = p->sigma;
        else return fmi3Error;
    }
    return fmi3OK;
}
fmi3Status fmi3SetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    Plant* p = i;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= 1 && vr[k] <= NU) p->u[vr[k] - 1] = v[k];
        else if (vr[k] == 100) p->sigma = v[k];
        else return fmi3Error;
    }
    return fmi3OK;
}
fmi3Status fmi3GetInt32(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Int32 v[], size_t nv) {
    Plant* p = i;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 101) v[k] = p->seed; else if (vr[k] == 102) v[k] = p->mode; else return fmi3Error;
    }
    return fmi3OK;
}
fmi3Status fmi3SetInt32(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Int32 v[], size_t nv) {
    Plant* p = i;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 101) p->seed = v[k]; else if (vr[k] == 102) p->mode = v[k]; else return fmi3Error;
    }
    return fmi3OK;
}
fmi3Status fmi3EnterStepMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3DoStep(fmi3Instance i, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet,
    fmi3Boolean* event, fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
    Plant* p = i;
    outputs(p, 1);
    p->time = t + h;
    *event = fmi3False; *terminate = fmi3False; *early = fmi3False; *last = p->time;
    return fmi3OK;
}
"""

UNUSED = [n for n in FMI3_UNUSED if n != "fmi3SetInt32"] + ["fmi3GetBoolean"]


def _c(rows) -> str:
    return "{" + ", ".join("{" + ", ".join(repr(float(v)) for v in row) + "}" for row in rows) + "}"


def build_static_fmu(tmp_path, K, offset=None) -> Path:
    """Compile the static plant y = K u + offset (+ mode on y1, + noise) as an FMI 3 co-simulation FMU."""
    import fmpy

    K = [list(map(float, row)) for row in K]
    ny, nu = len(K), len(K[0])
    offset = [0.0] * ny if offset is None else list(map(float, offset))
    tmp_path = Path(tmp_path)
    n = next(_serial)
    mid = f"static{n}"
    token = "5a1e0c4e-fd10-4a55-9e2a-" + f"{n:012d}"
    work = tmp_path / mid
    (work / "src").mkdir(parents=True)
    src = SOURCE % {"nu": nu, "ny": ny, "K": _c(K), "offset": "{" + ", ".join(map(repr, offset)) + "}"}
    (work / "src" / "model.c").write_text(src.replace("{TOKEN}", "{" + token + "}"))
    (work / "src" / "unused.c").write_text("\n".join(f"int {nm}(void) {{ return 3; }}" for nm in UNUSED) + "\n")
    binary = work / "binaries" / fmpy.platform_tuple / f"{mid}.so"
    binary.parent.mkdir(parents=True)
    subprocess.run([shutil.which("gcc") or "gcc", "-std=c99", "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Werror",
                    "-Wno-unused-parameter", "-I", str(fmi3_headers()), str(work / "src" / "model.c"),
                    str(work / "src" / "unused.c"), "-lm", "-o", str(binary)], check=True, capture_output=True, text=True)
    rows = ['<Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>']
    rows += [f'<Float64 name="u{j + 1}" valueReference="{j + 1}" causality="input" variability="continuous" '
             f'start="0"/>' for j in range(nu)]
    rows += [f'<Float64 name="y{i + 1}" valueReference="{nu + i + 1}" causality="output" variability="continuous"/>'
             for i in range(ny)]
    rows += ['<Float64 name="sigma" valueReference="100" causality="parameter" variability="fixed" start="0.01"/>',
             '<Int32 name="seed" valueReference="101" causality="parameter" variability="fixed" start="0"/>',
             '<Int32 name="mode" valueReference="102" causality="input" variability="discrete" start="1"/>']
    struct = "".join(f'<Output valueReference="{nu + i + 1}"/>' for i in range(ny))
    (work / "modelDescription.xml").write_text(
        f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" modelName="{mid}" '
        f'instantiationToken="{{{token}}}">\n<CoSimulation modelIdentifier="{mid}" '
        f'canHandleVariableCommunicationStepSize="true"/>\n<DefaultExperiment stepSize="0.1"/>\n'
        f'<ModelVariables>\n' + "\n".join(rows) + f'\n</ModelVariables>\n<ModelStructure>{struct}</ModelStructure>\n'
        f'</fmiModelDescription>\n')
    fmu = tmp_path / f"{mid}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        for path in sorted(work.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(work).as_posix())
    return fmu
