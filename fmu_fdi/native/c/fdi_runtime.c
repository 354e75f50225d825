/* fdi_runtime.c - the per-sample diagnosis runtime: generator -> evaluation -> thresholds ->
 * decision, with the step-size plans and the FMU state image (semantics: docs/semantics.md,
 * the same as fmu_fdi/runtime/engine.py).
 *
 * The instance block holds, in this order: the fdi_runtime header; the state regions
 * (doubles, 64-bit integers, bytes) and a backup copy of them (so a refused state image
 * leaves the instance as it was); two step-size plans (the current one and a candidate,
 * so a refused step leaves it as it was); scratch vectors and the matrix-exponential work.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "fdi_internal.h"

#define FDI_MAGIC 0x46444952554e5431ULL            /* "FDIRUNT1" */
static const unsigned char STATE_MAGIC[8] = {'F', 'D', 'I', 'S', 'T', 'A', 'T', '1'};
#define STATE_HEADER 48                              /* magic, hash, size, nd, ni, nb */
#define MAX_SUBSTEPS 10000
#define STEP_RTOL 1e-9

size_t fdi_n_u(const fdi_design *d) { return (size_t)d->n_u; }
size_t fdi_n_y(const fdi_design *d) { return (size_t)d->n_y; }
size_t fdi_n_outputs(const fdi_design *d) { return (size_t)(d->n_r + 3 * d->n_groups + 4); }
double fdi_sample_time(const fdi_design *d) { return d->Ts; }

static void say(char *why, size_t whylen, const char *msg)
{
    if (why && whylen) {
        strncpy(why, msg, whylen - 1);
        why[whylen - 1] = '\0';
    }
}

static int resamplable(const fdi_design *d)
{
    return d->gen_kind == FDI_GEN_LTI && d->has_cont;
}

/* Largest window an evaluator can need over all plans: windows keep their duration, so a
 * step down to Ts/16 multiplies them by up to 16 (rms, peak). */
static long capacity(const fdi_design *d, const fdi_eval_def *e)
{
    long w = e->kind == FDI_EV_RMS || e->kind == FDI_EV_CHI2 || e->kind == FDI_EV_PEAK || e->kind == FDI_EV_GLR
                 ? e->window : 1;
    if (resamplable(d) && (e->kind == FDI_EV_RMS || e->kind == FDI_EV_PEAK))
        w = 16 * w + 1;
    return w;
}

static long group_dim(const fdi_design *d, long g) { return d->group_start[g + 1] - d->group_start[g]; }

static long lti_order(const fdi_design *d) { return d->n_x > d->n_xc ? d->n_x : d->n_xc; }

/* The state slots of every component (and the bytes they carve for themselves), laid out
 * in one fixed order; with slot pointers NULL it only counts. */
static void layout_components(fdi_runtime *rt, const fdi_design *d, fdi_slots *s, fdi_carver *c)
{
    long g;
    rt->outputs = fdi_slot_d(s, fdi_n_outputs(d));
    rt->h = fdi_slot_d(s, 1);
    rt->scale = fdi_slot_d(s, 1);
    rt->x = d->gen_kind == FDI_GEN_LTI ? fdi_slot_d(s, (size_t)lti_order(d)) : NULL;
    rt->n_samples = fdi_slot_i(s, 1);
    rt->n_numeric_resets = fdi_slot_i(s, 1);
    for (g = 0; g < d->n_groups; g++) {
        fdi_evaluator tev, *ev = rt->ev ? &rt->ev[g] : &tev;
        fdi_threshold tth, *th = rt->th ? &rt->th[g] : &tth;
        fdi_evaluator_layout(ev, s, d->evals[g].kind, group_dim(d, g), capacity(d, &d->evals[g]));
        fdi_threshold_layout(th, s, &d->thr[g], capacity(d, &d->thr[g].ev));
    }
    fdi_decision_layout(&rt->dec, s, c, d);
    if (d->gen_kind == FDI_GEN_RLS)
        fdi_rls_layout(&rt->rls, s, c, d);
}

