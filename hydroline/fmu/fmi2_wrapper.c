/* FMI 2.0 wrapper of one hydroline plant (Model Exchange and Co-Simulation).
 *
 * Written for hydroline from the FMI 2.0.4 standard (Modelica Association, fmi-standard.org);
 * the few declarations needed are below, so the sources build with nothing but a C99
 * compiler and the C maths library:
 *
 *     cc -O2 -std=c99 -shared -fPIC -o <modelIdentifier>.so fmi2_wrapper.c -lm
 *
 * Compiled as one unit with
 *   model.c     the plant's right-hand side, exact sparse Jacobian, signals and sparse LU
 *               (hydroline.compiled.codegen: structure only, its numbers read from c[])
 *   bdf.c       hydroline's variable-order BDF integrator (Co-Simulation steps)
 *   fmu_data.h  this FMU's numbers: constants c[], state scales, the solved steady state,
 *               parameters, and the value-reference layout
 *
 * Value references (all Real): [0, N) states x [SI]; [N, 2N) their derivatives; [2N, 2N+NY)
 * the network's signals [SI]; [2N+NY, 2N+NY+NP) the runtime parameter vector p (inputs and
 * tunable parameters). Boolean 0: solve_steady_state.
 *
 * Initialization: at fmi2ExitInitializationMode the start state (the steady state solved by
 * hydroline at export) is kept when it is at rest for the parameters and inputs set; otherwise
 * (a tuned parameter, another input) the rest state is solved again here by pseudo-transient
 * continuation (implicit-Euler steps (I - dt J) dz = dt f with dt growing as the residual falls,
 * exact sparse Jacobian), unless solve_steady_state is false.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.c"
#include "bdf.c"
#include "fmu_data.h"

/* ---- FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h) -------------------------- */
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
typedef void* (*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void*);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
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

#if defined(_WIN32)
#define FMI2_Export __declspec(dllexport)
#else
#define FMI2_Export __attribute__((visibility("default")))
#endif

/* ---- instance ------------------------------------------------------------------------- */
#define HL_VR_DER HL_N
#define HL_VR_SIG (2 * HL_N)
#define HL_VR_PAR (2 * HL_N + HL_NY)
#define HL_VR_END (2 * HL_N + HL_NY + HL_NP)

enum { HL_INSTANTIATED, HL_INIT, HL_RUNNING, HL_TERMINATED, HL_ERROR };

typedef struct {
    hl_solver S;              /* integrator; S.p is the runtime parameter vector */
    double x[HL_N];           /* states, [SI] */
    double time;              /* [s] */
    double tol;               /* relative tolerance of the Co-Simulation integrator */
    int kind;                 /* fmi2ModelExchange or fmi2CoSimulation */
    int mode;
    int restart;              /* Co-Simulation: inputs, parameters or states changed */
    int solve_steady;         /* Boolean 0 */
    int logging;
    char name[256];
    fmi2CallbackFunctions cb;
} hl_fmu;

static void hl_log(hl_fmu* m, fmi2Status status, const char* fmt, ...) {
    if (!m->cb.logger) return;
    if (status == fmi2OK && !m->logging) return;
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    m->cb.logger(m->cb.componentEnvironment, m->name, status,
                 status == fmi2OK ? "logAll" : "logStatusError", "%s", msg);
}

static void hl_apply_mirrors(hl_fmu* m) {
    for (int k = 0; k < HL_FMU_NMIRROR; k++)
        m->S.p[hl_fmu_mirror[k][0]] = m->S.p[hl_fmu_mirror[k][1]];
}

static void hl_to_scaled(const hl_fmu* m, double* z) {
    for (int i = 0; i < HL_N; i++) z[i] = m->x[i] / m->S.scale[i];
}

/* Largest scaled residual |dz/dt| at the current state, [1/s] */
static double hl_residual(hl_fmu* m, double* f) {
    double z[HL_N], r = 0.;
    hl_to_scaled(m, z);
    hl_f(m->time, z, m->S.p, m->S.c, f);
    for (int i = 0; i < HL_N; i++) {
        if (!isfinite(f[i])) return INFINITY;
        r = fmax(r, fabs(f[i]));
    }
    return r;
}

/* Pseudo-transient continuation to the rest state (Kelley & Keyes, SIAM J. Numer. Anal. 35
 * (1998) 508), as hydroline.simulation.solve_steady_state does in Python. Returns 0 when the
 * scaled residual is below HL_FMU_STEADY_TOL. */
