/* fmi2_plant.c - FMI 2.0 co-simulation interface of the native benchmark plants (C99): the FMI 2.0
 * calling convention around np_glue.c (rules, checks, initialisation and the step are there).
 * Memory: one block from the host's allocateMemory at fmi2Instantiate, released at
 * fmi2FreeInstance. FMU states are not supported (canGetAndSetFMUstate="false", as the pythonfmu
 * plant). */
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "np_glue.h"

typedef struct {
    fmi2CallbackFunctions cb;
    char esc[1200];
} host2;

static void emit2(void *host, const char *instance, int status, const char *category, const char *msg) {
    host2 *h = host;
    size_t i, j = 0;
    if (!h->cb.logger) return;
    for (i = 0; msg[i] && j + 2 < sizeof h->esc; i++) { /* the FMI 2.0 message is a printf format */
        if (msg[i] == '%') h->esc[j++] = '%';
        h->esc[j++] = msg[i];
    }
    h->esc[j] = 0;
    h->cb.logger(h->cb.componentEnvironment, instance, (fmi2Status)status, category, h->esc);
}

#define HOST(in) ((host2 *)(void *)((unsigned char *)(in) + np_instance_bytes()))
#define INSTANCE(c)                                                                                        \
    np_instance *in = np_instance_of(c);                                                                   \
    if (!in) return fmi2Error

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    const char *name = instanceName ? instanceName : "", *why = NULL;
    void *block;
    np_instance *in;
    (void)fmuResourceLocation, (void)visible, (void)loggingOn;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (fmuType != fmi2CoSimulation) why = "fmi2Instantiate: this FMU supports co-simulation only";
    else if (!fmuGUID || strcmp(fmuGUID, NP_GUID) != 0)
        why = "fmi2Instantiate: the GUID does not match this FMU's modelDescription.xml";
    else if (!(block = functions->allocateMemory(1, np_instance_bytes() + sizeof(host2))))
        why = "fmi2Instantiate: out of memory";
    if (why) {
        if (functions->logger) functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError", why);
        return NULL;
    }
    in = np_instance_init(block, name, emit2, NULL);
    in->host = HOST(in);
    HOST(in)->cb = *functions;
    return in;
}

void fmi2FreeInstance(fmi2Component c) {
    np_instance *in = np_instance_of(c);
    if (!in) return;
    np_instance_release(in);
    HOST(in)->cb.freeMemory(in);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[]) {
    INSTANCE(c);
    (void)loggingOn, (void)n, (void)categories, (void)in;
    return fmi2OK; /* only Error and Discard messages are ever sent */
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    INSTANCE(c);
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    in->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    INSTANCE(c);
    return (fmi2Status)np_enter_initialization(in, "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    INSTANCE(c);
    return (fmi2Status)np_exit_initialization(in, "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c) {
    INSTANCE(c);
    return (fmi2Status)np_terminate(in, "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c) {
    INSTANCE(c);
    np_reset(in);
    return fmi2OK;
}

#define ACCESS(KIND, SET, body)                                                                            \
    size_t i;                                                                                              \
    INSTANCE(c);                                                                                           \
    if (nvr && !value) return (fmi2Status)np_report(in, NP_ERROR, "%s: NULL value array", __func__);       \
    if (np_check_access(in, __func__, vr, nvr, KIND, SET)) return fmi2Error;                               \
    for (i = 0; i < nvr; i++) body;                                                                        \
    return fmi2OK

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    ACCESS(NP_REAL, 0, value[i] = in->plant.v[vr[i]]);
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    ACCESS(NP_INTEGER, 0, value[i] = (fmi2Integer)in->plant.v[vr[i]]);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    ACCESS(NP_BOOLEAN, 0, value[i] = in->plant.v[vr[i]] != 0.0 ? fmi2True : fmi2False);
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    ACCESS(NP_REAL, 1, in->plant.v[vr[i]] = value[i]);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    ACCESS(NP_INTEGER, 1, in->plant.v[vr[i]] = value[i]);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    ACCESS(NP_BOOLEAN, 1, in->plant.v[vr[i]] = value[i] ? 1.0 : 0.0);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr, (void)value;
    return nvr || !np_instance_of(c) ? (fmi2Status)np_unsupported(c, "fmi2GetString", "no String variables") : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr, (void)value;
    return nvr || !np_instance_of(c) ? (fmi2Status)np_unsupported(c, "fmi2SetString", "no String variables") : fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    INSTANCE(c);
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)np_do_step(in, "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
}

/* ---- not supported (capability flags false in modelDescription.xml) ------------------------ */
#define UNSUPPORTED(name, why) return (fmi2Status)np_unsupported(c, name, why)
fmi2Status fmi2CancelStep(fmi2Component c) { UNSUPPORTED("fmi2CancelStep", "steps are synchronous"); }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetStatus", "steps are synchronous");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetRealStatus", "steps are synchronous");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetIntegerStatus", "steps are synchronous");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetBooleanStatus", "steps are synchronous");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetStringStatus", "steps are synchronous");
}
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; UNSUPPORTED("fmi2GetFMUstate", "no FMU state"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; UNSUPPORTED("fmi2SetFMUstate", "no FMU state"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; UNSUPPORTED("fmi2FreeFMUstate", "no FMU state"); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)s, (void)n;
    UNSUPPORTED("fmi2SerializedFMUstateSize", "no FMU state");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)s, (void)b, (void)n;
    UNSUPPORTED("fmi2SerializeFMUstate", "no FMU state");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)s, (void)b, (void)n;
    UNSUPPORTED("fmi2DeSerializeFMUstate", "no FMU state");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    UNSUPPORTED("fmi2GetDirectionalDerivative", "providesDirectionalDerivative=false");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    UNSUPPORTED("fmi2SetRealInputDerivatives", "canInterpolateInputs=false");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    UNSUPPORTED("fmi2GetRealOutputDerivatives", "maxOutputDerivativeOrder=0");
}