/* Lay the instance out in the block at base (base NULL: count only). Returns the bytes needed. */
static size_t layout(fdi_runtime *rt, const fdi_design *d, unsigned char *base)
{
    fdi_runtime tmp;
    fdi_carver c = {base, 0}, counter = {NULL, 0};
    fdi_slots s = {NULL, NULL, NULL, 0, 0, 0};
    long g, ng = d->n_groups, m = d->n_y + d->n_u, p = d->n_r + lti_order(d);
    size_t nd, ni, nb;
    if (!base)
        rt = &tmp;
    memset(rt, 0, sizeof *rt);
    rt->d = d;
    layout_components(rt, d, &s, &counter);   /* count */
    nd = s.nd;
    ni = s.ni;
    nb = s.nb;
    fdi_carve(&c, sizeof(fdi_runtime));
    s.d = fdi_carve(&c, nd * sizeof(double));
    s.i = fdi_carve(&c, ni * sizeof(fdi_int));
    s.b = fdi_carve(&c, nb);
    rt->bk_d = fdi_carve(&c, nd * sizeof(double));      /* backup of the state regions */
    rt->bk_i = fdi_carve(&c, ni * sizeof(fdi_int));
    rt->bk_b = fdi_carve(&c, nb);
    rt->ev = fdi_carve(&c, (size_t)ng * sizeof(fdi_evaluator));
    rt->th = fdi_carve(&c, (size_t)ng * sizeof(fdi_threshold));
    fdi_carve(&c, 0);                         /* align */
    if (base) {
        s.nd = s.ni = s.nb = 0;
        layout_components(rt, d, &s, &c);
        rt->st = s;
    } else {
        c.off += counter.off;
    }
    for (g = 0; g < 2; g++) {
        fdi_plan *pl = &rt->plan[g];
        pl->Mbuf = resamplable(d) ? fdi_carve(&c, (size_t)(p * (d->n_xc + m)) * sizeof(double)) : NULL;
        pl->ev = fdi_carve(&c, (size_t)ng * sizeof(fdi_eval_def));
        pl->thev = fdi_carve(&c, (size_t)ng * sizeof(fdi_eval_def));
    }
    rt->n_in = m;
    rt->n_out = (long)fdi_n_outputs(d);
    rt->max_dim = 1;
    for (g = 0; g < ng; g++)
        if (group_dim(d, g) > rt->max_dim)
            rt->max_dim = group_dim(d, g);
    rt->xv_len = lti_order(d) + m;
    rt->xv = fdi_carve(&c, (size_t)rt->xv_len * sizeof(double));
    rt->z = fdi_carve(&c, (size_t)p * sizeof(double));
    rt->v = fdi_carve(&c, (size_t)m * sizeof(double));
    rt->res = fdi_carve(&c, (size_t)d->n_r * sizeof(double));
    rt->evals = fdi_carve(&c, (size_t)ng * sizeof(double));
    rt->thrs = fdi_carve(&c, (size_t)ng * sizeof(double));
    rt->work = fdi_carve(&c, (size_t)(3 * rt->max_dim) * sizeof(double));  /* evaluator work, group residual */
    rt->fired = fdi_carve(&c, (size_t)ng);
    rt->zoh_work = resamplable(d)
        ? fdi_carve(&c, (fdi_zoh_work(d->n_xc, m) + (size_t)(d->n_xc * (d->n_xc + m))) * sizeof(double)) : NULL;
    return c.off + 16;
}

/* ------------------------------------------------------------------ step-size plans */
/* Python's round(x) for the positive, moderate values used here (ties to even). */
static double round_half_even(double x)
{
    double r = floor(x + 0.5);
    if (r - x == 0.5 && fmod(r, 2.0) != 0.0)
        r -= 1.0;
    return r;
}

/* Evaluator parameters at `ratio` times the design sample time (evaluation.py resampled):
 * windows keep their duration, forgetting factors their time constant, Narendra its gain. */
static void resample_eval(const fdi_eval_def *src, double ratio, fdi_eval_def *dst)
{
    *dst = *src;
    if (ratio == 1.0)
        return;
    if (src->kind == FDI_EV_RMS || src->kind == FDI_EV_PEAK) {
        double w = round_half_even((double)src->window / ratio);
        dst->window = w < 1.0 ? 1 : (long)w;
    } else if (src->kind == FDI_EV_EWRMS) {
        dst->lam = pow(src->lam, ratio);
    } else if (src->kind == FDI_EV_NARENDRA) {
        double g2 = pow(src->gamma, ratio);
        dst->gamma = g2;
        dst->beta = src->gamma < 1.0 ? src->beta * (1.0 - g2) / (1.0 - src->gamma) : src->beta;
    }
}

