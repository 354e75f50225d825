/* fdi_schedule.c - the scheduled diagnoser of the native FMU (C99; docs/semantics.md §12, the
 * same as fmu_fdi/runtime/schedule.py). See fdi_schedule.h.
 *
 * The instance block holds: the fdi_sched header, pointer tables, scratch (the LTI states saved
 * during a warm start, the offset sample, the outputs), then per member its runtime block and a
 * buffer for its state image (so a step one member refuses, or a state image one member refuses,
 * is rolled back on the members that took it: nothing changes). No allocation after init, no
 * global mutable state.
 */
#include "fdi_model.h"

#ifdef FDI_SCHEDULED
#define FDI_SCHEDULE_IMPLEMENTATION
#include "fdi_schedule.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "fdi_internal.h"

#define SCHED_MAGIC 0x4644495343484431ULL  /* "FDISCHD1" */
static const unsigned char IMAGE_MAGIC[8] = {'F', 'D', 'I', 'S', 'C', 'H', 'D', '1'};
#define IMAGE_HEADER 32                    /* magic, hash, total bytes, active */
#define IMAGE_SLACK 64                     /* a member's image: its state regions + a header */

struct fdi_sched {
    unsigned long long magic;
    const fdi_schedule *s;
    long active;            /* 0-based, -1 before the first valid sample */
    long n_member_out;
    fdi_runtime **m;
    unsigned char **image;  /* per member: state image buffer (rollback) */
    size_t *image_cap;
    double *xsave;          /* per member LTI state while a warm start may be undone */
    double *v;
    double *out;
};

static size_t align8(size_t n) { return (n + 7u) & ~(size_t)7u; }

static void say(char *why, size_t whylen, const char *msg)
{
    if (why && whylen) {
        strncpy(why, msg, whylen - 1);
        why[whylen - 1] = '\0';
    }
}

size_t fdi_sched_n_u(const fdi_schedule *s) { return fdi_n_u(s->members[0]); }
size_t fdi_sched_n_y(const fdi_schedule *s) { return fdi_n_y(s->members[0]); }
size_t fdi_sched_n_outputs(const fdi_schedule *s) { return fdi_n_outputs(s->members[0]) + 1; }
double fdi_sched_sample_time(const fdi_schedule *s) { return fdi_sample_time(s->members[0]); }

static size_t n_states(const fdi_schedule *s)
{
    size_t n = 0;
    long k;
    for (k = 0; k < s->K; k++) n += (size_t)s->members[k]->n_x;
    return n;
}

size_t fdi_sched_size(const fdi_schedule *s)
{
    size_t n = align8(sizeof(struct fdi_sched)) + 3 * align8(sizeof(void *) * (size_t)s->K) +
               align8(sizeof(double) * (n_states(s) + fdi_sched_n_u(s) + fdi_sched_n_y(s) + fdi_sched_n_outputs(s)));
    long k;
    for (k = 0; k < s->K; k++) {
        size_t r = align8(fdi_runtime_size(s->members[k]));
        n += r + align8(r + IMAGE_SLACK);
    }
    return n;
}

/* outputs (docs/semantics.md §12 step 5): the active member's (member 1's while none is active),
 * active_member inserted before fault_detected, numeric_reset = any member's, input_invalid = the
 * active member's or numeric_reset (an overflow in any member is an unusable sample, §8) */
static void compose(fdi_sched *rt)
{
    const long n = rt->n_member_out, K = rt->s->K;
    const double *src = fdi_runtime_outputs(rt->m[rt->active < 0 ? 0 : rt->active]);
    long i, k;
    int reset = 0;
    for (k = 0; k < K; k++)
        if (fdi_runtime_outputs(rt->m[k])[n - 1] != 0.0) reset = 1;
    for (i = 0; i < n - 4; i++) rt->out[i] = src[i];
    rt->out[n - 4] = (double)(rt->active + 1);
    for (i = n - 4; i < n; i++) rt->out[i + 1] = src[i];
    rt->out[n] = reset ? 1.0 : 0.0;
    if (reset) rt->out[n - 1] = 1.0;
}

