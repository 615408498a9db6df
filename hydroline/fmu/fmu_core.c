/* One hydroline plant as an FMU instance: the part shared by the FMI 2.0 and FMI 3.0 wrappers.
 *
 * Compiled as one unit (included by fmi2_wrapper.c or fmi3_wrapper.c) with
 *   model.c     the plant's right-hand side, exact sparse Jacobian, signals and sparse LU
 *               (hydroline.compiled.codegen: structure only, its numbers read from c[])
 *   bdf.c       hydroline's variable-order BDF integrator (Co-Simulation steps)
 *   fmu_data.h  this FMU's structure: the names of its states and parameters, where the
 *               accumulators sit, the kinds it was exported for
 *
 * The numbers are not compiled in: constants c[] (the components' numbers, the state scales,
 * the graph's own constants), the solved rest state, the parameters' start values and the
 * accumulators' charge are read at instantiation from resources/HL_FMU_NUMBERS_FILE, whose
 * GUID (instantiation token) and structure key must be the importer's and this binary's. So
 * rigs that differ only in numbers share one binary (hydroline builds it once per structure).
 * The file's values are IEEE-754 bit patterns in hexadecimal (exact, locale-independent),
 * each followed by its decimal value for the reader.
 *
 * Value references of the Real/Float64 variables: [0, N) states x [SI]; [N, 2N) their time
 * derivatives; [2N, 2N+NY) the network's signals [SI]; [2N+NY, 2N+NY+NP) the runtime parameter
 * vector p (inputs, then tunable parameters); then the Boolean solve_steady_state and (FMI 3.0)
 * the independent variable time. Status codes are FMI's (0 OK ... 3 Error).
 *
 * Initialization: at ExitInitializationMode the start state (the rest state solved by hydroline
 * at export) is kept when it is at rest for the parameters and inputs set; otherwise (a tuned
 * parameter, another input) the rest state is solved again here by pseudo-transient
 * continuation -- implicit-Euler steps (I - dt J) dz = dt f(z), dt growing as the residual
 * falls (Kelley & Keyes, SIAM J. Numer. Anal. 35 (1998) 508), exact sparse Jacobian -- as
 * hydroline.simulation.solve_steady_state does in Python, and the accumulators settle to the new
 * node pressures (their charge), unless solve_steady_state is false.
 */
#include <ctype.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.c"
#include "bdf.c"
#include "fmu_data.h"

#if defined(_WIN32)
#define HL_EXPORT __declspec(dllexport)
#else
#define HL_EXPORT __attribute__((visibility("default")))
#endif

#define HL_OK 0
#define HL_WARNING 1
#define HL_DISCARD 2
#define HL_ERROR 3

#define HL_VR_DER HL_N
#define HL_VR_SIG (2 * HL_N)
#define HL_VR_PAR (2 * HL_N + HL_NY)
#define HL_VR_END (2 * HL_N + HL_NY + HL_NP)
#define HL_FMU_VR_SOLVE_STEADY HL_VR_END      /* Boolean solve_steady_state */
#define HL_FMU_VR_TIME (HL_VR_END + 1)        /* FMI 3.0's independent variable */

enum { HL_INSTANTIATED, HL_INIT, HL_RUNNING, HL_TERMINATED, HL_FAILED };

typedef void (*hl_logger2)(void* env, const char* name, int status, const char* category,
                           const char* fmt, ...);
typedef void (*hl_logger3)(void* env, int status, const char* category, const char* message);

/* This FMU's numbers, read from its resources at instantiation */
typedef struct {
    double c[HL_NC];          /* constants of model.c: numbers, state scales, the graph's own */
    double scale[HL_N];       /* state scales, [SI] */
    double x0[HL_N];          /* the rest state solved at export, [SI] */
    double p0[HL_NP];         /* start values of the runtime parameters (inputs, tunables), [SI] */
    double pnominal[HL_NP];   /* their typical magnitudes (directional derivatives), [SI] */
    double acc_capacity[HL_FMU_NACC > 0 ? HL_FMU_NACC : 1];    /* accumulators' V0, [m^3] */
    double acc_precharge[HL_FMU_NACC > 0 ? HL_FMU_NACC : 1];   /* and p0, [Pa] */
} hl_fmu_numbers;

