/* fmi2_plant.c - FMI 2.0 co-simulation interface of the native benchmark plants (C99).
 *
 * The variables are the pythonfmu plant's (np_vars.h: same names, value references, types,
 * causality, variability and start values). Setting rules: a fixed parameter until
 * fmi2ExitInitializationMode, a tunable parameter or an input until fmi2Terminate, an output
 * never (fmi2Error). fmi2ExitInitializationMode runs the checks of the Python plant's
 * exit_initialization_mode and the plant's initialisation (state at the start time, first
 * outputs); a failure there returns fmi2Error with the reason logged. A failed step (non-finite
 * input, integrator failure) logs the reason with fmi2Error and returns fmi2Discard, and so does
 * every later step, as the Python plant does. Error messages always reach the logger; fmi2OK ones
 * are not sent.
 *
 * Memory: one block (instance record + plant state) from the host's allocateMemory at
 * fmi2Instantiate, released at fmi2FreeInstance; nothing else is allocated. No global mutable
 * state. FMU states are not supported (canGetAndSetFMUstate="false", as the pythonfmu plant).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "np_plant.h"

enum { M_INSTANTIATED, M_INITIALIZATION, M_STEP, M_TERMINATED };
enum { K_REAL, K_INTEGER, K_BOOLEAN };
enum { C_FIXED, C_TUNABLE, C_INPUT, C_OUTPUT };

static const int var_kinds[NP_N_VARS] = NP_VAR_KINDS;
static const int var_causality[NP_N_VARS] = NP_VAR_CAUSALITY;
static const double var_starts[NP_N_VARS] = NP_VAR_STARTS;
static const char *const var_names[NP_N_VARS] = NP_VAR_NAMES;

typedef struct {
    unsigned magic;
    np_plant plant;
    fmi2CallbackFunctions cb;
    char name[128];
    char esc[2 * sizeof(((np_plant *)0)->error) + 64];
    int mode, failed, logging;
} instance;

#define MAGIC 0x4e504c54u /* "NPLT" */

static instance *inst(fmi2Component c) {
    instance *in = c;
    return in && in->magic == MAGIC ? in : NULL;
}

static fmi2Status report(instance *in, fmi2Status status, const char *fmt, const char *a, const char *b) {
    char msg[sizeof in->esc / 2];
    size_t i, j = 0;
    snprintf(msg, sizeof msg, fmt, a, b);
    for (i = 0; msg[i] && j + 2 < sizeof in->esc; i++) { /* the FMI 2.0 message is a printf format */
        if (msg[i] == '%') in->esc[j++] = '%';
        in->esc[j++] = msg[i];
    }
    in->esc[j] = 0;
    if (in->cb.logger)
        in->cb.logger(in->cb.componentEnvironment, in->name, status,
                      status == fmi2Discard ? "logStatusDiscard" : "logStatusError", in->esc);
    return status;
}

static void reset_values(instance *in) {
    int vr;
    for (vr = 0; vr < NP_N_VARS; vr++) in->plant.v[vr] = var_starts[vr];
    in->mode = M_INSTANTIATED;
    in->failed = 0;
    in->plant.error[0] = 0;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    const char *name = instanceName ? instanceName : "";
    size_t bytes = sizeof(instance) + np_plant_state_size();
    instance *in;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
#define REFUSE(msg)                                                                                        \
    do {                                                                                                   \
        if (functions->logger) functions->logger(functions->componentEnvironment, name, fmi2Error,        \
                                                 "logStatusError", msg);                                   \
        return NULL;                                                                                       \
    } while (0)
    if (fmuType != fmi2CoSimulation) REFUSE("fmi2Instantiate: this FMU supports co-simulation only");
    if (!fmuGUID || strcmp(fmuGUID, NP_GUID) != 0)
        REFUSE("fmi2Instantiate: the GUID does not match this FMU's modelDescription.xml");
    in = functions->allocateMemory(1, bytes);
    if (!in) REFUSE("fmi2Instantiate: out of memory");
#undef REFUSE
    memset(in, 0, bytes);
    in->magic = MAGIC;
    in->cb = *functions;
    snprintf(in->name, sizeof in->name, "%s", name);
    in->plant.state = (np_plant_state *)(void *)(in + 1);
    in->logging = loggingOn != 0;
    reset_values(in);
    return in;
}

