/* fdi_schedule.h - the scheduled diagnoser of the native FMU (C99): K member runtimes and the
 * nearest-member rule with hysteresis of docs/semantics.md §12 (the same as
 * fmu_fdi/runtime/schedule.py).
 *
 * Only a scheduled build defines FDI_SCHEDULED (in the generated fdi_model.h, included first by
 * fdi_glue.h). Then this header renames, for the FMI glue only, the runtime API the glue calls
 * (fdi_runtime.h) to the scheduled one below, whose instance holds the K member runtimes in its
 * own block; the member runtimes themselves are the unchanged fdi_runtime. In a plain build it
 * declares nothing. Every function of fdi_runtime.h has its scheduled counterpart here, with the
 * same contract (refusals with a reason, nothing changed; state images validated, §10 and §12).
 */
#ifndef FDI_SCHEDULE_H
#define FDI_SCHEDULE_H

#ifdef FDI_SCHEDULED
#include <stddef.h>

#include "fdi_runtime.h"

/* Generated constant data (schedule_data.c, written by fmu_fdi/native/schedule_emit.py). */
typedef struct fdi_schedule {
    unsigned long long hash;            /* 64 bits of the SHA-256 of the emitted schedule and member hashes */
    long K, S;                          /* members, scheduling signals */
    const fdi_design *const *members;   /* K member designs (FDI_MEMBER_1 ..) */
    const long *sig_index;              /* S: index into [u; y] of each scheduling signal */
    const double *points;               /* K x S */
    const double *scale;                /* S */
    double hysteresis;
    const double *const *warm;          /* K gains n_x x (n_y + n_u), or NULL (no warm start) */
} fdi_schedule;

typedef struct fdi_sched fdi_sched;
extern const fdi_schedule FDI_SCHEDULE;

size_t fdi_sched_n_u(const fdi_schedule *s);
size_t fdi_sched_n_y(const fdi_schedule *s);
size_t fdi_sched_n_outputs(const fdi_schedule *s);
double fdi_sched_sample_time(const fdi_schedule *s);
size_t fdi_sched_size(const fdi_schedule *s);
fdi_status fdi_sched_init(fdi_sched *rt, const fdi_schedule *s, size_t nbytes);
void fdi_sched_reset(fdi_sched *rt);
fdi_status fdi_sched_advance(fdi_sched *rt, const double *u, const double *y, double h, char *why, size_t whylen);
const double *fdi_sched_outputs(const fdi_sched *rt);
double fdi_sched_step(const fdi_sched *rt);
double fdi_sched_sample_ratio(const fdi_sched *rt);
fdi_status fdi_sched_set_threshold_scale(fdi_sched *rt, double scale, char *why, size_t whylen);
double fdi_sched_threshold_scale(const fdi_sched *rt);
size_t fdi_sched_state_size(const fdi_sched *rt);
void fdi_sched_get_state(const fdi_sched *rt, unsigned char *buf);
fdi_status fdi_sched_set_state(fdi_sched *rt, const unsigned char *buf, size_t len, char *why, size_t whylen);

#ifndef FDI_SCHEDULE_IMPLEMENTATION  /* the glue sees the scheduled runtime under the plain names */
#define fdi_runtime fdi_sched
#define fdi_design fdi_schedule
#define FDI_DESIGN FDI_SCHEDULE
#define fdi_n_u fdi_sched_n_u
#define fdi_n_y fdi_sched_n_y
#define fdi_n_outputs fdi_sched_n_outputs
#define fdi_sample_time fdi_sched_sample_time
#define fdi_runtime_size fdi_sched_size
#define fdi_runtime_init fdi_sched_init
#define fdi_runtime_reset fdi_sched_reset
#define fdi_runtime_advance fdi_sched_advance
#define fdi_runtime_outputs fdi_sched_outputs
#define fdi_runtime_step fdi_sched_step
#define fdi_runtime_sample_ratio fdi_sched_sample_ratio
#define fdi_runtime_set_threshold_scale fdi_sched_set_threshold_scale
#define fdi_runtime_threshold_scale fdi_sched_threshold_scale
#define fdi_runtime_state_size fdi_sched_state_size
#define fdi_runtime_get_state fdi_sched_get_state
#define fdi_runtime_set_state fdi_sched_set_state
#endif
#endif
#endif