typedef struct {
    hl_solver S;              /* integrator; S.p is the runtime parameter vector */
    double x[HL_N];           /* states, [SI] */
    double time;              /* [s] */
    int me;                   /* 1: Model Exchange, 0: Co-Simulation */
    int mode;
    int restart;              /* Co-Simulation: inputs, parameters or states changed */
    int solve_steady;         /* the Boolean parameter solve_steady_state */
    int logging;
    char name[256];
    hl_logger2 log2;          /* the importer's logger (FMI 2.0 or 3.0) */
    hl_logger3 log3;
    void* env;
    hl_fmu_numbers num;       /* this FMU's numbers */
} hl_fmu;

static void hl_log(hl_fmu* m, int status, const char* fmt, ...) {
    if (status == HL_OK && !m->logging) return;
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    const char* cat = status == HL_OK ? "logAll" : "logStatusError";
    if (m->log2) m->log2(m->env, m->name, status, cat, "%s", msg);
    else if (m->log3) m->log3(m->env, status, cat, msg);
}

static void hl_apply_mirrors(hl_fmu* m) {
    for (int k = 0; k < HL_FMU_NMIRROR; k++)
        m->S.p[hl_fmu_mirror[k][0]] = m->S.p[hl_fmu_mirror[k][1]];
}

static void hl_to_scaled(const hl_fmu* m, double* z) {
    for (int i = 0; i < HL_N; i++) z[i] = m->x[i] / m->S.scale[i];
}

/* Largest scaled residual |dz/dt| at the current state, [1/s]; f gets dz/dt */
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

/* Pseudo-transient continuation to the rest state; 0 when the scaled residual is below
 * HL_FMU_STEADY_TOL. */
