/* vtol.c - VTOL aircraft (COMPleib HE1) under LQR state feedback, native (C99); the twin of
 * plant_fmus/vtol/vtol_plant.py and vtol_physics.py: x' = A x + B u, y = C x stepped exactly,
 * u = F y_meas + r with F = -K C^-1 computed at the communication points. */
#include "np_plant.h"

struct np_plant_state {
    np_linear sys; /* v = the inputs the aircraft receives */
    double x[4], F[8];
};

static const double A[16] = {-0.0366, 0.0271, 0.0188, -0.4555, 0.0482, -1.01, 0.0024, -4.0208,
                             0.1002, 0.3681, -0.707, 1.42, 0.0, 0.0, 1.0, 0.0};
static const double B[8] = {0.4422, 0.1761, 3.5446, -7.5922, -5.52, 4.49, 0.0, 0.0};
static const double C[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 1, 1};
static const double C_INV[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, -1, 1}; /* exact */
/* LQR gain of vtol_physics.K (Q = I4, R = I2, computed offline; tests/test_plant_fmus.py recomputes it) */
static const double K[8] = {0.9265980583247787, -0.01473996456202535, -0.9621624121321044, -1.386819391773749,
                            -0.02247765195723075, -0.8447507664432508, 0.18854771177973043, 0.7135346608114382};
static const np_sensor sensors[4] = {NP_SENSOR(vh, sensor_vh), NP_SENSOR(vv, sensor_vv), NP_SENSOR(q, sensor_q),
                                     NP_SENSOR(y4, sensor_y4)};
static const np_actuator actuators[2] = {NP_ACTUATOR(collective, actuator_collective),
                                         NP_ACTUATOR(cyclic, actuator_cyclic)};
static const int process_noise[2] = {V_std_w_collective, V_std_w_cyclic};

size_t np_plant_state_size(void) { return sizeof(np_plant_state); }

static void control(np_plant *p, const double *y) {
    const double *F = p->state->F;
    p->v[V_collective] = F[0] * y[0] + F[1] * y[1] + F[2] * y[2] + F[3] * y[3] + p->v[V_ref_collective];
    p->v[V_cyclic] = F[4] * y[0] + F[5] * y[1] + F[6] * y[2] + F[7] * y[3] + p->v[V_ref_cyclic];
}

int np_plant_initialize(np_plant *p) {
    np_plant_state *s = p->state;
    const double *v = p->v;
    double y[4];
    int i, j, l;
    np_linear_init(&s->sys, 4, 2, 4);
    for (i = 0; i < 16; i++) {
        s->sys.A[i] = A[i];
        s->sys.C[i] = C[i];
    }
    for (i = 0; i < 8; i++) s->sys.B[i] = B[i];
    s->sys.A[2 * 4 + 1] *= 1.0 + v[V_delta_a32];
    s->sys.A[2 * 4 + 3] *= 1.0 + v[V_delta_a34];
    s->sys.B[1 * 2 + 0] *= 1.0 + v[V_delta_b21];
    for (i = 0; i < 2; i++)
        for (j = 0; j < 4; j++) {
            double acc = 0.0;
            for (l = 0; l < 4; l++) acc += -K[i * 4 + l] * C_INV[l * 4 + j];
            s->F[i * 4 + j] = acc;
        }
    s->x[0] = v[V_vh_start];
    s->x[1] = v[V_vv_start];
    s->x[2] = v[V_q_start];
    s->x[3] = v[V_theta_start];
    for (i = 0; i < 4; i++) {
        double acc = 0.0;
        for (l = 0; l < 4; l++) acc += C[i * 4 + l] * s->x[l];
        y[i] = acc;
    }
    np_measure(p, sensors, 4, y, y);
    control(p, y);
    return 0;
}

int np_plant_advance(np_plant *p, double h) {
    np_plant_state *s = p->state;
    double cmd[2] = {p->v[V_collective], p->v[V_cyclic]}, u[2], w[2], y[4];
    np_actuate(p, actuators, 2, cmd, u);
    np_process_noise(p, process_noise, 2, w);
    u[0] = u[0] + w[0];
    u[1] = u[1] + w[1];
    np_linear_step(p, &s->sys, s->x, u, h, y);
    np_measure(p, sensors, 4, y, y);
    control(p, y);
    return 0;
}
