/* fmi3.c - FMI 3.0 co-simulation interface of the native diagnostic FMU (C99).
 *
 * State machine (FMI 3.0, section 4.2): Instantiated -> fmi3EnterInitializationMode ->
 * Initialization Mode -> fmi3ExitInitializationMode -> Step Mode (Event Mode first when the
 * importer asked for eventModeUsed; this FMU has no events, fmi3UpdateDiscreteStates reports
 * none) -> fmi3Terminate -> Terminated. A call out of order returns fmi3Error with the reason
 * logged and puts the instance in the Error state (fmi3Reset or fmi3FreeInstance only). A step
 * the runtime refuses returns fmi3Discard with the reason logged and lastSuccessfulTime = the
 * current communication point; the instance stays in Step Mode exactly as before the call.
 * Model-exchange, scheduled-execution, clock and derivative functions return fmi3Error.
 *
 * Variables: Float64 inputs and outputs, Boolean alarms/flags, Int32 isolated_fault, the
 * independent Float64 variable time (value reference 0). Memory: one calloc'd block at
 * instantiation; later only FMU-state objects (fmi3GetFMUState, fmi3DeserializeFMUState),
 * released by fmi3FreeFMUState.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fdi_glue.h"
#include "fmi3Functions.h"

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} fmi3_host;

#define HOST(fi) ((fmi3_host *)(void *)((unsigned char *)(fi) + fdi_instance_bytes((fi)->name)))

static void emit3(void *host, const char *instance, int status, const char *category, const char *msg) {
    fmi3_host *h = host;
    (void)instance;
    if (h->log) h->log(h->env, (fmi3Status)status, category, msg);
}

static void *alloc3(void *host, size_t n) { (void)host; return calloc(1, n); }
static void release3(void *host, void *p) { (void)host; free(p); }

static fdi_instance *inst(fmi3Instance c) { return fdi_is_instance(c) ? (fdi_instance *)c : NULL; }

#define GUARD(fn, allowed)                                                                                       \
    fdi_instance *fi = inst(instance);                                                                           \
    if (!fi) return fmi3Error;                                                                                   \
    if (!fdi_allowed(fi, fn, allowed)) return fmi3Error

#define ALL FDI_ANY_MODE
#define NOT_ERROR (ALL & ~FDI_ALLOW(FDI_M_ERROR))
#define GETTABLE (FDI_ALLOW(FDI_M_INITIALIZATION) | FDI_ALLOW(FDI_M_EVENT) | FDI_ALLOW(FDI_M_STEP) |              \
                  FDI_ALLOW(FDI_M_TERMINATED) | FDI_ALLOW(FDI_M_ERROR))
#define SETTABLE (FDI_ALLOW(FDI_M_INSTANTIATED) | FDI_ALLOW(FDI_M_INITIALIZATION) | FDI_ALLOW(FDI_M_EVENT) |       \
                  FDI_ALLOW(FDI_M_STEP))

static fmi3Status unsupported(fmi3Instance instance, const char *fn, const char *why) {
    fdi_instance *fi = inst(instance);
    if (!fi) return fmi3Error;
    fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "%s: not supported by this FMU (%s)", fn, why);
    return fmi3Error;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    fdi_instance *fi = inst(instance);
    if (!fi) return fmi3Error;
    return (fmi3Status)fdi_set_logging(fi, loggingOn, nCategories, categories, "fmi3SetDebugLogging");
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    const char *name = instanceName ? instanceName : "";
    char why[320];
    size_t nbytes;
    void *block;
    fdi_instance *fi;
    fmi3_host *h;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
#define FAIL(...)                                                                                                \
    do {                                                                                                         \
        snprintf(why, sizeof why, __VA_ARGS__);                                                                  \
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", why);                        \
        return NULL;                                                                                             \
    } while (0)
    if (!instantiationToken || strcmp(instantiationToken, FDI_TOKEN) != 0)
        FAIL("fmi3InstantiateCoSimulation: instantiationToken %s does not match this FMU's %s (modelDescription.xml "
             "of another build?)", instantiationToken ? instantiationToken : "(null)", FDI_TOKEN);
    if (nRequiredIntermediateVariables > 0)
        FAIL("fmi3InstantiateCoSimulation: this FMU has no intermediate variables (%zu requested)",
             nRequiredIntermediateVariables);
    {
        char reason[256];
        if (!fdi_model_consistent(reason, sizeof reason)) FAIL("fmi3InstantiateCoSimulation: %s", reason);
    }
    nbytes = fdi_instance_bytes(name) + sizeof(fmi3_host);
    block = calloc(1, nbytes);
    if (!block) FAIL("fmi3InstantiateCoSimulation: out of memory (%zu bytes)", nbytes);
    h = (fmi3_host *)(void *)((unsigned char *)block + fdi_instance_bytes(name));
    h->env = instanceEnvironment;
    h->log = logMessage;
    fi = fdi_instance_init(block, nbytes - sizeof(fmi3_host), name, emit3, h, alloc3, release3, loggingOn);
    if (!fi) {
        free(block);
        FAIL("fmi3InstantiateCoSimulation: the runtime refused the design");
    }
#undef FAIL
    fi->event_mode_used = eventModeUsed;
    fdi_log(fi, FDI_S_OK, FDI_C_ALL, "fmi3InstantiateCoSimulation: %s, %d inputs, %d outputs, Ts = %g s",
            FDI_MODEL_IDENTIFIER, FDI_N_INPUTS, FDI_N_OUTPUTS, fdi_sample_time(&FDI_DESIGN));
    return fi;
}

void fmi3FreeInstance(fmi3Instance instance) {
    fdi_instance *fi = inst(instance);
    if (!fi) return;
    fdi_instance_forget(fi);
    free(fi);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    GUARD("fmi3EnterInitializationMode", FDI_ALLOW(FDI_M_INSTANTIATED));
    (void)toleranceDefined;
    (void)tolerance;
    if (!isfinite(startTime) || (stopTimeDefined && !(stopTime >= startTime))) {   /* times are finite */
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi3EnterInitializationMode: startTime %g, stopTime %g", startTime,
                stopTime);
        return fmi3Error;
    }
    fi->time = startTime;
    fi->mode = FDI_M_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    GUARD("fmi3ExitInitializationMode", FDI_ALLOW(FDI_M_INITIALIZATION));
    fi->mode = fi->event_mode_used ? FDI_M_EVENT : FDI_M_STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    GUARD("fmi3EnterEventMode", FDI_ALLOW(FDI_M_STEP) | FDI_ALLOW(FDI_M_EVENT));
    if (!fi->event_mode_used) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi3EnterEventMode: the instance was created with eventModeUsed=false");
        fi->mode = FDI_M_ERROR;
        return fmi3Error;
    }
    fi->mode = FDI_M_EVENT;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    GUARD("fmi3EnterStepMode", FDI_ALLOW(FDI_M_EVENT));
    fi->mode = FDI_M_STEP;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    GUARD("fmi3UpdateDiscreteStates", FDI_ALLOW(FDI_M_EVENT));
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = fmi3False;
    if (valuesOfContinuousStatesChanged) *valuesOfContinuousStatesChanged = fmi3False;
    if (nextEventTimeDefined) *nextEventTimeDefined = fmi3False;
    if (nextEventTime) *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    GUARD("fmi3Terminate", FDI_ALLOW(FDI_M_STEP) | FDI_ALLOW(FDI_M_EVENT));
    fi->mode = FDI_M_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    GUARD("fmi3Reset", ALL);
    fdi_instance_reset(fi);
    return fmi3OK;
}

