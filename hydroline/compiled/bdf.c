/* Variable-order, variable-step BDF/NDF integrator for one generated network model.
 *
 * Compiled together with the generated model code (hl_f, hl_jac, hl_signals, hl_lu_factor,
 * hl_lu_solve, HL_* sizes) into one shared library; the whole run of a segment happens in C.
 * hl_jac is the network's bordered Jacobian (the connections cut open, codegen.py): the
 * Newton systems are solved in it; d(dz/dt)/dz itself is assembled by hl_jacobian_nonzeros.
 *
 * Method: the quasi-constant step size BDF of Shampine & Reichelt, "The MATLAB ODE suite",
 * SIAM J. Sci. Comput. 18 (1997) 1-22, with the NDF coefficients kappa (orders 1-5), in the
 * backward-difference form of SciPy's `solve_ivp(method="BDF")`. Departures, all as in
 * SUNDIALS CVODE (Hindmarsh et al., ACM TOMS 31 (2005) 363-396): the simplified Newton
 * iteration may stop after one iteration using the convergence rate remembered from earlier
 * steps; the iteration matrix W = I - c J is kept while c changes by less than 30 % and the
 * Newton update is then scaled by 2/(1 + c/c_W); W is refactored at least every 50 steps and
 * always with a fresh (exact, sparse) Jacobian. Step size changes below 20 % upward are
 * skipped. Every step-size choice takes a safety factor of 0.8 (SciPy: 0.9): on the hoses'
 * ringing modes 0.9 rejected 7-11 % of the steps; 0.8 rejects 3-4 %, with ~10 % fewer Newton
 * iterations on the closed-loop sine and a smaller error (benchmarks/README.md). Linear algebra: the generated sparse LU (no pivoting, fill-reducing order), with a
 * dense partial-pivoting LU as fallback when a pivot is tiny.
 *
 * Fixed-step mode (fixed_step > 0): constant h, order raised by one per step up to max_order,
 * no error control (for real-time style comparisons).
 *
 * Second method (hl_set_method(S, 1), at the end of this file): the three-stage Radau IIA
 * collocation method of order 5 (L-stable: no order is given up on lightly damped fast modes),
 * as SciPy's `solve_ivp(method="Radau")` after Hairer & Wanner's RADAU5 (Solving ODEs II,
 * section IV.8): Newton's system transformed into one real and one complex n x n system, both
 * through the bordered Jacobian's LU pattern (the complex one by the pattern tables,
 * hl_lu_factor_z / hl_lu_solve_z), the first Newton iteration accepted with the convergence
 * rate remembered from earlier steps (RADAU5's FACCON); every step-size choice takes the BDF's
 * safety factor HL_SAFETY (SciPy's Radau: 0.9).
 */
#include <stdlib.h>
#if defined(__SSE2__) || defined(_M_X64)
#include <xmmintrin.h>
#define HL_FLUSH_SUBNORMALS 1
#endif

#define HL_MAX_ORDER 5
#define HL_NEWTON_MAXITER 4
#define HL_MIN_FACTOR 0.2
#ifndef HL_MAX_FACTOR
#define HL_MAX_FACTOR 10.0     /* largest step increase at once */
#endif
#ifndef HL_STEP_THRESHOLD
#define HL_STEP_THRESHOLD 1.2   /* step increases below this factor are skipped */
#endif
#ifndef HL_SAFETY
#define HL_SAFETY 0.8          /* safety factor of every step-size choice (SciPy: 0.9) */
#endif
#ifndef HL_EARLY
#define HL_EARLY 0.             /* (candidate) shrink at once when an accepted step's error exceeds this */
#endif
#ifndef HL_DGMAX
#define HL_DGMAX 0.3            /* refactor W when c changed by more than this fraction */
#endif
#ifndef HL_PROBATION
#define HL_PROBATION 10         /* steps kept at order 2 after a drop for a stability limit */
#endif
#ifndef HL_DROP_RATIO
#define HL_DROP_RATIO 2.0       /* drop a limited order when accuracy asks for this times its limit */
#endif
#ifndef HL_BACKOFF
#define HL_BACKOFF 50           /* steps before another drop, after the first that did not pay */
#endif
#ifndef HL_MAX_BACKOFF
#define HL_MAX_BACKOFF 400      /* at most this many steps between two tries (3 doublings of 50): an
                                 * uncapped backoff could lock a run at a limited order 3-5 with
                                 * its steps held at that order's limit (0.05 m sections: 5 000
                                 * or 37 000 steps by the rest state's rounding; capped, ~5 000) */
#endif
#ifndef HL_MSBP
#define HL_MSBP 50              /* refactor W at least every this many steps */
#endif

typedef struct {
    double p[HL_NP], c[HL_NC], scale[HL_N];
    double rtol, atol, max_step, fixed_step, newton_coef;
    int max_order;
    /* each state's ceiling on its absolute tolerance (scaled; 0, as calloc leaves it, or
     * INFINITY: none; hl_set_atol_ceilings) and the absolute tolerance its error weight takes,
     * min(atol, ceiling), to single precision (hl_inverse_weights) */
    double atol_ceiling[HL_N];
    float atol_state[HL_N];
    /* largest step of each order on the model's oscillatory modes (NDF3-5 are not A-stable):
     * order_limit[q] for q = 1..5, INFINITY where none (hl_set_order_limits) */
    double order_limit[HL_MAX_ORDER + 2];
    /* state */
    double t, h_abs, t_bound;
    /* the segment's end as seen by f: the double just below t_bound (an input that jumps at
     * t_bound, a step command's t >= time, belongs to the next segment; seen at t_bound
     * itself, every try to land there failed the error test and the step shrank geometrically
     * toward it: 40-50 steps before each breakpoint) */
    double t_left;
    double D[HL_MAX_ORDER + 3][HL_N];
    int order, n_equal_steps;
    /* stability-limited orders: steps left at order 2 after dropping there (no increase), and
     * the step count before which no new drop is tried (after order 2 lost: backoff) */
    int probation;
    long long drop_after, drop_backoff;
    int have_lu, lu_dense, steps_since_lu;
    double c_lu, crate;
    double jnz[HL_NENZ];      /* the bordered Jacobian (codegen.py) */
    double lu[HL_NLU];
    double dense[HL_NE * HL_NE];
    int piv[HL_NE];
    /* step history for dense output */
    double t_old, h_step;
    int order_step;
    /* statistics */
    long long nsteps, nfev, njev, nlu, nrej, nnewton_fail, ndense;
    int status;
    /* diagnostics: last state whose derivative was not finite in a Newton iterate (-1: none),
     * and the most steps one hl_advance call may take (0: no limit) */
    int last_nonfinite;
    long long max_steps;
    /* Radau IIA (method 1): the last step's stages Z_i = y(t_old + c_i h) - y(t_old), its
     * dense-output coefficients Q, the state before it, f at the current state, the complex
     * system's factors (re, im interleaved), the previous step and error norm (predictive
     * step control; < 0: none), the remembered Newton rate factor, the step the factors are
     * for, and flags: a Jacobian held, evaluated at the current step, the last step's
     * polynomial usable as the predictor */
    int method;
    double rZ[3][HL_N], rQ[3][HL_N], ry_old[HL_N], rf[HL_N];
    double luz[2 * HL_NLU];
    /* the complex factors again in the order the solve reads them (hl_lu_rows_z): L's and U's
     * entries row by row, and U's inverted diagonal, real and imaginary parts apart */
    double zl[2][HL_NLU], zu[2][HL_NLU], zd[2][HL_NE];
    double h_abs_old, err_old, faccon, h_lu;
    int have_jac, current_jac, have_sol;
    /* the step at which Newton's iteration last failed, halved (INFINITY: none): no step
     * grows past it until HL_RADAU_PROBE_STEPS steps have converged in two iterations, then it
     * doubles; and the count of those steps */
    double h_newton;
    int newton_good;
} hl_solver;

static int hl_radau_step(hl_solver* S);
static void hl_radau_dense(const hl_solver* S, double t, double* z);
static void hl_radau_init(hl_solver* S, const double* f0);

