/* fdi_runtime.h - the per-sample diagnosis runtime of the native diagnostic FMU (C99).
 *
 * Contract between the runtime (fdi_runtime.c and friends) and the FMI glue (fmi2.c, fmi3.c).
 * The semantics are those of docs/semantics.md, the same as fmu_fdi/runtime/ (Python); the
 * conformance suite (tests/test_native_conformance.py) is the judge.
 *
 * Memory: the glue allocates fdi_runtime_size(design) bytes once at instantiation (FMI 2:
 * the host's allocateMemory; FMI 3: calloc), 8-byte aligned, and hands them to fdi_runtime_init;
 * the runtime never allocates. No global mutable state: everything lives in that block.
 */
#ifndef FDI_RUNTIME_H
#define FDI_RUNTIME_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Generated constant data (design_data.c, written by fmu_fdi/native/emit.py); layout private
 * to the runtime. The glue only sees the pointer FDI_DESIGN. */
typedef struct fdi_design fdi_design;
extern const fdi_design FDI_DESIGN;

typedef struct fdi_runtime fdi_runtime;   /* opaque, lives in the glue's block */

typedef enum { FDI_OK = 0, FDI_DISCARD = 1, FDI_ERROR = 2 } fdi_status;

/* Sizes of the design: inputs are u (n_u, design order) then y (n_y); outputs in the order
 * of fmu_fdi.runtime.engine.output_names (residuals, evaluations, thresholds, alarms,
 * fault_detected, isolated_fault, input_invalid, and any flag docs/semantics.md adds). */
size_t fdi_n_u(const fdi_design *d);
size_t fdi_n_y(const fdi_design *d);
size_t fdi_n_outputs(const fdi_design *d);
double fdi_sample_time(const fdi_design *d);

size_t fdi_runtime_size(const fdi_design *d);                 /* bytes for one instance */
fdi_status fdi_runtime_init(fdi_runtime *rt, const fdi_design *d, size_t nbytes);
void fdi_runtime_reset(fdi_runtime *rt);                        /* to the initial state */

/* Diagnose the sample (u, y) over the communication step h (seconds). FDI_DISCARD: the step
 * cannot be served (reason written to why, NUL-terminated, at most whylen bytes) and the
 * runtime is exactly as before the call. */
fdi_status fdi_runtime_advance(fdi_runtime *rt, const double *u, const double *y, double h,
                               char *why, size_t whylen);
const double *fdi_runtime_outputs(const fdi_runtime *rt);       /* n_outputs values */
double fdi_runtime_step(const fdi_runtime *rt);                 /* the current communication step */
double fdi_runtime_sample_ratio(const fdi_runtime *rt);         /* effective sample time / Ts */

/* The tunable parameter threshold_scale (finite, >= 0 as docs/semantics.md §6;
 * else FDI_ERROR with a reason and the scale unchanged). */
fdi_status fdi_runtime_set_threshold_scale(fdi_runtime *rt, double scale, char *why, size_t whylen);
double fdi_runtime_threshold_scale(const fdi_runtime *rt);

/* FMU state: a self-describing byte image (magic, design hash, size) of everything that
 * changes at run time. set_state validates magic, design hash, size and finiteness and
 * returns FDI_ERROR with a reason (runtime unchanged) for anything else. */
size_t fdi_runtime_state_size(const fdi_runtime *rt);
void fdi_runtime_get_state(const fdi_runtime *rt, unsigned char *buf);
fdi_status fdi_runtime_set_state(fdi_runtime *rt, const unsigned char *buf, size_t len,
                                 char *why, size_t whylen);

#ifdef __cplusplus
}
#endif
#endif
