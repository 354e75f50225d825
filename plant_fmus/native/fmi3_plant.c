/* fmi3_plant.c - FMI 3.0 co-simulation interface of the native benchmark plants (C99): the FMI 3.0
 * calling convention around np_glue.c (rules, checks, initialisation and the step are there).
 * The variables are the FMI 2.0 plant's (same value references; Real -> Float64, Integer -> Int32),
 * plus the independent variable time (value reference NP_N_VARS). No event mode, no clocks, no
 * FMU state. Memory: one calloc at fmi3InstantiateCoSimulation, freed at fmi3FreeInstance. */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "np_glue.h"

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} host3;

static void emit3(void *host, const char *instance, int status, const char *category, const char *msg) {
    host3 *h = host;
    (void)instance;
    if (h->log) h->log(h->env, (fmi3Status)status, category, msg);
}

#define HOST(in) ((host3 *)(void *)((unsigned char *)(in) + np_instance_bytes()))
#define INSTANCE(c)                                                                                        \
    np_instance *in = np_instance_of(c);                                                                   \
    if (!in) return fmi3Error
#define TIME_VR ((fmi3ValueReference)NP_N_VARS)

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    const char *why = NULL;
    void *block = NULL;
    np_instance *in;
    (void)instanceName, (void)resourcePath, (void)visible, (void)loggingOn, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)intermediateUpdate;
    if (!instantiationToken || strcmp(instantiationToken, NP_GUID) != 0)
        why = "fmi3InstantiateCoSimulation: the instantiationToken does not match this FMU's modelDescription.xml";
    else if (eventModeUsed) why = "fmi3InstantiateCoSimulation: this FMU has no event mode (hasEventMode=false)";
    else if (nRequiredIntermediateVariables) why = "fmi3InstantiateCoSimulation: this FMU has no intermediate variables";
    else if (!(block = calloc(1, np_instance_bytes() + sizeof(host3)))) why = "fmi3InstantiateCoSimulation: out of memory";
    if (why) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", why);
        return NULL;
    }
    in = np_instance_init(block, instanceName, emit3, NULL);
    in->host = HOST(in);
    HOST(in)->env = instanceEnvironment;
    HOST(in)->log = logMessage;
    return in;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU supports co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    np_instance *in = np_instance_of(instance);
    if (!in) return;
    np_instance_release(in);
    free(in);
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t n, const fmi3String categories[]) {
    INSTANCE(instance);
    (void)loggingOn, (void)n, (void)categories, (void)in;
    return fmi3OK; /* only Error and Discard messages are ever sent */
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    int s;
    INSTANCE(instance);
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    s = np_enter_initialization(in, "fmi3EnterInitializationMode");
    if (s == NP_OK) in->time = startTime;
    return (fmi3Status)s;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    INSTANCE(instance);
    return (fmi3Status)np_exit_initialization(in, "fmi3ExitInitializationMode");
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    INSTANCE(instance);
    return (fmi3Status)np_terminate(in, "fmi3Terminate");
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    INSTANCE(instance);
    np_reset(in);
    return fmi3OK;
}