static int hl_solve_steady(hl_fmu* m) {
    double f[HL_N], fn[HL_N], z[HL_N], dz[HL_N];
    double r = hl_residual(m, f);
    if (r < HL_FMU_STEADY_TOL) return 0;
    double norm = 0., dt = 1e-5;
    for (int i = 0; i < HL_N; i++) norm += f[i] * f[i];
    norm = sqrt(norm);
    hl_to_scaled(m, z);
    for (int it = 0; it < 2000; it++) {
        if (hl_new_lu(&m->S, m->time, z, dt) != 0) { dt *= 0.1; continue; }
        for (int i = 0; i < HL_N; i++) dz[i] = dt * f[i];
        hl_solve(&m->S, dz);
        double zn[HL_N], nn = 0.;
        int finite = 1;
        for (int i = 0; i < HL_N; i++) zn[i] = z[i] + dz[i];
        hl_f(m->time, zn, m->S.p, m->S.c, fn);
        r = 0.;
        for (int i = 0; i < HL_N; i++) {
            if (!isfinite(fn[i])) finite = 0;
            nn += fn[i] * fn[i];
            r = fmax(r, fabs(fn[i]));
        }
        nn = sqrt(nn);
        if (!finite || nn > 10. * norm) { dt *= 0.1; if (dt < 1e-14) break; continue; }
        memcpy(z, zn, sizeof z);
        memcpy(f, fn, sizeof f);
        dt = fmin(dt * fmax(norm / fmax(nn, 1e-300), 0.5), 1e12);
        norm = nn;
        if (r < HL_FMU_STEADY_TOL) {
            for (int i = 0; i < HL_N; i++) m->x[i] = z[i] * m->S.scale[i];
            m->S.have_lu = 0;
            return 0;
        }
    }
    m->S.have_lu = 0;
    return -1;
}

/* ---- common functions ------------------------------------------------------------------ */
FMI2_Export const char* fmi2GetTypesPlatform(void) { return "default"; }
FMI2_Export const char* fmi2GetVersion(void) { return "2.0"; }

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n,
                                           const fmi2String categories[]) {
    (void)n; (void)categories;
    ((hl_fmu*)c)->logging = loggingOn;
    return fmi2OK;
}

static void hl_reset(hl_fmu* m) {
    hl_setup(&m->S, hl_fmu_p0, hl_fmu_c, hl_fmu_scale, HL_FMU_RTOL, HL_FMU_RTOL * 0.1, 0., 0., 5, 0.1);
    hl_set_max_steps(&m->S, 5000000);
    memcpy(m->x, hl_fmu_x0, sizeof m->x);
    m->time = 0.;
    m->tol = HL_FMU_RTOL;
    m->restart = 1;
    m->solve_steady = 1;
    m->mode = HL_INSTANTIATED;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                          fmi2String fmuGUID, fmi2String resourceLocation,
                                          const fmi2CallbackFunctions* functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)resourceLocation; (void)visible;
    if (fmuGUID && strcmp(fmuGUID, HL_FMU_GUID) != 0) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", "fmi2Instantiate: GUID %s does not match this "
                              "binary's %s", fmuGUID, HL_FMU_GUID);
        return NULL;
    }
    if ((fmuType == fmi2ModelExchange && !HL_FMU_ME) || (fmuType == fmi2CoSimulation && !HL_FMU_CS)) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", "fmi2Instantiate: this FMU was exported without "
                              "%s", fmuType == fmi2ModelExchange ? "Model Exchange" : "Co-Simulation");
        return NULL;
    }
    hl_coefficients();
    hl_fmu* m = (hl_fmu*)calloc(1, sizeof(hl_fmu));
    if (!m) return NULL;
    if (functions) m->cb = *functions;
    snprintf(m->name, sizeof m->name, "%s", instanceName ? instanceName : "hydroline");
    m->kind = fmuType;
    m->logging = loggingOn;
    hl_reset(m);
    return m;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) { free(c); }

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                           fmi2Real tolerance, fmi2Real startTime,
                                           fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    hl_fmu* m = (hl_fmu*)c;
    (void)stopTimeDefined; (void)stopTime;
    if (toleranceDefined && tolerance > 0) {
        m->tol = tolerance;
        m->S.rtol = tolerance;
        m->S.atol = 0.1 * tolerance;
    }
    m->time = startTime;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ((hl_fmu*)c)->mode = HL_INIT;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    hl_fmu* m = (hl_fmu*)c;
    hl_apply_mirrors(m);
    if (m->solve_steady && hl_solve_steady(m) != 0) {
        double f[HL_N];
        double r = hl_residual(m, f);
        int worst = 0;
        for (int i = 0; i < HL_N; i++) if (fabs(f[i]) > fabs(f[worst])) worst = i;
        hl_log(m, fmi2Error, "steady state not found at t = %g s: scaled residual %g 1/s at state "
               "%s (set solve_steady_state = false to start from the given states)", m->time, r,
               hl_fmu_state_names[worst]);
        m->mode = HL_ERROR;
        return fmi2Error;
    }
    m->mode = HL_RUNNING;
    m->restart = 1;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    ((hl_fmu*)c)->mode = HL_TERMINATED;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    hl_reset((hl_fmu*)c);
    return fmi2OK;
}