static int hl_solve_steady(hl_fmu* m) {
    double f[HL_N], fn[HL_N], z[HL_N], dz[HL_N], zn[HL_N];
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
        double nn = 0.;
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
        /* grown by the residual ratio and at least 1.5x per accepted step, as the Python
         * solver does (hydroline.engine.steady_state): a slow transient would creep */
        dt = fmin(dt * fmax(norm / fmax(nn, 1e-300), 1.5), 1e12);
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

static void hl_reset(hl_fmu* m) {
    hl_coefficients();
    hl_setup(&m->S, m->num.p0, m->num.c, m->num.scale, HL_FMU_RTOL, 0.1 * HL_FMU_RTOL, 0., 0.,
             5, 0.1);
    hl_set_max_steps(&m->S, 5000000);
    memcpy(m->x, m->num.x0, sizeof m->x);
    m->time = 0.;
    m->restart = 1;
    m->solve_steady = 1;
    m->mode = HL_INSTANTIATED;
}

/* The numbers file's path from the resources location: an FMI 2.0 URI (file:///dir/,
 * file:/dir/, percent-encoded) or an FMI 3.0 path; 0 on success. */
static int hl_numbers_path(const char* location, int is_uri, char* path, size_t size) {
    const char* s = location;
    size_t k = 0;
    if (!s || !*s) return -1;
    if (is_uri) {
        if (strncmp(s, "file://", 7) == 0) {
            s += 7;
            if (strncmp(s, "localhost/", 10) == 0) s += 9;
        } else if (strncmp(s, "file:", 5) == 0) {
            s += 5;
        } else {
            return -1;
        }
#if defined(_WIN32)
        if (s[0] == '/' && s[1] && s[2] == ':') s++;   /* file:///C:/dir */
#endif
    }
    for (; *s && k + 1 < size; s++) {
        if (is_uri && s[0] == '%' && isxdigit((unsigned char)s[1])
            && isxdigit((unsigned char)s[2])) {
            char hex[3] = {s[1], s[2], 0};
            path[k++] = (char)strtol(hex, NULL, 16);
            s += 2;
        } else {
            path[k++] = *s;
        }
    }
    if (k > 0 && path[k - 1] != '/' && path[k - 1] != '\\' && k + 1 < size) path[k++] = '/';
    path[k] = 0;
    if (k + strlen(HL_FMU_NUMBERS_FILE) + 1 > size) return -1;
    strcat(path, HL_FMU_NUMBERS_FILE);
    return 0;
}

/* One line of the numbers file without its end; 0 at the end of the file */
static int hl_line(FILE* f, char* line, size_t size) {
    if (!fgets(line, (int)size, f)) return 0;
    line[strcspn(line, "\r\n")] = 0;
    return 1;
}

/* A section "<label> <count>" of n values, one a line: "<IEEE-754 bits, hex> <decimal>" */
static int hl_read_values(FILE* f, const char* label, double* v, int n, char* why, size_t nwhy) {
    char line[256], word[64];
    int count = -1;
    if (!hl_line(f, line, sizeof line) || sscanf(line, "%63s %d", word, &count) != 2
        || strcmp(word, label) != 0 || count != n) {
        snprintf(why, nwhy, "expected %d values of '%s' in its numbers file (another FMU's?)",
                 n, label);
        return -1;
    }
    for (int i = 0; i < n; i++) {
        unsigned long long bits;
        char* end;
        if (!hl_line(f, line, sizeof line)) {
            snprintf(why, nwhy, "its numbers file ends within '%s'", label);
            return -1;
        }
        bits = strtoull(line, &end, 16);
        if (end == line) {
            snprintf(why, nwhy, "value %d of '%s' in its numbers file is not a hexadecimal bit "
                     "pattern", i, label);
            return -1;
        }
        memcpy(&v[i], &bits, sizeof(double));
        if (!isfinite(v[i])) {
            snprintf(why, nwhy, "value %d of '%s' in its numbers file is not finite", i, label);
            return -1;
        }
    }
    return 0;
}

/* Read this FMU's numbers from its resources; 0 on success, else why (one line) */
static int hl_load_numbers(hl_fmu_numbers* num, const char* location, int is_uri,
                           const char* guid, char* why, size_t nwhy) {
    char path[4096], line[512], word[64], value[256];
    if (hl_numbers_path(location, is_uri, path, sizeof path) != 0) {
        snprintf(why, nwhy, "no usable resources location (got %s): the FMU's numbers are in "
                 "resources/" HL_FMU_NUMBERS_FILE, location ? location : "none");
        return -1;
    }
    FILE* f = fopen(path, "rb");
    if (!f) {
        snprintf(why, nwhy, "cannot read %s", path);
        return -1;
    }
    int rc = -1;
    why[0] = 0;
    if (!hl_line(f, line, sizeof line) || strcmp(line, HL_FMU_NUMBERS_HEAD) != 0) {
        snprintf(why, nwhy, "%s is not a hydroline FMU numbers file of this version", path);
    } else if (!hl_line(f, line, sizeof line) || sscanf(line, "%63s %255s", word, value) != 2
               || strcmp(word, "guid") != 0 || (guid && strcmp(value, guid) != 0)) {
        snprintf(why, nwhy, "the GUID (instantiation token) does not match its numbers file's");
    } else if (!hl_line(f, line, sizeof line) || sscanf(line, "%63s %255s", word, value) != 2
               || strcmp(word, "structure") != 0 || strcmp(value, HL_FMU_STRUCTURE) != 0) {
        snprintf(why, nwhy, "its numbers file was written for another structure than this binary");
    } else if (hl_read_values(f, "constants", num->c, HL_NC, why, nwhy) == 0
               && hl_read_values(f, "state_scales", num->scale, HL_N, why, nwhy) == 0
               && hl_read_values(f, "rest_state", num->x0, HL_N, why, nwhy) == 0
               && hl_read_values(f, "parameters", num->p0, HL_NP, why, nwhy) == 0
               && hl_read_values(f, "parameter_nominals", num->pnominal, HL_NP, why, nwhy) == 0
               && hl_read_values(f, "accumulator_capacities", num->acc_capacity, HL_FMU_NACC,
                                 why, nwhy) == 0
               && hl_read_values(f, "accumulator_precharges", num->acc_precharge, HL_FMU_NACC,
                                 why, nwhy) == 0) {
        rc = 0;
    }
    fclose(f);
    return rc;
}

/* A new instance with this FMU's numbers from its resources (location: an FMI 2.0 URI when
 * is_uri, else an FMI 3.0 path); NULL with why (one line) when they cannot be read. */
static hl_fmu* hl_instantiate(const char* name, int me, int logging, const char* location,
                              int is_uri, const char* guid, char* why, size_t nwhy) {
    hl_fmu* m = (hl_fmu*)calloc(1, sizeof(hl_fmu));
    if (!m) {
        snprintf(why, nwhy, "out of memory");
        return NULL;
    }
    if (hl_load_numbers(&m->num, location, is_uri, guid, why, nwhy) != 0) {
        free(m);
        return NULL;
    }
    snprintf(m->name, sizeof m->name, "%s", name ? name : "hydroline");
    m->me = me;
    m->logging = logging;
    hl_reset(m);
    return m;
}

static void hl_setup_experiment(hl_fmu* m, int tolerance_defined, double tolerance, double start) {
    if (tolerance_defined && tolerance > 0) {
        m->S.rtol = tolerance;
        m->S.atol = 0.1 * tolerance;
    }
    m->time = start;
}

/* Accumulators adopt the node pressure at rest as the end of their isothermal charge (as
 * PistonAccumulator.settle in Python: gas volume V0 p0 / p, reference pressure p, M16);
 * returns 1 when something changed. */
static int hl_settle_accumulators(hl_fmu* m) {
    double z[HL_N], y[HL_NY];
    int changed = 0;
    hl_to_scaled(m, z);
    hl_signals(m->time, z, m->S.p, m->S.c, y);
    for (int k = 0; k < HL_FMU_NACC; k++) {
        double p_node = y[hl_fmu_acc[k].node_signal];
        if (!(p_node > m->num.acc_precharge[k])) continue;   /* empty: piston on its stop */
        double v = m->num.acc_capacity[k] * m->num.acc_precharge[k] / p_node;
        if (fabs(v - m->x[hl_fmu_acc[k].gas_state]) > 1e-12 * m->S.scale[hl_fmu_acc[k].gas_state])
            changed = 1;
        m->x[hl_fmu_acc[k].gas_state] = v;
        m->S.p[hl_fmu_acc[k].reference_parameter] = p_node;
    }
    return changed;
}

static int hl_exit_initialization(hl_fmu* m) {
    double f[HL_N];
    hl_apply_mirrors(m);
    if (m->solve_steady && hl_residual(m, f) >= HL_FMU_STEADY_TOL) {
        int failed = hl_solve_steady(m) != 0;
        for (int round = 0; !failed && round < 4 && hl_settle_accumulators(m); round++)
            failed = hl_solve_steady(m) != 0;
        if (failed) {
            double r = hl_residual(m, f);
            int worst = 0;
            for (int i = 0; i < HL_N; i++) if (fabs(f[i]) > fabs(f[worst])) worst = i;
            hl_log(m, HL_ERROR, "steady state not found at t = %g s: scaled residual %g 1/s at "
                   "state %s (set solve_steady_state = false to start from the given states)",
                   m->time, r, hl_fmu_state_names[worst]);
            m->mode = HL_FAILED;
            return HL_ERROR;
        }
    }
    m->mode = HL_RUNNING;
    m->restart = 1;
    return HL_OK;
}

static int hl_bad_vr(hl_fmu* m, const char* fn, unsigned int v) {
    hl_log(m, HL_ERROR, "%s: unknown value reference %u", fn, v);
    return HL_ERROR;
}

static int hl_get_real(hl_fmu* m, const unsigned int* vr, size_t nvr, double* value, const char* fn) {
    double z[HL_N], dz[HL_N], y[HL_NY];
    int have_dz = 0, have_y = 0;
    hl_to_scaled(m, z);
    for (size_t k = 0; k < nvr; k++) {
        unsigned int v = vr[k];
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
        } else if (v == HL_FMU_VR_TIME) {
            value[k] = m->time;
        } else {
            return hl_bad_vr(m, fn, v);
        }
    }
    return HL_OK;
}

