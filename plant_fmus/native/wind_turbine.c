/* wind_turbine.c - wind-turbine FDI benchmark (Odgaard et al.): three pitch systems, drive train
 * and converter, native (C99); the twin of plant_fmus/wind_turbine/windturbine_plant.py and
 * windturbine_physics.py. One linear system of 10 states, stepped exactly; it is rebuilt when the
 * pitch fault levels or the drive-train efficiency change (the Python plant caches one per level). */
#include <math.h>
#include <string.h>

#include "np_plant.h"

struct np_plant_state {
    np_linear sys; /* v = (beta_ref_1..3, tau_g_ref as applied, tau_r, converter offset) */
    double x[10];
    double key[7]; /* pitch fault levels theta (pressure drop 1..3, air in oil 1..3), efficiency change */
    int built;
};

#define S(y) NP_SENSOR(y, sensor_##y)
#define A_(u) NP_ACTUATOR(u, actuator_##u)
static const np_sensor sensors[11] = {S(beta_1_m1), S(beta_1_m2), S(beta_2_m1), S(beta_2_m2), S(beta_3_m1),
                                      S(beta_3_m2), S(omega_r_m1), S(omega_r_m2), S(omega_g_m1), S(omega_g_m2),
                                      S(tau_g_m)};
static const np_actuator actuators[4] = {A_(beta_ref_1), A_(beta_ref_2), A_(beta_ref_3), A_(tau_g_ref)};
static const int pitch_faults[6] = {V_f_pitch_1_pressure_drop, V_f_pitch_2_pressure_drop, V_f_pitch_3_pressure_drop,
                                    V_f_pitch_1_air_in_oil,    V_f_pitch_2_air_in_oil,    V_f_pitch_3_air_in_oil};
static const int process_noise[1] = {V_std_w_tau_r};

size_t np_plant_state_size(void) { return sizeof(np_plant_state); }

static double clip01(double x) { x = 0.0 > x ? 0.0 : x; return 1.0 < x ? 1.0 : x; } /* min(max(x, 0), 1) */

static void output_matrix(np_linear *L) { /* y = (beta_i twice each, omega_r x2, omega_g x2, tau_g) */
    int i;
    memset(L->C, 0, sizeof L->C);
    for (i = 0; i < 3; i++) L->C[(2 * i) * 10 + 2 * i] = L->C[(2 * i + 1) * 10 + 2 * i] = 1.0;
    L->C[6 * 10 + 6] = L->C[7 * 10 + 6] = 1.0;
    L->C[8 * 10 + 7] = L->C[9 * 10 + 7] = 1.0;
    L->C[10 * 10 + 9] = 1.0;
}