fdi_status fdi_sched_init(fdi_sched *rt, const fdi_schedule *s, size_t nbytes)
{
    unsigned char *p = (unsigned char *)rt;
    long k;
    if (!rt || nbytes < fdi_sched_size(s)) return FDI_ERROR;
    memset(rt, 0, sizeof *rt);
    rt->s = s;
    rt->n_member_out = (long)fdi_n_outputs(s->members[0]);
    p += align8(sizeof(struct fdi_sched));
    rt->m = (fdi_runtime **)(void *)p;
    p += align8(sizeof(void *) * (size_t)s->K);
    rt->image = (unsigned char **)(void *)p;
    p += align8(sizeof(void *) * (size_t)s->K);
    rt->image_cap = (size_t *)(void *)p;
    p += align8(sizeof(void *) * (size_t)s->K);
    rt->xsave = (double *)(void *)p;
    rt->v = rt->xsave + n_states(s);
    rt->out = rt->v + fdi_sched_n_u(s) + fdi_sched_n_y(s);
    p += align8(sizeof(double) * (n_states(s) + fdi_sched_n_u(s) + fdi_sched_n_y(s) + fdi_sched_n_outputs(s)));
    for (k = 0; k < s->K; k++) {
        size_t r = align8(fdi_runtime_size(s->members[k]));
        rt->m[k] = (fdi_runtime *)(void *)p;
        p += r;
        rt->image[k] = p;
        rt->image_cap[k] = align8(r + IMAGE_SLACK);
        p += rt->image_cap[k];
        if (fdi_runtime_init(rt->m[k], s->members[k], r) != FDI_OK) return FDI_ERROR;
        if (fdi_runtime_state_size(rt->m[k]) > rt->image_cap[k]) return FDI_ERROR;
    }
    rt->magic = SCHED_MAGIC;
    fdi_sched_reset(rt);
    return FDI_OK;
}

void fdi_sched_reset(fdi_sched *rt)
{
    long k;
    for (k = 0; k < rt->s->K; k++) fdi_runtime_reset(rt->m[k]);
    rt->active = -1;
    compose(rt);
}

const double *fdi_sched_outputs(const fdi_sched *rt) { return rt->out; }
/* the members run on the same calls: member 1's step and plan are every member's */
double fdi_sched_step(const fdi_sched *rt) { return fdi_runtime_step(rt->m[0]); }
double fdi_sched_sample_ratio(const fdi_sched *rt) { return fdi_runtime_sample_ratio(rt->m[0]); }

/* docs/semantics.md §3 with member 1's ranges (the members share signals and ranges) */
static int valid_sample(const fdi_design *d, const double *u, const double *y)
{
    long i;
    for (i = 0; i < d->n_u; i++)
        if (!(isfinite(u[i]) && d->lo[i] <= u[i] && u[i] <= d->hi[i])) return 0;
    for (i = 0; i < d->n_y; i++)
        if (!(isfinite(y[i]) && d->lo[d->n_u + i] <= y[i] && y[i] <= d->hi[d->n_u + i])) return 0;
    return 1;
}

/* §12 step 2: x_k = M_k v_k, v_k = [y - y0_k; u - u0_k]; the states before are kept in xsave */
static void warm_start(fdi_sched *rt, const double *u, const double *y)
{
    const fdi_schedule *s = rt->s;
    double *save = rt->xsave;
    long k, i;
    for (k = 0; k < s->K; k++) {
        const fdi_design *d = s->members[k];
        fdi_runtime *m = rt->m[k];
        const long n = d->n_x, nin = d->n_y + d->n_u;
        int finite = 1;
        memcpy(save, m->x, sizeof(double) * (size_t)n);
        if (n > 0 && s->warm[k]) {
            for (i = 0; i < d->n_y; i++) rt->v[i] = y[i] - d->y0[i];
            for (i = 0; i < d->n_u; i++) rt->v[d->n_y + i] = u[i] - d->u0[i];
            fdi_matvec(s->warm[k], n, nin, rt->v, m->x);
            for (i = 0; i < n; i++) finite = finite && isfinite(m->x[i]);
            if (!finite) memcpy(m->x, save, sizeof(double) * (size_t)n);
        }
        save += n;
    }
}