static int hl_set_real(hl_fmu* m, const unsigned int* vr, size_t nvr, const double* value, const char* fn) {
    for (size_t k = 0; k < nvr; k++) {
        unsigned int v = vr[k];
        if (v < HL_N && m->mode <= HL_INIT) {
            m->x[v] = value[k];
        } else if (v >= HL_VR_PAR && v < HL_VR_END) {
            if (!isfinite(value[k])) {
                hl_log(m, HL_ERROR, "%s: %s must be finite, got %g", fn,
                       hl_fmu_parameter_names[v - HL_VR_PAR], value[k]);
                return HL_ERROR;
            }
            if (m->S.p[v - HL_VR_PAR] != value[k]) m->restart = 1;
            m->S.p[v - HL_VR_PAR] = value[k];
        } else {
            hl_log(m, HL_ERROR, "%s: value reference %u cannot be set%s", fn, v,
                   v < HL_N ? " after initialization (set the continuous states instead)" : "");
            return HL_ERROR;
        }
    }
    hl_apply_mirrors(m);
    return HL_OK;
}

static int hl_get_bool(hl_fmu* m, const unsigned int* vr, size_t nvr, int* value, const char* fn) {
    for (size_t k = 0; k < nvr; k++) {
        if (vr[k] != HL_FMU_VR_SOLVE_STEADY) return hl_bad_vr(m, fn, vr[k]);
        value[k] = m->solve_steady;
    }
    return HL_OK;
}