static const double hl_kappa[] = {0., -0.1850, -1. / 9., -0.0823, -0.0415, 0.};
static double hl_gamma_[HL_MAX_ORDER + 2], hl_alpha_[HL_MAX_ORDER + 2], hl_errc_[HL_MAX_ORDER + 2];
static double hl_U_[HL_MAX_ORDER + 1][HL_MAX_ORDER + 1][HL_MAX_ORDER + 1];
static int hl_coef_ready = 0;
static void hl_R_matrix(int order, double f, double M[HL_MAX_ORDER + 1][HL_MAX_ORDER + 1]);

static void hl_coefficients(void) {
    if (hl_coef_ready) return;
    hl_gamma_[0] = 0.;
    for (int k = 1; k <= HL_MAX_ORDER; k++) hl_gamma_[k] = hl_gamma_[k - 1] + 1. / k;
    for (int k = 0; k <= HL_MAX_ORDER; k++) {
        hl_alpha_[k] = (1. - hl_kappa[k]) * hl_gamma_[k];
        hl_errc_[k] = hl_kappa[k] * hl_gamma_[k] + 1. / (k + 1);
        hl_R_matrix(k, 1., hl_U_[k]);   /* change_D's U = R(1), per order */
    }
    hl_coef_ready = 1;
}

static double hl_rms(const double* v, const double* w) {
    double s = 0.;
    for (int i = 0; i < HL_N; i++) { double q = v[i] / w[i]; s += q * q; }
    return sqrt(s / HL_N);
}

/* rms of v_i * winv_i, winv the inverse error weights 1 / (atol + rtol |y_i|). Summed in
 * HL_LANES interleaved partial sums: one running sum is a chain of dependent additions (~4
 * cycles each, not vectorised without reassociation), 0.4 us a norm at 330 states, two to
 * four norms a step. */
#define HL_LANES 8
static double hl_wrms(const double* v, const double* winv) {
    double s[HL_LANES] = {0.};
    int i = 0;
    for (; i + HL_LANES <= HL_N; i += HL_LANES)
        for (int l = 0; l < HL_LANES; l++) { double q = v[i + l] * winv[i + l]; s[l] += q * q; }
    for (; i < HL_N; i++) { double q = v[i] * winv[i]; s[0] += q * q; }
    double total = 0.;
    for (int l = 0; l < HL_LANES; l++) total += s[l];
    return sqrt(total / HL_N);
}

/* rms of k * v_i * winv_i */
static double hl_wrms_k(double k, const double* v, const double* winv) {
    return fabs(k) * hl_wrms(v, winv);
}

/* Whether every v_i is finite; where not, the last index that is not goes to *last. Checked
 * as a sum of v_i * 0 (0 for a finite v_i, NaN for inf or NaN) in HL_LANES partial sums
 * (vectorised; a test and branch per entry cost as much as a norm). */
static int hl_all_finite(const double* v, int* last) {
    double s[HL_LANES] = {0.};
    int i = 0;
    for (; i + HL_LANES <= HL_N; i += HL_LANES)
        for (int l = 0; l < HL_LANES; l++) s[l] += v[i + l] * 0.;
    for (; i < HL_N; i++) s[0] += v[i] * 0.;
    double total = 0.;
    for (int l = 0; l < HL_LANES; l++) total += s[l];
    if (total == 0.) return 1;
    for (i = 0; i < HL_N; i++)
        if (!isfinite(v[i])) *last = i;
    return 0;
}

/* winv_i = 1 / (atol + rtol |y_i|), the inverse error weights, to single precision (7
 * digits: the weights set how errors are measured, not the solution). A double division per
 * state costs ~4 cycles, two per step; single precision ones go eight to a vector. */
static void hl_inverse_weights(const hl_solver* S, const double* y, double* winv) {
    const float rtol = (float)S->rtol;
    for (int i = 0; i < HL_N; i++) winv[i] = 1.f / (S->atol_state[i] + rtol * (float)fabs(y[i]));
}

/* State i's absolute tolerance: min(atol, its ceiling) (no ceiling, 0: atol itself) */
static double hl_state_atol(const hl_solver* S, int i) {
    return S->atol_ceiling[i] > 0 ? fmin(S->atol, S->atol_ceiling[i]) : S->atol;
}

/* atol_state_i, hl_state_atol to single precision */
static void hl_state_tolerances(hl_solver* S) {
    for (int i = 0; i < HL_N; i++) S->atol_state[i] = (float)hl_state_atol(S, i);
}

static void hl_eval_f(hl_solver* S, double t, const double* z, double* dz) {
    hl_f(t, z, S->p, S->c, dz);
    S->nfev++;
}

/* The predictor y = sum_k D[k] and psi = sum_k gamma_k / alpha_q D[k], k = 0..q (q >= 1),
 * state by state with the orders unrolled: each difference is read once (a pass over the
 * arrays per difference read and wrote y and psi q times), the sums in the same order. */
#define HL_PREDICT(Q) \
    for (int i = 0; i < HL_N; i++) { \
        double y = S->D[0][i] + S->D[1][i], ps = S->D[1][i] * g[1]; \
        for (int k = 2; k <= (Q); k++) { y += S->D[k][i]; ps += S->D[k][i] * g[k]; } \
        y_predict[i] = y; psi[i] = ps; \
    }
static void hl_predict(const hl_solver* S, int order, double* y_predict, double* psi) {
    double g[HL_MAX_ORDER + 1];
    for (int k = 1; k <= order; k++) g[k] = hl_gamma_[k] / hl_alpha_[order];
    switch (order) {
    case 1: HL_PREDICT(1) break;
    case 2: HL_PREDICT(2) break;
    case 3: HL_PREDICT(3) break;
    case 4: HL_PREDICT(4) break;
    default: HL_PREDICT(5) break;
    }
}

/* After an accepted step with correction d: D[q+2] = d - D[q+1], D[q+1] = d, then D[k] +=
 * D[k+1] for k = q..0; state by state with the orders unrolled, as hl_predict. */
#define HL_UPDATE(Q) \
    for (int i = 0; i < HL_N; i++) { \
        double up = d[i]; \
        S->D[(Q) + 2][i] = up - S->D[(Q) + 1][i]; \
        S->D[(Q) + 1][i] = up; \
        for (int k = (Q); k >= 0; k--) { up = S->D[k][i] + up; S->D[k][i] = up; } \
    }
static void hl_update_D(hl_solver* S, int order, const double* d) {
    switch (order) {
    case 1: HL_UPDATE(1) break;
    case 2: HL_UPDATE(2) break;
    case 3: HL_UPDATE(3) break;
    case 4: HL_UPDATE(4) break;
    default: HL_UPDATE(5) break;
    }
}

/* D[0..order] <- R(factor) U D : same interpolating polynomial, new step (SciPy change_D) */
static void hl_R_matrix(int order, double f, double M[HL_MAX_ORDER + 1][HL_MAX_ORDER + 1]) {
    for (int j = 0; j <= order; j++) M[0][j] = 1.;
    for (int i = 1; i <= order; i++) {
        M[i][0] = 0.;
        for (int j = 1; j <= order; j++) M[i][j] = M[i - 1][j] * (i - 1 - f * j) / i;
    }
}

static void hl_change_D(hl_solver* S, int order, double factor) {
    /* U = R(1) depends on the order only: hl_U_[order], made by hl_coefficients */
    double R[HL_MAX_ORDER + 1][HL_MAX_ORDER + 1], RU[HL_MAX_ORDER + 1][HL_MAX_ORDER + 1];
    hl_R_matrix(order, factor, R);
    for (int i = 0; i <= order; i++)
        for (int j = 0; j <= order; j++) {
            double s = 0.;
            for (int k = 0; k <= order; k++) s += R[i][k] * hl_U_[order][k][j];
            RU[i][j] = s;
        }
    double tmp[HL_MAX_ORDER + 1][HL_N];
    for (int j = 0; j <= order; j++) {
        for (int n = 0; n < HL_N; n++) tmp[j][n] = 0.;
        for (int k = 0; k <= order; k++) {
            double r = RU[k][j];
            const double* Dk = S->D[k];
            for (int n = 0; n < HL_N; n++) tmp[j][n] += r * Dk[n];
        }
    }
    memcpy(S->D[0], tmp[0], sizeof(double) * HL_N * (order + 1));
}

/* ---- linear algebra ------------------------------------------------------------------- */
/* Dense LU with partial pivoting of the n x n row-major A, in place; -1 if singular. As
 * LINPACK's dgefa: a row exchange at step k moves columns k.. only (the multipliers of the
 * earlier steps stay in their rows), which is what the interleaved exchanges and eliminations
 * of hl_dense_lu_solve (dgesl) expect. */