/* ---- get/set --------------------------------------------------------------------------- */
static fmi2Status hl_bad_vr(hl_fmu* m, const char* fn, fmi2ValueReference v) {
    hl_log(m, fmi2Error, "%s: unknown value reference %u", fn, v);
    return fmi2Error;
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   fmi2Real value[]) {
    hl_fmu* m = (hl_fmu*)c;
    double z[HL_N], dz[HL_N], y[HL_NY];
    int have_dz = 0, have_y = 0;
    hl_to_scaled(m, z);
    for (size_t k = 0; k < nvr; k++) {
        fmi2ValueReference v = vr[k];
        if (v < HL_N) {
            value[k] = m->x[v];
        } else if (v < HL_VR_SIG) {
            if (!have_dz) { hl_f(m->time, z, m->S.p, m->S.c, dz); have_dz = 1; }
            value[k] = dz[v - HL_VR_DER] * m->S.scale[v - HL_VR_DER];
        } else if (v < HL_VR_PAR) {
            if (!have_y) { hl_signals(m->time, z, m->S.p, m->S.c, y); have_y = 1; }
            value[k] = y[v - HL_VR_SIG];
        } else if (v < HL_VR_END) {
            value[k] = m->S.p[v - HL_VR_PAR];
        } else {
            return hl_bad_vr(m, "fmi2GetReal", v);
        }
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    hl_fmu* m = (hl_fmu*)c;
    for (size_t k = 0; k < nvr; k++) {
        fmi2ValueReference v = vr[k];
        if (v < HL_N && m->mode <= HL_INIT) {
            m->x[v] = value[k];
        } else if (v >= HL_VR_PAR && v < HL_VR_END) {
            if (!isfinite(value[k])) {
                hl_log(m, fmi2Error, "fmi2SetReal: %s must be finite, got %g",
                       hl_fmu_parameter_names[v - HL_VR_PAR], value[k]);
                return fmi2Error;
            }
            if (m->S.p[v - HL_VR_PAR] != value[k]) m->restart = 1;
            m->S.p[v - HL_VR_PAR] = value[k];
        } else {
            hl_log(m, fmi2Error, "fmi2SetReal: value reference %u cannot be set%s", v,
                   v < HL_N ? " after initialization (use fmi2SetContinuousStates)" : "");
            return fmi2Error;
        }
    }
    hl_apply_mirrors(m);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Integer value[]) {
    (void)value;
    return nvr ? hl_bad_vr((hl_fmu*)c, "fmi2GetInteger", vr[0]) : fmi2OK;
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Integer value[]) {
    (void)value;
    return nvr ? hl_bad_vr((hl_fmu*)c, "fmi2SetInteger", vr[0]) : fmi2OK;
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Boolean value[]) {
    hl_fmu* m = (hl_fmu*)c;
    for (size_t k = 0; k < nvr; k++) {
        if (vr[k] != 0) return hl_bad_vr(m, "fmi2GetBoolean", vr[k]);
        value[k] = m->solve_steady;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Boolean value[]) {
    hl_fmu* m = (hl_fmu*)c;
    for (size_t k = 0; k < nvr; k++) {
        if (vr[k] != 0) return hl_bad_vr(m, "fmi2SetBoolean", vr[k]);
        m->solve_steady = value[k] != 0;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     fmi2String value[]) {
    (void)value;
    return nvr ? hl_bad_vr((hl_fmu*)c, "fmi2GetString", vr[0]) : fmi2OK;
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2String value[]) {
    (void)value;
    return nvr ? hl_bad_vr((hl_fmu*)c, "fmi2SetString", vr[0]) : fmi2OK;
}

/* ---- FMU state: a copy of the whole instance ------------------------------------------- */
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* state) {
    if (!*state) *state = malloc(sizeof(hl_fmu));
    if (!*state) return fmi2Error;
    memcpy(*state, c, sizeof(hl_fmu));
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    if (!state) return fmi2Error;
    memcpy(c, state, sizeof(hl_fmu));
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* state) {
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t* size) {
    (void)c; (void)state;
    *size = sizeof(hl_fmu);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state,
                                             fmi2Byte serializedState[], size_t size) {
    (void)c;
    if (size < sizeof(hl_fmu)) return fmi2Error;
    memcpy(serializedState, state, sizeof(hl_fmu));
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                               size_t size, fmi2FMUstate* state) {
    (void)c;
    if (size != sizeof(hl_fmu)) return fmi2Error;
    if (!*state) *state = malloc(sizeof(hl_fmu));
    if (!*state) return fmi2Error;
    memcpy(*state, serializedState, sizeof(hl_fmu));
    return fmi2OK;
}

/* ---- directional derivatives ------------------------------------------------------------
 * d(derivatives)/d(states) exactly from the generated sparse Jacobian; any other pair (an
 * output, or with respect to an input or parameter) by central differences. */
static void hl_unknowns(hl_fmu* m, const fmi2ValueReference* vu, size_t nu, double* out) {
    fmi2GetReal(m, vu, nu, out);
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown[],
                                                    size_t nUnknown, const fmi2ValueReference vKnown[],
                                                    size_t nKnown, const fmi2Real dvKnown[],
                                                    fmi2Real dvUnknown[]) {
    hl_fmu* m = (hl_fmu*)c;
    int exact = 1;
    for (size_t k = 0; k < nUnknown; k++) if (vUnknown[k] < HL_VR_DER || vUnknown[k] >= HL_VR_SIG) exact = 0;
    for (size_t k = 0; k < nKnown; k++) if (vKnown[k] >= HL_N) exact = 0;
    if (exact) {
        double z[HL_N], jnz[HL_NNZ], dzk[HL_N], w[HL_N];
        hl_to_scaled(m, z);
        hl_jac(m->time, z, m->S.p, m->S.c, jnz);
        memset(dzk, 0, sizeof dzk);
        for (size_t k = 0; k < nKnown; k++) dzk[vKnown[k]] += dvKnown[k] / m->S.scale[vKnown[k]];
        memset(w, 0, sizeof w);
        for (int j = 0; j < HL_N; j++)
            if (dzk[j] != 0.)
                for (long long q = hl_jac_colind[j]; q < hl_jac_colind[j + 1]; q++)
                    w[hl_jac_row[q]] += jnz[q] * dzk[j];
        for (size_t k = 0; k < nUnknown; k++) {
            int i = (int)(vUnknown[k] - HL_VR_DER);
            dvUnknown[k] = w[i] * m->S.scale[i];
        }
        return fmi2OK;
    }
    double* base = (double*)malloc(sizeof(double) * (nKnown + 2 * nUnknown + 1));
    if (!base) return fmi2Error;
    double* up = base + nKnown;
    double* dn = up + nUnknown;
    double eps = 1e-6;
    for (size_t k = 0; k < nKnown; k++) {
        fmi2ValueReference v = vKnown[k];
        if (v >= HL_N && !(v >= HL_VR_PAR && v < HL_VR_END)) { free(base); return hl_bad_vr(m, "fmi2GetDirectionalDerivative", v); }
        fmi2GetReal(m, &v, 1, &base[k]);
    }
    double nrm = 0.;
    for (size_t k = 0; k < nKnown; k++) nrm = fmax(nrm, fabs(dvKnown[k]) / fmax(fabs(base[k]), vKnown[k] < HL_N ? m->S.scale[vKnown[k]] : hl_fmu_pnominal[vKnown[k] - HL_VR_PAR]));
    double h = nrm > 0 ? eps / nrm : 1.;
    for (int sgn = 0; sgn < 2; sgn++) {
        for (size_t k = 0; k < nKnown; k++) {
            fmi2ValueReference v = vKnown[k];
            double val = base[k] + (sgn ? -h : h) * dvKnown[k];
            if (v < HL_N) m->x[v] = val; else m->S.p[v - HL_VR_PAR] = val;
        }
        hl_apply_mirrors(m);
        hl_unknowns(m, vUnknown, nUnknown, sgn ? dn : up);
    }
    for (size_t k = 0; k < nKnown; k++) {
        fmi2ValueReference v = vKnown[k];
        if (v < HL_N) m->x[v] = base[k]; else m->S.p[v - HL_VR_PAR] = base[k];
    }
    hl_apply_mirrors(m);
    for (size_t k = 0; k < nUnknown; k++) dvUnknown[k] = (up[k] - dn[k]) / (2. * h);
    free(base);
    return fmi2OK;
}

/* ---- Co-Simulation: hydroline's BDF integrator between communication points -------------- */
FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                                   size_t nvr, const fmi2Integer order[],
                                                   const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    hl_log((hl_fmu*)c, fmi2Error, "fmi2SetRealInputDerivatives: inputs are held constant over a "
           "communication step (canInterpolateInputs = false)");
    return fmi2Error;
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                                    size_t nvr, const fmi2Integer order[],
                                                    fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    hl_log((hl_fmu*)c, fmi2Error, "fmi2GetRealOutputDerivatives: not provided (MaxOutputDerivativeOrder = 0)");
    return fmi2Error;
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    hl_fmu* m = (hl_fmu*)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (m->mode != HL_RUNNING) {
        hl_log(m, fmi2Error, "fmi2DoStep: not in step mode (initialise first)");
        return fmi2Error;
    }
    if (!(h > 0)) {
        hl_log(m, fmi2Error, "fmi2DoStep: communication step size must be > 0 [s], got %g", h);
        return fmi2Error;
    }
    double t_end = t + h;
    if (m->restart || fabs(t - m->S.t) > 1e-12 * fmax(1., fabs(t))) {
        hl_init(&m->S, t, m->x, t_end);    /* inputs may jump at t: order 1, fresh history */
        m->restart = 0;
    } else {
        m->S.t_bound = t_end;              /* smooth continuation of the last step */
    }
    int done = 0;
    int rc = hl_advance(&m->S, 1, &t_end, m->x, NULL, &done, HL_N);
    if (rc != 0 || done != 1) {
        double xs[HL_N], ts;
        hl_get_state(&m->S, xs, &ts);
        hl_log(m, fmi2Error, "fmi2DoStep: integrator failed at t = %g s (code %d: -1 step size "
               "below the resolution of t, -2 singular iteration matrix, -4 non-finite "
               "derivative, -5 too many steps)", ts, rc);
        m->mode = HL_ERROR;
        return fmi2Error;
    }
    m->time = t_end;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

FMI2_Export fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status* value) {
    (void)c; (void)s;
    *value = fmi2OK;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real* value) {
    hl_fmu* m = (hl_fmu*)c;
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = m->time;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer* value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean* value) {
    (void)c;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String* value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

/* ---- Model Exchange: the ODE ------------------------------------------------------------ */
FMI2_Export fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }

FMI2_Export fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
    (void)c;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }

FMI2_Export fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi2Boolean* enterEventMode, fmi2Boolean* terminateSimulation) {
    (void)c; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    ((hl_fmu*)c)->time = t;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    hl_fmu* m = (hl_fmu*)c;
    if (nx != HL_N) {
        hl_log(m, fmi2Error, "fmi2SetContinuousStates: %u states expected, got %u", (unsigned)HL_N, (unsigned)nx);
        return fmi2Error;
    }
    memcpy(m->x, x, sizeof m->x);
    m->restart = 1;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    hl_fmu* m = (hl_fmu*)c;
    if (nx != HL_N) return fmi2Error;
    double z[HL_N];
    hl_to_scaled(m, z);
    hl_f(m->time, z, m->S.p, m->S.c, dx);
    for (int i = 0; i < HL_N; i++) {
        dx[i] *= m->S.scale[i];
        if (!isfinite(dx[i])) {
            hl_log(m, fmi2Discard, "fmi2GetDerivatives: derivative of %s is not finite at t = %g s",
                   hl_fmu_state_names[i], m->time);
            return fmi2Discard;
        }
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t ni) {
    (void)c; (void)z;
    return ni == 0 ? fmi2OK : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    hl_fmu* m = (hl_fmu*)c;
    if (nx != HL_N) return fmi2Error;
    memcpy(x, m->x, sizeof m->x);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    hl_fmu* m = (hl_fmu*)c;
    if (nx != HL_N) return fmi2Error;
    memcpy(x_nominal, m->S.scale, sizeof(double) * HL_N);
    return fmi2OK;
}