static void undo_warm_start(fdi_sched *rt)
{
    const double *save = rt->xsave;
    long k;
    for (k = 0; k < rt->s->K; k++) {
        const long n = rt->s->members[k]->n_x;
        memcpy(rt->m[k]->x, save, sizeof(double) * (size_t)n);
        save += n;
    }
}

/* §12 step 4: nearest member with hysteresis on the sample's scheduling values */
static long nearest(const fdi_schedule *s, const double *u, const double *y, long active)
{
    const long nu = (long)fdi_sched_n_u(s);
    long best = -1, k, j;
    double best_d = HUGE_VAL, d_active = HUGE_VAL;
    for (k = 0; k < s->K; k++) {
        double acc = 0.0, dk;
        for (j = 0; j < s->S; j++) {
            const long at = s->sig_index[j];
            const double sj = at < nu ? u[at] : y[at - nu];
            const double q = (sj - s->points[k * s->S + j]) / s->scale[j];
            acc += q * q;
        }
        dk = sqrt(acc);
        if (dk < best_d) {
            best = k;
            best_d = dk;
        }
        if (k == active) d_active = dk;
    }
    if (active < 0 || best_d + s->hysteresis < d_active) return best;
    return active;
}

/* members 1..n back to the images saved in rt->image (which they produced: cannot fail) */
static void restore_members(fdi_sched *rt, long n)
{
    char ignored[8];
    long j;
    for (j = 0; j < n; j++)
        fdi_runtime_set_state(rt->m[j], rt->image[j], fdi_runtime_state_size(rt->m[j]), ignored, sizeof ignored);
}

fdi_status fdi_sched_advance(fdi_sched *rt, const double *u, const double *y, double h, char *why, size_t whylen)
{
    const fdi_schedule *s = rt->s;
    const int new_step = h != *rt->m[0]->h;
    const int valid = valid_sample(s->members[0], u, y);   /* §3: the members' common verdict */
    int warm = 0;
    long k;
    if (new_step)  /* a step some member may refuse: keep every member's state to roll back */
        for (k = 0; k < s->K; k++) fdi_runtime_get_state(rt->m[k], rt->image[k]);
    if (rt->active < 0 && s->warm && valid) {
        warm_start(rt, u, y);
        warm = 1;
    }
    for (k = 0; k < s->K; k++) {
        fdi_status st = fdi_runtime_advance(rt->m[k], u, y, h, why, whylen);
        if (st == FDI_OK) continue;
        if (k == 0) {  /* nothing has changed but the warm start */
            if (warm) undo_warm_start(rt);
            return st;
        }
        if (!new_step) return FDI_ERROR;
        restore_members(rt, s->K);   /* the images predate the warm start too */
        return st;
    }
    if (valid)   /* an overflow inside a member (§8) does not hold the schedule: s is a valid sample */
        rt->active = nearest(s, u, y, rt->active);
    compose(rt);
    return FDI_OK;
}

fdi_status fdi_sched_set_threshold_scale(fdi_sched *rt, double scale, char *why, size_t whylen)
{
    long k;
    if (fdi_runtime_set_threshold_scale(rt->m[0], scale, why, whylen) != FDI_OK) return FDI_ERROR;
    for (k = 1; k < rt->s->K; k++) fdi_runtime_set_threshold_scale(rt->m[k], scale, why, whylen);
    return FDI_OK;
}

double fdi_sched_threshold_scale(const fdi_sched *rt) { return fdi_runtime_threshold_scale(rt->m[0]); }

/* ---- state image: magic[8] | u64 hash | u64 total | i64 active | per member: u64 len, image */
size_t fdi_sched_state_size(const fdi_sched *rt)
{
    size_t n = IMAGE_HEADER;
    long k;
    for (k = 0; k < rt->s->K; k++) n += 8 + fdi_runtime_state_size(rt->m[k]);
    return n;
}