void fmi2FreeInstance(fmi2Component c) {
    instance *in = inst(c);
    if (!in) return;
    in->magic = 0;
    in->cb.freeMemory(in);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[]) {
    instance *in = inst(c);
    (void)n;
    (void)categories;
    if (!in) return fmi2Error;
    in->logging = loggingOn != 0;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    instance *in = inst(c);
    (void)toleranceDefined, (void)tolerance, (void)startTime, (void)stopTimeDefined, (void)stopTime;
    if (!in) return fmi2Error;
    if (in->mode != M_INSTANTIATED) return report(in, fmi2Error, "%s%s", "fmi2SetupExperiment: ", "only after fmi2Instantiate");
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    instance *in = inst(c);
    if (!in) return fmi2Error;
    if (in->mode != M_INSTANTIATED) return report(in, fmi2Error, "%s%s", "fmi2EnterInitializationMode: ", "only after fmi2Instantiate or fmi2Reset");
    in->mode = M_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    instance *in = inst(c);
    if (!in) return fmi2Error;
    if (in->mode != M_INITIALIZATION) return report(in, fmi2Error, "%s%s", "fmi2ExitInitializationMode: ", "not in initialization mode");
    in->mode = M_STEP;
    if (np_start(&in->plant) || np_plant_initialize(&in->plant)) {
        in->failed = 1;
        return report(in, fmi2Error, "initialisation failed: %s%s", in->plant.error, "");
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    instance *in = inst(c);
    if (!in) return fmi2Error;
    in->mode = M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    instance *in = inst(c);
    if (!in) return fmi2Error;
    reset_values(in);
    return fmi2OK;
}

/* ---- values --------------------------------------------------------------------------------- */
static fmi2Status check_vr(instance *in, fmi2ValueReference vr, int kind, const char *fn) {
    static const char *const kinds[3] = {"Real", "Integer", "Boolean"};
    char buf[160];
    if (vr >= NP_N_VARS) {
        snprintf(buf, sizeof buf, "%u", (unsigned)vr);
        return report(in, fmi2Error, "%s: no variable with value reference %s", fn, buf);
    }
    if (var_kinds[vr] != kind) {
        snprintf(buf, sizeof buf, "%s is %s, not %s", var_names[vr], kinds[var_kinds[vr]], kinds[kind]);
        return report(in, fmi2Error, "%s: variable %s", fn, buf);
    }
    return fmi2OK;
}

static fmi2Status check_set(instance *in, fmi2ValueReference vr, const char *fn) {
    int c = var_causality[vr];
    if (c == C_OUTPUT) return report(in, fmi2Error, "%s: %s is an output and cannot be set", fn, var_names[vr]);
    if (c == C_FIXED && in->mode != M_INSTANTIATED && in->mode != M_INITIALIZATION)
        return report(in, fmi2Error, "%s: %s is a fixed parameter, settable only before initialisation ends", fn,
                      var_names[vr]);
    if (in->mode == M_TERMINATED) return report(in, fmi2Error, "%s: %s cannot be set after fmi2Terminate", fn, var_names[vr]);
    return fmi2OK;
}

/* every value reference exists and has the type; for a setter also settable now (all or nothing) */
static fmi2Status checked(instance *in, const fmi2ValueReference vr[], size_t nvr, int kind, const char *fn, int set) {
    size_t i;
    for (i = 0; i < nvr; i++)
        if (check_vr(in, vr[i], kind, fn) || (set && check_set(in, vr[i], fn))) return fmi2Error;
    return fmi2OK;
}

#define ACCESS(in, kind, fn, set, body)                                                                    \
    instance *in = inst(c);                                                                                \
    size_t i;                                                                                              \
    if (!in || checked(in, vr, nvr, kind, fn, set)) return fmi2Error;                                      \
    for (i = 0; i < nvr; i++) body;                                                                        \
    return fmi2OK

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    ACCESS(in, K_REAL, "fmi2GetReal", 0, value[i] = in->plant.v[vr[i]]);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    ACCESS(in, K_INTEGER, "fmi2GetInteger", 0, value[i] = (fmi2Integer)in->plant.v[vr[i]]);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    ACCESS(in, K_BOOLEAN, "fmi2GetBoolean", 0, value[i] = in->plant.v[vr[i]] != 0.0 ? fmi2True : fmi2False);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    instance *in = inst(c);
    (void)vr, (void)value;
    if (!in) return fmi2Error;
    return nvr ? report(in, fmi2Error, "%s%s", "fmi2GetString: ", "this FMU has no String variables") : fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    ACCESS(in, K_REAL, "fmi2SetReal", 1, in->plant.v[vr[i]] = value[i]);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    ACCESS(in, K_INTEGER, "fmi2SetInteger", 1, in->plant.v[vr[i]] = value[i]);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    ACCESS(in, K_BOOLEAN, "fmi2SetBoolean", 1, in->plant.v[vr[i]] = value[i] ? 1.0 : 0.0);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    instance *in = inst(c);
    (void)vr, (void)value;
    if (!in) return fmi2Error;
    return nvr ? report(in, fmi2Error, "%s%s", "fmi2SetString: ", "this FMU has no String variables") : fmi2OK;
}

/* ---- stepping ------------------------------------------------------------------------------- */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    instance *in = inst(c);
    char t[40], h[40];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!in) return fmi2Error;
    if (in->mode != M_STEP) return report(in, fmi2Error, "%s%s", "fmi2DoStep: ", "not in step mode");
    snprintf(t, sizeof t, "%.17g", currentCommunicationPoint);
    if (in->failed) return report(in, fmi2Discard, "cannot step at t=%s: %s", t, in->plant.error);
    if (!(communicationStepSize > 0)) {
        snprintf(h, sizeof h, "%.17g", communicationStepSize);
        np_fail(&in->plant, "communication step must be > 0, got %s", h);
    } else if (np_check_inputs(&in->plant) == 0 && np_plant_advance(&in->plant, communicationStepSize) == 0) {
        return fmi2OK;
    }
    in->failed = 1;
    return report(in, fmi2Discard, "step at t=%s failed: %s", t, in->plant.error);
}


static fmi2Status no_status(fmi2Component c, const fmi2StatusKind s) {
    instance *in = inst(c);
    (void)s;
    return in ? report(in, fmi2Discard, "%s%s", "fmi2Get*Status: ", "no asynchronous steps, nothing to report") : fmi2Error;
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) { (void)value; return no_status(c, s); }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) { (void)value; return no_status(c, s); }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) { (void)value; return no_status(c, s); }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) { (void)value; return no_status(c, s); }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) { (void)value; return no_status(c, s); }

/* ---- not supported (capability flags false in modelDescription.xml) ------------------------ */
static fmi2Status unsupported(fmi2Component c, const char *fn) {
    instance *in = inst(c);
    return in ? report(in, fmi2Error, "%s: %s", fn, "not supported by this FMU") : fmi2Error;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2GetFMUstate"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return unsupported(c, "fmi2SetFMUstate"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2FreeFMUstate"); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)s, (void)n;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)s, (void)b, (void)n;
    return unsupported(c, "fmi2SerializeFMUstate");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)s, (void)b, (void)n;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}