/* ---- variables ------------------------------------------------------------------------------ */
#define ACCESS(NAME, TYPE, CONST, KIND, SET, body)                                                         \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    CONST TYPE values[], size_t nValues) {                                                 \
        size_t i;                                                                                          \
        INSTANCE(instance);                                                                                \
        if (nValues != nValueReferences || (nValues && !values))                                          \
            return (fmi3Status)np_report(in, NP_ERROR, "%s: %zu values for %zu variables", #NAME, nValues,  \
                                         nValueReferences);                                                \
        for (i = 0; i < nValueReferences; i++) {                                                           \
            fmi3ValueReference vr = valueReferences[i];                                                    \
            if (!(KIND == NP_REAL && !SET && vr == TIME_VR) && np_check_access(in, #NAME, &vr, 1, KIND, SET)) \
                return fmi3Error;                                                                          \
        }                                                                                                  \
        for (i = 0; i < nValueReferences; i++) body;                                                       \
        return fmi3OK;                                                                                     \
    }

ACCESS(fmi3GetFloat64, fmi3Float64, , NP_REAL, 0,
       values[i] = valueReferences[i] == TIME_VR ? in->time : in->plant.v[valueReferences[i]])
ACCESS(fmi3GetInt32, fmi3Int32, , NP_INTEGER, 0, values[i] = (fmi3Int32)in->plant.v[valueReferences[i]])
ACCESS(fmi3GetBoolean, fmi3Boolean, , NP_BOOLEAN, 0, values[i] = in->plant.v[valueReferences[i]] != 0.0)
ACCESS(fmi3SetFloat64, fmi3Float64, const, NP_REAL, 1, in->plant.v[valueReferences[i]] = values[i])
ACCESS(fmi3SetInt32, fmi3Int32, const, NP_INTEGER, 1, in->plant.v[valueReferences[i]] = values[i])
ACCESS(fmi3SetBoolean, fmi3Boolean, const, NP_BOOLEAN, 1, in->plant.v[valueReferences[i]] = values[i] ? 1.0 : 0.0)

/* types this FMU has no variable of: an empty request is fine, anything else an error */
#define NO_SUCH_TYPE(NAME, TYPE, CONST)                                                                    \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    CONST TYPE values[], size_t nValues) {                                                 \
        (void)valueReferences, (void)values, (void)nValues;                                                \
        if (nValueReferences == 0 && np_instance_of(instance)) return fmi3OK;                              \
        return (fmi3Status)np_unsupported(instance, #NAME, "no variable of this type");                    \
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
    (void)valueReferences, (void)valueSizes, (void)values, (void)nValues;
    if (nValueReferences == 0 && np_instance_of(instance)) return fmi3OK;
    return (fmi3Status)np_unsupported(instance, "fmi3GetBinary", "no Binary variable");
}
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueReferences, (void)valueSizes, (void)values, (void)nValues;
    if (nValueReferences == 0 && np_instance_of(instance)) return fmi3OK;
    return (fmi3Status)np_unsupported(instance, "fmi3SetBinary", "no Binary variable");
}

/* ---- stepping ------------------------------------------------------------------------------- */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    int s;
    INSTANCE(instance);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime)
        return (fmi3Status)np_report(in, NP_ERROR, "%s", "fmi3DoStep: NULL output argument");
    s = np_do_step(in, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = s == NP_OK ? in->time : currentCommunicationPoint;
    return (fmi3Status)s;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    INSTANCE(instance);
    (void)in;
    if (!n) return fmi3Error;
    *n = 0;
    return fmi3OK;
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    INSTANCE(instance);
    (void)in;
    if (!n) return fmi3Error;
    *n = 0;
    return fmi3OK;
}