static int hl_set_bool(hl_fmu* m, const unsigned int* vr, size_t nvr, const int* value, const char* fn) {
    for (size_t k = 0; k < nvr; k++) {
        if (vr[k] != HL_FMU_VR_SOLVE_STEADY) return hl_bad_vr(m, fn, vr[k]);
        m->solve_steady = value[k] != 0;
    }
    return HL_OK;
}

/* Directional derivative: d(derivatives)/d(states) exactly from the generated sparse Jacobian;
 * any other pair (an output, or with respect to an input or parameter) by central differences. */
static int hl_directional(hl_fmu* m, const unsigned int* vu, size_t nu, const unsigned int* vk,
                          size_t nk, const double* dvk, double* dvu) {
    int exact = 1;
    for (size_t k = 0; k < nu; k++) if (vu[k] < HL_VR_DER || vu[k] >= HL_VR_SIG) exact = 0;
    for (size_t k = 0; k < nk; k++) if (vk[k] >= HL_N) exact = 0;
    if (exact) {
        double z[HL_N], jnz[HL_NNZ], dzk[HL_N], w[HL_N];
        hl_to_scaled(m, z);
        if (hl_jacobian_nonzeros(m->time, z, m->S.p, m->S.c, jnz) != 0) return HL_ERROR;
        memset(dzk, 0, sizeof dzk);
        for (size_t k = 0; k < nk; k++) dzk[vk[k]] += dvk[k] / m->S.scale[vk[k]];
        memset(w, 0, sizeof w);
        for (int j = 0; j < HL_N; j++)
            if (dzk[j] != 0.)
                for (long long q = hl_jac_colind[j]; q < hl_jac_colind[j + 1]; q++)
                    w[hl_jac_row[q]] += jnz[q] * dzk[j];
        for (size_t k = 0; k < nu; k++) {
            int i = (int)(vu[k] - HL_VR_DER);
            dvu[k] = w[i] * m->S.scale[i];
        }
        return HL_OK;
    }
    double* base = (double*)malloc(sizeof(double) * (nk + 2 * nu + 1));
    if (!base) return HL_ERROR;
    double* up = base + nk;
    double* dn = up + nu;
    for (size_t k = 0; k < nk; k++) {
        unsigned int v = vk[k];
        if (v >= HL_N && !(v >= HL_VR_PAR && v < HL_VR_END)) {
            free(base);
            return hl_bad_vr(m, "GetDirectionalDerivative", v);
        }
        hl_get_real(m, &v, 1, &base[k], "GetDirectionalDerivative");
    }
    double nrm = 0.;
    for (size_t k = 0; k < nk; k++) {
        double typical = vk[k] < HL_N ? m->S.scale[vk[k]] : m->num.pnominal[vk[k] - HL_VR_PAR];
        nrm = fmax(nrm, fabs(dvk[k]) / fmax(fabs(base[k]), typical));
    }
    double h = nrm > 0 ? 1e-6 / nrm : 1.;
    for (int sgn = 0; sgn < 2; sgn++) {
        for (size_t k = 0; k < nk; k++) {
            double val = base[k] + (sgn ? -h : h) * dvk[k];
            if (vk[k] < HL_N) m->x[vk[k]] = val; else m->S.p[vk[k] - HL_VR_PAR] = val;
        }
        hl_apply_mirrors(m);
        hl_get_real(m, vu, nu, sgn ? dn : up, "GetDirectionalDerivative");
    }
    for (size_t k = 0; k < nk; k++) {
        if (vk[k] < HL_N) m->x[vk[k]] = base[k]; else m->S.p[vk[k] - HL_VR_PAR] = base[k];
    }
    hl_apply_mirrors(m);
    for (size_t k = 0; k < nu; k++) dvu[k] = (up[k] - dn[k]) / (2. * h);
    free(base);
    return HL_OK;
}

