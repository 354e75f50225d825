/* dts200.c - DTS200 three-tank plant, native (C99); the twin of plant_fmus/dts200/dts200_plant.py
 * and dts200_physics.py (Torricelli dynamics with the regularised root below D_LAM, leaks,
 * clogging, level limits; integrated by the adaptive Dormand-Prince 5(4) of np_support.c over
 * each communication step, with the step proposal carried over as in the Python plant). */
#include <math.h>

#include "np_plant.h"

#define D_LAM 0.01

struct np_plant_state {
    double x[3];
};

typedef struct { /* the right-hand side for the inputs held over a step (rates_function) */
    double c13, c32, c20, area, h_max, q1, q2, k_leak[3];
    int leaky;
} rates;

static const np_sensor sensors[3] = {NP_SENSOR(h1, sensor_h1), NP_SENSOR(h2, sensor_h2), NP_SENSOR(h3, sensor_h3)};
static const np_actuator pumps[2] = {NP_ACTUATOR(Q1, pump_Q1), NP_ACTUATOR(Q2, pump_Q2)};
static const int process_noise[2] = {V_std_w_Q1, V_std_w_Q2};

size_t np_plant_state_size(void) { return sizeof(np_plant_state); }

static double root(double d) { /* sgn(d) sqrt(|d|), regularised below D_LAM (dts200_physics.root) */
    double z;
    if (fabs(d) >= D_LAM) return copysign(sqrt(fabs(d)), d);
    z = d / D_LAM;
    return sqrt(D_LAM) * (1.25 * z - 0.25 * np_pow(z, 3.0));
}

static double pmax(double a, double b) { return b > a ? b : a; }
static double pmin(double a, double b) { return b < a ? b : a; }

static void f(const void *ctx, const double *h, double *out) {
    const rates *r = ctx;
    double h1 = h[0], h2 = h[1], h3 = h[2];
    double q13 = r->c13 * root(h1 - h3), q32 = r->c32 * root(h3 - h2), q20 = r->c20 * root(pmax(h2, 0.0));
    int i;
    out[0] = r->q1 - q13;
    out[1] = r->q2 + q32 - q20;
    out[2] = q13 - q32;
    for (i = 0; i < 3; i++) {
        double hi = h[i];
        double dh = (r->leaky && r->k_leak[i] != 0.0 ? out[i] - r->k_leak[i] * root(pmax(hi, 0.0)) : out[i]) / r->area;
        if ((hi >= r->h_max && dh > 0.0) || (hi <= 0.0 && dh < 0.0)) dh = 0.0;
        out[i] = dh;
    }
}

static void publish(np_plant *p) {
    double *v = p->v;
    const double *x = p->state->x;
    np_measure(p, sensors, 3, x, NULL);
    v[V_overflow] = (x[0] >= v[V_h_max] || x[1] >= v[V_h_max] || x[2] >= v[V_h_max]) ? 1.0 : 0.0;
    v[V_empty] = (x[0] < D_LAM || x[1] < D_LAM || x[2] < D_LAM) ? 1.0 : 0.0;
}

int np_plant_initialize(np_plant *p) {
    static const int positive[4] = {V_area, V_pipe_area, V_g, V_h_max};
    static const char *const names[4] = {"area", "pipe_area", "g", "h_max"};
    double *v = p->v, *x = p->state->x;
    int i;
    for (i = 0; i < 4; i++)
        if (!(v[positive[i]] > 0)) return np_fail(p, "parameter %s must be > 0, got %g", names[i], v[positive[i]]);
    x[0] = v[V_h1_start];
    x[1] = v[V_h2_start];
    x[2] = v[V_h3_start];
    if (pmin(pmin(x[0], x[1]), x[2]) < 0 || pmax(pmax(x[0], x[1]), x[2]) > v[V_h_max])
        return np_fail(p, "initial levels [%g, %g, %g] must lie in [0, h_max=%g]", x[0], x[1], x[2], v[V_h_max]);
    publish(p);
    return 0;
}

int np_plant_advance(np_plant *p, double h) {
    const double *v = p->v;
    double cmd[2] = {v[V_Q1], v[V_Q2]}, q[2], w[2], k, s2g, lo[3] = {0.0, 0.0, 0.0}, hi[3];
    static const int leaks[3] = {V_f_leak_T1, V_f_leak_T2, V_f_leak_T3};
    static const int clogs[3] = {V_f_clog_13, V_f_clog_32, V_f_clog_20};
    double clog[3];
    rates r;
    int i;
    np_actuate(p, pumps, 2, cmd, q);
    np_process_noise(p, process_noise, 2, w);
    for (i = 0; i < 2; i++) q[i] = pmin(pmax(q[i] + w[i], 0.0), v[V_q_max]);
    for (i = 0; i < 3; i++) clog[i] = pmin(pmax(v[clogs[i]], 0.0), 1.0);
    k = v[V_pipe_area] * sqrt(2.0 * v[V_g]);
    r.c13 = (1.0 - clog[0]) * v[V_az1] * k;
    r.c32 = (1.0 - clog[1]) * v[V_az3] * k;
    r.c20 = (1.0 - clog[2]) * v[V_az2] * k;
    s2g = sqrt(2.0 * v[V_g]);
    r.area = v[V_area];
    r.h_max = v[V_h_max];
    r.q1 = q[0];
    r.q2 = q[1];
    r.leaky = 0;
    for (i = 0; i < 3; i++) {
        r.k_leak[i] = pmax(v[leaks[i]], 0.0) * s2g;
        if (pmax(v[leaks[i]], 0.0) != 0.0) r.leaky = 1;
        hi[i] = v[V_h_max];
    }
    if (np_dopri5(p, f, &r, p->state->x, 3, h, lo, hi)) return -1;
    publish(p);
    return 0;
}
