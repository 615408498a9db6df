/* FMI 2.0 interface of one hydroline plant (Model Exchange and Co-Simulation).
 *
 * Written for hydroline from the FMI 2.0.4 standard (Modelica Association, fmi-standard.org);
 * the few declarations needed are below, so the sources build with a C99 compiler and the C
 * maths library alone:
 *
 *     cc -O2 -std=c99 -shared -fPIC -o <modelIdentifier>.so fmi2_wrapper.c -lm
 *
 * The plant, its integrator and the instance logic are in fmu_core.c (included). In FMI 2.0
 * the Boolean solve_steady_state has value reference HL_VR_END (see fmu_core.c).
 */
#include "fmu_core.c"

typedef void* fmi2Component;
typedef void* fmi2ComponentEnvironment;
typedef void* fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char* fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void* (*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void*);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;
typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

#define M ((hl_fmu*)c)

/* ---- common functions ------------------------------------------------------------------ */
HL_EXPORT const char* fmi2GetTypesPlatform(void) { return "default"; }
HL_EXPORT const char* fmi2GetVersion(void) { return "2.0"; }

HL_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n,
                                         const fmi2String categories[]) {
    (void)n; (void)categories;
    M->logging = loggingOn;
    return fmi2OK;
}

HL_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                        fmi2String fmuGUID, fmi2String resourceLocation,
                                        const fmi2CallbackFunctions* functions,
                                        fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    char why[1200] = "";
    hl_fmu* m = NULL;
    if (fmuType == fmi2ModelExchange && !HL_FMU_ME)
        snprintf(why, sizeof why, "this FMU was exported without Model Exchange");
    else if (fmuType == fmi2CoSimulation && !HL_FMU_CS)
        snprintf(why, sizeof why, "this FMU was exported without Co-Simulation");
    else
        m = hl_instantiate(instanceName, fmuType == fmi2ModelExchange, loggingOn,
                           resourceLocation, 1, fmuGUID, why, sizeof why);
    if (!m) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", "fmi2Instantiate: %s", why);
        return NULL;
    }
    if (functions) {
        m->log2 = (hl_logger2)functions->logger;
        m->env = functions->componentEnvironment;
    }
    return m;
}

HL_EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }

HL_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                         fmi2Real tolerance, fmi2Real startTime,
                                         fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)stopTimeDefined; (void)stopTime;
    hl_setup_experiment(M, toleranceDefined, tolerance, startTime);
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    M->mode = HL_INIT;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return (fmi2Status)hl_exit_initialization(M);
}

HL_EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    M->mode = HL_TERMINATED;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    hl_reset(M);
    return fmi2OK;
}

/* ---- get/set --------------------------------------------------------------------------- */
HL_EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Real value[]) {
    return (fmi2Status)hl_get_real(M, vr, nvr, value, "fmi2GetReal");
}

HL_EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Real value[]) {
    return (fmi2Status)hl_set_real(M, vr, nvr, value, "fmi2SetReal");
}

HL_EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                    fmi2Integer value[]) {
    (void)value;
    return nvr ? (fmi2Status)hl_bad_vr(M, "fmi2GetInteger", vr[0]) : fmi2OK;
}

HL_EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                    const fmi2Integer value[]) {
    (void)value;
    return nvr ? (fmi2Status)hl_bad_vr(M, "fmi2SetInteger", vr[0]) : fmi2OK;
}

HL_EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                    fmi2Boolean value[]) {
    return (fmi2Status)hl_get_bool(M, vr, nvr, value, "fmi2GetBoolean");
}

HL_EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                    const fmi2Boolean value[]) {
    return (fmi2Status)hl_set_bool(M, vr, nvr, value, "fmi2SetBoolean");
}

HL_EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   fmi2String value[]) {
    (void)value;
    return nvr ? (fmi2Status)hl_bad_vr(M, "fmi2GetString", vr[0]) : fmi2OK;
}

HL_EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2String value[]) {
    (void)value;
    return nvr ? (fmi2Status)hl_bad_vr(M, "fmi2SetString", vr[0]) : fmi2OK;
}

/* ---- FMU state ------------------------------------------------------------------------- */
HL_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* state) {
    return (fmi2Status)hl_get_state_copy(M, state);
}

HL_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    return (fmi2Status)hl_set_state_copy(M, state);
}

HL_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* state) {
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t* size) {
    (void)c; (void)state;
    *size = sizeof(hl_fmu);
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state,
                                           fmi2Byte serializedState[], size_t size) {
    (void)c;
    if (size < sizeof(hl_fmu)) return fmi2Error;
    memcpy(serializedState, state, sizeof(hl_fmu));
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                             size_t size, fmi2FMUstate* state) {
    (void)c;
    return (fmi2Status)hl_deserialize(serializedState, size, state);
}

HL_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown[],
                                                  size_t nUnknown, const fmi2ValueReference vKnown[],
                                                  size_t nKnown, const fmi2Real dvKnown[],
                                                  fmi2Real dvUnknown[]) {
    return (fmi2Status)hl_directional(M, vUnknown, nUnknown, vKnown, nKnown, dvKnown, dvUnknown);
}

/* ---- Co-Simulation --------------------------------------------------------------------- */
HL_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                                 size_t nvr, const fmi2Integer order[],
                                                 const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    hl_log(M, HL_ERROR, "fmi2SetRealInputDerivatives: inputs are held constant over a "
           "communication step (canInterpolateInputs = false)");
    return fmi2Error;
}

HL_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                                  size_t nvr, const fmi2Integer order[],
                                                  fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    hl_log(M, HL_ERROR, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder = 0)");
    return fmi2Error;
}

HL_EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h,
                                fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)hl_do_step(M, t, h);
}

HL_EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

HL_EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status* value) {
    (void)c; (void)s;
    *value = fmi2OK;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real* value) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = M->time;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer* value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

HL_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean* value) {
    (void)c;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String* value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

/* ---- Model Exchange -------------------------------------------------------------------- */
HL_EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }

HL_EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
    (void)c;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }

HL_EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                 fmi2Boolean* enterEventMode, fmi2Boolean* terminateSimulation) {
    (void)c; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    M->time = t;
    return fmi2OK;
}

HL_EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    return (fmi2Status)hl_set_states(M, x, nx);
}

HL_EXPORT fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    return (fmi2Status)hl_get_derivatives(M, dx, nx);
}

HL_EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t ni) {
    (void)c; (void)z;
    return ni == 0 ? fmi2OK : fmi2Error;
}

HL_EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    return (fmi2Status)hl_get_states(M, x, nx);
}

HL_EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    return (fmi2Status)hl_get_nominals(M, x_nominal, nx);
}
