/* fdi_internal.h - the runtime's private structures (shared by its translation units).
 *
 * Everything an instance owns lives in the block handed to fdi_runtime_init. The state
 * that changes at run time is kept in three contiguous regions (doubles, 64-bit integers,
 * bytes) so that an FMU state image is a validated copy of them; everything else
 * (pointers, plans, scratch) is derived from the design and the current step size.
 */
#ifndef FDI_INTERNAL_H
#define FDI_INTERNAL_H

#include <stddef.h>

#include "fdi_design.h"

typedef long long fdi_int;
/* Counters in a state image are below 2^53 (they grow by one per sample: never reached), where
 * every integer is a double: the peak evaluator stores sample indices as doubles, and an image
 * claiming more is refused (docs/semantics.md S10). */
#define FDI_EXACT_MAX (1LL << 53)

/* Bump allocator over the instance block; with base == NULL it only counts. */
typedef struct {
    unsigned char *base;
    size_t off;
} fdi_carver;

void *fdi_carve(fdi_carver *c, size_t bytes);

/* Slot counters of the state regions while laying them out. */
typedef struct {
    double *d;
    fdi_int *i;
    unsigned char *b;
    size_t nd, ni, nb;
} fdi_slots;

double *fdi_slot_d(fdi_slots *s, size_t n);
fdi_int *fdi_slot_i(fdi_slots *s, size_t n);
unsigned char *fdi_slot_b(fdi_slots *s, size_t n);

/* ------------------------------------------------------------------ evaluators */
typedef struct {
    long dim, cap;          /* residual dimension, largest window over all plans */
    int kind;
    double *value;          /* the last evaluation */
    double *acc;            /* ring sum (rms, chi2), acc (ewrms), re (narendra) */
    double *buf;            /* ring (rms, chi2: cap), deque indices (peak: cap+1), history (glr: cap*dim), gp (cusum: dim) */
    double *buf2;           /* deque values (peak: cap+1), gm (cusum: dim) */
    fdi_int *i;             /* [0] ring position / deque head / history head, [1] count / deque length, [2] peak sample index */
} fdi_evaluator;

void fdi_evaluator_layout(fdi_evaluator *e, fdi_slots *s, int kind, long dim, long cap);
void fdi_evaluator_reset(fdi_evaluator *e);
int fdi_evaluator_check(const fdi_evaluator *e, const fdi_eval_def *def);  /* state image sane */
int fdi_evaluator_finite(const fdi_evaluator *e);
double fdi_evaluator_step_sq(fdi_evaluator *e, const fdi_eval_def *def, double sq);
double fdi_evaluator_step(fdi_evaluator *e, const fdi_eval_def *def, const double *r, double *work);

int fdi_nonnegative(const double *x, size_t n);   /* every x[j] >= 0 */

/* Correctly rounded sum of x[0..n) (Python's math.fsum: Shewchuk's partials, half-even fix). */
double fdi_fsum(const double *x, long n);

/* ------------------------------------------------------------------ thresholds */
typedef struct {
    const fdi_threshold_def *def;
    double *value;
    fdi_evaluator ev;       /* adaptive: E_u; majorant: E(b) */
    double *hist;           /* majorant: ||u(k-j)||, ring of n_taps */
    double *old_max;
    fdi_int *pos;           /* majorant: ring position of ||u(k)|| */
} fdi_threshold;

void fdi_threshold_layout(fdi_threshold *t, fdi_slots *s, const fdi_threshold_def *def, long cap);
void fdi_threshold_reset(fdi_threshold *t);
int fdi_threshold_check(const fdi_threshold *t, const fdi_eval_def *ev);
int fdi_threshold_finite(const fdi_threshold *t);
double fdi_threshold_step(fdi_threshold *t, const fdi_eval_def *ev, double unorm);