/* ---- variables ------------------------------------------------------------------------------- */
#define CHECK_ARRAYS(fn)                                                                                         \
    if (nValueReferences && (!valueReferences || !values)) {                                                     \
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, fn ": NULL array");                                                \
        return fmi3Error;                                                                                        \
    }                                                                                                            \
    if (nValues != nValueReferences) {                                                                           \
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, fn ": %zu values for %zu scalar variables", nValues,                \
                nValueReferences);                                                                               \
        return fmi3Error;                                                                                        \
    }

#define GETTER(NAME, TYPE, KIND, CONVERT)                                                                        \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,    \
                    TYPE values[], size_t nValues) {                                                             \
        size_t i;                                                                                                \
        double v;                                                                                                \
        GUARD(#NAME, GETTABLE);                                                                                  \
        CHECK_ARRAYS(#NAME)                                                                                      \
        for (i = 0; i < nValueReferences; i++) {                                                                 \
            if (!fdi_get_fast(fi, KIND, valueReferences[i], &v) &&                                               \
                fdi_get(fi, #NAME, KIND, valueReferences[i], &v) != FDI_S_OK)                                    \
                return fmi3Error;                                                                                \
            values[i] = CONVERT;                                                                                 \
        }                                                                                                        \
        return fmi3OK;                                                                                           \
    }

GETTER(fmi3GetFloat64, fmi3Float64, FDI_KIND_REAL, v)
GETTER(fmi3GetInt32, fmi3Int32, FDI_KIND_INTEGER, (fmi3Int32)fdi_int_output(v))
GETTER(fmi3GetBoolean, fmi3Boolean, FDI_KIND_BOOLEAN, v != 0.0)

#define SETTER(NAME, TYPE, KIND)                                                                                 \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,    \
                    const TYPE values[], size_t nValues) {                                                       \
        size_t i;                                                                                                \
        GUARD(#NAME, SETTABLE);                                                                                  \
        CHECK_ARRAYS(#NAME)                                                                                      \
        for (i = 0; i < nValueReferences; i++)                                                                   \
            if (!fdi_set_fast(fi, KIND, valueReferences[i], (double)values[i]) &&                                \
                fdi_set(fi, #NAME, KIND, valueReferences[i], (double)values[i]) != FDI_S_OK)                     \
                return fmi3Error;                                                                                \
        return fmi3OK;                                                                                           \
    }

SETTER(fmi3SetFloat64, fmi3Float64, FDI_KIND_REAL)
SETTER(fmi3SetInt32, fmi3Int32, FDI_KIND_INTEGER)
SETTER(fmi3SetBoolean, fmi3Boolean, FDI_KIND_BOOLEAN)

/* types this FMU has no variable of: an empty request is fine, anything else an error */
#define NO_SUCH_TYPE(NAME, TYPE, CONST)                                                                          \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,    \
                    CONST TYPE values[], size_t nValues) {                                                       \
        GUARD(#NAME, GETTABLE | SETTABLE);                                                                       \
        (void)values; (void)nValues;                                                                             \
        if (nValueReferences == 0) return fmi3OK;                                                                \
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, #NAME ": this FMU has no variable of this type (value reference %u)",  \
                valueReferences ? valueReferences[0] : 0u);                                                      \
        return fmi3Error;                                                                                        \
    }

NO_SUCH_TYPE(fmi3GetFloat32, fmi3Float32, )
NO_SUCH_TYPE(fmi3GetInt8, fmi3Int8, )
NO_SUCH_TYPE(fmi3GetUInt8, fmi3UInt8, )
NO_SUCH_TYPE(fmi3GetInt16, fmi3Int16, )
NO_SUCH_TYPE(fmi3GetUInt16, fmi3UInt16, )
NO_SUCH_TYPE(fmi3GetUInt32, fmi3UInt32, )
NO_SUCH_TYPE(fmi3GetInt64, fmi3Int64, )
NO_SUCH_TYPE(fmi3GetUInt64, fmi3UInt64, )
NO_SUCH_TYPE(fmi3GetString, fmi3String, )
NO_SUCH_TYPE(fmi3SetFloat32, fmi3Float32, const)
NO_SUCH_TYPE(fmi3SetInt8, fmi3Int8, const)
NO_SUCH_TYPE(fmi3SetUInt8, fmi3UInt8, const)
NO_SUCH_TYPE(fmi3SetInt16, fmi3Int16, const)
NO_SUCH_TYPE(fmi3SetUInt16, fmi3UInt16, const)
NO_SUCH_TYPE(fmi3SetUInt32, fmi3UInt32, const)
NO_SUCH_TYPE(fmi3SetInt64, fmi3Int64, const)
NO_SUCH_TYPE(fmi3SetUInt64, fmi3UInt64, const)
NO_SUCH_TYPE(fmi3SetString, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    return nValueReferences == 0 && inst(instance) ? fmi3OK : unsupported(instance, "fmi3GetBinary", "no Binary variable");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    return nValueReferences == 0 && inst(instance) ? fmi3OK : unsupported(instance, "fmi3SetBinary", "no Binary variable");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) {
    (void)valueReferences; (void)values;
    return nValueReferences == 0 && inst(instance) ? fmi3OK : unsupported(instance, "fmi3GetClock", "no clocks");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) {
    (void)valueReferences; (void)values;
    return nValueReferences == 0 && inst(instance) ? fmi3OK : unsupported(instance, "fmi3SetClock", "no clocks");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference; (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies", "providesPerElementDependencies=false");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies", "providesPerElementDependencies=false");
}

/* ---- FMU state ------------------------------------------------------------------------------ */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    GUARD("fmi3GetFMUState", NOT_ERROR);
    return (fmi3Status)fdi_state_get(fi, "fmi3GetFMUState", FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    GUARD("fmi3SetFMUState", NOT_ERROR);
    return (fmi3Status)fdi_state_set(fi, "fmi3SetFMUState", FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    fdi_instance *fi = inst(instance);
    if (!fi) return fmi3Error;
    return (fmi3Status)fdi_state_free(fi, "fmi3FreeFMUState", FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    fdi_instance *fi = inst(instance);
    if (!fi) return fmi3Error;
    return (fmi3Status)fdi_state_size(fi, "fmi3SerializedFMUStateSize", FMUState, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    fdi_instance *fi = inst(instance);
    if (!fi) return fmi3Error;
    return (fmi3Status)fdi_state_serialize(fi, "fmi3SerializeFMUState", FMUState, serializedState, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    fdi_instance *fi = inst(instance);
    if (!fi) return fmi3Error;
    return (fmi3Status)fdi_state_deserialize(fi, "fmi3DeserializeFMUState", serializedState, size, FMUState);
}

/* ---- derivatives, configuration, clocks, model exchange: not provided ----------------------------- */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "fmi3GetDirectionalDerivative", "providesDirectionalDerivatives=false");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "fmi3GetAdjointDerivative", "providesAdjointDerivatives=false");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterConfigurationMode", "no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3ExitConfigurationMode", "no structural parameters");
}

#define NO_CLOCK_GET(NAME, ...)                                                                                  \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,    \
                    __VA_ARGS__) {                                                                               \
        (void)valueReferences; (void)nValueReferences;                                                           \
        return unsupported(instance, #NAME, "no clocks");                                                        \
    }

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals; (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalDecimal", "no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions; (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalFraction", "no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return unsupported(instance, "fmi3GetShiftDecimal", "no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3GetShiftFraction", "no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals;
    return unsupported(instance, "fmi3SetIntervalDecimal", "no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetIntervalFraction", "no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return unsupported(instance, "fmi3SetShiftDecimal", "no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetShiftFraction", "no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return unsupported(instance, "fmi3EvaluateDiscreteStates", "co-simulation only");
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterContinuousTimeMode", "co-simulation only");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    return unsupported(instance, "fmi3CompletedIntegratorStep", "co-simulation only");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    return unsupported(instance, "fmi3SetTime", "co-simulation only");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return unsupported(instance, "fmi3SetContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives; (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStateDerivatives", "co-simulation only");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators; (void)nEventIndicators;
    return unsupported(instance, "fmi3GetEventIndicators", "co-simulation only");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals; (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNominalsOfContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    fdi_instance *fi = inst(instance);
    if (!fi || !nEventIndicators) return fmi3Error;
    *nEventIndicators = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    fdi_instance *fi = inst(instance);
    if (!fi || !nContinuousStates) return fmi3Error;
    *nContinuousStates = 0;
    return fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)valueReferences; (void)orders; (void)values; (void)nValues;
    return nValueReferences == 0 && inst(instance) ? fmi3OK
                                                   : unsupported(instance, "fmi3GetOutputDerivatives",
                                                                 "maxOutputDerivativeOrder=0");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    int s;
    GUARD("fmi3DoStep", FDI_ALLOW(FDI_M_STEP));
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        fdi_log(fi, FDI_S_ERROR, FDI_C_ERROR, "fmi3DoStep: NULL output argument");
        return fmi3Error;
    }
    s = fdi_do_step(fi, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = s == FDI_S_OK ? fi->time : currentCommunicationPoint;
    return (fmi3Status)s;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition", "co-simulation only");
}