/* Fill *pl for communication step h; 0 with the reason in why if h cannot be served. */
static int make_plan(fdi_runtime *rt, double h, fdi_plan *pl, char *why, size_t whylen)
{
    const fdi_design *d = rt->d;
    double Ts = d->Ts, ratio, k;
    long g, m = rt->n_in;
    char msg[256];
    if (!(isfinite(h) && h > 0.0)) {
        snprintf(msg, sizeof msg, "communication step must be a positive number, got %g", h);
        say(why, whylen, msg);
        return 0;
    }
    ratio = h / Ts;
    if (ratio > MAX_SUBSTEPS + 0.5) {
        snprintf(msg, sizeof msg, "step %g s is %.6g design sample times Ts = %g s: more than %d sub-steps per call",
                 h, ratio, Ts, MAX_SUBSTEPS);
        say(why, whylen, msg);
        return 0;
    }
    k = floor(ratio + 0.5);
    pl->h = h;
    if (k >= 1.0 && fabs(ratio - k) <= STEP_RTOL * k) {
        pl->substeps = (fdi_int)k;
        pl->ratio = 1.0;
        pl->n_x = d->gen_kind == FDI_GEN_LTI ? d->n_x : 0;
        pl->M = d->M;
        for (g = 0; g < d->n_groups; g++) {
            pl->ev[g] = d->evals[g];
            pl->thev[g] = d->thr[g].ev;
        }
        return 1;
    }
    if (!resamplable(d)) {
        snprintf(msg, sizeof msg, "step %g s is not an integer multiple of the design sample time %g s and the "
                 "design exists only in discrete time, so it cannot be re-discretised exactly", h, Ts);
        say(why, whylen, msg);
        return 0;
    }
    if (!(ratio >= 1.0 / 16.0 && ratio <= MAX_SUBSTEPS)) {
        snprintf(msg, sizeof msg, "step %g s is not an integer multiple of the design sample time %g s and outside "
                 "the re-discretisation range [Ts/16, %d Ts] = [%g, %g] s", h, Ts, MAX_SUBSTEPS, Ts / 16.0,
                 Ts * MAX_SUBSTEPS);
        say(why, whylen, msg);
        return 0;
    }
    if (d->n_xc != d->n_x) {
        snprintf(msg, sizeof msg, "step %g s differs from the design sample time %g s, and the continuous design "
                 "(order %ld) is not the realisation of the discrete one (order %ld): the generator state cannot "
                 "carry over", h, Ts, d->n_xc, d->n_x);
        say(why, whylen, msg);
        return 0;
    }
    for (g = 0; g < d->n_groups; g++) {
        int kind = d->evals[g].kind, tkind = d->thr[g].kind;
        if (kind == FDI_EV_CHI2 || kind == FDI_EV_CUSUM || kind == FDI_EV_GLR || tkind == FDI_TH_MAJORANT) {
            snprintf(msg, sizeof msg, "step %g s differs from the design sample time %g s: %s", h, Ts,
                     tkind == FDI_TH_MAJORANT
                         ? "a majorant threshold is an impulse-response bound at the design sample time and "
                           "cannot run at another step size"
                         : "a statistical test (chi2, cusum, glr) is defined per design sample and cannot run "
                           "at another step size");
            say(why, whylen, msg);
            return 0;
        }
        resample_eval(&d->evals[g], ratio, &pl->ev[g]);
        resample_eval(&d->thr[g].ev, ratio, &pl->thev[g]);
    }
    {   /* M = [[Cc, Dc], [Ad, Bd]] */
        long n = d->n_xc, r, j, nr = d->n_r;
        double *Ad = rt->zoh_work + fdi_zoh_work(n, m), *Bd = Ad + n * n;
        if (!fdi_zoh(d->Ac, d->Bc, n, m, h, Ad, Bd, rt->zoh_work)) {
            snprintf(msg, sizeof msg, "step %g s: the matrix exponential of the continuous design is not finite", h);
            say(why, whylen, msg);
            return 0;
        }
        for (r = 0; r < nr; r++) {
            for (j = 0; j < n; j++)
                pl->Mbuf[r * (n + m) + j] = d->Cc[r * n + j];
            for (j = 0; j < m; j++)
                pl->Mbuf[r * (n + m) + n + j] = d->Dc[r * m + j];
        }
        for (r = 0; r < n; r++) {
            for (j = 0; j < n; j++)
                pl->Mbuf[(nr + r) * (n + m) + j] = Ad[r * n + j];
            for (j = 0; j < m; j++)
                pl->Mbuf[(nr + r) * (n + m) + n + j] = Bd[r * m + j];
        }
    }
    pl->substeps = 1;
    pl->ratio = ratio;
    pl->n_x = d->n_xc;
    pl->M = pl->Mbuf;
    return 1;
}

