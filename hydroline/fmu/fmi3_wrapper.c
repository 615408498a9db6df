/* FMI 3.0 interface of one hydroline plant (Model Exchange and Co-Simulation).
 *
 * Written for hydroline from the FMI 3.0 standard (Modelica Association, fmi-standard.org);
 * the declarations needed are below, so the sources build with a C99 compiler and the C
 * maths library alone:
 *
 *     cc -O2 -std=c99 -shared -fPIC -o <modelIdentifier>.so fmi3_wrapper.c -lm
 *
 * The plant, its integrator and the instance logic are in fmu_core.c (included). Only
 * Float64 and Boolean variables exist; the other types' functions refuse every value
 * reference. No clocks, no events, no scheduled execution.
 */
#include <stdbool.h>
#include <stdint.h>

#include "fmu_core.c"

typedef void* fmi3Instance;
typedef void* fmi3InstanceEnvironment;
typedef void* fmi3FMUState;
typedef uint32_t fmi3ValueReference;
typedef float fmi3Float32;
typedef double fmi3Float64;
typedef int8_t fmi3Int8;
typedef uint8_t fmi3UInt8;
typedef int16_t fmi3Int16;
typedef uint16_t fmi3UInt16;
typedef int32_t fmi3Int32;
typedef uint32_t fmi3UInt32;
typedef int64_t fmi3Int64;
typedef uint64_t fmi3UInt64;
typedef bool fmi3Boolean;
typedef char fmi3Char;
typedef const fmi3Char* fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte* fmi3Binary;
typedef bool fmi3Clock;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef enum { fmi3Independent, fmi3Constant, fmi3Fixed, fmi3Tunable, fmi3Discrete, fmi3Dependent } fmi3DependencyKind;
typedef enum { fmi3IntervalNotYetKnown, fmi3IntervalUnchanged, fmi3IntervalChanged } fmi3IntervalQualifier;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean*, fmi3Float64*);
typedef void (*fmi3ClockUpdateCallback)(fmi3InstanceEnvironment);
typedef void (*fmi3LockPreemptionCallback)(void);
typedef void (*fmi3UnlockPreemptionCallback)(void);

#define M ((hl_fmu*)instance)

/* ---- common functions ------------------------------------------------------------------ */
HL_EXPORT const char* fmi3GetVersion(void) { return "3.0"; }

HL_EXPORT fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                                         size_t nCategories, const fmi3String categories[]) {
    (void)nCategories; (void)categories;
    M->logging = loggingOn;
    return fmi3OK;
}

static fmi3Instance hl_instantiate3(fmi3String name, fmi3String token, fmi3String resourcePath,
                                    int me, fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                    fmi3LogMessageCallback log) {
    char why[1200] = "";
    hl_fmu* m = NULL;
    if (me && !HL_FMU_ME)
        snprintf(why, sizeof why, "this FMU was exported without Model Exchange");
    else if (!me && !HL_FMU_CS)
        snprintf(why, sizeof why, "this FMU was exported without Co-Simulation");
    else
        m = hl_instantiate(name, me, loggingOn, resourcePath, 0, token, why, sizeof why);
    if (!m) {
        if (log) log(env, fmi3Error, "logStatusError", why);
        return NULL;
    }
    m->log3 = (hl_logger3)log;
    m->env = env;
    return m;
}

HL_EXPORT fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                    fmi3String resourcePath, fmi3Boolean visible,
                                                    fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                                    fmi3LogMessageCallback logMessage) {
    (void)visible;
    return hl_instantiate3(instanceName, instantiationToken, resourcePath, 1, loggingOn, env,
                           logMessage);
}

HL_EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                                   fmi3String resourcePath, fmi3Boolean visible,
                                                   fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                                   fmi3Boolean earlyReturnAllowed,
                                                   const fmi3ValueReference requiredIntermediateVariables[],
                                                   size_t nRequiredIntermediateVariables,
                                                   fmi3InstanceEnvironment env,
                                                   fmi3LogMessageCallback logMessage,
                                                   fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible; (void)eventModeUsed; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    return hl_instantiate3(instanceName, instantiationToken, resourcePath, 0, loggingOn, env,
                           logMessage);
}

HL_EXPORT fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                                         fmi3String resourcePath, fmi3Boolean visible,
                                                         fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                                         fmi3LogMessageCallback logMessage,
                                                         fmi3ClockUpdateCallback clockUpdate,
                                                         fmi3LockPreemptionCallback lockPreemption,
                                                         fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage) logMessage(env, fmi3Error, "logStatusError", "scheduled execution is not supported");
    return NULL;
}

HL_EXPORT void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

HL_EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                 fmi3Float64 tolerance, fmi3Float64 startTime,
                                                 fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)stopTimeDefined; (void)stopTime;
    hl_setup_experiment(M, toleranceDefined, tolerance, startTime);
    M->mode = HL_INIT;
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return (fmi3Status)hl_exit_initialization(M);
}

