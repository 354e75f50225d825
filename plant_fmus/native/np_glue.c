/* np_glue.c - the FMI-version-independent part of the native plants' glue (see np_glue.h). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "np_glue.h"

enum { M_INSTANTIATED, M_INITIALIZATION, M_STEP, M_TERMINATED };
enum { C_FIXED, C_TUNABLE, C_INPUT, C_OUTPUT }; /* np_vars.h NP_VAR_CAUSALITY */

static const int var_kinds[NP_N_VARS] = NP_VAR_KINDS;
static const int var_causality[NP_N_VARS] = NP_VAR_CAUSALITY;
static const double var_starts[NP_N_VARS] = NP_VAR_STARTS;
static const char *const var_names[NP_N_VARS] = NP_VAR_NAMES;
static const char *const kind_names[3] = {"Real", "Integer", "Boolean"};

#define MAGIC 0x4e504c54u /* "NPLT" */

size_t np_instance_bytes(void) { return sizeof(np_instance) + np_plant_state_size(); }

np_instance *np_instance_init(void *block, const char *name, np_log_fn log, void *host) {
    np_instance *in = block;
    memset(block, 0, np_instance_bytes());
    in->magic = MAGIC;
    in->log = log;
    in->host = host;
    snprintf(in->name, sizeof in->name, "%s", name ? name : "");
    in->plant.state = (np_plant_state *)(void *)(in + 1);
    np_reset(in);
    return in;
}

np_instance *np_instance_of(void *component) {
    np_instance *in = component;
    return in && in->magic == MAGIC ? in : NULL;
}

void np_instance_release(np_instance *in) { in->magic = 0; }

void np_reset(np_instance *in) {
    int vr;
    for (vr = 0; vr < NP_N_VARS; vr++) in->plant.v[vr] = var_starts[vr];
    in->mode = M_INSTANTIATED;
    in->failed = 0;
    in->time = 0.0;
    in->plant.error[0] = 0;
}

int np_report(np_instance *in, int status, const char *fmt, ...) {
    char msg[sizeof in->plant.error + 200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (in->log) in->log(in->host, in->name, status == NP_DISCARD ? NP_ERROR : status,
                         status == NP_DISCARD ? "logStatusDiscard" : "logStatusError", msg);
    return status;
}

int np_unsupported(void *component, const char *fn, const char *why) {
    np_instance *in = np_instance_of(component);
    return in ? np_report(in, NP_ERROR, "%s: not supported by this FMU (%s)", fn, why) : NP_ERROR;
}

int np_enter_initialization(np_instance *in, const char *fn) {
    if (in->mode != M_INSTANTIATED) return np_report(in, NP_ERROR, "%s: only after instantiation or reset", fn);
    in->mode = M_INITIALIZATION;
    return NP_OK;
}

int np_exit_initialization(np_instance *in, const char *fn) {
    if (in->mode != M_INITIALIZATION) return np_report(in, NP_ERROR, "%s: not in initialization mode", fn);
    in->mode = M_STEP;
    if (np_start(&in->plant) || np_plant_initialize(&in->plant)) {
        in->failed = 1;
        return np_report(in, NP_ERROR, "%s: initialisation failed: %s", fn, in->plant.error);
    }
    return NP_OK;
}

int np_terminate(np_instance *in, const char *fn) {
    if (in->mode != M_STEP && in->mode != M_INITIALIZATION)
        return np_report(in, NP_ERROR, "%s: only in initialization or step mode", fn);
    in->mode = M_TERMINATED;
    return NP_OK;
}

int np_check_access(np_instance *in, const char *fn, const unsigned *vr, size_t n, int kind, int set) {
    size_t i;
    if (n && !vr) return np_report(in, NP_ERROR, "%s: NULL value reference array", fn);
    for (i = 0; i < n; i++) {
        unsigned r = vr[i];
        int c;
        if (r >= NP_N_VARS) return np_report(in, NP_ERROR, "%s: no variable with value reference %u", fn, r);
        if (var_kinds[r] != kind)
            return np_report(in, NP_ERROR, "%s: variable %s is %s, not %s", fn, var_names[r], kind_names[var_kinds[r]],
                             kind_names[kind]);
        if (!set) continue;
        c = var_causality[r];
        if (c == C_OUTPUT) return np_report(in, NP_ERROR, "%s: %s is an output and cannot be set", fn, var_names[r]);
        if (c == C_FIXED && in->mode != M_INSTANTIATED && in->mode != M_INITIALIZATION)
            return np_report(in, NP_ERROR, "%s: %s is a fixed parameter, settable only before initialisation ends",
                             fn, var_names[r]);
        if (in->mode == M_TERMINATED) return np_report(in, NP_ERROR, "%s: %s cannot be set after terminate", fn, var_names[r]);
    }
    return NP_OK;
}

int np_do_step(np_instance *in, const char *fn, double t, double h) {
    if (in->mode != M_STEP) return np_report(in, NP_ERROR, "%s: not in step mode", fn);
    if (in->failed) return np_report(in, NP_DISCARD, "%s: cannot step at t=%.17g: %s", fn, t, in->plant.error);
    if (!(h > 0))
        np_fail(&in->plant, "communication step must be > 0, got %.17g", h);
    else if (np_check_inputs(&in->plant) == 0 && np_plant_advance(&in->plant, h) == 0) {
        in->time = t + h;
        return NP_OK;
    }
    in->failed = 1;
    return np_report(in, NP_DISCARD, "%s: step at t=%.17g failed: %s", fn, t, in->plant.error);
}
