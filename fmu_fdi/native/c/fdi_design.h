/* fdi_design.h - layout of the generated constant design data (private to the runtime).
 *
 * design_data.c (written by fmu_fdi/native/emit.py) defines `const fdi_design FDI_DESIGN`
 * with this layout; every derived constant (the stacked generator matrix, whitening
 * matrices, normalised fault directions) is emitted as computed by the Python runtime, with
 * hex float literals, so both runtimes start from bit-identical numbers.
 * Matrices are row-major. Counts obey the design-file limits (docs/semantics.md, S5).
 */
#ifndef FDI_DESIGN_H
#define FDI_DESIGN_H

#include "fdi_runtime.h"

enum { FDI_GEN_LTI = 0, FDI_GEN_RLS = 1 };
enum { FDI_EV_NORM = 0, FDI_EV_RMS, FDI_EV_EWRMS, FDI_EV_PEAK, FDI_EV_NARENDRA,
       FDI_EV_CHI2, FDI_EV_CUSUM, FDI_EV_GLR };
enum { FDI_TH_FIXED = 0, FDI_TH_ADAPTIVE, FDI_TH_MAJORANT };
enum { FDI_ISO_NONE = 0, FDI_ISO_STRUCTURE, FDI_ISO_DIRECTION };
enum { FDI_RLS_RESET_NONE = 0, FDI_RLS_RESET_FLOOR, FDI_RLS_RESET_PERIODIC };

/* One evaluation function (fmu_fdi/runtime/evaluation.py). */
typedef struct {
    int kind;
    long window;                  /* rms, chi2, peak, glr */
    double lam;                   /* ewrms */
    double alpha, beta, gamma;    /* narendra */
    double delta;                 /* cusum */
    const double *W;              /* dim x dim whitening (chi2, cusum, glr) */
} fdi_eval_def;

/* One threshold (fmu_fdi/runtime/thresholds.py). */
typedef struct {
    int kind;
    double value;                 /* fixed */
    double J0, a;                 /* adaptive, majorant */
    fdi_eval_def ev;              /* adaptive: evaluator of ||u - u0||; majorant: the group's */
    long n_taps;                  /* majorant */
    const double *taps;
    double tail;
} fdi_threshold_def;

/* One RLS estimator (fmu_fdi/runtime/rls.py). */
typedef struct {
    long n_in, npar, nx;
    const long *inputs;           /* n_in indices into [y; u] */
    const double *A, *B, *C, *D;  /* nx x nx, nx x n_in, (npar+1) x nx, (npar+1) x n_in */
    const double *theta0;
    long skip, warmup;
    double sigma_floor, trace_max, trace_min;
} fdi_rls_est_def;

struct fdi_design {
    unsigned long long hash;      /* 64 bits of the SHA-256 of the emitted data: guards FMU state images */
    long n_u, n_y, n_r, n_groups, n_faults;
    double Ts;
    const double *u0, *y0;        /* operating point */
    const double *lo, *hi;        /* valid range per signal, u then y (+-HUGE_VAL: none) */
    int gen_kind;
    /* LTI: [r; x+] = M [x; v], M = [[C, D], [A, B]], (n_r + n_x) x (n_x + n_y + n_u) */
    long n_x;
    const double *M;
    /* continuous LTI (has_cont): re-discretised exactly at other steps */
    int has_cont;
    long n_xc;
    const double *Ac, *Bc, *Cc, *Dc;
    /* RLS */
    long rls_n_est;
    const fdi_rls_est_def *rls_est;
    double rls_mu, rls_P0, rls_sigma_rel, rls_mu_sigma, rls_clip;
    int rls_policy;
    long rls_period;
    int rls_clip_after_inf;       /* forgetting 1: never clip */
    long rls_clip_after;
    /* groups: residual indices group_idx[group_start[g] .. group_start[g+1]) */
    const long *group_start, *group_idx;
    const fdi_eval_def *evals;    /* n_groups */
    const fdi_threshold_def *thr; /* n_groups */
    /* decision */
    long k_of, n_of;
    int latch, isolation;
    const unsigned char *S;       /* n_groups x n_faults (structure) */
    const double *Ddir;           /* n_r x n_faults normalised directions (direction) */
    const unsigned char *Dvalid;  /* n_faults */
    double min_margin;
};

#endif