HL_EXPORT fmi3Status fmi3EnterEventMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

HL_EXPORT fmi3Status fmi3Terminate(fmi3Instance instance) {
    M->mode = HL_TERMINATED;
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3Reset(fmi3Instance instance) {
    hl_reset(M);
    return fmi3OK;
}

/* ---- get/set --------------------------------------------------------------------------- */
HL_EXPORT fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Float64 values[], size_t nValues) {
    (void)nValues;
    return (fmi3Status)hl_get_real(M, vr, nvr, values, "fmi3GetFloat64");
}

HL_EXPORT fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Float64 values[], size_t nValues) {
    (void)nValues;
    return (fmi3Status)hl_set_real(M, vr, nvr, values, "fmi3SetFloat64");
}

HL_EXPORT fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Boolean values[], size_t nValues) {
    (void)nValues;
    for (size_t k = 0; k < nvr; k++) {
        int v;
        int rc = hl_get_bool(M, &vr[k], 1, &v, "fmi3GetBoolean");
        if (rc) return (fmi3Status)rc;
        values[k] = v != 0;
    }
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Boolean values[], size_t nValues) {
    (void)nValues;
    for (size_t k = 0; k < nvr; k++) {
        int v = values[k] ? 1 : 0;
        int rc = hl_set_bool(M, &vr[k], 1, &v, "fmi3SetBoolean");
        if (rc) return (fmi3Status)rc;
    }
    return fmi3OK;
}

/* the types this FMU has no variables of */
#define HL_NO_VARIABLES(NAME, CONST, TYPE)                                                     \
    HL_EXPORT fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                              CONST TYPE values[], size_t nValues) {                           \
        (void)values; (void)nValues;                                                           \
        return nvr ? (fmi3Status)hl_bad_vr(M, #NAME, vr[0]) : fmi3OK;                          \
    }
HL_NO_VARIABLES(fmi3GetFloat32, , fmi3Float32)
HL_NO_VARIABLES(fmi3GetInt8, , fmi3Int8)
HL_NO_VARIABLES(fmi3GetUInt8, , fmi3UInt8)
HL_NO_VARIABLES(fmi3GetInt16, , fmi3Int16)
HL_NO_VARIABLES(fmi3GetUInt16, , fmi3UInt16)
HL_NO_VARIABLES(fmi3GetInt32, , fmi3Int32)
HL_NO_VARIABLES(fmi3GetUInt32, , fmi3UInt32)
HL_NO_VARIABLES(fmi3GetInt64, , fmi3Int64)
HL_NO_VARIABLES(fmi3GetUInt64, , fmi3UInt64)
HL_NO_VARIABLES(fmi3GetString, , fmi3String)
HL_NO_VARIABLES(fmi3SetFloat32, const, fmi3Float32)
HL_NO_VARIABLES(fmi3SetInt8, const, fmi3Int8)
HL_NO_VARIABLES(fmi3SetUInt8, const, fmi3UInt8)
HL_NO_VARIABLES(fmi3SetInt16, const, fmi3Int16)
HL_NO_VARIABLES(fmi3SetUInt16, const, fmi3UInt16)
HL_NO_VARIABLES(fmi3SetInt32, const, fmi3Int32)
HL_NO_VARIABLES(fmi3SetUInt32, const, fmi3UInt32)
HL_NO_VARIABLES(fmi3SetInt64, const, fmi3Int64)
HL_NO_VARIABLES(fmi3SetUInt64, const, fmi3UInt64)
HL_NO_VARIABLES(fmi3SetString, const, fmi3String)

HL_EXPORT fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3GetBinary", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3SetBinary", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Clock values[]) {
    (void)values;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3GetClock", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Clock values[]) {
    (void)values;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3SetClock", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr,
                                                         size_t* nDependencies) {
    (void)vr; (void)nDependencies;
    hl_log(M, HL_ERROR, "fmi3GetNumberOfVariableDependencies: dependencies are not declared "
           "(every unknown may depend on every known)");
    return fmi3Error;
}

HL_EXPORT fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                                 size_t elementIndicesOfDependent[],
                                                 fmi3ValueReference independents[],
                                                 size_t elementIndicesOfIndependents[],
                                                 fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents;
    (void)elementIndicesOfIndependents; (void)dependencyKinds; (void)nDependencies;
    hl_log(M, HL_ERROR, "fmi3GetVariableDependencies: dependencies are not declared");
    return fmi3Error;
}

/* ---- FMU state ------------------------------------------------------------------------- */
HL_EXPORT fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState* state) {
    return (fmi3Status)hl_get_state_copy(M, state);
}

HL_EXPORT fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state) {
    return (fmi3Status)hl_set_state_copy(M, state);
}

