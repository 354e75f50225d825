/* fmi2.c - FMI 2.0 co-simulation interface of the native diagnostic FMU (C99).
 *
 * State machine (FMI 2.0.4, section 4.2.4): Instantiated -> (fmi2SetupExperiment)
 * fmi2EnterInitializationMode -> Initialization Mode -> fmi2ExitInitializationMode -> Step Mode
 * (stepComplete) -> fmi2Terminate -> Terminated. A call out of order returns fmi2Error with the
 * reason logged and puts the instance in the Error state (fmi2Reset or fmi2FreeInstance only).
 * A step the runtime refuses returns fmi2Discard with the reason logged; the instance stays in
 * Step Mode exactly as before the call (a master may retry with another step, with or without
 * restoring a saved state). Bad values (threshold_scale, FMU states) return fmi2Error, are
 * refused and leave the instance as it was. Error and Fatal messages always reach the logger;
 * the others only with logging on and their category enabled.
 *
 * Memory: the instance is one block from the host's allocateMemory at fmi2Instantiate; the
 * only later allocations are FMU-state objects (fmi2GetFMUstate, fmi2DeSerializeFMUstate),
 * also through allocateMemory, released by fmi2FreeFMUstate.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fdi_glue.h"
#include "fmi2Functions.h"

typedef struct {
    fmi2CallbackFunctions cb;
    char esc[2 * sizeof(((fdi_instance *)0)->msg)];
} fmi2_host;

/* instance block: fdi_instance layout, then the host record */
#define HOST(fi) ((fmi2_host *)(void *)((unsigned char *)(fi) + fdi_instance_bytes((fi)->name)))

static void emit2(void *host, const char *instance, int status, const char *category, const char *msg) {
    fmi2_host *h = host;
    size_t i, j = 0;
    if (!h->cb.logger) return;
    for (i = 0; msg[i] && j + 2 < sizeof h->esc; i++) {  /* the FMI 2.0 message is a printf format */
        if (msg[i] == '%') h->esc[j++] = '%';
        h->esc[j++] = msg[i];
    }
    h->esc[j] = 0;
    h->cb.logger(h->cb.componentEnvironment, instance, (fmi2Status)status, category, h->esc);
}

static void *alloc2(void *host, size_t n) { return ((fmi2_host *)host)->cb.allocateMemory(1, n); }
static void release2(void *host, void *p) { ((fmi2_host *)host)->cb.freeMemory(p); }

static fdi_instance *inst(fmi2Component c) { return fdi_is_instance(c) ? (fdi_instance *)c : NULL; }

#define GUARD(fn, allowed)                                                                                       \
    fdi_instance *fi = inst(c);                                                                                  \
    if (!fi) return fmi2Error;                                                                                   \
    if (!fdi_allowed(fi, fn, allowed)) return fmi2Error

#define ALL (FDI_ALLOW(FDI_M_INSTANTIATED) | FDI_ALLOW(FDI_M_INITIALIZATION) | FDI_ALLOW(FDI_M_STEP) |            \
             FDI_ALLOW(FDI_M_TERMINATED) | FDI_ALLOW(FDI_M_ERROR))
#define NOT_ERROR (ALL & ~FDI_ALLOW(FDI_M_ERROR))
#define GETTABLE (FDI_ALLOW(FDI_M_INITIALIZATION) | FDI_ALLOW(FDI_M_STEP) | FDI_ALLOW(FDI_M_TERMINATED) |          \
                  FDI_ALLOW(FDI_M_ERROR))
#define SETTABLE (FDI_ALLOW(FDI_M_INSTANTIATED) | FDI_ALLOW(FDI_M_INITIALIZATION) | FDI_ALLOW(FDI_M_STEP))

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    const char *name = instanceName ? instanceName : "";
    char why[320];
    size_t nbytes;
    void *block;
    fdi_instance *fi;
    fmi2_host *h;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "fmi2Instantiate: the callback functions allocateMemory and freeMemory are required");
        return NULL;
    }
