/* np_support.c - run-time support shared by the native plants (C99); the C twin of
 * plant_fmus/_support.py. Each function names the Python function it mirrors; the arithmetic is
 * written in the same order (no fused multiply-add: ISO C mode compiles with -ffp-contract=off),
 * so the adaptive integrator takes the same steps as the Python plant and noise-free runs agree
 * to rounding. min/max follow Python's (the first argument unless the second is strictly
 * smaller/larger), which matters only for signed zeros.
 *
 * The one documented difference: the noise stream. The Python plants draw from numpy's PCG64
 * (SeedSequence seeding, ziggurat normals); the native plants from xoshiro256** seeded by
 * splitmix64 with Marsaglia's polar method. The draws per step are the same in number and order,
 * and both are standard normal, but a seed gives a different sequence in the two languages.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "np_plant.h"

static const char *const var_names[] = NP_VAR_NAMES;
static const int real_inputs[] = NP_REAL_INPUTS;

static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }

int np_fail(np_plant *p, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(p->error, sizeof p->error, fmt, ap);
    va_end(ap);
    return -1;
}

double np_pow(double x, double y) {
    volatile double e = y; /* opaque to the optimiser: no pow(x, 2) -> x * x */
    return pow(x, e);
}

int np_check_inputs(np_plant *p) {
    size_t i;
    for (i = 0; i < sizeof real_inputs / sizeof real_inputs[0]; i++) {
        int vr = real_inputs[i];
        if (vr >= 0 && !isfinite(p->v[vr]))
            return np_fail(p, "input %s is %g; inputs must be finite", var_names[vr], p->v[vr]);
    }
    return 0;
}

int np_start(np_plant *p) {
    int vr;
    if (!(p->v[V_rtol] > 0)) return np_fail(p, "parameter rtol must be > 0, got %g", p->v[V_rtol]);
    if (!(p->v[V_atol] > 0)) return np_fail(p, "parameter atol must be > 0, got %g", p->v[V_atol]);
    if (p->v[V_seed] < 0) return np_fail(p, "parameter seed must be >= 0, got %.0f", p->v[V_seed]);
    for (vr = 0; vr < NP_N_VARS; vr++)
        if (strncmp(var_names[vr], "std_", 4) == 0 && !(p->v[vr] >= 0))
            return np_fail(p, "parameter %s must be >= 0, got %g", var_names[vr], p->v[vr]);
    np_rng_seed(&p->rng, (unsigned long long)p->v[V_seed]);
    p->h_ode = 0.0;
    p->v[V_ode_steps] = 0.0;
    return np_check_inputs(p);
}

