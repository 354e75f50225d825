/* dr300.c - DC motor DR300 with its PI speed controller, native (C99); the twin of
 * plant_fmus/dr300/dr300_plant.py and dr300_physics.py (minimal order-4 realisation of Gu, Gd,
 * stepped exactly; the PI controller at the communication step, forward-Euler integral). */
#include "np_plant.h"

struct np_plant_state {
    np_linear sys; /* v = (voltage received, load torque) */
    double x[4], xi, e, kp, ki;
};

static const np_sensor sensors[1] = {NP_SENSOR(speed, sensor_speed)};
static const np_actuator actuators[1] = {NP_ACTUATOR(voltage, actuator_voltage)};
static const int process_noise[1] = {V_std_w_load_torque};

size_t np_plant_state_size(void) { return sizeof(np_plant_state); }

static void control(np_plant *p, double y_meas) { /* PI output for the coming step */
    np_plant_state *s = p->state;
    s->e = p->v[V_speed_ref] - y_meas;
    p->v[V_voltage] = s->kp * s->e + s->ki * s->xi;
}

int np_plant_initialize(np_plant *p) {
    np_plant_state *s = p->state;
    const double *v = p->v;
    double T1 = v[V_T1], T2 = v[V_T2], T3 = v[V_T3], y;
    double T[3] = {T1, T2, T3};
    static const char *const names[3] = {"T1", "T2", "T3"};
    int i;
    for (i = 0; i < 3; i++)
        if (!(T[i] > 0)) return np_fail(p, "parameter %s must be > 0, got %g", names[i], T[i]);
    np_linear_init(&s->sys, 4, 2, 1);
    s->sys.A[0 * 4 + 0] = -1 / T1;
    s->sys.A[1 * 4 + 0] = 1 / T2;
    s->sys.A[1 * 4 + 1] = -1 / T2;
    s->sys.A[3 * 4 + 1] = 1 / T3;
    s->sys.A[3 * 4 + 2] = 1 / T3;
    s->sys.A[3 * 4 + 3] = -1 / T3;
    s->sys.B[0 * 2 + 0] = v[V_k_u] / T1;
    s->sys.B[2 * 2 + 1] = -v[V_k_d];
    s->sys.C[3] = 1.0;
    s->kp = v[V_k_c] * T1;
    s->ki = v[V_k_c];
    for (i = 0; i < 4; i++) s->x[i] = 0.0;
    s->xi = 0.0;
    y = 0.0; /* C x with x = 0 */
    np_measure(p, sensors, 1, &y, &y);
    control(p, y);
    return 0;
}

int np_plant_advance(np_plant *p, double h) {
    np_plant_state *s = p->state;
    double cmd = p->v[V_voltage], u[2], w, y;
    np_actuate(p, actuators, 1, &cmd, u);
    np_process_noise(p, process_noise, 1, &w);
    u[1] = p->v[V_load_torque] + w;
    np_linear_step(p, &s->sys, s->x, u, h, &y);
    s->xi += h * s->e;
    np_measure(p, sensors, 1, &y, &y);
    control(p, y);
    return 0;
}