static int same_step(double h, double h_prev) { return fabs(h - h_prev) <= STEP_RTOL * h_prev; }

/* ------------------------------------------------------------------ components */
static void reset_stage(fdi_runtime *rt)
{
    long g;
    for (g = 0; g < rt->d->n_groups; g++) {
        fdi_evaluator_reset(&rt->ev[g]);
        fdi_threshold_reset(&rt->th[g]);
    }
}

static void reset_generator(fdi_runtime *rt)
{
    if (rt->d->gen_kind == FDI_GEN_LTI)
        memset(rt->x, 0, (size_t)lti_order(rt->d) * sizeof(double));
    else
        fdi_rls_reset(&rt->rls);
}

size_t fdi_runtime_size(const fdi_design *d)
{
    return layout(NULL, d, NULL);
}

void fdi_runtime_reset(fdi_runtime *rt)
{
    const fdi_design *d = rt->d;
    rt->cur = 0;
    make_plan(rt, d->Ts, &rt->plan[0], NULL, 0);
    *rt->h = d->Ts;
    reset_generator(rt);
    reset_stage(rt);
    fdi_decision_reset(&rt->dec);
    memset(rt->outputs, 0, (size_t)rt->n_out * sizeof(double));
    *rt->n_samples = 0;
    *rt->n_numeric_resets = 0;
}

fdi_status fdi_runtime_init(fdi_runtime *rt, const fdi_design *d, size_t nbytes)
{
    if (!rt || !d || nbytes < fdi_runtime_size(d) || ((uintptr_t)(void *)rt & 7u) != 0)
        return FDI_ERROR;   /* the block must be 8-byte aligned (doubles, 64-bit integers) */
    layout(rt, d, (unsigned char *)rt);
    rt->magic = FDI_MAGIC;
    rt->nbytes = nbytes;
    *rt->scale = 1.0;
    fdi_runtime_reset(rt);
    return FDI_OK;
}

/* ------------------------------------------------------------------ one sample */
/* Generator, evaluators and thresholds for one (sub-)sample into rt->res/evals/thrs;
 * 0 if anything became non-finite (docs/semantics.md S8, an overflow). rt->fired gets each
 * group's raw test for the overflow case: fired if the group's evaluation overflowed (a residual
 * of the group, J_g or the evaluator's state not finite; every group if the generator state is
 * not finite), else J_g >= threshold_g. */
