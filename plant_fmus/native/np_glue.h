/* np_glue.h - the FMI-version-independent part of the native plants' FMI glue (C99): the instance
 * record, its modes, the setting rules, the checks of every get/set, initialisation and the step.
 * fmi2_plant.c and fmi3_plant.c wrap it in the FMI 2.0 and FMI 3.0 calling conventions.
 *
 * Rules (as the pythonfmu plant): a fixed parameter is settable until initialisation ends, a
 * tunable parameter or an input until terminate, an output never; a get/set that breaks a rule
 * changes nothing (all or nothing) and returns Error with the reason logged. Initialisation runs
 * the checks of the Python plant's exit_initialization_mode and the plant's initialize(); a
 * failure returns Error. A failed step (non-finite input, invalid step, integrator failure)
 * returns Discard with the reason logged (status Error, as the Python plant logs it), and so does
 * every later step. Memory: the host allocates np_instance_bytes() once at instantiation; nothing
 * else is allocated. No global mutable state. */
#ifndef NP_GLUE_H
#define NP_GLUE_H

#include <stddef.h>

#include "np_plant.h"

enum { NP_OK = 0, NP_WARNING = 1, NP_DISCARD = 2, NP_ERROR = 3 }; /* = fmi2Status = fmi3Status */
enum { NP_REAL, NP_INTEGER, NP_BOOLEAN };                        /* np_vars.h NP_VAR_KINDS */

/* log sink of the FMI layer: status, category and the message (plain text, no format) */
typedef void (*np_log_fn)(void *host, const char *instance, int status, const char *category, const char *msg);

typedef struct {
    unsigned magic;
    int mode, failed;
    double time;
    np_log_fn log;
    void *host;
    char name[128];
    np_plant plant;
} np_instance;

size_t np_instance_bytes(void);
/* Lay out the instance in block (np_instance_bytes() bytes, zeroed by this call). */
np_instance *np_instance_init(void *block, const char *name, np_log_fn log, void *host);
np_instance *np_instance_of(void *component); /* NULL unless it is one of ours */
void np_instance_release(np_instance *in);
void np_reset(np_instance *in);
int np_report(np_instance *in, int status, const char *fmt, ...);

int np_enter_initialization(np_instance *in, const char *fn);
int np_exit_initialization(np_instance *in, const char *fn);
int np_terminate(np_instance *in, const char *fn);
/* every value reference exists and has the kind; set: also settable now */
int np_check_access(np_instance *in, const char *fn, const unsigned *vr, size_t n, int kind, int set);
int np_do_step(np_instance *in, const char *fn, double t, double h);
int np_unsupported(void *component, const char *fn, const char *why);

#endif