/* ---- not supported (capability flags false in modelDescription.xml) ------------------------ */
#define UNSUPPORTED(name, why) return (fmi3Status)np_unsupported(instance, name, why)
fmi3Status fmi3EnterEventMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterEventMode", "hasEventMode=false"); }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterStepMode", "hasEventMode=false"); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *a, fmi3Boolean *b, fmi3Boolean *c,
                                    fmi3Boolean *d, fmi3Boolean *e, fmi3Float64 *f) {
    (void)a, (void)b, (void)c, (void)d, (void)e, (void)f;
    UNSUPPORTED("fmi3UpdateDiscreteStates", "hasEventMode=false");
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Clock values[]) {
    (void)vr, (void)n, (void)values;
    UNSUPPORTED("fmi3GetClock", "no clocks");
}
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Clock values[]) {
    (void)vr, (void)n, (void)values;
    UNSUPPORTED("fmi3SetClock", "no clocks");
}
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    (void)vr, (void)n;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies", "providesPerElementDependencies=false");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t a[],
                                       fmi3ValueReference b[], size_t c[], fmi3DependencyKind d[], size_t n) {
    (void)dependent, (void)a, (void)b, (void)c, (void)d, (void)n;
    UNSUPPORTED("fmi3GetVariableDependencies", "providesPerElementDependencies=false");
}
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *s) { (void)s; UNSUPPORTED("fmi3GetFMUState", "no FMU state"); }
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState s) { (void)s; UNSUPPORTED("fmi3SetFMUState", "no FMU state"); }
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *s) { (void)s; UNSUPPORTED("fmi3FreeFMUState", "no FMU state"); }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState s, size_t *n) {
    (void)s, (void)n;
    UNSUPPORTED("fmi3SerializedFMUStateSize", "no FMU state");
}
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState s, fmi3Byte b[], size_t n) {
    (void)s, (void)b, (void)n;
    UNSUPPORTED("fmi3SerializeFMUState", "no FMU state");
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte b[], size_t n, fmi3FMUState *s) {
    (void)b, (void)n, (void)s;
    UNSUPPORTED("fmi3DeserializeFMUState", "no FMU state");
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference u[], size_t nu,
                                        const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[], size_t ns,
                                        fmi3Float64 sens[], size_t nsens) {
    (void)u, (void)nu, (void)k, (void)nk, (void)seed, (void)ns, (void)sens, (void)nsens;
    UNSUPPORTED("fmi3GetDirectionalDerivative", "providesDirectionalDerivatives=false");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[], size_t ns,
                                    fmi3Float64 sens[], size_t nsens) {
    (void)u, (void)nu, (void)k, (void)nk, (void)seed, (void)ns, (void)sens, (void)nsens;
    UNSUPPORTED("fmi3GetAdjointDerivative", "providesAdjointDerivatives=false");
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterConfigurationMode", "no structural parameters"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { UNSUPPORTED("fmi3ExitConfigurationMode", "no structural parameters"); }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 a[],
                                  fmi3IntervalQualifier q[]) {
    (void)vr, (void)n, (void)a, (void)q;
    UNSUPPORTED("fmi3GetIntervalDecimal", "no clocks");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt64 a[],
                                   fmi3UInt64 b[], fmi3IntervalQualifier q[]) {
    (void)vr, (void)n, (void)a, (void)b, (void)q;
    UNSUPPORTED("fmi3GetIntervalFraction", "no clocks");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 a[]) {
    (void)vr, (void)n, (void)a;
    UNSUPPORTED("fmi3GetShiftDecimal", "no clocks");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt64 a[],
                                fmi3UInt64 b[]) {
    (void)vr, (void)n, (void)a, (void)b;
    UNSUPPORTED("fmi3GetShiftFraction", "no clocks");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Float64 a[]) {
    (void)vr, (void)n, (void)a;
    UNSUPPORTED("fmi3SetIntervalDecimal", "no clocks");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 a[],
                                   const fmi3UInt64 b[]) {
    (void)vr, (void)n, (void)a, (void)b;
    UNSUPPORTED("fmi3SetIntervalFraction", "no clocks");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Float64 a[]) {
    (void)vr, (void)n, (void)a;
    UNSUPPORTED("fmi3SetShiftDecimal", "no clocks");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 a[],
                                const fmi3UInt64 b[]) {
    (void)vr, (void)n, (void)a, (void)b;
    UNSUPPORTED("fmi3SetShiftFraction", "no clocks");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { UNSUPPORTED("fmi3EvaluateDiscreteStates", "co-simulation only"); }
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterContinuousTimeMode", "co-simulation only"); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean a, fmi3Boolean *b, fmi3Boolean *c) {
    (void)a, (void)b, (void)c;
    UNSUPPORTED("fmi3CompletedIntegratorStep", "co-simulation only");
}
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t) { (void)t; UNSUPPORTED("fmi3SetTime", "co-simulation only"); }
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n) {
    (void)x, (void)n;
    UNSUPPORTED("fmi3SetContinuousStates", "co-simulation only");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    (void)x, (void)n;
    UNSUPPORTED("fmi3GetContinuousStateDerivatives", "co-simulation only");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    (void)x, (void)n;
    UNSUPPORTED("fmi3GetEventIndicators", "co-simulation only");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    (void)x, (void)n;
    UNSUPPORTED("fmi3GetContinuousStates", "co-simulation only");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    (void)x, (void)n;
    UNSUPPORTED("fmi3GetNominalsOfContinuousStates", "co-simulation only");
}
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr, (void)orders, (void)values, (void)nValues;
    if (n == 0 && np_instance_of(instance)) return fmi3OK;
    UNSUPPORTED("fmi3GetOutputDerivatives", "maxOutputDerivativeOrder=0");
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clock, fmi3Float64 t) {
    (void)clock, (void)t;
    UNSUPPORTED("fmi3ActivateModelPartition", "co-simulation only");
}
