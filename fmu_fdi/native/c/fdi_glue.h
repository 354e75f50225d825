/* fdi_glue.h - what the FMI 2.0 and FMI 3.0 glue (fmi2.c, fmi3.c) share (C99).
 *
 * One instance of the native diagnostic FMU: the FMI mode (state machine), the inputs as set
 * by the host, the runtime (fdi_runtime.h) and the logger. Everything lives in one block
 * allocated at instantiation (fdi_instance_bytes); nothing is allocated afterwards except the
 * FMU-state objects a host asks for (fmi2GetFMUstate / fmi3GetFMUState / deserialization),
 * which the FMI standard makes the FMU allocate and fmiXFreeFMUstate releases.
 *
 * The variables and their value references come from the generated fdi_model.h:
 *   vr 0                      time (FMI 3.0 only: the independent variable)
 *   vr 1 .. N_INPUTS          plant inputs u then plant outputs y (Real/Float64 inputs)
 *   vr N_INPUTS + 1           threshold_scale (tunable parameter)
 *   vr N_INPUTS + 2 + j       output j of fdi_runtime_outputs (kind FDI_OUTPUT_KINDS[j])
 */
#ifndef FDI_GLUE_H
#define FDI_GLUE_H

#include <stdarg.h>
#include <stddef.h>

#include "fdi_model.h"
#include "fdi_runtime.h"
#include "fdi_schedule.h"  /* a scheduled design (FDI_SCHEDULED) renames the runtime API used below */

enum { FDI_KIND_REAL = 0, FDI_KIND_BOOLEAN = 1, FDI_KIND_INTEGER = 2 };

/* statuses: the numbering of fmi2Status and fmi3Status (OK, Warning, Discard, Error, Fatal) */
enum { FDI_S_OK = 0, FDI_S_WARNING = 1, FDI_S_DISCARD = 2, FDI_S_ERROR = 3, FDI_S_FATAL = 4 };

/* FMI modes; FDI_M_EVENT only in FMI 3.0 with eventModeUsed */
enum { FDI_M_INSTANTIATED = 0, FDI_M_INITIALIZATION, FDI_M_EVENT, FDI_M_STEP, FDI_M_TERMINATED, FDI_M_ERROR };
#define FDI_ALLOW(m) (1u << (m))
#define FDI_ANY_MODE 0x3Fu

#define FDI_VR_TIME 0u
#define FDI_VR_INPUT0 1u
#define FDI_VR_SCALE ((unsigned)FDI_N_INPUTS + 1u)
#define FDI_VR_OUTPUT0 ((unsigned)FDI_N_INPUTS + 2u)
#define FDI_VR_END (FDI_VR_OUTPUT0 + (unsigned)FDI_N_OUTPUTS)

/* log categories, the same as the Python target's (fmu_fdi/fmu/slave_base.py) */
enum { FDI_C_WARNING = 0, FDI_C_DISCARD, FDI_C_ERROR, FDI_C_FATAL, FDI_C_ALL, FDI_C_EVENTS, FDI_C_INPUT,
       FDI_C_STATE, FDI_C_NUMERIC, FDI_N_CATEGORIES };
extern const char *const FDI_CATEGORY_NAMES[FDI_N_CATEGORIES];

/* The host's logger as the glue sees it: a plain message (no printf format). */
typedef void (*fdi_emit_fn)(void *host, const char *instance, int status, const char *category, const char *msg);
typedef void *(*fdi_alloc_fn)(void *host, size_t nbytes);  /* zeroed memory or NULL */
typedef void (*fdi_release_fn)(void *host, void *p);

typedef struct fdi_instance {
    unsigned long magic;
    int mode;
    int event_mode_used;          /* FMI 3.0: exit initialization to Event Mode */
    double time;
    double *inputs;               /* FDI_N_INPUTS values: u then y */
    fdi_runtime *rt;
    const double *outputs;        /* fdi_runtime_outputs(rt), refreshed after every runtime call */
    char *name;
    fdi_emit_fn emit;
    fdi_alloc_fn alloc;
    fdi_release_fn release;
    void *host;
    int logging_on;
    unsigned categories;          /* bit c: category c switched on */
    int last_detected, last_isolated;
    char why[256];
    char msg[640];
} fdi_instance;

