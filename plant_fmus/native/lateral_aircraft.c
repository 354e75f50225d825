/* lateral_aircraft.c - lateral aircraft (Varga, Examples 6.1/6.2) with loss-of-effectiveness
 * actuator faults, native (C99); the twin of plant_fmus/lateral_aircraft/lateral_plant.py:
 * x' = A x + Bu Gamma u_applied + w, y = x, stepped exactly (np_linear_step). */
#include "np_plant.h"

struct np_plant_state {
    np_linear sys; /* v = (Gamma u_applied, w) */
    double x[4];
};

static const double A[16] = {-0.4492, 0.046, 0.0053, -0.9926, 0.0, 0.0, 1.0, 0.0067,
                             -50.8436, 0.0, -5.2184, 0.722, 16.4148, 0.0, 0.0026, -0.6627};
static const double BU[8] = {0.0004, 0.0011, 0.0, 0.0, -1.4161, 0.2621, -0.0633, -0.1205};
static const np_sensor sensors[4] = {NP_SENSOR(beta, sensor_beta), NP_SENSOR(phi, sensor_phi),
                                     NP_SENSOR(p, sensor_p), NP_SENSOR(r, sensor_r)};
static const np_actuator actuators[2] = {NP_ACTUATOR(u1, actuator_u1), NP_ACTUATOR(u2, actuator_u2)};
static const int process_noise[4] = {V_std_w_beta, V_std_w_phi, V_std_w_p, V_std_w_r};

size_t np_plant_state_size(void) { return sizeof(np_plant_state); }

static double clip01(double x) { x = 0.0 > x ? 0.0 : x; return 1.0 < x ? 1.0 : x; } /* min(max(x, 0), 1) */

int np_plant_initialize(np_plant *p) {
    np_plant_state *s = p->state;
    int i, j;
    np_linear_init(&s->sys, 4, 6, 4);
    for (i = 0; i < 4; i++) {
        for (j = 0; j < 4; j++) {
            s->sys.A[i * 4 + j] = A[i * 4 + j];
            s->sys.C[i * 4 + j] = i == j ? 1.0 : 0.0;
            s->sys.B[i * 6 + 2 + j] = i == j ? 1.0 : 0.0;
        }
        for (j = 0; j < 2; j++) s->sys.B[i * 6 + j] = BU[i * 2 + j];
    }
    s->x[0] = p->v[V_beta_start];
    s->x[1] = p->v[V_phi_start];
    s->x[2] = p->v[V_p_start];
    s->x[3] = p->v[V_r_start];
    np_measure(p, sensors, 4, s->x, NULL);
    return 0;
}

int np_plant_advance(np_plant *p, double h) {
    np_plant_state *s = p->state;
    const double *v = p->v;
    double cmd[2] = {v[V_u1], v[V_u2]}, u[6], y[4];
    double eff[2] = {1.0 - clip01(v[V_gamma_1] + v[V_f_loe_u1]), 1.0 - clip01(v[V_gamma_2] + v[V_f_loe_u2])};
    np_actuate(p, actuators, 2, cmd, u);
    u[0] = eff[0] * u[0];
    u[1] = eff[1] * u[1];
    np_process_noise(p, process_noise, 4, u + 2);
    np_linear_step(p, &s->sys, s->x, u, h, y);
    np_measure(p, sensors, 4, y, NULL);
    return 0;
}