static int hl_dense_lu(double* A, int n, int* piv) {
    for (int k = 0; k < n; k++) {
        int p = k;
        double best = fabs(A[k * n + k]);
        for (int i = k + 1; i < n; i++)
            if (fabs(A[i * n + k]) > best) { best = fabs(A[i * n + k]); p = i; }
        piv[k] = p;
        if (!(best > 0.)) return -1;
        if (p != k)
            for (int j = k; j < n; j++) {
                double tmp = A[k * n + j]; A[k * n + j] = A[p * n + j]; A[p * n + j] = tmp;
            }
        double inv = 1. / A[k * n + k];
        for (int i = k + 1; i < n; i++) {
            double l = A[i * n + k] * inv;
            A[i * n + k] = l;
            if (l != 0.)
                for (int j = k + 1; j < n; j++) A[i * n + j] -= l * A[k * n + j];
        }
    }
    return 0;
}

static void hl_dense_lu_solve(const double* A, int n, const int* piv, double* b) {
    for (int k = 0; k < n; k++) {
        int p = piv[k];
        if (p != k) { double tmp = b[k]; b[k] = b[p]; b[p] = tmp; }
        for (int i = k + 1; i < n; i++) b[i] -= A[i * n + k] * b[k];
    }
    for (int k = n - 1; k >= 0; k--) {
        double s = b[k];
        for (int j = k + 1; j < n; j++) s -= A[k * n + j] * b[j];
        b[k] = s / A[k * n + k];
    }
}

/* The bordered W = [[I - g F_z, -g F_v], [-H_z, I - H_v]] (codegen.py), dense: the fallback
 * when a pivot of the sparse LU is tiny */
static int hl_dense_factor(hl_solver* S, double g) {
    double* A = S->dense;
    memset(A, 0, sizeof(double) * HL_NE * HL_NE);
    for (int j = 0; j < HL_NE; j++)
        for (long long k = hl_ext_colind[j]; k < hl_ext_colind[j + 1]; k++)
            A[hl_ext_row[k] * HL_NE + j] = -(hl_ext_row[k] < HL_N ? g : 1.) * S->jnz[k];
    for (int i = 0; i < HL_NE; i++) A[i * HL_NE + i] += 1.;
    return hl_dense_lu(A, HL_NE, S->piv);
}

static void hl_dense_solve(const hl_solver* S, double* b) {
    double v[HL_NE];
    memcpy(v, b, sizeof(double) * HL_N);
    for (int i = HL_N; i < HL_NE; i++) v[i] = 0.;      /* the cut signals' rows */
    hl_dense_lu_solve(S->dense, HL_NE, S->piv, v);
    memcpy(b, v, sizeof(double) * HL_N);
}

/* d(dz/dt)/dz at (t, z), nonzeros in the pattern hl_jac_colind / hl_jac_row: the Schur
 * complement J = F_z + F_v (I - H_v)^-1 H_z of the bordered Jacobian, column by column (for
 * checks, the steady state and the FMU's directional derivatives, not the integrator's
 * steps; no n x n work array). Returns -1 when out of memory or I - H_v is singular. */
static int hl_jacobian_nonzeros(double t, const double* z, const double* p, const double* c,
                                double* jnz) {
#if HL_NV == 0
    hl_jac(t, z, p, c, jnz);
    return 0;
#else
    int rc = -1;
    double* m = malloc(sizeof(double) * HL_NENZ);
    double* hv = calloc((size_t)HL_NV * HL_NV, sizeof(double));    /* I - H_v */
    double* tz = calloc((size_t)HL_NV * HL_N, sizeof(double));     /* H_z, then (I - H_v)^-1 H_z, by columns */
    double* col = calloc(HL_N, sizeof(double));                    /* one column of J */
    int piv[HL_NV];
    if (!(m && hv && tz && col)) goto done;
    hl_jac(t, z, p, c, m);
    for (int i = 0; i < HL_NV; i++) hv[i * HL_NV + i] = 1.;
    for (int j = 0; j < HL_NE; j++)
        for (long long k = hl_ext_colind[j]; k < hl_ext_colind[j + 1]; k++) {
            long long i = hl_ext_row[k];
            if (j < HL_N && i >= HL_N) tz[(long long)j * HL_NV + (i - HL_N)] = m[k];
            else if (j >= HL_N && i >= HL_N) hv[(i - HL_N) * HL_NV + (j - HL_N)] -= m[k];
        }
    if (hl_dense_lu(hv, HL_NV, piv) != 0) goto done;
    for (int j = 0; j < HL_N; j++) {
        const double* tj = tz + (long long)j * HL_NV;
        hl_dense_lu_solve(hv, HL_NV, piv, tz + (long long)j * HL_NV);
        for (long long k = hl_ext_colind[j]; k < hl_ext_colind[j + 1]; k++)   /* F_z[:, j] */
            if (hl_ext_row[k] < HL_N) col[hl_ext_row[k]] = m[k];
        for (int v = 0; v < HL_NV; v++) {                                  /* + F_v T[:, j] */
            if (tj[v] == 0.) continue;
            for (long long k = hl_ext_colind[HL_N + v]; k < hl_ext_colind[HL_N + v + 1]; k++)
                if (hl_ext_row[k] < HL_N) col[hl_ext_row[k]] += m[k] * tj[v];
        }
        for (long long k = hl_jac_colind[j]; k < hl_jac_colind[j + 1]; k++) {
            jnz[k] = col[hl_jac_row[k]];
            col[hl_jac_row[k]] = 0.;
        }
    }
    rc = 0;
done:
    if (rc != 0)
        for (int k = 0; k < HL_NNZ; k++) jnz[k] = NAN;
    free(m); free(hv); free(tz); free(col);
    return rc;
#endif
}

/* Factors of I - c J (the Jacobian in S->jnz): the sparse LU, or the dense one where the
 * sparse pivots fail; -1 when both do */
static int hl_real_factor(hl_solver* S, double c) {
    S->nlu++;
    S->lu_dense = 0;
    if (hl_lu_factor(S->jnz, c, S->lu) != 0) {
        S->ndense++;
        if (hl_dense_factor(S, c) != 0) return -1;
        S->lu_dense = 1;
    }
    return 0;
}

/* Fresh Jacobian at (t, z) and factors of I - c J */
static int hl_new_lu(hl_solver* S, double t, const double* z, double c) {
    hl_jac(t, z, S->p, S->c, S->jnz);
    S->njev++;
    if (hl_real_factor(S, c) != 0) return -1;
    S->have_lu = 1;
    S->c_lu = c;
    S->steps_since_lu = 0;
    S->crate = 1.;
    return 0;
}

static void hl_solve(const hl_solver* S, double* b) {
    if (S->lu_dense) hl_dense_solve(S, b); else hl_lu_solve(S->lu, b);
}

/* Simplified Newton iteration for the BDF system; returns 1 when converged */
static int hl_newton(hl_solver* S, double t_new, const double* y_predict, double c,
                     const double* psi, const double* winv, double tol, double* y, double* d,
                     int* n_iter) {
    double f[HL_N], dy[HL_N];
    double dy_norm_old = -1.;
    double gfac = 2. / (1. + c / S->c_lu);   /* CVODE's correction for a stale c in W */
    for (int k = 0; k < HL_NEWTON_MAXITER; k++) {   /* y, d: set by the first iteration */
        *n_iter = k + 1;
        hl_eval_f(S, fmin(t_new, S->t_left), k ? y : y_predict, f);
        if (k == 0)
            for (int i = 0; i < HL_N; i++) dy[i] = c * f[i] - psi[i];
        else
            for (int i = 0; i < HL_N; i++) dy[i] = c * f[i] - psi[i] - d[i];
        if (!hl_all_finite(dy, &S->last_nonfinite)) return 0;
        hl_solve(S, dy);
        if (gfac != 1.) for (int i = 0; i < HL_N; i++) dy[i] *= gfac;
        double dy_norm = hl_wrms(dy, winv);
        double rate = -1.;
        if (dy_norm_old > 0.) {
            rate = dy_norm / dy_norm_old;
            double rate_pow = rate;   /* rate^(HL_NEWTON_MAXITER - k) */
            for (int m = k + 1; m < HL_NEWTON_MAXITER; m++) rate_pow *= rate;
            if (rate >= 1. || rate_pow / (1. - rate) * dy_norm > tol)
                return 0;
            S->crate = fmax(0.3 * S->crate, rate);
        }
        if (k == 0)
            for (int i = 0; i < HL_N; i++) { y[i] = y_predict[i] + dy[i]; d[i] = dy[i]; }
        else
            for (int i = 0; i < HL_N; i++) { y[i] += dy[i]; d[i] += dy[i]; }
        if (dy_norm == 0.) return 1;
        if (rate < 0.) {
            if (dy_norm * fmin(1., S->crate) <= tol) return 1;
        } else if (rate / (1. - rate) * dy_norm < tol) {
            return 1;
        }
        dy_norm_old = dy_norm;
    }
    return 0;
}