#define FAIL(...)                                                                                                \
    do {                                                                                                         \
        snprintf(why, sizeof why, __VA_ARGS__);                                                                  \
        if (functions->logger)                                                                                   \
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError", "%s", why);    \
        return NULL;                                                                                             \
    } while (0)
    if (fmuType != fmi2CoSimulation)
        FAIL("fmi2Instantiate: this FMU supports co-simulation only (fmuType %d requested)", (int)fmuType);
    if (!fmuGUID || strcmp(fmuGUID, FDI_TOKEN) != 0)
        FAIL("fmi2Instantiate: GUID %s does not match this FMU's %s (modelDescription.xml of another build?)",
             fmuGUID ? fmuGUID : "(null)", FDI_TOKEN);
    {
        char reason[256];
        if (!fdi_model_consistent(reason, sizeof reason)) FAIL("fmi2Instantiate: %s", reason);
    }
    nbytes = fdi_instance_bytes(name) + sizeof(fmi2_host);
    block = functions->allocateMemory(1, nbytes);
    if (!block) FAIL("fmi2Instantiate: out of memory (%zu bytes)", nbytes);
    h = (fmi2_host *)(void *)((unsigned char *)block + fdi_instance_bytes(name));
    h->cb = *functions;
    fi = fdi_instance_init(block, nbytes - sizeof(fmi2_host), name, emit2, h, alloc2, release2, loggingOn);
    if (!fi) {
        functions->freeMemory(block);
        FAIL("fmi2Instantiate: the runtime refused the design");
    }
#undef FAIL
    fdi_log(fi, FDI_S_OK, FDI_C_ALL, "fmi2Instantiate: %s, %d inputs, %d outputs, Ts = %g s", FDI_MODEL_IDENTIFIER,
            FDI_N_INPUTS, FDI_N_OUTPUTS, fdi_sample_time(&FDI_DESIGN));
    return fi;
}

void fmi2FreeInstance(fmi2Component c) {
    fdi_instance *fi = inst(c);
    fmi2CallbackFreeMemory release;
    if (!fi) return;
    release = HOST(fi)->cb.freeMemory;
    fdi_instance_forget(fi);
    release(fi);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    return (fmi2Status)fdi_set_logging(fi, loggingOn, nCategories, categories, "fmi2SetDebugLogging");
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    GUARD("fmi2SetupExperiment", FDI_ALLOW(FDI_M_INSTANTIATED));
    (void)toleranceDefined;
    (void)tolerance;
    if (!isfinite(startTime) || (stopTimeDefined && !(stopTime >= startTime))) {   /* times are finite */
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi2SetupExperiment: startTime %g, stopTime %g", startTime, stopTime);
        return fmi2Error;
    }
    fi->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    GUARD("fmi2EnterInitializationMode", FDI_ALLOW(FDI_M_INSTANTIATED));
    fi->mode = FDI_M_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    GUARD("fmi2ExitInitializationMode", FDI_ALLOW(FDI_M_INITIALIZATION));
    fi->mode = FDI_M_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    GUARD("fmi2Terminate", FDI_ALLOW(FDI_M_STEP));
    fi->mode = FDI_M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    GUARD("fmi2Reset", ALL);
    fdi_instance_reset(fi);
    return fmi2OK;
}

#define GETTER(NAME, TYPE, KIND, CONVERT)                                                                        \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, TYPE value[]) {                   \
        size_t i;                                                                                                \
        double v;                                                                                                \
        GUARD(#NAME, GETTABLE);                                                                                  \
        if (nvr && (!vr || !value)) {                                                                            \
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, #NAME ": NULL array");                                         \
            return fmi2Error;                                                                                    \
        }                                                                                                        \
        for (i = 0; i < nvr; i++) {                                                                              \
            if (!fdi_get_fast(fi, KIND, vr[i], &v) &&                                                            \
                (vr[i] == FDI_VR_TIME || fdi_get(fi, #NAME, KIND, vr[i], &v) != FDI_S_OK)) {                     \
                if (vr[i] == FDI_VR_TIME)                                                                        \
                    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, #NAME ": no variable has value reference 0");          \
                return fmi2Error;                                                                                \
            }                                                                                                    \
            value[i] = CONVERT;                                                                                  \
        }                                                                                                        \
        return fmi2OK;                                                                                           \
    }

GETTER(fmi2GetReal, fmi2Real, FDI_KIND_REAL, v)
GETTER(fmi2GetInteger, fmi2Integer, FDI_KIND_INTEGER, (fmi2Integer)fdi_int_output(v))
GETTER(fmi2GetBoolean, fmi2Boolean, FDI_KIND_BOOLEAN, v != 0.0 ? fmi2True : fmi2False)

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    GUARD("fmi2GetString", GETTABLE);
    (void)value;
    if (nvr == 0) return fmi2OK;
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi2GetString: this FMU has no String variable (value reference %u)",
            vr ? vr[0] : 0u);
    return fmi2Error;
}