/* ---- noise ---------------------------------------------------------------------------------- */
static unsigned long long splitmix64(unsigned long long *x) {
    unsigned long long z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

void np_rng_seed(np_rng *r, unsigned long long seed) {
    int i;
    for (i = 0; i < 4; i++) r->s[i] = splitmix64(&seed);
    r->has_spare = 0;
    r->spare = 0.0;
}

static unsigned long long rotl(unsigned long long x, int k) { return (x << k) | (x >> (64 - k)); }

static double uniform(np_rng *r) { /* xoshiro256**, 53 bits -> [0, 1) */
    unsigned long long *s = r->s;
    unsigned long long out = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return (double)(out >> 11) * 0x1.0p-53;
}

double np_normal(np_rng *r) { /* Marsaglia polar method: two independent N(0, 1) per accepted pair */
    double a, b, q, m;
    if (r->has_spare) {
        r->has_spare = 0;
        return r->spare;
    }
    do {
        a = 2.0 * uniform(r) - 1.0;
        b = 2.0 * uniform(r) - 1.0;
        q = a * a + b * b;
    } while (q >= 1.0 || q == 0.0);
    m = sqrt(-2.0 * log(q) / q);
    r->spare = b * m;
    r->has_spare = 1;
    return a * m;
}

/* ---- fault channels ------------------------------------------------------------------------- */
void np_measure(np_plant *p, const np_sensor *s, int n, const double *y_true, double *y_meas) {
    int i, noise = p->v[V_noise_enable] != 0.0;
    for (i = 0; i < n; i++) {
        const double *v = p->v;
        double z = noise ? np_normal(&p->rng) : 0.0, sd = noise ? v[s[i].std] : 0.0;
        double y = v[s[i].stuck] >= 0.5 ? v[s[i].value] : v[s[i].gain] * y_true[i] + v[s[i].f] + sd * z;
        p->v[s[i].y] = y;
        if (y_meas) y_meas[i] = y;
    }
}

void np_actuate(const np_plant *p, const np_actuator *a, int n, const double *u_command, double *u_applied) {
    int i;
    const double *v = p->v;
    for (i = 0; i < n; i++)
        u_applied[i] = v[a[i].stuck] >= 0.5 ? v[a[i].value] : v[a[i].gain] * u_command[i] + v[a[i].f];
}

void np_process_noise(np_plant *p, const int *std_vr, int n, double *w) {
    int i, noise = p->v[V_noise_enable] != 0.0;
    for (i = 0; i < n; i++) w[i] = noise ? p->v[std_vr[i]] * np_normal(&p->rng) : 0.0;
}

/* ---- Dormand-Prince 5(4) (Hairer, Norsett, Wanner, Solving ODEs I, Table II.5.2) ------------ */
#define NP_MAX_ODE 16
#define NP_MAX_STEPS 100000

int np_dopri5(np_plant *p, np_rhs f, const void *ctx, double *x0, int n, double span, const double *lo,
              const double *hi) {
    static const double a21 = 1.0 / 5, a31 = 3.0 / 40, a32 = 9.0 / 40, a41 = 44.0 / 45, a42 = -56.0 / 15,
                        a43 = 32.0 / 9, a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561,
                        a54 = -212.0 / 729, a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247,
                        a64 = 49.0 / 176, a65 = -5103.0 / 18656, b1 = 35.0 / 384, b3 = 500.0 / 1113,
                        b4 = 125.0 / 192, b5 = -2187.0 / 6784, b6 = 11.0 / 84, e1 = 71.0 / 57600,
                        e3 = -71.0 / 16695, e4 = 71.0 / 1920, e5 = -17253.0 / 339200, e6 = 22.0 / 525,
                        e7 = -1.0 / 40;
    double x[NP_MAX_ODE], xs[NP_MAX_ODE], xn[NP_MAX_ODE], k1[NP_MAX_ODE], k2[NP_MAX_ODE], k3[NP_MAX_ODE],
        k4[NP_MAX_ODE], k5[NP_MAX_ODE], k6[NP_MAX_ODE], k7[NP_MAX_ODE];
    double rtol = p->v[V_rtol], atol = p->v[V_atol], t = 0.0, h = p->h_ode;
    int i, it, n_acc = 0;
    if (n > NP_MAX_ODE) return np_fail(p, "dopri5: %d states exceed NP_MAX_ODE = %d", n, NP_MAX_ODE);
    memcpy(x, x0, (size_t)n * sizeof *x);
    h = !(h > 0) ? span : py_min(h, span);
    f(ctx, x, k1);
    for (it = 0; it < NP_MAX_STEPS; it++) {
        double remaining = span - t, step, acc = 0.0, err, factor;
        if (remaining <= 1e-12 * span) {
            memcpy(x0, x, (size_t)n * sizeof *x);
            p->h_ode = h;
            p->v[V_ode_steps] += n_acc;
            return 0;
        }
        step = py_min(h, remaining);
        for (i = 0; i < n; i++) xs[i] = x[i] + step * (a21 * k1[i]);
        f(ctx, xs, k2);
        for (i = 0; i < n; i++) xs[i] = x[i] + step * (a31 * k1[i] + a32 * k2[i]);
        f(ctx, xs, k3);
        for (i = 0; i < n; i++) xs[i] = x[i] + step * (a41 * k1[i] + a42 * k2[i] + a43 * k3[i]);
        f(ctx, xs, k4);
        for (i = 0; i < n; i++) xs[i] = x[i] + step * (a51 * k1[i] + a52 * k2[i] + a53 * k3[i] + a54 * k4[i]);
        f(ctx, xs, k5);
        for (i = 0; i < n; i++)
            xs[i] = x[i] + step * (a61 * k1[i] + a62 * k2[i] + a63 * k3[i] + a64 * k4[i] + a65 * k5[i]);
        f(ctx, xs, k6);
        for (i = 0; i < n; i++) xn[i] = x[i] + step * (b1 * k1[i] + b3 * k3[i] + b4 * k4[i] + b5 * k5[i] + b6 * k6[i]);
        f(ctx, xn, k7);
        for (i = 0; i < n; i++) {
            double e = step * (e1 * k1[i] + e3 * k3[i] + e4 * k4[i] + e5 * k5[i] + e6 * k6[i] + e7 * k7[i]);
            /* (...) ** 2 in Python: pow of the C library, which may differ from q * q by an ulp, and
             * an ulp in the error norm can flip an accept/reject decision */
            acc += np_pow(e / (atol + rtol * py_max(fabs(x[i]), fabs(xn[i]))), 2.0);
        }
        err = sqrt(acc / n);
        if (!isfinite(err)) return np_fail(p, "non-finite derivative while integrating at state (%g, ...)", x[0]);
        factor = err == 0.0 ? 5.0 : py_min(5.0, py_max(0.2, 0.9 * np_pow(err, -0.2)));
        if (err <= 1.0) {
            t += step;
            if (lo && hi) {
                int changed = 0;
                for (i = 0; i < n; i++) {
                    double c = py_min(py_max(xn[i], lo[i]), hi[i]);
                    if (c != xn[i]) changed = 1;
                    xn[i] = c;
                }
                if (changed) f(ctx, xn, k7);
            }
            memcpy(x, xn, (size_t)n * sizeof *x);
            memcpy(k1, k7, (size_t)n * sizeof *x);
            n_acc++;
            h = step == h ? step * factor : py_max(h, step * factor);
        } else {
            h = step * py_min(1.0, factor);
        }
    }
    return np_fail(p, "integrator took more than %d steps for one communication step of %g s (rtol=%g, atol=%g): "
                      "the step is too long for the dynamics or the state diverges", NP_MAX_STEPS, span, rtol, atol);
}

/* ---- exact linear step ---------------------------------------------------------------------- */
static void matmul(const double *X, const double *Y, double *Z, int r, int k, int c) { /* Z = X Y */
    int i, j, l;
    for (i = 0; i < r; i++)
        for (j = 0; j < c; j++) {
            double s = 0.0;
            for (l = 0; l < k; l++) s += X[i * k + l] * Y[l * c + j];
            Z[i * c + j] = s;
        }
}

#define N2 (2 * NP_MAXN)
void np_phi1(const double *A, int n, double h, double *psi) {
    /* exp([[A, I], [0, 0]] h) by scaling and squaring with a Taylor polynomial of degree 18
     * (Moler & Van Loan, method 3), exactly as phi1() of _support.py */
    double M[N2 * N2], E[N2 * N2], T[N2 * N2], U[N2 * N2], norm = 0.0;
    int i, j, k, s = 0, m = 2 * n;
    memset(M, 0, sizeof M);
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) M[i * m + j] = A[i * n + j] * h;
        M[i * m + n + i] = 1.0 * h;
    }
    for (j = 0; j < m; j++) {
        double c = 0.0;
        for (i = 0; i < m; i++) c += fabs(M[i * m + j]);
        norm = py_max(norm, c);
    }
    if (norm > 0.5) s = (int)py_max(0.0, ceil(log2(norm / 0.5)));
    for (i = 0; i < m * m; i++) M[i] = M[i] / ldexp(1.0, s);
    for (i = 0; i < m * m; i++) E[i] = T[i] = (i / m == i % m) ? 1.0 : 0.0;
    for (k = 1; k < 19; k++) {
        matmul(T, M, U, m, m, m);
        for (i = 0; i < m * m; i++) {
            T[i] = U[i] / k;
            E[i] = E[i] + T[i];
        }
    }
    for (k = 0; k < s; k++) {
        matmul(E, E, U, m, m, m);
        memcpy(E, U, (size_t)(m * m) * sizeof *E);
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++) psi[i * n + j] = E[i * m + n + j];
}