/* ---- public API ------------------------------------------------------------------------ */
int hl_sizes(long long* out) {
    out[0] = HL_N; out[1] = HL_NP; out[2] = HL_NC; out[3] = HL_NY; out[4] = HL_NNZ;
    out[5] = HL_NLU; out[6] = (long long)sizeof(hl_solver);
    return 0;
}

void* hl_new(void) { hl_coefficients(); return calloc(1, sizeof(hl_solver)); }
void hl_free(void* S) { free(S); }

int hl_setup(hl_solver* S, const double* p, const double* c, const double* scale, double rtol,
             double atol, double max_step, double fixed_step, int max_order, double newton_coef) {
    memcpy(S->p, p, sizeof(double) * HL_NP);
    memcpy(S->c, c, sizeof(double) * HL_NC);
    memcpy(S->scale, scale, sizeof(double) * HL_N);
    S->rtol = rtol; S->atol = atol;
    hl_state_tolerances(S);
    S->max_step = max_step > 0 ? max_step : INFINITY;
    S->fixed_step = fixed_step;
    S->max_order = max_order < 1 ? 1 : (max_order > HL_MAX_ORDER ? HL_MAX_ORDER : max_order);
    S->newton_coef = newton_coef;
    for (int q = 0; q < HL_MAX_ORDER + 2; q++) S->order_limit[q] = INFINITY;
    return 0;
}

/* Largest step of each order 1..5 (limits[0..4], [s]; INFINITY: none): an order is kept only
 * while its step stays below its limit, else the step is taken at a lower order
 * (hydroline.compiled.stability: the NDF orders 3-5 on lightly damped fast modes). */
int hl_set_order_limits(hl_solver* S, const double* limits) {
    for (int q = 1; q <= HL_MAX_ORDER; q++)
        S->order_limit[q] = limits[q - 1] > 0 ? limits[q - 1] : INFINITY;
    return 0;
}

/* Each state's ceiling on its absolute tolerance, on the scaled state (ceiling [SI] / scale;
 * INFINITY or <= 0: none): its error weight takes min(atol, ceiling) from the next step on,
 * whatever atol hl_setup sets later (a state whose dynamics has a resolution: the piston
 * velocity against the friction's regularisation velocity). None set: the weights of atol. */
int hl_set_atol_ceilings(hl_solver* S, const double* ceilings) {
    for (int i = 0; i < HL_N; i++) S->atol_ceiling[i] = ceilings[i] > 0 ? ceilings[i] : 0.;
    hl_state_tolerances(S);
    return 0;
}

int hl_set_parameters(hl_solver* S, const double* p) {
    memcpy(S->p, p, sizeof(double) * HL_NP);
    return 0;
}

/* The integration method: 0 the variable-order NDF/BDF (the default), 1 Radau IIA of order 5;
 * set before hl_init. Returns 0, or -1 for an unknown method. */
int hl_set_method(hl_solver* S, int method) {
    if (method != 0 && method != 1) return -1;
    S->method = method;
    return 0;
}

/* Start a segment at t0 from unscaled state x0 (order 1, SciPy's initial step choice). */
int hl_init(hl_solver* S, double t0, const double* x0, double t_bound) {
    double z[HL_N], f0[HL_N], f1[HL_N], y1[HL_N], w[HL_N], df[HL_N];
    for (int i = 0; i < HL_N; i++) z[i] = x0[i] / S->scale[i];
    S->t = t0; S->t_bound = t_bound; S->order = 1; S->n_equal_steps = 0;
    S->t_left = nextafter(t_bound, -INFINITY);
    S->probation = 0; S->drop_after = 0; S->drop_backoff = 0;
    S->have_lu = 0; S->crate = 1.; S->status = 0; S->h_step = 0.;
    hl_eval_f(S, t0, z, f0);
    double interval = fabs(t_bound - t0), h;
    if (S->fixed_step > 0) {
        h = fmin(S->fixed_step, interval);
    } else {
        for (int i = 0; i < HL_N; i++) w[i] = hl_state_atol(S, i) + fabs(z[i]) * S->rtol;
        double d0 = hl_rms(z, w), d1 = hl_rms(f0, w), h0;
        h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
        h0 = fmin(h0, interval);
        for (int i = 0; i < HL_N; i++) y1[i] = z[i] + h0 * f0[i];
        hl_eval_f(S, t0 + h0, y1, f1);
        for (int i = 0; i < HL_N; i++) df[i] = f1[i] - f0[i];
        double d2 = hl_rms(df, w) / h0, h1;
        if (d1 <= 1e-15 && d2 <= 1e-15) h1 = fmax(1e-6, h0 * 1e-3);
        else h1 = pow(0.01 / fmax(d1, d2), S->method == 1 ? 0.25 : 0.5);   /* error order 3 / 1 */
        h = fmin(fmin(100 * h0, h1), fmin(interval, S->max_step));
    }
    S->h_abs = h;
    memcpy(S->D[0], z, sizeof(double) * HL_N);
    for (int i = 0; i < HL_N; i++) S->D[1][i] = f0[i] * h;
    for (int k = 2; k < HL_MAX_ORDER + 3; k++) memset(S->D[k], 0, sizeof(double) * HL_N);
    if (S->method == 1) hl_radau_init(S, f0);
    return 0;
}

/* One accepted step; returns 0, or <0 on failure (-1 step too small, -2 singular W,
 * -3 Newton failed in fixed-step mode). hl_advance adds -4 (step too small after a
 * non-finite derivative) and -5 (max_steps reached). */