void fdi_sched_get_state(const fdi_sched *rt, unsigned char *buf)
{
    uint64_t hdr[2];
    int64_t active = rt->active;
    long k;
    memcpy(buf, IMAGE_MAGIC, 8);
    hdr[0] = rt->s->hash;
    hdr[1] = fdi_sched_state_size(rt);
    memcpy(buf + 8, hdr, sizeof hdr);
    memcpy(buf + 24, &active, 8);
    buf += IMAGE_HEADER;
    for (k = 0; k < rt->s->K; k++) {
        uint64_t len = fdi_runtime_state_size(rt->m[k]);
        memcpy(buf, &len, 8);
        fdi_runtime_get_state(rt->m[k], buf + 8);
        buf += 8 + len;
    }
}

fdi_status fdi_sched_set_state(fdi_sched *rt, const unsigned char *buf, size_t len, char *why, size_t whylen)
{
    const fdi_schedule *s = rt->s;
    uint64_t hdr[2];
    int64_t active;
    const unsigned char *p;
    char msg[256];
    long k;
    if (!buf || len < IMAGE_HEADER || memcmp(buf, IMAGE_MAGIC, 8) != 0) {
        say(why, whylen, "not a state image of a scheduled diagnoser (bad magic)");
        return FDI_ERROR;
    }
    memcpy(hdr, buf + 8, sizeof hdr);
    memcpy(&active, buf + 24, 8);
    if (hdr[0] != s->hash || hdr[1] != len || len != fdi_sched_state_size(rt) || active < -1 || active >= s->K) {
        snprintf(msg, sizeof msg, "state image of another scheduled design or size (%lu bytes, this instance needs "
                 "%lu; active member %lld of %ld)", (unsigned long)len, (unsigned long)fdi_sched_state_size(rt),
                 (long long)active, s->K);
        say(why, whylen, msg);
        return FDI_ERROR;
    }
    for (k = 0, p = buf + IMAGE_HEADER; k < s->K; k++) {
        uint64_t n;
        memcpy(&n, p, 8);
        if (n != fdi_runtime_state_size(rt->m[k])) {
            snprintf(msg, sizeof msg, "member %ld's state image has %lu bytes, it needs %lu", k + 1, (unsigned long)n,
                     (unsigned long)fdi_runtime_state_size(rt->m[k]));
            say(why, whylen, msg);
            return FDI_ERROR;
        }
        p += 8 + n;
    }
    for (k = 0; k < s->K; k++) fdi_runtime_get_state(rt->m[k], rt->image[k]);
    for (k = 0, p = buf + IMAGE_HEADER; k < s->K; k++) {
        const size_t n = fdi_runtime_state_size(rt->m[k]);
        if (fdi_runtime_set_state(rt->m[k], p + 8, n, why, whylen) != FDI_OK) {
            restore_members(rt, k);
            snprintf(msg, sizeof msg, "member %ld: %s", k + 1, why ? why : "state refused");
            say(why, whylen, msg);
            return FDI_ERROR;
        }
        p += 8 + n;
    }
    for (k = 1; k < s->K; k++)   /* members run on the same calls (§12): one step, scale, sample count */
        if (*rt->m[k]->h != *rt->m[0]->h || *rt->m[k]->scale != *rt->m[0]->scale ||
            *rt->m[k]->n_samples != *rt->m[0]->n_samples) {
            snprintf(msg, sizeof msg, "member %ld is at step %g, threshold_scale %g after %lld samples, member 1 at "
                     "%g, %g, %lld (members run on the same calls)", k + 1, *rt->m[k]->h, *rt->m[k]->scale,
                     (long long)*rt->m[k]->n_samples, *rt->m[0]->h, *rt->m[0]->scale, (long long)*rt->m[0]->n_samples);
            say(why, whylen, msg);
            restore_members(rt, s->K);
            return FDI_ERROR;
        }
    if (active >= 0 && *rt->m[0]->n_samples == 0) {   /* a member becomes active on a valid sample */
        snprintf(msg, sizeof msg, "active member %lld before any valid sample", (long long)active + 1);
        say(why, whylen, msg);
        restore_members(rt, s->K);
        return FDI_ERROR;
    }
    rt->active = (long)active;
    compose(rt);
    return FDI_OK;
}
#else
typedef int fdi_schedule_not_built;  /* a plain design: ISO C wants a declaration in every file */
#endif