static int sample(fdi_runtime *rt, double unorm)
{
    const fdi_design *d = rt->d;
    const fdi_plan *pl = &rt->plan[rt->cur];
    long g, j, nr = d->n_r, ng = d->n_groups;
    double scale = *rt->scale;
    int ok = 1, gen_ok = 1;
    if (d->gen_kind == FDI_GEN_LTI) {
        long n = pl->n_x, m = rt->n_in;
        memcpy(rt->xv, rt->x, (size_t)n * sizeof(double));
        memcpy(rt->xv + n, rt->v, (size_t)m * sizeof(double));
        fdi_matvec(pl->M, nr + n, n + m, rt->xv, rt->z);
        memcpy(rt->x, rt->z + nr, (size_t)n * sizeof(double));
        memcpy(rt->res, rt->z, (size_t)nr * sizeof(double));
        for (j = 0; j < n && gen_ok; j++)
            gen_ok = isfinite(rt->x[j]);
    } else {
        fdi_rls_step(&rt->rls, rt->v, rt->res);
        gen_ok = fdi_rls_finite(&rt->rls);
    }
    ok = gen_ok;
    for (g = 0; g < ng; g++) {
        const long *idx = d->group_idx + d->group_start[g];
        long dim = group_dim(d, g);
        fdi_evaluator *ev = &rt->ev[g];
        int kind = ev->kind, group_ok = gen_ok;
        double e;
        for (j = 0; j < dim; j++)
            group_ok = group_ok && isfinite(rt->res[idx[j]]);
        if (kind == FDI_EV_CHI2 || kind == FDI_EV_CUSUM || kind == FDI_EV_GLR) {
            double *rg = rt->work + 2 * rt->max_dim;   /* after the evaluator's own work */
            for (j = 0; j < dim; j++)
                rg[j] = rt->res[idx[j]];
            e = fdi_evaluator_step(ev, &pl->ev[g], rg, rt->work);
        } else {
            double sq;
            if (dim == 1) {
                double xr = rt->res[idx[0]];
                sq = xr * xr;
            } else {
                sq = 0.0;
                for (j = 0; j < dim; j++)
                    sq += rt->res[idx[j]] * rt->res[idx[j]];
            }
            e = fdi_evaluator_step_sq(ev, &pl->ev[g], sq);
        }
        rt->evals[g] = e;
        rt->thrs[g] = scale * fdi_threshold_step(&rt->th[g], &pl->thev[g], unorm);
        group_ok = group_ok && isfinite(e) && fdi_evaluator_finite(ev);
        rt->fired[g] = (unsigned char)(!group_ok || e >= rt->thrs[g]);
        ok = ok && group_ok && isfinite(rt->thrs[g]) && fdi_threshold_finite(&rt->th[g]);
    }
    return ok;
}

/* The decision outputs (alarms, fault_detected, isolated_fault) from rt->dec. */
static void decision_outputs(fdi_runtime *rt)
{
    long i, nr = rt->d->n_r, ng = rt->d->n_groups;
    double *out = rt->outputs;
    int any = 0;
    for (i = 0; i < ng; i++) {
        out[nr + 2 * ng + i] = rt->dec.alarms[i] ? 1.0 : 0.0;
        any |= rt->dec.alarms[i];
    }
    out[nr + 3 * ng] = any ? 1.0 : 0.0;
    out[nr + 3 * ng + 1] = (double)*rt->dec.isolated;
}

fdi_status fdi_runtime_advance(fdi_runtime *rt, const double *u, const double *y, double h,
                               char *why, size_t whylen)
{
    const fdi_design *d;
    long i, nr, ng, nu, ny;
    fdi_int s;
    double unorm = 0.0, *out;
    int valid = 1, ok = 1;
    if (!rt || rt->magic != FDI_MAGIC) {
        say(why, whylen, "runtime not initialised");
        return FDI_ERROR;
    }
    d = rt->d;
    nr = d->n_r;
    ng = d->n_groups;
    nu = d->n_u;
    ny = d->n_y;
    out = rt->outputs;
    if (!same_step(h, *rt->h)) {
        int nxt = 1 - rt->cur;
        fdi_plan *np = &rt->plan[nxt];
        double prev_ratio = rt->plan[rt->cur].ratio;
        if (!make_plan(rt, h, np, why, whylen))
            return FDI_DISCARD;
        rt->cur = nxt;
        *rt->h = h;
        if (np->ratio != prev_ratio)
            reset_stage(rt);
    }
    out[nr + 3 * ng + 3] = 0.0;
    for (i = 0; i < nu && valid; i++)
        valid = isfinite(u[i]) && d->lo[i] <= u[i] && u[i] <= d->hi[i];
    for (i = 0; i < ny && valid; i++)
        valid = isfinite(y[i]) && d->lo[nu + i] <= y[i] && y[i] <= d->hi[nu + i];
    if (!valid) {
        out[nr + 3 * ng + 2] = 1.0;
        return FDI_OK;
    }
    out[nr + 3 * ng + 2] = 0.0;
    for (i = 0; i < ny; i++) {
        rt->v[i] = y[i] - d->y0[i];
        ok = ok && isfinite(rt->v[i]);
    }
    for (i = 0; i < nu; i++) {
        double du = u[i] - d->u0[i];
        rt->v[ny + i] = du;
        unorm += du * du;
        ok = ok && isfinite(du);
    }
    unorm = sqrt(unorm);
    ok = ok && isfinite(unorm);
    if (!ok) {   /* the sample offsets overflowed: every group's raw test fires (S8) */
        memset(rt->fired, 1, (size_t)ng);
        fdi_decision_step_fired(&rt->dec, rt->fired, NULL);
        decision_outputs(rt);
    }
    for (s = 0; ok && s < rt->plan[rt->cur].substeps; s++) {
        if (!sample(rt, unorm)) {   /* overflow: the decision steps with the overflow raw tests */
            ok = 0;
            fdi_decision_step_fired(&rt->dec, rt->fired, NULL);
            decision_outputs(rt);
            break;
        }
        fdi_decision_step(&rt->dec, rt->evals, rt->thrs, rt->res, rt->fired);
        memcpy(out, rt->res, (size_t)nr * sizeof(double));
        memcpy(out + nr, rt->evals, (size_t)ng * sizeof(double));
        memcpy(out + nr + ng, rt->thrs, (size_t)ng * sizeof(double));
        decision_outputs(rt);
    }
    if (!ok) {   /* S8: discard the sub-sample, restart generator, evaluators and thresholds */
        reset_generator(rt);
        reset_stage(rt);
        out[nr + 3 * ng + 2] = 1.0;
        out[nr + 3 * ng + 3] = 1.0;
        *rt->n_numeric_resets += 1;
    }
    *rt->n_samples += 1;
    return FDI_OK;
}