static int hl_step(hl_solver* S) {
    double y_predict[HL_N], psi[HL_N], winv[HL_N], y_new[HL_N], d[HL_N];
    double t = S->t;
    int order = S->order;
    double min_step = 10. * fabs(nextafter(t, INFINITY) - t);
    double h_abs = S->h_abs;
    int fixed = S->fixed_step > 0;
    if (h_abs > S->max_step) {
        hl_change_D(S, order, S->max_step / h_abs); h_abs = S->max_step; S->n_equal_steps = 0;
    } else if (h_abs < min_step) {
        hl_change_D(S, order, min_step / h_abs); h_abs = min_step; S->n_equal_steps = 0;
    }
    while (order > 1 && h_abs > S->order_limit[order]) {   /* beyond this order's stability */
        order--; S->order = order; S->n_equal_steps = 0;
    }
    double error_norm = 0., safety = HL_SAFETY, t_new = t;
    int n_iter = 1;
    for (;;) {
        if (h_abs < min_step) return -1;
        t_new = t + h_abs;
        if (t_new - S->t_bound > 0 || S->t_bound - t_new < min_step) {
            t_new = S->t_bound;
            hl_change_D(S, order, (t_new - t) / h_abs);
            S->n_equal_steps = 0;
        }
        double h = t_new - t;
        h_abs = h;
        hl_predict(S, order, y_predict, psi);
        hl_inverse_weights(S, y_predict, winv);
        double c = h / hl_alpha_[order];
        double tol = S->newton_coef / hl_errc_[order];
        int converged = 0, fresh = 0;
        if (!S->have_lu || fabs(c / S->c_lu - 1.) > HL_DGMAX || S->steps_since_lu >= HL_MSBP) {
            if (hl_new_lu(S, t_new, y_predict, c) != 0) return -2;
            fresh = 1;
        }
        for (;;) {
            converged = hl_newton(S, t_new, y_predict, c, psi, winv, tol, y_new, d, &n_iter);
            if (converged || fresh) break;
            if (hl_new_lu(S, t_new, y_predict, c) != 0) return -2;
            fresh = 1;
        }
        if (!converged) {
            S->nnewton_fail++;
            if (fixed) return -3;
            h_abs *= 0.5;
            hl_change_D(S, order, 0.5);
            S->n_equal_steps = 0;
            S->have_lu = 0;
            continue;
        }
        safety = HL_SAFETY * (2 * HL_NEWTON_MAXITER + 1) / (2 * HL_NEWTON_MAXITER + n_iter);
        hl_inverse_weights(S, y_new, winv);
        error_norm = hl_wrms_k(hl_errc_[order], d, winv);
        if (!fixed && error_norm > 1.) {
            S->nrej++;
            double factor = fmax(HL_MIN_FACTOR, safety * pow(error_norm, -1. / (order + 1)));
            h_abs *= factor;
            hl_change_D(S, order, factor);
            S->n_equal_steps = 0;
            continue;
        }
        break;
    }
    S->nsteps++;
    S->steps_since_lu++;
    S->n_equal_steps++;
    if (S->probation > 0) S->probation--;
    S->t_old = t;
    S->t = t_new;
    S->h_step = h_abs;
    S->order_step = order;
    S->h_abs = h_abs;
    hl_update_D(S, order, d);
    if (fixed) {
        if (order < S->max_order) S->order = order + 1;
        return 0;
    }
    if (S->n_equal_steps < order + 1) {
        if (HL_EARLY > 0. && error_norm > HL_EARLY) {   /* (candidate) */
            double factor = safety * pow(error_norm, -1. / (order + 1));
            if (factor < 1.) {
                S->h_abs *= factor;
                hl_change_D(S, order, factor);
                S->n_equal_steps = 0;
            }
        }
        return 0;
    }
    double e_m = INFINITY, e_p = INFINITY;
    if (order > 1) e_m = hl_wrms_k(hl_errc_[order - 1], S->D[order], winv);
    if (order < S->max_order) e_p = hl_wrms_k(hl_errc_[order + 1], S->D[order + 2], winv);
    double fm = e_m > 0 ? pow(e_m, -1. / order) : INFINITY;
    double f0 = error_norm > 0 ? pow(error_norm, -1. / (order + 1)) : INFINITY;
    double fp = e_p > 0 ? pow(e_p, -1. / (order + 2)) : INFINITY;
    if (order == 1) fm = 0.;
    if (order >= S->max_order) fp = 0.;
    /* each candidate's step factor, at most its order's stability limit allows: an order whose
     * limit binds is left (one order down, the step at the limit), and not entered from
     * below (its error estimates carry the fast mode it lets ring; order 2 damps it) */
    double cm = safety * fm, c0 = safety * f0, cp = safety * fp;
    int limited = order >= 3 && c0 > HL_DROP_RATIO * S->order_limit[order] / h_abs;
    if (order > 1) cm = fmin(cm, S->order_limit[order - 1] / h_abs);
    c0 = fmin(c0, S->order_limit[order] / h_abs);
    if (order < S->max_order) {
        if (S->probation > 0 || h_abs >= S->order_limit[order + 1]) cp = 0.;
        else cp = fmin(cp, S->order_limit[order + 1] / h_abs);
    }
    int delta = 0;
    double best = c0;
    if (limited && S->nsteps >= S->drop_after) {
        /* held at a stability limit: to order 2 (A-stable, damps the fast mode), same step,
         * for HL_PROBATION steps at least; kept while its steps outgrow order 3's limit */
        delta = 2 - order;
        best = 1.;
        S->probation = HL_PROBATION;
    } else {
        if (cm > best) { best = cm; delta = -1; }
        if (cp > best) { best = cp; delta = 1; }
        if (delta == 1 && order == 2 && S->order_limit[3] < INFINITY) {
            /* back up from order 2 below order 3's limit: the drop did not pay; try the next
             * one only after twice as many steps as last time, at most HL_MAX_BACKOFF */
            S->drop_backoff = S->drop_backoff ? 2 * S->drop_backoff : HL_BACKOFF;
            if (S->drop_backoff > HL_MAX_BACKOFF) S->drop_backoff = HL_MAX_BACKOFF;
            S->drop_after = S->nsteps + S->drop_backoff;
        }
    }
    order += delta;
    S->order = order;
    double factor = fmin(HL_MAX_FACTOR, best);
    S->n_equal_steps = 0;
    if (factor >= 1. && factor < HL_STEP_THRESHOLD) return 0;   /* not worth a change (CVODE's threshold) */
    S->h_abs *= factor;
    hl_change_D(S, order, factor);
    return 0;
}

/* Interpolate the last step's polynomial at t (scaled state); D holds it as backward
 * differences for the current step size and order (change_D keeps the polynomial). */
static void hl_dense_output(const hl_solver* S, double t, double* z) {
    if (S->method == 1) { hl_radau_dense(S, t, z); return; }
    int q = S->order;
    double h = S->h_abs, prod = (t - S->t) / h;   /* j = 1 (q >= 1) */
    for (int i = 0; i < HL_N; i++) z[i] = S->D[0][i] + S->D[1][i] * prod;
    for (int j = 2; j <= q; j++) {
        prod *= (t - (S->t - (j - 1) * h)) / (j * h);
        for (int i = 0; i < HL_N; i++) z[i] += S->D[j][i] * prod;
    }
}

static int hl_advance_run(hl_solver* S, int n_out, const double* t_out, double* X, double* Y,
                          int* n_done, long long ld);

/* Integrate toward t_bound, writing states X (unscaled, row-major) and signals Y at the
 * n_out output times; returns after the last output time or at t_bound.
 *
 * Subnormal numbers (below 2.2e-308) are flushed to zero while it runs (x86's MXCSR flags
 * FTZ and DAZ, restored on return; what -ffast-math sets for a whole program): while the
 * piston decelerates on its stop (0.3 m hose, Radau) the factors of the Newton matrices held
 * 1-7 (real) and 7-18 (complex) subnormal entries of 829, products of tiny Jacobian entries
 * in the elimination; every solve through them paid a microcode assist (~100 cycles) per
 * operation, 2.3x the solves' time: the impact's 10 ms window took 3.2 ms CPU instead of
 * 2.0 ms. No result this integrator gives depends on numbers that small. */
int hl_advance(hl_solver* S, int n_out, const double* t_out, double* X, double* Y,
               int* n_done, long long ld) {
#ifdef HL_FLUSH_SUBNORMALS
    unsigned int csr = _mm_getcsr();
    _mm_setcsr(csr | 0x8040u);      /* FTZ (bit 15) and DAZ (bit 6) */
    int rc = hl_advance_run(S, n_out, t_out, X, Y, n_done, ld);
    _mm_setcsr(csr);
    return rc;
#else
    return hl_advance_run(S, n_out, t_out, X, Y, n_done, ld);
#endif
}

static int hl_advance_run(hl_solver* S, int n_out, const double* t_out, double* X, double* Y,
                          int* n_done, long long ld) {
    /* row j of X (states) at X + j*ld, of Y (signals) at Y + j*ld: one shared output table */
    double z[HL_N];
    int j = 0;
    long long steps = 0;
    /* outputs at or before the current time (e.g. t_out == t0) */
    while (j < n_out && t_out[j] <= S->t) {
        if (t_out[j] >= S->t || S->h_step <= 0.) memcpy(z, S->D[0], sizeof z);
        else hl_dense_output(S, t_out[j], z);
        for (int i = 0; i < HL_N; i++) X[(long long)j * ld + i] = z[i] * S->scale[i];
        if (Y) hl_signals(t_out[j], z, S->p, S->c, Y + (long long)j * ld);
        j++;
    }
    while (j < n_out && S->t < S->t_bound) {
        S->last_nonfinite = -1;
        int rc = (S->max_steps > 0 && steps++ >= S->max_steps) ? -5
                 : (S->method == 1 ? hl_radau_step(S) : hl_step(S));
        if (rc == -1 && S->last_nonfinite >= 0) rc = -4;   /* the step shrank on non-finite f */
        if (rc != 0) { S->status = rc; *n_done = j; return rc; }
        while (j < n_out && (t_out[j] <= S->t || S->t >= S->t_bound)) {
            if (t_out[j] >= S->t) memcpy(z, S->D[0], sizeof z);
            else hl_dense_output(S, t_out[j], z);
            for (int i = 0; i < HL_N; i++) X[(long long)j * ld + i] = z[i] * S->scale[i];
            if (Y) hl_signals(t_out[j], z, S->p, S->c, Y + (long long)j * ld);
            j++;
        }
    }
    *n_done = j;
    return 0;
}