static void build_system(np_plant *p, const double *key) {
    /* pitch_matrices(p, theta_pressure_drop, theta_air_in_oil) and drive_train_matrices(p, d_eta) */
    const double *v = p->v;
    np_linear *L = &p->state->sys;
    double wn = v[V_omega_n], zeta = v[V_zeta];
    double Bdt = v[V_B_dt], Br = v[V_B_r], Bg = v[V_B_g], Ng = v[V_N_g], K = v[V_K_dt], Jg = v[V_J_g], Jr = v[V_J_r];
    double eta = v[V_eta_dt] + key[6], *A = L->A, *B = L->B;
    int i;
    np_linear_init(L, 10, 6, 11);
    output_matrix(L);
    for (i = 0; i < 3; i++) {
        double w2 = np_pow(wn, 2.0), c = 2 * zeta * wn, wf;
        wf = v[V_omega_n_pressure_drop];
        w2 += key[i] * (np_pow(wf, 2.0) - np_pow(wn, 2.0));
        c += key[i] * (2 * v[V_zeta_pressure_drop] * wf - 2 * zeta * wn);
        wf = v[V_omega_n_air_in_oil];
        w2 += key[3 + i] * (np_pow(wf, 2.0) - np_pow(wn, 2.0));
        c += key[3 + i] * (2 * v[V_zeta_air_in_oil] * wf - 2 * zeta * wn);
        A[(2 * i) * 10 + 2 * i + 1] = 1.0;
        A[(2 * i + 1) * 10 + 2 * i] = -w2;
        A[(2 * i + 1) * 10 + 2 * i + 1] = -c;
        B[(2 * i + 1) * 6 + i] = w2;
    }
    A[6 * 10 + 6] = -(Bdt + Br) / Jr;
    A[6 * 10 + 7] = Bdt / (Ng * Jr);
    A[6 * 10 + 8] = -K / Jr;
    A[7 * 10 + 6] = eta * Bdt / (Ng * Jg);
    A[7 * 10 + 7] = -(eta * Bdt / np_pow(Ng, 2.0) + Bg) / Jg;
    A[7 * 10 + 8] = eta * K / (Ng * Jg);
    A[7 * 10 + 9] = -1.0 / Jg;
    A[8 * 10 + 6] = 1.0;
    A[8 * 10 + 7] = -1.0 / Ng;
    A[9 * 10 + 9] = -v[V_alpha_gc];
    B[9 * 6 + 3] = v[V_alpha_gc];
    B[6 * 6 + 4] = 1.0 / Jr;
    B[7 * 6 + 5] = -1.0 / Jg; /* the converter offset acts on the generator */
    memcpy(p->state->key, key, sizeof p->state->key);
    p->state->built = 1;
}

int np_plant_initialize(np_plant *p) {
    static const int positive[5] = {V_J_g, V_J_r, V_N_g, V_K_dt, V_alpha_gc};
    static const char *const names[5] = {"J_g", "J_r", "N_g", "K_dt", "alpha_gc"};
    np_plant_state *s = p->state;
    const double *v = p->v;
    double Ng = v[V_N_g], Br = v[V_B_r], w = v[V_omega_r_op], tau_g = v[V_tau_g_op], tau_r, y[11];
    int i, j;
    for (i = 0; i < 5; i++)
        if (!(v[positive[i]] > 0)) return np_fail(p, "parameter %s must be > 0, got %g", names[i], v[positive[i]]);
    s->built = 0;
    output_matrix(&s->sys);
    tau_r = Ng * (tau_g + v[V_B_g] * Ng * w) / v[V_eta_dt] + Br * w; /* operating_point() */
    for (i = 0; i < 3; i++) {
        s->x[2 * i] = v[V_beta_op];
        s->x[2 * i + 1] = 0.0;
    }
    s->x[6] = w;
    s->x[7] = Ng * w;
    s->x[8] = (tau_r - Br * w) / v[V_K_dt];
    s->x[9] = tau_g;
    for (i = 0; i < 11; i++) {
        double acc = 0.0;
        for (j = 0; j < 10; j++) acc += s->sys.C[i * 10 + j] * s->x[j];
        y[i] = acc;
    }
    np_measure(p, sensors, 11, y, NULL);
    return 0;
}

int np_plant_advance(np_plant *p, double h) {
    np_plant_state *s = p->state;
    const double *v = p->v;
    double key[7], cmd[4] = {v[V_beta_ref_1], v[V_beta_ref_2], v[V_beta_ref_3], v[V_tau_g_ref]}, u[6], w, y[11];
    double offset = v[V_f_converter_offset];
    int i;
    for (i = 0; i < 6; i++) key[i] = clip01(v[pitch_faults[i]]);
    key[6] = v[V_f_drive_train_efficiency];
    if (!s->built || memcmp(key, s->key, sizeof key) != 0) build_system(p, key);
    np_actuate(p, actuators, 4, cmd, u);
    np_process_noise(p, process_noise, 1, &w);
    u[4] = v[V_tau_r] + w;
    u[5] = offset;
    np_linear_step(p, &s->sys, s->x, u, h, y);
    y[10] += offset; /* the measured torque is the one acting, offset included */
    np_measure(p, sensors, 11, y, NULL);
    return 0;
}