const double *fdi_runtime_outputs(const fdi_runtime *rt) { return rt->outputs; }
double fdi_runtime_step(const fdi_runtime *rt) { return *rt->h; }
double fdi_runtime_sample_ratio(const fdi_runtime *rt) { return rt->plan[rt->cur].ratio; }

fdi_status fdi_runtime_set_threshold_scale(fdi_runtime *rt, double scale, char *why, size_t whylen)
{
    char msg[128];
    if (!(isfinite(scale) && scale >= 0.0)) {
        snprintf(msg, sizeof msg, "threshold_scale must be a finite number >= 0, got %g", scale);
        say(why, whylen, msg);
        return FDI_ERROR;
    }
    *rt->scale = scale;
    return FDI_OK;
}

double fdi_runtime_threshold_scale(const fdi_runtime *rt) { return *rt->scale; }

/* ------------------------------------------------------------------ FMU state image */
/* Header: magic (8 bytes), design hash, image size, and the counts of doubles, integers and
 * bytes (64-bit little- or big-endian as the host: images are not portable across byte orders),
 * then the three state regions. */
size_t fdi_runtime_state_size(const fdi_runtime *rt)
{
    return STATE_HEADER + rt->st.nd * sizeof(double) + rt->st.ni * sizeof(fdi_int) + rt->st.nb;
}

void fdi_runtime_get_state(const fdi_runtime *rt, unsigned char *buf)
{
    unsigned long long hdr[5];
    hdr[0] = rt->d->hash;
    hdr[1] = fdi_runtime_state_size(rt);
    hdr[2] = rt->st.nd;
    hdr[3] = rt->st.ni;
    hdr[4] = rt->st.nb;
    memcpy(buf, STATE_MAGIC, 8);
    memcpy(buf + 8, hdr, sizeof hdr);
    buf += STATE_HEADER;
    memcpy(buf, rt->st.d, rt->st.nd * sizeof(double));
    buf += rt->st.nd * sizeof(double);
    memcpy(buf, rt->st.i, rt->st.ni * sizeof(fdi_int));
    buf += rt->st.ni * sizeof(fdi_int);
    memcpy(buf, rt->st.b, rt->st.nb);
}

/* The outputs fit the decision state: alarms, fault_detected and isolated_fault are the
 * decision's; the two flags are 0 or 1; evaluations are >= 0 (every kind's J is). */
static int outputs_sane(const fdi_runtime *rt)
{
    const double *out = rt->outputs;
    long i, nr = rt->d->n_r, ng = rt->d->n_groups;
    int any = 0;
    for (i = 0; i < ng; i++) {
        if (out[nr + 2 * ng + i] != (rt->dec.alarms[i] ? 1.0 : 0.0) || !(out[nr + i] >= 0.0))
            return 0;
        any |= rt->dec.alarms[i];
    }
    return out[nr + 3 * ng] == (any ? 1.0 : 0.0) && out[nr + 3 * ng + 1] == (double)*rt->dec.isolated &&
           (out[nr + 3 * ng + 2] == 0.0 || out[nr + 3 * ng + 2] == 1.0) &&
           (out[nr + 3 * ng + 3] == 0.0 || out[nr + 3 * ng + 3] == 1.0);
}