int hl_last_nonfinite(const hl_solver* S) { return S->last_nonfinite; }

void hl_set_max_steps(hl_solver* S, long long max_steps) { S->max_steps = max_steps; }

void hl_get_state(const hl_solver* S, double* x, double* t) {
    for (int i = 0; i < HL_N; i++) x[i] = S->D[0][i] * S->scale[i];
    *t = S->t;
}

void hl_stats(const hl_solver* S, long long* out) {
    out[0] = S->nsteps; out[1] = S->nfev; out[2] = S->njev; out[3] = S->nlu;
    out[4] = S->nrej; out[5] = S->nnewton_fail; out[6] = S->ndense;
}

void hl_reset_stats(hl_solver* S) {
    S->nsteps = S->nfev = S->njev = S->nlu = S->nrej = S->nnewton_fail = S->ndense = 0;
}

/* Plain evaluations (unscaled x), for checks and the steady-state solver */
void hl_rhs(const hl_solver* S, double t, const double* x, double* dx) {
    double z[HL_N];
    for (int i = 0; i < HL_N; i++) z[i] = x[i] / S->scale[i];
    hl_f(t, z, S->p, S->c, dx);
    for (int i = 0; i < HL_N; i++) dx[i] *= S->scale[i];
}

/* The bordered Jacobian (codegen.py) at (t, x), x unscaled, with runtime parameters p,
 * constants c and state scales: its nonzeros in hl_ext_colind / hl_ext_row order (states
 * scaled, the cut signals in SI). Needs no solver: for the steady state's sparse solves. */
void hl_bordered_jacobian(double t, const double* x, const double* p, const double* c,
                          const double* scale, double* out) {
    double z[HL_N];
    for (int i = 0; i < HL_N; i++) z[i] = x[i] / scale[i];
    hl_jac(t, z, p, c, out);
}

/* Sizes of the bordered Jacobian: out = {states, states + cut signals, nonzeros} */
void hl_bordered_sizes(long long* out) { out[0] = HL_N; out[1] = HL_NE; out[2] = HL_NENZ; }

/* Its compressed-column pattern: colind (HL_NE + 1 entries) and row (HL_NENZ entries) */
void hl_bordered_pattern(long long* colind, long long* row) {
    memcpy(colind, hl_ext_colind, sizeof(long long) * (HL_NE + 1));
    memcpy(row, hl_ext_row, sizeof(long long) * HL_NENZ);
}

int hl_scaled_jacobian(const hl_solver* S, double t, const double* x, double* jnz) {
    double z[HL_N];
    for (int i = 0; i < HL_N; i++) z[i] = x[i] / S->scale[i];
    return hl_jacobian_nonzeros(t, z, S->p, S->c, jnz);
}

/* ---- Radau IIA of order 5 (method 1) ------------------------------------------------------
 * Collocation at c = ((4 - sqrt 6)/10, (4 + sqrt 6)/10, 1); the stages Z_i = y(t + c_i h) - y
 * solve Z = h (A x I) F(Z). Newton's matrix (A^-1/h x I - I x J) is block-diagonalised by
 * A^-1 = T diag(mu_r, mu_c, conj mu_c) T^-1 into one real system (mu_r/h I - J) and one complex
 * one (mu_c/h I - J), each the bordered I - g J with g = h/mu (g complex for the second). The
 * constants are SciPy's (scipy/integrate/_ivp/radau.py), from Hairer & Wanner's RADAU5. */
#define HL_RADAU_MAXITER 6
#ifndef HL_RADAU_PROBE_STEPS
/* After a Newton failure, steps well converged before the step may grow past the halved
 * failing one (twice it, each time). The error test alone grew the step again at once, up to
 * 10x: with the piston resting on its stop (its velocity through the friction's steep slope
 * at zero speed), rtol 1e-3 on the 30-mode rig took 408 Newton failures and 1 054
 * factorisation pairs, 43.5 ms; capped 77 and 340, 25.7 ms; other runs unchanged within 3 %
 * with 10-30 % fewer factorisations (benchmarks/README.md, "Radau IIA by default") */
#define HL_RADAU_PROBE_STEPS 10
#endif
static const double hl_rc[3] = {0.15505102572168222, 0.6449489742783178, 1.};
static const double hl_rE[3] = {-10.048809399827414, 1.382142733160748, -0.3333333333333333};
static const double hl_rT[3][3] = {{0.09443876248897524, -0.1412552950209542, 0.03002919410514742},
                                   {0.2502131229653333, 0.20412935229379994, -0.3829421127572619},
                                   {1., 1., 0.}};
static const double hl_rTI[3][3] = {{4.178718591551904, 0.32768282076106237, 0.5233764454994495},
                                    {-4.178718591551904, -0.32768282076106237, 0.47662355450055044},
                                    {0.5028726349457868, -2.571926949855605, 0.5960392048282249}};
static const double hl_rP[3][3] = {{10.048809399827414, -25.62959144707664, 15.580782047249224},
                                   {-1.382142733160748, 10.296258113743303, -8.914115380582556},
                                   {0.3333333333333333, -2.6666666666666665, 3.3333333333333335}};
#define HL_MU_REAL 3.637834252744496
#define HL_MU_RE 2.6810828736277523
#define HL_MU_IM (-3.050430199247411)

/* LU of the bordered I - g J for complex g = gr + i gi, in the real factor's pattern and order
 * (codegen.py's tables); a holds re, im interleaved. Returns the 1-based failing pivot or 0. */
static int hl_lu_factor_z(const double* jnz, double gr, double gi, double* a) {
    memset(a, 0, sizeof(double) * 2 * HL_NLU);
    for (int k = 0; k < HL_LU_NJ; k++) {
        int s = hl_lu_jslot[k];
        a[2 * s] = -gr * jnz[k]; a[2 * s + 1] = -gi * jnz[k];
    }
    for (int k = 0; k < HL_LU_NSIG; k++) {          /* the cut signals' rows: not times g */
        int m = hl_lu_signal_nz[k], s = hl_lu_jslot[m];
        a[2 * s] = -jnz[m]; a[2 * s + 1] = 0.;
    }
    for (int k = 0; k < HL_NE; k++) a[2 * hl_lu_diag[k]] += 1.;
    for (int k = 0; k < HL_NE; k++) {
        int d = hl_lu_diag[k];
        double pr = a[2 * d], pi = a[2 * d + 1], m2 = pr * pr + pi * pi;
        if (!(sqrt(m2) > HL_PIVOT_TOL)) return k + 1;
        double ir = pr / m2, ii = -pi / m2;           /* 1 / pivot */
        a[2 * d] = ir; a[2 * d + 1] = ii;
        for (int m = hl_lu_lstart[k]; m < hl_lu_lstart[k + 1]; m++) {
            int ls = hl_lu_lslot[m];
            double xr = a[2 * ls], xi = a[2 * ls + 1];
            double lr = xr * ir - xi * ii, li = xr * ii + xi * ir;
            a[2 * ls] = lr; a[2 * ls + 1] = li;
            for (int q = hl_lu_ustart[m]; q < hl_lu_ustart[m + 1]; q++) {
                int tg = hl_lu_tgt[q], sr = hl_lu_src[q];
                double ur = a[2 * sr], ui = a[2 * sr + 1];
                a[2 * tg] -= lr * ur - li * ui;
                a[2 * tg + 1] -= lr * ui + li * ur;
            }
        }
    }
    return 0;
}

/* hl_lu_factor_z's factors (slots, re and im interleaved) copied into the order the solve
 * reads them: each row's L and U entries in sequence, real and imaginary parts apart. The
 * solve then reads its factors in sequence instead of through the slot tables, for one pass
 * over the factors per factorisation. */
static void hl_lu_rows_z(const double* a, double zl[2][HL_NLU], double zu[2][HL_NLU],
                         double zd[2][HL_NE]) {
    for (int m = 0; m < hl_lu_lrowstart[HL_NE]; m++) {
        int s = hl_lu_lrslot[m];
        zl[0][m] = a[2 * s]; zl[1][m] = a[2 * s + 1];
    }
    for (int q = 0; q < hl_lu_urowstart[HL_NE]; q++) {
        int s = hl_lu_uslot[q];
        zu[0][q] = a[2 * s]; zu[1][q] = a[2 * s + 1];
    }
    for (int k = 0; k < HL_NE; k++) {
        int d = hl_lu_diag[k];
        zd[0][k] = a[2 * d]; zd[1][k] = a[2 * d + 1];
    }
}

