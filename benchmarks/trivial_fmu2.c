/* trivial_fmu2.c - the floor of benchmarks/native_speed.py: an FMI 2.0 co-simulation FMU with the
 * native diagnostic FMU's interface (same variables and value references: inputs 1..N_IN,
 * threshold_scale N_IN + 1, outputs from N_IN + 2) whose step copies inputs to outputs.
 * Compile with -DN_IN=.. -DN_OUT=.. -DGUID=\"..\". No state machine, no checks: the cost of
 * the FMI calls themselves. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define N_VARS (N_IN + 2 + N_OUT)

typedef struct {
    double v[N_VARS];
    fmi2CallbackFunctions cb;
} Trivial;

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    Trivial *t;
    (void)name; (void)type; (void)res; (void)visible; (void)logging;
    if (!guid || strcmp(guid, GUID) != 0) return NULL;
    t = cb->allocateMemory(1, sizeof(Trivial));
    if (t) t->cb = *cb;
    return t;
}

void fmi2FreeInstance(fmi2Component c) {
    Trivial *t = c;
    if (t) t->cb.freeMemory(t);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real d, fmi2Boolean e, fmi2Real f) {
    (void)c; (void)a; (void)b; (void)d; (void)e; (void)f;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { memset(((Trivial *)c)->v, 0, sizeof(double) * N_VARS); return fmi2OK; }

#define ACCESS(NAME, TYPE, CONST, STMT)                                                                          \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t n, CONST TYPE value[]) {                \
        Trivial *t = c;                                                                                          \
        size_t i;                                                                                                \
        for (i = 0; i < n; i++) {                                                                                \
            if (vr[i] >= N_VARS) return fmi2Error;                                                               \
            STMT;                                                                                                \
        }                                                                                                        \
        return fmi2OK;                                                                                           \
    }

ACCESS(fmi2GetReal, fmi2Real, , value[i] = t->v[vr[i]])
ACCESS(fmi2GetInteger, fmi2Integer, , value[i] = (fmi2Integer)t->v[vr[i]])
ACCESS(fmi2GetBoolean, fmi2Boolean, , value[i] = t->v[vr[i]] != 0.0)
ACCESS(fmi2SetReal, fmi2Real, const, t->v[vr[i]] = value[i])
ACCESS(fmi2SetInteger, fmi2Integer, const, t->v[vr[i]] = value[i])
ACCESS(fmi2SetBoolean, fmi2Boolean, const, t->v[vr[i]] = value[i])

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    (void)c; (void)vr; (void)value;
    return n ? fmi2Error : fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    (void)c; (void)vr; (void)value;
    return n ? fmi2Error : fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t0, fmi2Real h, fmi2Boolean no) {
    Trivial *t = c;
    int j;
    (void)t0; (void)h; (void)no;
    for (j = 0; j < N_OUT; j++) t->v[N_IN + 2 + j] = t->v[1 + j % N_IN];
    return fmi2OK;
}

/* the rest of the FMI 2.0 co-simulation interface: not used by the benchmark */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)c; (void)s; (void)n;
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)c; (void)s; (void)b; (void)n;
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)c; (void)s; (void)b; (void)n;
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real d[], fmi2Real e[]) {
    (void)c; (void)a; (void)na; (void)b; (void)nb; (void)d; (void)e;
    return fmi2Error;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) {
    (void)c; (void)vr; (void)n; (void)o; (void)v;
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) {
    (void)c; (void)vr; (void)n; (void)o; (void)v;
    return fmi2Error;
}
fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