/* The loaded regions describe a state a run of this design can reach (docs/semantics.md S10):
 * every count and index within what the design allows, every derived value consistent. */
static int state_sane(fdi_runtime *rt)
{
    const fdi_plan *pl = &rt->plan[rt->cur];
    long g;
    if (*rt->n_samples < 0 || *rt->n_samples >= FDI_EXACT_MAX || *rt->n_numeric_resets < 0 ||
        *rt->n_numeric_resets > *rt->n_samples || !(*rt->scale >= 0.0))
        return 0;
    for (g = 0; g < rt->d->n_groups; g++)
        if (!fdi_evaluator_check(&rt->ev[g], &pl->ev[g]) || !fdi_threshold_check(&rt->th[g], &pl->thev[g]))
            return 0;
    if (rt->d->gen_kind == FDI_GEN_RLS && !fdi_rls_check(&rt->rls))
        return 0;
    return fdi_decision_load(&rt->dec) && outputs_sane(rt);
}

fdi_status fdi_runtime_set_state(fdi_runtime *rt, const unsigned char *buf, size_t len,
                                 char *why, size_t whylen)
{
    unsigned long long hdr[5];
    size_t nd = rt->st.nd, ni = rt->st.ni, nb = rt->st.nb, k;
    const unsigned char *bi = buf + STATE_HEADER + nd * sizeof(double), *bb = bi + ni * sizeof(fdi_int);
    double h;
    char msg[200];
    int old_cur = rt->cur, nxt = 1 - rt->cur;
    if (!buf || len < STATE_HEADER || memcmp(buf, STATE_MAGIC, 8) != 0) {
        say(why, whylen, "not an FMU state image of fmu-fdi's native runtime (bad magic)");
        return FDI_ERROR;
    }
    memcpy(hdr, buf + 8, sizeof hdr);
    if (hdr[0] != rt->d->hash) {
        say(why, whylen, "the FMU state image belongs to another design (design hash differs)");
        return FDI_ERROR;
    }
    if (hdr[1] != len || len != fdi_runtime_state_size(rt) || hdr[2] != nd || hdr[3] != ni || hdr[4] != nb) {
        snprintf(msg, sizeof msg, "FMU state image has %lu bytes, this instance needs %lu",
                 (unsigned long)len, (unsigned long)fdi_runtime_state_size(rt));
        say(why, whylen, msg);
        return FDI_ERROR;
    }
    for (k = 0; k < nd; k++) {
        double x;
        memcpy(&x, buf + STATE_HEADER + k * sizeof(double), sizeof x);
        if (!isfinite(x)) {
            say(why, whylen, "FMU state image holds a non-finite number");
            return FDI_ERROR;
        }
    }
    memcpy(&h, buf + STATE_HEADER + (size_t)(rt->h - rt->st.d) * sizeof(double), sizeof h);
    if (h != *rt->h) {   /* exact: the saved step, not one within tolerance */
        if (!make_plan(rt, h, &rt->plan[nxt], why, whylen))
            return FDI_ERROR;
        rt->cur = nxt;
    }
    /* back up, load, check; restore on failure */
    memcpy(rt->bk_d, rt->st.d, nd * sizeof(double));
    memcpy(rt->bk_i, rt->st.i, ni * sizeof(fdi_int));
    memcpy(rt->bk_b, rt->st.b, nb);
    memcpy(rt->st.d, buf + STATE_HEADER, nd * sizeof(double));
    memcpy(rt->st.i, bi, ni * sizeof(fdi_int));
    memcpy(rt->st.b, bb, nb);
    if (!state_sane(rt)) {
        memcpy(rt->st.d, rt->bk_d, nd * sizeof(double));
        memcpy(rt->st.i, rt->bk_i, ni * sizeof(fdi_int));
        memcpy(rt->st.b, rt->bk_b, nb);
        rt->cur = old_cur;
        fdi_decision_load(&rt->dec);
        say(why, whylen, "FMU state image is inconsistent with this design (a count, index or derived value that "
            "no run of the design can produce)");
        return FDI_ERROR;
    }
    return FDI_OK;
}