/* Solve (I - g J) x = b in place with the complex factors in reading order (hl_lu_rows_z;
 * b = br + i bi, states only): both substitutions by rows, each unknown gathered once */
static void hl_lu_solve_z(const hl_solver* S, double* br, double* bi) {
    const double *lr = S->zl[0], *li = S->zl[1], *ur = S->zu[0], *ui = S->zu[1];
    double vr[HL_NE], vi[HL_NE];
    for (int i = 0; i < HL_NE; i++) {               /* L (unit diagonal) */
        int o = hl_lu_perm[i];
        double sr = o < HL_N ? br[o] : 0., si = o < HL_N ? bi[o] : 0.;
        for (int m = hl_lu_lrowstart[i]; m < hl_lu_lrowstart[i + 1]; m++) {
            int k = hl_lu_lcol[m];
            sr -= lr[m] * vr[k] - li[m] * vi[k];
            si -= lr[m] * vi[k] + li[m] * vr[k];
        }
        vr[i] = sr; vi[i] = si;
    }
    for (int k = HL_NE - 1; k >= 0; k--) {          /* U; its diagonal stored inverted */
        double sr = vr[k], si = vi[k];
        for (int q = hl_lu_urowstart[k]; q < hl_lu_urowstart[k + 1]; q++) {
            int j = hl_lu_ucol[q];
            sr -= ur[q] * vr[j] - ui[q] * vi[j];
            si -= ur[q] * vi[j] + ui[q] * vr[j];
        }
        vr[k] = sr * S->zd[0][k] - si * S->zd[1][k];
        vi[k] = sr * S->zd[1][k] + si * S->zd[0][k];
    }
    for (int k = 0; k < HL_NE; k++) {
        int o = hl_lu_perm[k];
        if (o < HL_N) { br[o] = vr[k]; bi[o] = vi[k]; }
    }
}

static void hl_radau_init(hl_solver* S, const double* f0) {
    memcpy(S->rf, f0, sizeof(double) * HL_N);
    S->h_abs_old = -1.; S->err_old = -1.; S->faccon = 1.;
    S->h_newton = INFINITY; S->newton_good = 0;
    S->have_jac = 0; S->current_jac = 0; S->have_sol = 0;
}

/* Fresh Jacobian at (t, z) (the bordered one, in S->jnz) */
static void hl_radau_jacobian(hl_solver* S, double t, const double* z) {
    hl_jac(t, z, S->p, S->c, S->jnz);
    S->njev++;
    S->have_jac = 1;
    S->current_jac = 1;
    S->have_lu = 0;
}

/* Factors of both systems for step h; -1 when one is singular */
static int hl_radau_factor(hl_solver* S, double h) {
    double g = h / HL_MU_REAL;
    if (hl_real_factor(S, g) != 0) return -1;
    double m2 = HL_MU_RE * HL_MU_RE + HL_MU_IM * HL_MU_IM;     /* g = h / mu_c */
    if (hl_lu_factor_z(S->jnz, h * HL_MU_RE / m2, -h * HL_MU_IM / m2, S->luz) != 0) return -1;
    hl_lu_rows_z(S->luz, S->zl, S->zu, S->zd);
    S->have_lu = 1;
    S->h_lu = h;
    return 0;
}

/* Simplified Newton iteration for the stages Z (predictor in, solution out); 1 when converged.
 * Convergence as RADAU5: the first iteration may end it with the rate remembered from earlier
 * steps (S->faccon); a rate >= 0.99, or one that cannot meet tol within the iterations left,
 * ends it as failed. */
static int hl_radau_newton(hl_solver* S, double t, const double* y, double h, double Z[3][HL_N],
                           const double* winv, double tol, int* n_iter, double* rate_out) {
    double W[3][HL_N], F[3][HL_N], zi[HL_N], dr[HL_N], dre[HL_N], dim[HL_N];
    const double mr = HL_MU_REAL / h, mcr = HL_MU_RE / h, mci = HL_MU_IM / h;
    const double gr = h / HL_MU_REAL, m2 = HL_MU_RE * HL_MU_RE + HL_MU_IM * HL_MU_IM;
    const double gcr = h * HL_MU_RE / m2, gci = -h * HL_MU_IM / m2;
    for (int i = 0; i < 3; i++)
        for (int n = 0; n < HL_N; n++)
            W[i][n] = hl_rTI[i][0] * Z[0][n] + hl_rTI[i][1] * Z[1][n] + hl_rTI[i][2] * Z[2][n];
    double norm_old = -1., rate = -1.;
    S->faccon = pow(fmax(S->faccon, 2.2e-16), 0.8);
    for (int k = 0; k < HL_RADAU_MAXITER; k++) {
        *n_iter = k + 1;
        for (int i = 0; i < 3; i++) {
            for (int n = 0; n < HL_N; n++) zi[n] = y[n] + Z[i][n];
            hl_eval_f(S, fmin(t + hl_rc[i] * h, S->t_left), zi, F[i]);
            if (!hl_all_finite(F[i], &S->last_nonfinite)) return 0;
        }
        for (int n = 0; n < HL_N; n++) {
            double f0 = F[0][n], f1 = F[1][n], f2 = F[2][n];
            double a = hl_rTI[0][0] * f0 + hl_rTI[0][1] * f1 + hl_rTI[0][2] * f2 - mr * W[0][n];
            double br = hl_rTI[1][0] * f0 + hl_rTI[1][1] * f1 + hl_rTI[1][2] * f2
                        - (mcr * W[1][n] - mci * W[2][n]);
            double bi = hl_rTI[2][0] * f0 + hl_rTI[2][1] * f1 + hl_rTI[2][2] * f2
                        - (mcr * W[2][n] + mci * W[1][n]);
            dr[n] = gr * a;
            dre[n] = gcr * br - gci * bi;
            dim[n] = gcr * bi + gci * br;
        }
        hl_solve(S, dr);
        hl_lu_solve_z(S, dre, dim);
        double s2 = 0.;
        {
            double a1 = hl_wrms(dr, winv), a2 = hl_wrms(dre, winv), a3 = hl_wrms(dim, winv);
            s2 = (a1 * a1 + a2 * a2 + a3 * a3) / 3.;
        }
        double norm = sqrt(s2);
        if (norm_old > 0.) {
            rate = norm / norm_old;
            if (rate >= 0.99) return 0;
            S->faccon = rate / (1. - rate);
            double rp = 1.;     /* rate^(maxiter - 1 - k) */
            for (int m = k + 1; m < HL_RADAU_MAXITER; m++) rp *= rate;
            if (S->faccon * norm * rp > tol) return 0;
        }
        for (int n = 0; n < HL_N; n++) { W[0][n] += dr[n]; W[1][n] += dre[n]; W[2][n] += dim[n]; }
        for (int i = 0; i < 3; i++)
            for (int n = 0; n < HL_N; n++)
                Z[i][n] = hl_rT[i][0] * W[0][n] + hl_rT[i][1] * W[1][n] + hl_rT[i][2] * W[2][n];
        *rate_out = rate;
        if (S->faccon * norm <= tol) return 1;
        norm_old = norm;
    }
    return 0;
}

/* SciPy's predictive (Gustafsson) step factor for an error norm, before the safety factor */
static double hl_radau_factor_of(double h, double h_old, double err, double err_old) {
    double mult = 1.;
    if (err_old > 0. && h_old > 0. && err > 0.) mult = h / h_old * pow(err_old / err, 0.25);
    return err > 0. ? fmin(1., mult) * pow(err, -0.25) : HL_MAX_FACTOR;
}

/* The stages' predictor for a step h from t: the last step's collocation polynomial,
 * extrapolated (zero at a segment's start) */
static void hl_radau_predict(const hl_solver* S, double t, double h, double Z[3][HL_N]) {
    if (!S->have_sol) { memset(Z, 0, sizeof(double) * 3 * HL_N); return; }
    for (int i = 0; i < 3; i++) {
        double x = (t + hl_rc[i] * h - S->t_old) / S->h_step;
        for (int n = 0; n < HL_N; n++)
            Z[i][n] = ((S->rQ[2][n] * x + S->rQ[1][n]) * x + S->rQ[0][n]) * x - S->rZ[2][n];
    }
}