HL_EXPORT fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState* state) {
    (void)instance;
    free(*state);
    *state = NULL;
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState state, size_t* size) {
    (void)instance; (void)state;
    *size = sizeof(hl_fmu);
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState state,
                                           fmi3Byte serializedState[], size_t size) {
    (void)instance;
    if (size < sizeof(hl_fmu)) return fmi3Error;
    memcpy(serializedState, state, sizeof(hl_fmu));
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                             size_t size, fmi3FMUState* state) {
    (void)instance;
    return (fmi3Status)hl_deserialize((const char*)serializedState, size, state);
}

HL_EXPORT fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                                  size_t nUnknowns, const fmi3ValueReference knowns[],
                                                  size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                                  fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)nSeed; (void)nSensitivity;
    return (fmi3Status)hl_directional(M, unknowns, nUnknowns, knowns, nKnowns, seed, sensitivity);
}

HL_EXPORT fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                              size_t nUnknowns, const fmi3ValueReference knowns[],
                                              size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                              fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    hl_log(M, HL_ERROR, "fmi3GetAdjointDerivative: not provided (providesAdjointDerivatives = false)");
    return fmi3Error;
}

/* ---- configuration, clocks, discrete states: none -------------------------------------- */
HL_EXPORT fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { (void)instance; return fmi3Error; }
HL_EXPORT fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { (void)instance; return fmi3Error; }

HL_EXPORT fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                            fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)intervals; (void)qualifiers;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3GetIntervalDecimal", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                             fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                             fmi3IntervalQualifier qualifiers[]) {
    (void)counters; (void)resolutions; (void)qualifiers;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3GetIntervalFraction", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                         fmi3Float64 shifts[]) {
    (void)shifts;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3GetShiftDecimal", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                          fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)counters; (void)resolutions;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3GetShiftFraction", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                            const fmi3Float64 intervals[]) {
    (void)intervals;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3SetIntervalDecimal", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                             const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)counters; (void)resolutions;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3SetIntervalFraction", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                         const fmi3Float64 shifts[]) {
    (void)shifts;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3SetShiftDecimal", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                          const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)counters; (void)resolutions;
    return nvr ? (fmi3Status)hl_bad_vr(M, "fmi3SetShiftFraction", vr[0]) : fmi3OK;
}

HL_EXPORT fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { (void)instance; return fmi3OK; }

HL_EXPORT fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate,
                                              fmi3Boolean* terminateSimulation,
                                              fmi3Boolean* nominalsOfContinuousStatesChanged,
                                              fmi3Boolean* valuesOfContinuousStatesChanged,
                                              fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime) {
    (void)instance;
    *discreteStatesNeedUpdate = false;
    *terminateSimulation = false;
    *nominalsOfContinuousStatesChanged = false;
    *valuesOfContinuousStatesChanged = false;
    *nextEventTimeDefined = false;
    *nextEventTime = 0.;
    return fmi3OK;
}

/* ---- Model Exchange -------------------------------------------------------------------- */
HL_EXPORT fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

HL_EXPORT fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                                 fmi3Boolean* enterEventMode, fmi3Boolean* terminateSimulation) {
    (void)instance; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = false;
    *terminateSimulation = false;
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    M->time = time;
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx) {
    return (fmi3Status)hl_set_states(M, x, nx);
}

HL_EXPORT fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t nx) {
    return (fmi3Status)hl_get_derivatives(M, dx, nx);
}

HL_EXPORT fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t ni) {
    (void)instance; (void)z;
    return ni == 0 ? fmi3OK : fmi3Error;
}

HL_EXPORT fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx) {
    return (fmi3Status)hl_get_states(M, x, nx);
}

HL_EXPORT fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nx) {
    return (fmi3Status)hl_get_nominals(M, nominals, nx);
}

HL_EXPORT fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t* n) {
    (void)instance;
    *n = 0;
    return fmi3OK;
}

HL_EXPORT fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t* n) {
    (void)instance;
    *n = HL_N;
    return fmi3OK;
}

/* ---- Co-Simulation --------------------------------------------------------------------- */
HL_EXPORT fmi3Status fmi3EnterStepMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

HL_EXPORT fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                              const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    hl_log(M, HL_ERROR, "fmi3GetOutputDerivatives: not provided (maxOutputDerivativeOrder = 0)");
    return fmi3Error;
}

HL_EXPORT fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                fmi3Boolean* eventHandlingNeeded, fmi3Boolean* terminateSimulation,
                                fmi3Boolean* earlyReturn, fmi3Float64* lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    int rc = hl_do_step(M, currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    *lastSuccessfulTime = M->time;
    return (fmi3Status)rc;
}

/* ---- Scheduled Execution: not supported ------------------------------------------------- */
HL_EXPORT fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                                fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    hl_log(M, HL_ERROR, "fmi3ActivateModelPartition: scheduled execution is not supported");
    return fmi3Error;
}