/* Co-Simulation step [t, t + h] with hydroline's BDF integrator; the step history is kept
 * while nothing changed since the last step (else a restart at order 1: inputs may jump). */
static int hl_do_step(hl_fmu* m, double t, double h) {
    if (m->mode != HL_RUNNING) {
        hl_log(m, HL_ERROR, "DoStep: not in step mode (initialise first)");
        return HL_ERROR;
    }
    if (!(h > 0)) {
        hl_log(m, HL_ERROR, "DoStep: communication step size must be > 0 [s], got %g", h);
        return HL_ERROR;
    }
    double t_end = t + h;
    if (m->restart || fabs(t - m->S.t) > 1e-12 * fmax(1., fabs(t))) {
        hl_init(&m->S, t, m->x, t_end);
        m->restart = 0;
    } else {
        m->S.t_bound = t_end;
    }
    int done = 0;
    int rc = hl_advance(&m->S, 1, &t_end, m->x, NULL, &done, HL_N);
    if (rc != 0 || done != 1) {
        double xs[HL_N], ts;
        hl_get_state(&m->S, xs, &ts);
        hl_log(m, HL_ERROR, "DoStep: integrator failed at t = %g s (code %d: -1 step size below "
               "the resolution of t, -2 singular iteration matrix, -4 non-finite derivative, "
               "-5 too many steps)", ts, rc);
        m->mode = HL_FAILED;
        return HL_ERROR;
    }
    m->time = t_end;
    return HL_OK;
}

static int hl_set_states(hl_fmu* m, const double* x, size_t nx) {
    if (nx != HL_N) {
        hl_log(m, HL_ERROR, "SetContinuousStates: %u states expected, got %u", (unsigned)HL_N,
               (unsigned)nx);
        return HL_ERROR;
    }
    memcpy(m->x, x, sizeof m->x);
    m->restart = 1;
    return HL_OK;
}

static int hl_get_derivatives(hl_fmu* m, double* dx, size_t nx) {
    if (nx != HL_N) return HL_ERROR;
    double z[HL_N];
    hl_to_scaled(m, z);
    hl_f(m->time, z, m->S.p, m->S.c, dx);
    for (int i = 0; i < HL_N; i++) {
        dx[i] *= m->S.scale[i];
        if (!isfinite(dx[i])) {
            hl_log(m, HL_DISCARD, "GetDerivatives: derivative of %s is not finite at t = %g s",
                   hl_fmu_state_names[i], m->time);
            return HL_DISCARD;
        }
    }
    return HL_OK;
}

static int hl_get_states(hl_fmu* m, double* x, size_t nx) {
    if (nx != HL_N) return HL_ERROR;
    memcpy(x, m->x, sizeof m->x);
    return HL_OK;
}

static int hl_get_nominals(hl_fmu* m, double* x, size_t nx) {
    if (nx != HL_N) return HL_ERROR;
    memcpy(x, m->S.scale, sizeof(double) * HL_N);
    return HL_OK;
}

/* FMU state: a copy of the whole instance */
static int hl_get_state_copy(hl_fmu* m, void** state) {
    if (!*state) *state = malloc(sizeof(hl_fmu));
    if (!*state) return HL_ERROR;
    memcpy(*state, m, sizeof(hl_fmu));
    return HL_OK;
}

static int hl_set_state_copy(hl_fmu* m, const void* state) {
    if (!state) return HL_ERROR;
    hl_logger2 l2 = m->log2;
    hl_logger3 l3 = m->log3;
    void* env = m->env;
    memcpy(m, state, sizeof(hl_fmu));
    m->log2 = l2; m->log3 = l3; m->env = env;   /* this instance's importer */
    return HL_OK;
}

static int hl_deserialize(const char* bytes, size_t size, void** state) {
    if (size != sizeof(hl_fmu)) return HL_ERROR;
    if (!*state) *state = malloc(sizeof(hl_fmu));
    if (!*state) return HL_ERROR;
    memcpy(*state, bytes, sizeof(hl_fmu));
    return HL_OK;
}