/* One accepted Radau IIA step; 0, or <0 as hl_step */
static int hl_radau_step(hl_solver* S) {
    double Z[3][HL_N], winv[HL_N], y_new[HL_N], err[HL_N], tmp[HL_N], f_new[HL_N];
    double* y = S->D[0];
    double t = S->t;
    double min_step = 10. * fabs(nextafter(t, INFINITY) - t);
    double h_abs = S->h_abs, h_old = S->h_abs_old, err_old = S->err_old;
    if (h_abs > S->max_step) { h_abs = S->max_step; h_old = -1.; err_old = -1.; }
    else if (h_abs < min_step) { h_abs = min_step; h_old = -1.; err_old = -1.; }
    double tol = fmax(10. * 2.2e-16 / S->rtol, fmin(0.03, sqrt(S->rtol)));
    double t_new = t, error_norm = 0., safety = HL_SAFETY, rate = -1.;
    int rejected = 0, shrunk = 0, n_iter = 1;   /* shrunk: a try of this step failed */
    int jac_at_end = 0;     /* the Jacobian is the one at the end of a failed try */
    int newton_failed = 0;
    if (!S->have_jac) hl_radau_jacobian(S, t, y);
    for (;;) {
        if (h_abs < min_step) return -1;
        t_new = t + h_abs;
        if (t_new - S->t_bound > 0 || S->t_bound - t_new < min_step) t_new = S->t_bound;
        double h = t_new - t;
        h_abs = h;
        hl_radau_predict(S, t, h, Z);
        hl_inverse_weights(S, y, winv);
        int converged = 0;
        for (;;) {
            if (!S->have_lu || S->h_lu != h)
                if (hl_radau_factor(S, h) != 0) return -2;
            rate = -1.;
            converged = hl_radau_newton(S, t, y, h, Z, winv, tol, &n_iter, &rate);
            if (converged || S->current_jac) break;
            /* a stale Jacobian: a fresh one, same step, at the last iterate's end of the
             * step (where the next step starts) where that is finite, else at its start */
            if (S->last_nonfinite < 0) {
                for (int n = 0; n < HL_N; n++) y_new[n] = y[n] + Z[2][n];
                hl_radau_jacobian(S, fmin(t_new, S->t_left), y_new);
                jac_at_end = 1;
            } else {
                hl_radau_jacobian(S, t, y);
            }
            hl_radau_predict(S, t, h, Z);
        }
        if (!converged) {
            S->nnewton_fail++;
            newton_failed = 1;
            h_abs *= 0.5;
            S->h_newton = h_abs;
            S->newton_good = 0;
            S->faccon = 1.;
            shrunk = 1;
            /* the end-of-step Jacobian kept for one shorter try, then the start's */
            if (jac_at_end && ++jac_at_end > 2) { hl_radau_jacobian(S, t, y); jac_at_end = 0; }
            continue;
        }
        for (int n = 0; n < HL_N; n++) y_new[n] = y[n] + Z[2][n];
        /* error estimate (Hairer & Wanner IV.8 (8.19)-(8.20)): (mu_r/h I - J)^-1 (f + ZE) */
        double gr = h / HL_MU_REAL;
        for (int n = 0; n < HL_N; n++) {
            double ze = (hl_rE[0] * Z[0][n] + hl_rE[1] * Z[1][n] + hl_rE[2] * Z[2][n]) / h;
            tmp[n] = ze;
            err[n] = gr * (S->rf[n] + ze);
        }
        hl_solve(S, err);
        double ew[HL_N];
        for (int n = 0; n < HL_N; n++) {
            double a = fabs(y[n]), b = fabs(y_new[n]);
            float m = (float)(a > b ? a : b);
            ew[n] = 1.f / (S->atol_state[n] + (float)S->rtol * m);
        }
        error_norm = hl_wrms(err, ew);
        /* the BDF's safety factor (SciPy's Radau: 0.9): on the 0.3 m hose 101 rejected steps
         * instead of 144, 497 factorisations instead of 631, 5 % more steps */
        safety = HL_SAFETY * (2 * HL_RADAU_MAXITER + 1) / (2 * HL_RADAU_MAXITER + n_iter);
        if (rejected && error_norm > 1.) {     /* after a rejection: the refined estimate */
            double ye[HL_N], fe[HL_N];
            for (int n = 0; n < HL_N; n++) ye[n] = y[n] + err[n];
            hl_eval_f(S, t, ye, fe);
            for (int n = 0; n < HL_N; n++) err[n] = gr * (fe[n] + tmp[n]);
            hl_solve(S, err);
            error_norm = hl_wrms(err, ew);
        }
        if (error_norm > 1.) {
            S->nrej++;
            double factor = hl_radau_factor_of(h_abs, h_old, error_norm, err_old);
            h_abs *= fmax(HL_MIN_FACTOR, safety * factor);
            rejected = 1;
            shrunk = 1;
            continue;
        }
        break;
    }
    int recompute_jac = n_iter > 2 && rate > 1e-3;
    double factor = fmin(HL_MAX_FACTOR, safety * hl_radau_factor_of(h_abs, h_old, error_norm, err_old));
    /* after a sudden fall of the error (below half the last step's), growth no larger than
     * the last step's error allows: on a ringing line the error estimate rises and falls
     * with the ringing's phase, and a step grown at its dip was rejected at the next rise
     * (0.3 m hose, after the stop: every ~10th step, a factorisation pair for the rejection
     * and one for the regrowth). On any fall it slowed the growth after the closed-loop
     * sine's valve reversals: 1 578 steps instead of 1 395; on a fall by half, 1 477. */
    if (factor > 1. && err_old > 2. * error_norm && !rejected)
        factor = fmax(1., fmin(factor, safety * pow(err_old, -0.25)));
    if (!recompute_jac && factor < 1.2) factor = 1.;   /* keep the step (and the factors) */
    /* no growth right after a failed try (RADAU5's rule, which SciPy's Radau leaves out):
     * at the piston's impact a step accepted just after a rejection has a tiny error, the
     * step grew 10x onto the contact again and failed again (five rounds of a Newton failure,
     * a rejection and a factorisation pair each on the 0.3 m hose) */
    if (shrunk && factor > 1.) factor = 1.;
    hl_eval_f(S, fmin(t_new, S->t_left), y_new, f_new);
    S->nsteps++;
    memcpy(S->ry_old, y, sizeof(double) * HL_N);
    memcpy(y, y_new, sizeof(double) * HL_N);
    memcpy(S->rf, f_new, sizeof(double) * HL_N);
    memcpy(S->rZ, Z, sizeof Z);
    for (int j = 0; j < 3; j++)
        for (int n = 0; n < HL_N; n++)
            S->rQ[j][n] = Z[0][n] * hl_rP[0][j] + Z[1][n] * hl_rP[1][j] + Z[2][n] * hl_rP[2][j];
    S->have_sol = 1;
    S->t_old = t;
    S->t = t_new;
    S->h_step = h_abs;
    S->order_step = 5;
    S->order = 5;
    S->h_abs_old = h_abs;
    S->err_old = error_norm;
    S->h_abs = h_abs * factor;
    if (S->h_newton < INFINITY) {         /* below the step Newton failed at (halved) */
        if (!newton_failed && n_iter <= 2 && ++S->newton_good >= HL_RADAU_PROBE_STEPS) {
            S->h_newton *= 2.; S->newton_good = 0;
        }
        if (S->h_abs > S->h_newton) S->h_abs = fmax(h_abs, S->h_newton);
    }
    if (recompute_jac) hl_radau_jacobian(S, t_new, y);
    else S->current_jac = 0;
    return 0;
}

/* The last step's collocation polynomial at t (scaled state) */
static void hl_radau_dense(const hl_solver* S, double t, double* z) {
    if (!S->have_sol) { memcpy(z, S->D[0], sizeof(double) * HL_N); return; }
    double x = (t - S->t_old) / S->h_step;
    for (int n = 0; n < HL_N; n++)
        z[n] = S->ry_old[n] + ((S->rQ[2][n] * x + S->rQ[1][n]) * x + S->rQ[0][n]) * x;
}