/* Bytes of the block for an instance called name; fdi_instance_init lays it out. */
size_t fdi_instance_bytes(const char *name);
fdi_instance *fdi_instance_init(void *block, size_t nbytes, const char *name, fdi_emit_fn emit, void *host,
                                fdi_alloc_fn alloc, fdi_release_fn release, int logging_on);
/* Checks the generated model data against the runtime's design; 0 and a reason in why if not. */
int fdi_model_consistent(char *why, size_t whylen);
int fdi_is_instance(const void *p);      /* a live instance of this FMU (magic check) */
void fdi_instance_reset(fdi_instance *fi);
void fdi_instance_forget(fdi_instance *fi);  /* before the block is freed */

void fdi_log(fdi_instance *fi, int status, int category, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* Is function fn allowed in the current mode? If not: log the reason, enter FDI_M_ERROR, 0. */
int fdi_not_allowed(fdi_instance *fi, const char *fn, unsigned allowed);
static inline int fdi_allowed(fdi_instance *fi, const char *fn, unsigned allowed) {
    return (allowed & FDI_ALLOW(fi->mode)) ? 1 : fdi_not_allowed(fi, fn, allowed);
}
const char *fdi_mode_name(int mode);
int fdi_set_logging(fdi_instance *fi, int on, size_t n, const char *const categories[], const char *fn);

/* Variable access by value reference; kind is the type the host asks for. */
int fdi_get(fdi_instance *fi, const char *fn, int kind, unsigned vr, double *value);
int fdi_set(fdi_instance *fi, const char *fn, int kind, unsigned vr, double value);
/* The common cases inline (an output of the right kind, a plant input); everything else,
 * errors included, through fdi_get / fdi_set. */
extern const signed char FDI_OUTPUT_KIND_TABLE[];
static inline int fdi_get_fast(fdi_instance *fi, int kind, unsigned vr, double *value) {
    if (vr - FDI_VR_OUTPUT0 < (unsigned)FDI_N_OUTPUTS && FDI_OUTPUT_KIND_TABLE[vr - FDI_VR_OUTPUT0] == kind) {
        *value = fi->outputs[vr - FDI_VR_OUTPUT0];
        return 1;
    }
    return 0;
}
static inline int fdi_set_fast(fdi_instance *fi, int kind, unsigned vr, double value) {
    if (kind == FDI_KIND_REAL && vr - FDI_VR_INPUT0 < (unsigned)FDI_N_INPUTS) {
        fi->inputs[vr - FDI_VR_INPUT0] = value;
        return 1;
    }
    return 0;
}
/* An output as an FMI Integer: clamped to the 32-bit range (NaN: 0), never undefined behaviour. */
static inline int fdi_int_output(double v) {
    return v != v ? 0 : v <= -2147483648.0 ? (-2147483647 - 1) : v >= 2147483647.0 ? 2147483647 : (int)v;
}
/* The step; returns FDI_S_OK, FDI_S_DISCARD (reason logged; nothing changed) or FDI_S_ERROR. */
int fdi_do_step(fdi_instance *fi, const char *fn, double t, double h);

/* FMU state: a byte image (magic, sizes, time, inputs, runtime image); objects for the host. */
size_t fdi_image_bytes(const fdi_instance *fi);
void fdi_image_get(const fdi_instance *fi, unsigned char *buf);
int fdi_image_set(fdi_instance *fi, const unsigned char *buf, size_t len, const char *fn);
int fdi_image_check(fdi_instance *fi, const unsigned char *buf, size_t len, const char *fn);

typedef struct fdi_state_obj fdi_state_obj;
int fdi_state_get(fdi_instance *fi, const char *fn, void **state);
int fdi_state_set(fdi_instance *fi, const char *fn, const void *state);
int fdi_state_free(fdi_instance *fi, const char *fn, void **state);
int fdi_state_size(fdi_instance *fi, const char *fn, const void *state, size_t *size);
int fdi_state_serialize(fdi_instance *fi, const char *fn, const void *state, unsigned char *buf, size_t size);
int fdi_state_deserialize(fdi_instance *fi, const char *fn, const unsigned char *buf, size_t size, void **state);

#endif