#define SETTER(NAME, TYPE, KIND)                                                                                 \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const TYPE value[]) {             \
        size_t i;                                                                                                \
        GUARD(#NAME, SETTABLE);                                                                                  \
        if (nvr && (!vr || !value)) {                                                                            \
            fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, #NAME ": NULL array");                                         \
            return fmi2Error;                                                                                    \
        }                                                                                                        \
        for (i = 0; i < nvr; i++) {                                                                              \
            if (vr[i] == FDI_VR_TIME) {                                                                          \
                fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, #NAME ": no variable has value reference 0");              \
                return fmi2Error;                                                                                \
            }                                                                                                    \
            if (!fdi_set_fast(fi, KIND, vr[i], (double)value[i]) &&                                              \
                fdi_set(fi, #NAME, KIND, vr[i], (double)value[i]) != FDI_S_OK)                                   \
                return fmi2Error;                                                                                \
        }                                                                                                        \
        return fmi2OK;                                                                                           \
    }

SETTER(fmi2SetReal, fmi2Real, FDI_KIND_REAL)
SETTER(fmi2SetInteger, fmi2Integer, FDI_KIND_INTEGER)
SETTER(fmi2SetBoolean, fmi2Boolean, FDI_KIND_BOOLEAN)

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    GUARD("fmi2SetString", SETTABLE);
    (void)value;
    if (nvr == 0) return fmi2OK;
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi2SetString: this FMU has no String variable (value reference %u)",
            vr ? vr[0] : 0u);
    return fmi2Error;
}

/* ---- FMU state ------------------------------------------------------------------------------ */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    GUARD("fmi2GetFMUstate", NOT_ERROR);
    return (fmi2Status)fdi_state_get(fi, "fmi2GetFMUstate", FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    GUARD("fmi2SetFMUstate", NOT_ERROR);
    return (fmi2Status)fdi_state_set(fi, "fmi2SetFMUstate", FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    return (fmi2Status)fdi_state_free(fi, "fmi2FreeFMUstate", FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    return (fmi2Status)fdi_state_size(fi, "fmi2SerializedFMUstateSize", FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    return (fmi2Status)fdi_state_serialize(fi, "fmi2SerializeFMUstate", FMUstate, (unsigned char *)serializedState,
                                           size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    return (fmi2Status)fdi_state_deserialize(fi, "fmi2DeSerializeFMUstate", (const unsigned char *)serializedState,
                                             size, FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    fdi_instance *fi = inst(c);
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    if (!fi) return fmi2Error;
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi2GetDirectionalDerivative: not provided "
            "(providesDirectionalDerivative=false)");
    return fmi2Error;
}

/* ---- co-simulation ---------------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    fdi_instance *fi = inst(c);
    (void)vr; (void)order; (void)value;
    if (!fi) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi2SetRealInputDerivatives: inputs are sampled, not interpolated "
            "(canInterpolateInputs=false)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    fdi_instance *fi = inst(c);
    (void)vr; (void)order; (void)value;
    if (!fi) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder=0)");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    GUARD("fmi2DoStep", FDI_ALLOW(FDI_M_STEP));
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)fdi_do_step(fi, "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    GUARD("fmi2CancelStep", 0u);  /* no asynchronous step is ever in progress */
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    (void)value;
    fdi_log(fi, FDI_S_DISCARD, FDI_C_DISCARD, "fmi2GetStatus(%d): no asynchronous step, no status to report", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    if (s == fmi2LastSuccessfulTime && value) {
        *value = fi->time;
        return fmi2OK;
    }
    fdi_log(fi, FDI_S_DISCARD, FDI_C_DISCARD, "fmi2GetRealStatus(%d): only fmi2LastSuccessfulTime", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    (void)value;
    fdi_log(fi, FDI_S_DISCARD, FDI_C_DISCARD, "fmi2GetIntegerStatus(%d): no integer status", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    if (s == fmi2Terminated && value) {  /* a refused step never ends the simulation */
        *value = fmi2False;
        return fmi2OK;
    }
    fdi_log(fi, FDI_S_DISCARD, FDI_C_DISCARD, "fmi2GetBooleanStatus(%d): only fmi2Terminated", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    fdi_instance *fi = inst(c);
    if (!fi) return fmi2Error;
    (void)value;
    fdi_log(fi, FDI_S_DISCARD, FDI_C_DISCARD, "fmi2GetStringStatus(%d): no string status", (int)s);
    return fmi2Discard;
}