/* ------------------------------------------------------------------ decision */
typedef struct {
    const fdi_design *d;
    unsigned char *raw;     /* n_groups x n_of raw tests, ring per group */
    unsigned char *alarms, *latched;
    fdi_int *pos;           /* ring position per group (oldest entry) */
    fdi_int *isolated;
    fdi_int *count;         /* fired tests in each ring (derived, not in the image) */
} fdi_decision;

void fdi_decision_layout(fdi_decision *dec, fdi_slots *s, fdi_carver *c, const fdi_design *d);
void fdi_decision_reset(fdi_decision *dec);
int fdi_decision_load(fdi_decision *dec);   /* validate image, rebuild counts; 0 if bad */
/* raw tests evals >= thrs (written to fired, n_groups bytes of scratch) */
void fdi_decision_step(fdi_decision *dec, const double *evals, const double *thrs, const double *r,
                       unsigned char *fired);
/* raw tests given; r NULL: direction unknown (an overflowed sub-sample, docs/semantics.md S8) */
void fdi_decision_step_fired(fdi_decision *dec, const unsigned char *fired, const double *r);

/* ------------------------------------------------------------------ RLS generator */
typedef struct {
    const fdi_design *d;
    fdi_int *k;
    double **x, **theta, **P, **sigma2, **psi2;
    fdi_int **updates, **resets;
    double *work;           /* z, w, Pphi, K, J, JP (largest estimator) */
} fdi_rls;

void fdi_rls_layout(fdi_rls *g, fdi_slots *s, fdi_carver *c, const fdi_design *d);
void fdi_rls_reset(fdi_rls *g);
int fdi_rls_check(const fdi_rls *g);
int fdi_rls_finite(const fdi_rls *g);
void fdi_rls_step(fdi_rls *g, const double *v, double *r);

/* ------------------------------------------------------------------ dense linear algebra */
/* y = M x, M rows x cols row-major, sums in column order */
void fdi_matvec(const double *M, long rows, long cols, const double *x, double *y);
/* Work doubles needed by fdi_zoh for an n-state, m-input system. */
size_t fdi_zoh_work(long n, long m);
/* Ad = e^{A h}, Bd = int_0^h e^{A t} dt B (one exponential of [[A, B], [0, 0]] h);
 * returns 0 if the exponential is not finite or the Pade denominator singular. */
int fdi_zoh(const double *A, const double *B, long n, long m, double h, double *Ad, double *Bd, double *work);
/* e^A (n x n) by scaling and squaring with the [13/13] Pade approximant (Higham 2005). */
int fdi_expm(const double *A, long n, double *E, double *work);

/* ------------------------------------------------------------------ the instance */
typedef struct {
    double h;               /* communication step this plan serves */
    fdi_int substeps;
    double ratio;           /* effective sample time / Ts (1: the design's own) */
    const double *M;        /* [[C, D], [A, B]] of the generator used */
    long n_x;
    double *Mbuf;           /* own M (re-discretised plans) */
    fdi_eval_def *ev;       /* per group, resampled */
    fdi_eval_def *thev;     /* per group: threshold evaluator, resampled */
} fdi_plan;

struct fdi_runtime {
    unsigned long long magic;
    const fdi_design *d;
    size_t nbytes;
    /* state regions */
    fdi_slots st;
    double *bk_d;           /* backup of the regions while a state image is checked */
    fdi_int *bk_i;
    unsigned char *bk_b;
    double *outputs, *h, *scale, *x;  /* x: LTI generator state (largest order) */
    fdi_int *n_samples, *n_numeric_resets;
    fdi_evaluator *ev;
    fdi_threshold *th;
    fdi_decision dec;
    fdi_rls rls;
    /* derived */
    fdi_plan plan[2];
    int cur;
    long n_in, n_out, max_dim, xv_len;
    double *xv, *z, *v, *res, *evals, *thrs, *work, *zoh_work;
    unsigned char *fired;   /* per group: raw test of the sub-sample (S8: overflow counts as fired) */
};

#endif