void np_linear_init(np_linear *L, int n, int m, int p) {
    memset(L, 0, sizeof *L);
    L->n = n;
    L->m = m;
    L->p = p;
}

static void linear_matrix(np_linear *L, double h) {
    /* W = [[P], [C + C P_x, C P_u]], P = Psi(h) [A, B] (ExactLinear.matrix) */
    double psi[NP_MAXN * NP_MAXN], AB[NP_MAXN * (NP_MAXN + NP_MAXM)], P[NP_MAXN * (NP_MAXN + NP_MAXM)];
    int n = L->n, m = L->m, c = n + m, i, j;
    np_phi1(L->A, n, h, psi);
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) AB[i * c + j] = L->A[i * n + j];
        for (j = 0; j < m; j++) AB[i * c + n + j] = L->B[i * m + j];
    }
    matmul(psi, AB, P, n, n, c);
    memcpy(L->W, P, (size_t)(n * c) * sizeof *P);
    matmul(L->C, P, L->W + n * c, L->p, n, c);
    for (i = 0; i < L->p; i++)
        for (j = 0; j < n; j++) L->W[(n + i) * c + j] += L->C[i * n + j];
    L->h_W = h;
    L->valid = 1;
}

void np_linear_step(np_plant *pl, np_linear *L, double *x, const double *v, double h, double *y) {
    double z[NP_MAXN + NP_MAXM];
    int n = L->n, c = n + L->m, i, j;
    if (!L->valid || L->h_W != h) linear_matrix(L, h);
    memcpy(z, x, (size_t)n * sizeof *z);
    memcpy(z + n, v, (size_t)L->m * sizeof *z);
    for (i = 0; i < n + L->p; i++) {
        double s = 0.0;
        for (j = 0; j < c; j++) s += L->W[i * c + j] * z[j];
        if (i < n) x[i] = x[i] + s;
        else y[i - n] = s;
    }
    pl->v[V_ode_steps] += 1.0;
}
